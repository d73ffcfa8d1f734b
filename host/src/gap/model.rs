//! The gap tool's model of a recording: per frame, the base simulator's Monte-Carlo draws and the
//! zones' covariates, computed once; then any candidate configuration (base + sim-to-real effects)
//! is evaluated by applying the effects' forward models (from `crate::sim`) to the draws, without
//! re-running the simulator. Dropout effects scale a draw's survival probability, noise effects
//! add to its kernel scale, distance effects move it: the likelihood is smooth in every parameter.

use rayon::prelude::*;

use super::data::{GapData, GapFrame};
use super::likelihood::{Density, Draw, ZoneFit};
use crate::rng::Rng;
use crate::sim::covariates::{zone_covariates, ZoneCovariates};
use crate::sim::effects::{self, EffectFit};
use crate::sim::{simulate_with_covariates, SimConfig, SimError};

/// One frame, prepared.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// Zone rows, cols.
    pub rows: usize,
    /// Zone columns.
    pub cols: usize,
    /// Monte-Carlo draws under the base configuration, draw-major (`k * zones + z`).
    pub draws: Vec<Draw>,
    /// Number of draws `K`.
    pub k: usize,
    /// Covariates per zone over the nominal windows (localisation: what a real recording shows).
    pub cov: Vec<ZoneCovariates>,
    /// Covariates per draw and zone over that draw's own moved windows, draw-major like
    /// [`Prepared::draws`]: the inputs of the window-dependent forward models (`dark_dropout`,
    /// `edge_mixing`, `multipath`), exactly as the simulator computes them.
    pub draw_cov: Vec<ZoneCovariates>,
    /// The real measurement per zone (`None`: no target).
    pub real: Vec<Option<f32>>,
    /// Frame time, seconds.
    pub t_s: f64,
}

impl Prepared {
    /// Number of zones.
    pub fn zones(&self) -> usize {
        self.rows * self.cols
    }
}

/// Scale of the Student-t₃ kernel that stands for Gaussian noise of standard deviation 1: the
/// maximum-likelihood t₃ scale on N(0, 1) data (solves E[4z²/(3 + z²)] = 1, z = x/s). With the
/// plain σ the fitted `range_noise.sigma_per_m` came out ≈ 0.75× the simulator's.
pub const T3_SCALE_OF_GAUSSIAN: f32 = 0.7935;

/// Seed of draw `k` of frame `f` for a run seeded `seed`.
fn draw_seed(seed: u64, f: usize, k: usize) -> u64 {
    Rng::derive(seed ^ 0x6A9_0000, (f as u64) << 20 | k as u64).next_u64()
}

/// Simulates `k` draws of frame `f` under `base` and computes its covariates.
pub fn prepare_frame(
    base: &SimConfig,
    frame: &GapFrame,
    f: usize,
    k: usize,
    seed: u64,
) -> Result<Prepared, SimError> {
    let input = frame.sim_input();
    let (rows, cols) = (usize::from(base.grid.rows), usize::from(base.grid.cols));
    let mut draws = Vec::with_capacity(k * rows * cols);
    let mut draw_cov = Vec::with_capacity(k * rows * cols);
    for j in 0..k {
        let (out, c) = simulate_with_covariates(base, &input, draw_seed(seed, f, j))?;
        draw_cov.extend(c);
        for z in 0..rows * cols {
            let valid = out.is_valid(z);
            draws.push(Draw {
                p: f32::from(u8::from(valid)),
                d: out.distance_mm[z] / 1000.0,
                s: 0.0,
                peak: out.truth[z].peak_m,
            });
        }
    }
    let rects = base.grid.zone_rects_px(frame.width, frame.height);
    let (w, h) = (frame.width as i64, frame.height as i64);
    let mut px = Vec::new();
    let cov = rects
        .iter()
        .enumerate()
        .map(|(z, r)| {
            px.clear();
            let (y0, x0) = ((r[0].floor() as i64).max(0), (r[1].floor() as i64).max(0));
            let (y1, x1) = ((r[2].ceil() as i64).min(h), (r[3].ceil() as i64).min(w));
            for y in y0..y1 {
                for x in x0..x1 {
                    px.push((y * w + x) as u32);
                }
            }
            zone_covariates(&input, &px, 1.0, z, rows, cols)
        })
        .collect();
    let real = frame
        .real_valid
        .iter()
        .zip(&frame.real_m)
        .map(|(&v, &d)| (v && d > 0.0).then_some(d))
        .collect();
    Ok(Prepared {
        rows,
        cols,
        draws,
        k,
        cov,
        draw_cov,
        real,
        t_s: frame.t_s,
    })
}

/// Prepares every frame of `data` in parallel (calling `progress` after each).
pub fn prepare(
    base: &SimConfig,
    data: &GapData,
    k: usize,
    seed: u64,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<Prepared>, SimError> {
    data.frames
        .par_iter()
        .enumerate()
        .map(|(f, frame)| {
            let p = prepare_frame(base, frame, f, k, seed);
            progress();
            p
        })
        .collect()
}

/// The draws of `prep` under `model` (its sim-to-real effects that `base` lacks applied to the
/// base draws), with background zones shifted by `shift` (`[dr, dc]`, `calibration_shift`).
pub fn transform(
    model: &SimConfig,
    base: &SimConfig,
    prep: &Prepared,
    shift: [i64; 2],
) -> Vec<Draw> {
    let on = |e: &EffectFit| e.enabled(model) && !e.enabled(base);
    let (z_n, rows, cols) = (prep.zones(), prep.rows, prep.cols);
    let mut out = prep.draws.clone();
    if shift != [0, 0] {
        let q = f64::from(
            model.calibration_shift.percentile[0] + model.calibration_shift.percentile[1],
        ) / 2.0;
        for k in 0..prep.k {
            let d = &mut out[k * z_n..(k + 1) * z_n];
            let mut peaks: Vec<f32> = d.iter().map(|x| x.peak).filter(|&p| p > 0.0).collect();
            if peaks.is_empty() {
                continue;
            }
            peaks.sort_by(f32::total_cmp);
            let thr = peaks[((q * (peaks.len() - 1) as f64).floor() as usize).min(peaks.len() - 1)];
            let before = d.to_vec();
            for (z, x) in d.iter_mut().enumerate() {
                if x.peak <= thr {
                    continue;
                }
                let (r, c) = ((z / cols) as i64 + shift[0], (z % cols) as i64 + shift[1]);
                if (0..rows as i64).contains(&r) && (0..cols as i64).contains(&c) {
                    let src = before[(r as usize) * cols + c as usize];
                    *x = Draw {
                        peak: x.peak,
                        ..src
                    };
                } else {
                    x.p = 0.0;
                }
            }
        }
    }
    let (radial, bias, edge, multi, xtalk, wiggle, noise) = (
        on(&effects::radial_distance::FIT),
        on(&effects::range_bias::FIT),
        on(&effects::edge_mixing::FIT),
        on(&effects::multipath::FIT),
        on(&effects::zone_crosstalk::FIT),
        on(&effects::bin_wiggle::FIT),
        on(&effects::range_noise::FIT),
    );
    let (rdrop, ddrop, bdrop) = (
        on(&effects::range_dropout::FIT),
        on(&effects::dark_dropout::FIT),
        on(&effects::border_dropout::FIT),
    );
    // The learned terms (flexible forms) apply last, as in the simulator's pipeline.
    let learned = model.learned.enabled && !model.learned.terms.is_empty() && !base.learned.enabled;
    let mut dist = vec![0.0f32; z_n];
    let mut valid = vec![0.0f32; z_n];
    for k in 0..prep.k {
        let d = &mut out[k * z_n..(k + 1) * z_n];
        let dc = &prep.draw_cov[k * z_n..(k + 1) * z_n];
        for (z, x) in d.iter_mut().enumerate() {
            let c = &dc[z];
            if x.p <= 0.0 {
                continue;
            }
            if radial {
                x.d *= model.radial_distance.factor(c.grid_pos);
            }
            if bias {
                x.d = model.range_bias.distance(x.d);
            }
            if edge {
                x.d = model.edge_mixing.distance(x.d, c);
            }
            if multi {
                x.d = model.multipath.distance(x.d, c);
            }
        }
        if xtalk {
            for (z, x) in d.iter().enumerate() {
                dist[z] = x.d;
                valid[z] = x.p;
            }
            model.zone_crosstalk.blur(rows, cols, &mut dist, &valid);
            for (z, x) in d.iter_mut().enumerate() {
                x.d = dist[z];
            }
        }
        for (z, x) in d.iter_mut().enumerate() {
            let c = &dc[z];
            if x.p <= 0.0 {
                continue;
            }
            if wiggle {
                x.d = model.bin_wiggle.distance(x.d);
            }
            if noise {
                let s = T3_SCALE_OF_GAUSSIAN * model.range_noise.sigma(x.d);
                x.s = (x.s * x.s + s * s).sqrt();
            }
            if rdrop {
                x.p *= 1.0 - model.range_dropout.loss_probability(x.d);
            }
            if ddrop {
                x.p *= 1.0 - model.dark_dropout.loss_probability(c);
            }
            if bdrop {
                x.p *= 1.0 - model.border_dropout.loss_probability(c.radius);
            }
            if learned {
                let l = &model.learned;
                x.d = l.distance(x.d, c);
                let s = T3_SCALE_OF_GAUSSIAN * l.sigma(x.d, c);
                x.s = (x.s * x.s + s * s).sqrt();
                x.p *= 1.0 - l.loss_probability(x.d, c);
            }
        }
    }
    out
}

/// The frame-level scenarios of `model`: `(weight, shift)`; one unshifted scenario unless the
/// model adds a `calibration_shift` the base lacks (then the frame is unshifted with probability
/// `1 − frame_probability`, else shifted uniformly in `{−m..m}²`).
pub fn scenarios(model: &SimConfig, base: &SimConfig) -> Vec<(f64, [i64; 2])> {
    let cs = &model.calibration_shift;
    if !cs.enabled || base.calibration_shift.enabled {
        return vec![(1.0, [0, 0])];
    }
    let [mr, mc] = cs.max_shift_zones.map(i64::from);
    let n = ((2 * mr + 1) * (2 * mc + 1)) as f64;
    let fp = f64::from(cs.frame_probability);
    let mut v = Vec::new();
    for dr in -mr..=mr {
        for dc in -mc..=mc {
            let w = fp / n + if dr == 0 && dc == 0 { 1.0 - fp } else { 0.0 };
            v.push((w, [dr, dc]));
        }
    }
    v
}

/// Scores every zone of `prep` under `draws` (from [`transform`]).
pub fn score_zones(density: &Density, prep: &Prepared, draws: &[Draw]) -> Vec<ZoneFit> {
    let z_n = prep.zones();
    let mut buf = vec![Draw::default(); prep.k];
    (0..z_n)
        .map(|z| {
            for (k, b) in buf.iter_mut().enumerate() {
                *b = draws[k * z_n + z];
            }
            density.score(&buf, prep.real[z])
        })
        .collect()
}

/// A frame's evaluation under one model.
#[derive(Clone, Debug)]
pub struct FrameEval {
    /// Negative log-likelihood of the frame (sum over zones; a mixture over shift scenarios).
    pub nll: f64,
    /// Per-zone fits under the most probable scenario.
    pub zones: Vec<ZoneFit>,
}

/// Evaluates frame `prep` under `model`; `detail` also keeps the per-zone fits.
pub fn eval_frame(
    density: &Density,
    model: &SimConfig,
    base: &SimConfig,
    prep: &Prepared,
    detail: bool,
) -> FrameEval {
    let sc = scenarios(model, base);
    let mut best: Option<(f64, Vec<ZoneFit>)> = None;
    let mut terms = Vec::with_capacity(sc.len());
    for (w, shift) in sc {
        if w <= 0.0 {
            continue;
        }
        let draws = transform(model, base, prep, shift);
        let zones = score_zones(density, prep, &draws);
        let nll: f64 = zones.iter().map(|z| z.nll).sum();
        let lw = w.ln() - nll;
        terms.push(lw);
        if detail && best.as_ref().is_none_or(|b| lw > b.0) {
            best = Some((lw, zones));
        }
    }
    let m = terms.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lse = m + terms.iter().map(|t| (t - m).exp()).sum::<f64>().ln();
    FrameEval {
        nll: -lse,
        zones: best.map(|b| b.1).unwrap_or_default(),
    }
}

/// Per-frame NLL of frames `idx` under `model`.
pub fn frame_nlls(
    density: &Density,
    model: &SimConfig,
    base: &SimConfig,
    frames: &[Prepared],
    idx: &[usize],
) -> Vec<f64> {
    idx.par_iter()
        .map(|&f| eval_frame(density, model, base, &frames[f], false).nll)
        .collect()
}
