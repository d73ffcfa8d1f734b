//! Calibration: simulated input frames (scene generator → dToF simulator → projection), the
//! activation range of every value over those frames, and the int8 parameters chosen from them.
//!
//! Ranges come from a [`RangeRule`]: the plain **minimum / maximum** over all calibration
//! frames, or (the default) the range that minimises the expected int8 error over a histogram of
//! the calibration values (**MSE clipping**: a few outliers no longer stretch the step of every
//! other value). Either way ranges are widened to include 0 so zero padding and ReLU zeros are
//! exact. Values whose
//! range the op fixes ignore calibration: `rgb`, `minmax_norm` and `sigmoid` outputs span [0, 1];
//! `sparse` spans [0, the bins head's `max_depth_m`]; `upsample_bilinear` and `pixel_shuffle`
//! keep their input's parameters (the engine requires it).

use super::net::{Net, OpKind, Storage, RGB, SPARSE};
use crate::scene::{camera_for, render_scene, SceneConfig};
use crate::sim::{preset, simulate, SimError};
use depthor_core::calibration::{Calibration, DistanceKind, DtofGeometry, Extrinsics};
use depthor_core::hal::ZoneView;
use depthor_core::kernels::requant::QParams;
use depthor_core::projection::{project_to_sparse, ProjectionError};

/// Smallest activation range (real units) given to a value; keeps scales positive when a
/// value was constant over the calibration set.
pub const MIN_RANGE: f32 = 1e-6;

/// One network input: what a camera and a dToF sensor give the engine.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Rows.
    pub height: usize,
    /// Columns.
    pub width: usize,
    /// RGB888 interleaved, `H×W×3` (the engine's input).
    pub rgb: Vec<u8>,
    /// Projected dToF depth `H×W`, metres, 0 = no point.
    pub sparse_m: Vec<f32>,
}

impl Frame {
    /// The float network's `rgb` input: planar `[3,H,W]`, `byte/255`.
    pub fn rgb_planar(&self) -> Vec<f32> {
        let n = self.height * self.width;
        let mut v = vec![0f32; 3 * n];
        for (i, px) in self.rgb.chunks_exact(3).enumerate().take(n) {
            for c in 0..3 {
                v[c * n + i] = px[c] as f32 / 255.0;
            }
        }
        v
    }
}

/// Why calibration frames could not be made.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The simulator rejected its input or preset.
    #[error("dToF simulator: {0}")]
    Sim(#[from] SimError),
    /// Projection failed.
    #[error("projection: {0:?}")]
    Projection(ProjectionError),
}

/// `count` simulated frames at `height × width` for the sensor preset `preset_name` (`mcu`,
/// `phone`): scene `seed + k` rendered by [`render_scene`], its zones simulated by
/// [`simulate`], projected to a sparse map with the zone rectangles' centres.
pub fn simulated_frames(
    preset_name: &str,
    height: usize,
    width: usize,
    count: usize,
    seed: u64,
) -> Result<Vec<Frame>, FrameError> {
    simulated_frames_in(
        &SceneConfig::default(),
        preset_name,
        height,
        width,
        count,
        seed,
    )
}

/// [`simulated_frames`] of scenes drawn from `cfg` (e.g. a close-range scene configuration).
pub fn simulated_frames_in(
    cfg: &SceneConfig,
    preset_name: &str,
    height: usize,
    width: usize,
    count: usize,
    seed: u64,
) -> Result<Vec<Frame>, FrameError> {
    let sim = preset(preset_name)?;
    let (w, h) = (width as u32, height as u32);
    (0..count as u64)
        .map(|k| {
            let s = seed.wrapping_add(k);
            let cam = camera_for(cfg, s, w, h);
            let scene = render_scene(cfg, s, cam);
            let zones = simulate(&sim, &scene.sim_input(), s)?;
            let cal = Calibration {
                camera: cam,
                dtof: DtofGeometry {
                    rows: zones.rows,
                    cols: zones.cols,
                    fov_deg: [45.0, 45.0], // unused: the zone rectangles place the points
                    distance: DistanceKind::Z,
                    max_range_m: 10.0,
                },
                dtof_to_camera: Extrinsics::IDENTITY,
                zone_rects_px: Some(&zones.zone_rects_px),
            };
            let view = ZoneView {
                rows: zones.rows,
                cols: zones.cols,
                distance_mm: &zones.distance_mm,
                status: &zones.status,
            };
            let mut sparse_m = vec![0f32; height * width];
            project_to_sparse(&cal, &view, &mut sparse_m).map_err(FrameError::Projection)?;
            Ok(Frame {
                height,
                width,
                rgb: scene.rgb,
                sparse_m,
            })
        })
        .collect()
}

/// Running minimum and maximum of every value of a network.
#[derive(Clone, Debug, PartialEq)]
pub struct Ranges {
    /// Per value: smallest element seen (`+∞` before any frame).
    pub min: Vec<f32>,
    /// Per value: largest element seen (`−∞` before any frame).
    pub max: Vec<f32>,
}

impl Ranges {
    /// Empty ranges for `n` values.
    pub fn new(n: usize) -> Ranges {
        Ranges {
            min: vec![f32::INFINITY; n],
            max: vec![f32::NEG_INFINITY; n],
        }
    }

    /// Widens the ranges with one float run's values.
    pub fn observe(&mut self, values: &[Vec<f32>]) {
        for ((lo, hi), v) in self.min.iter_mut().zip(&mut self.max).zip(values) {
            for &x in v {
                if x.is_finite() {
                    *lo = lo.min(x);
                    *hi = hi.max(x);
                }
            }
        }
    }
}

/// Why a `--ranges-file` entry was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RangeFileError {
    /// The name is not a stored value of the folded network.
    #[error("range for {0:?}: no int8 value of the network has that name")]
    UnknownValue(String),
    /// `lo > hi` or a bound is not finite.
    #[error("range for {name:?}: [{lo}, {hi}] is not a finite, ordered range")]
    BadRange {
        /// Value name.
        name: String,
        /// Lower bound.
        lo: f32,
        /// Upper bound.
        hi: f32,
    },
}

/// Replaces the calibrated ranges of the values named in `given` (value name → `[lo, hi]`, e.g.
/// the ranges a quantisation-aware run trained with); the other values keep theirs, and so do
/// int16 values (a given range is an int8 one: it would clip what int16 keeps).
pub fn override_ranges(
    net: &Net,
    ranges: &mut Ranges,
    given: &[(String, [f32; 2])],
) -> Result<(), RangeFileError> {
    for (name, [lo, hi]) in given {
        let v = net
            .values
            .iter()
            .position(|v| &v.name == name && v.storage != Storage::F32)
            .ok_or_else(|| RangeFileError::UnknownValue(name.clone()))?;
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(RangeFileError::BadRange {
                name: name.clone(),
                lo: *lo,
                hi: *hi,
            });
        }
        if net.values[v].storage == Storage::I8 {
            ranges.min[v] = *lo;
            ranges.max[v] = *hi;
        }
    }
    Ok(())
}

/// How activation ranges are chosen from the calibration values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum RangeRule {
    /// Minimum and maximum over all frames: nothing is ever clipped.
    MinMax,
    /// The `[lo, hi]` (within min/max) minimising clipping error plus rounding error
    /// (`step²/12` per value) over the calibration histogram.
    #[default]
    Mse,
}

/// A `--ranges` value that names no [`RangeRule`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown range rule {0:?} (minmax, mse)")]
pub struct UnknownRangeRule(pub String);

impl std::str::FromStr for RangeRule {
    type Err = UnknownRangeRule;
    fn from_str(s: &str) -> Result<Self, UnknownRangeRule> {
        match s {
            "minmax" => Ok(RangeRule::MinMax),
            "mse" => Ok(RangeRule::Mse),
            _ => Err(UnknownRangeRule(s.to_string())),
        }
    }
}

/// Bins of each value's calibration histogram.
pub const HISTOGRAM_BINS: usize = 2048;

/// Candidate clip points tried per side by [`Histograms::mse_ranges`] (fractions of the side's
/// full extent, from 1 down to 1/4).
const CLIP_CANDIDATES: usize = 64;

/// Per-value histograms over fixed `[min, max]` ranges (from a first, min/max pass).
#[derive(Clone, Debug, PartialEq)]
pub struct Histograms {
    lo: Vec<f32>,
    hi: Vec<f32>,
    counts: Vec<Vec<u64>>,
}

impl Histograms {
    /// Empty histograms spanning `ranges` widened to include 0.
    pub fn new(ranges: &Ranges) -> Histograms {
        let widen = |x: f32, f: fn(f32, f32) -> f32| if x.is_finite() { f(x, 0.0) } else { 0.0 };
        let lo: Vec<f32> = ranges.min.iter().map(|&x| widen(x, f32::min)).collect();
        let hi: Vec<f32> = ranges.max.iter().map(|&x| widen(x, f32::max)).collect();
        let counts = vec![vec![0; HISTOGRAM_BINS]; lo.len()];
        Histograms { lo, hi, counts }
    }

    /// Counts one float run's values (outside the span: clamped to the end bins).
    pub fn observe(&mut self, values: &[Vec<f32>]) {
        for (i, v) in values.iter().enumerate().take(self.counts.len()) {
            let (lo, hi) = (self.lo[i], self.hi[i]);
            let per = HISTOGRAM_BINS as f32 / (hi - lo).max(MIN_RANGE);
            let bins = &mut self.counts[i];
            for &x in v.iter().filter(|x| x.is_finite()) {
                let b = ((x - lo) * per).clamp(0.0, (HISTOGRAM_BINS - 1) as f32) as usize;
                bins[b] += 1;
            }
        }
    }

    /// The MSE-optimal range of every value (see [`RangeRule::Mse`]).
    pub fn mse_ranges(&self) -> Ranges {
        let (min, max) = (0..self.counts.len()).map(|i| self.mse_range(i)).unzip();
        Ranges { min, max }
    }

    /// Grid search over clip points on bin edges; O(1) per candidate with prefix sums of
    /// `c`, `c·x`, `c·x²` (x = bin centre).
    fn mse_range(&self, i: usize) -> (f32, f32) {
        let (lo, hi) = (self.lo[i] as f64, self.hi[i] as f64);
        let width = (hi - lo) / HISTOGRAM_BINS as f64;
        if width <= 0.0 {
            return (lo as f32, hi as f32);
        }
        let mut c = vec![0f64; HISTOGRAM_BINS + 1];
        let mut cx = c.clone();
        let mut cxx = c.clone();
        for (b, &n) in self.counts[i].iter().enumerate() {
            let (n, x) = (n as f64, lo + (b as f64 + 0.5) * width);
            c[b + 1] = c[b] + n;
            cx[b + 1] = cx[b] + n * x;
            cxx[b + 1] = cxx[b] + n * x * x;
        }
        let edge = |e: usize| lo + e as f64 * width;
        // Σ over bins [from, to) of n·(x − t)².
        let sq = |from: usize, to: usize, t: f64| {
            let (n, s, ss) = (c[to] - c[from], cx[to] - cx[from], cxx[to] - cxx[from]);
            ss - 2.0 * t * s + t * t * n
        };
        let zero = ((-lo / width).round() as usize).min(HISTOGRAM_BINS);
        let candidates = |from: usize, to: usize| -> Vec<usize> {
            // Edges from `to` (full extent) towards `from`, down to a quarter of the extent.
            let mut v: Vec<usize> = (0..CLIP_CANDIDATES)
                .map(|k| {
                    let f = 1.0 - 0.75 * k as f64 / (CLIP_CANDIDATES - 1) as f64;
                    (from as f64 + (to as f64 - from as f64) * f).round() as usize
                })
                .collect();
            v.dedup();
            v
        };
        let highs = candidates(zero, HISTOGRAM_BINS);
        let lows: Vec<usize> = candidates(HISTOGRAM_BINS - zero, HISTOGRAM_BINS)
            .into_iter()
            .map(|e| HISTOGRAM_BINS - e)
            .collect();
        let mut best = (f64::INFINITY, lo, hi);
        for &a in &lows {
            for &b in highs.iter().filter(|&&b| b >= a) {
                let (ta, tb) = (edge(a), edge(b));
                let step = (tb - ta).max(MIN_RANGE as f64) / 255.0;
                let inside = c[b] - c[a];
                let err = inside * step * step / 12.0 + sq(0, a, ta) + sq(b, HISTOGRAM_BINS, tb);
                if err < best.0 {
                    best = (err, ta, tb);
                }
            }
        }
        (best.1 as f32, best.2 as f32)
    }
}

/// Asymmetric int8 parameters covering `[lo, hi]` widened to include 0:
/// `scale = (hi − lo)/255`, `zero_point = round(−128 − lo/scale)`.
pub fn affine_params(lo: f32, hi: f32) -> QParams {
    let lo = if lo.is_finite() { lo.min(0.0) } else { 0.0 };
    let hi = if hi.is_finite() { hi.max(0.0) } else { 0.0 };
    let scale = (hi - lo).max(MIN_RANGE) / 255.0;
    let zero_point = (-128.0 - lo / scale).round().clamp(-128.0, 127.0) as i32;
    QParams { scale, zero_point }
}

/// Headroom of an int16 value's range over its calibrated min/max: frames beyond calibration do
/// not clip, and the step stays 128× finer than int8's over the same range.
pub const I16_HEADROOM: f32 = 2.0;

/// Symmetric int16 parameters (zero point 0) covering `[lo, hi]` with [`I16_HEADROOM`]:
/// `scale = I16_HEADROOM · max(|lo|, |hi|) / 32767`.
pub fn symmetric_i16_params(lo: f32, hi: f32) -> QParams {
    let m = [lo, hi]
        .iter()
        .filter(|v| v.is_finite())
        .fold(0f32, |a, v| a.max(v.abs()));
    QParams {
        scale: (I16_HEADROOM * m).max(MIN_RANGE) / 32767.0,
        zero_point: 0,
    }
}

/// The blob parameters of every value of `net` from calibrated `ranges` (rules in the module
/// doc). f32 values get scale 1, zero point 0 (ignored by the engine).
pub fn choose_qparams(net: &Net, ranges: &Ranges) -> Vec<QParams> {
    let unit = affine_params(0.0, 1.0);
    let max_depth = net
        .ops
        .iter()
        .find_map(|o| match &o.kind {
            OpKind::BinsHead { attrs, .. } => Some(attrs.max_depth),
            _ => None,
        })
        .unwrap_or(ranges.max[SPARSE]);
    let mut qs: Vec<QParams> = Vec::with_capacity(net.values.len());
    qs.push(unit); // rgb
    qs.push(affine_params(0.0, max_depth));
    debug_assert_eq!((RGB, SPARSE), (0, 1));
    for op in &net.ops {
        let v = op.output;
        let q = if net.values[v].storage == Storage::F32 {
            QParams {
                scale: 1.0,
                zero_point: 0,
            }
        } else if net.values[v].storage == Storage::I16 {
            symmetric_i16_params(ranges.min[v], ranges.max[v])
        } else {
            match op.kind {
                OpKind::MinMaxNorm(_) | OpKind::Sigmoid => unit,
                OpKind::Upsample(_) => match net.values[v].params_of {
                    Some(c) => affine_params(ranges.min[c], ranges.max[c]),
                    None => qs[op.inputs[0]],
                },
                OpKind::PixelShuffle(_) => qs[op.inputs[0]],
                _ => affine_params(ranges.min[v], ranges.max[v]),
            }
        };
        qs.push(q);
    }
    qs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn affine_params_by_hand() {
        // [0, 2.55]: scale 0.01, 0 at code −128.
        let q = affine_params(0.0, 2.55);
        assert!((q.scale - 0.01).abs() < 1e-7);
        assert_eq!(q.zero_point, -128);
        // [−1, 1.55]: scale 0.01, 0 at −128 + 100 = −28.
        let q = affine_params(-1.0, 1.55);
        assert_eq!(q.zero_point, -28);
        assert_eq!(q.quantize(0.0), -28);
        // A positive-only range still includes 0; a constant zero range keeps a positive scale.
        assert_eq!(affine_params(1.0, 2.55).zero_point, -128);
        assert!(affine_params(0.0, 0.0).scale > 0.0);
    }

    /// Σ (x − dequantise(quantise(x)))² under the parameters of `[lo, hi]`.
    fn int8_error(v: &[f32], lo: f32, hi: f32) -> f64 {
        let q = affine_params(lo, hi);
        v.iter()
            .map(|&x| (x as f64 - q.dequantize(q.quantize(x)) as f64).powi(2))
            .sum()
    }

    fn mse_range_of(v: &[f32]) -> (f32, f32) {
        let mut r = Ranges::new(1);
        r.observe(std::slice::from_ref(&v.to_vec()));
        let mut h = Histograms::new(&r);
        h.observe(std::slice::from_ref(&v.to_vec()));
        let m = h.mse_ranges();
        (m.min[0], m.max[0])
    }

    #[test]
    fn mse_clips_a_heavy_tail_and_keeps_a_uniform_spread() {
        // 100 000 exponential values (max ≈ 11.5): the tail is worth clipping, and the clipped
        // range really quantises them with less error than min/max.
        let n = 100_000;
        let e: Vec<f32> = (0..n)
            .map(|k| -((k as f32 + 0.5) / n as f32).ln())
            .collect();
        let max = e.iter().copied().fold(0.0, f32::max);
        let (lo, hi) = mse_range_of(&e);
        assert_eq!(lo, 0.0);
        assert!(hi < 0.9 * max, "{hi} of {max}");
        assert!(int8_error(&e, lo, hi) < int8_error(&e, 0.0, max));
        // One outlier among 10 000 uniform values costs more clipped than kept: kept.
        let mut o: Vec<f32> = (0..10_000).map(|k| k as f32 / 9_999.0).collect();
        o.push(100.0);
        assert!(mse_range_of(&o).1 > 90.0);
        // Uniform data: clipping only hurts, the range stays (nearly) full.
        let u: Vec<f32> = (0..10_000)
            .map(|k| -1.0 + 2.0 * k as f32 / 9_999.0)
            .collect();
        let (lo, hi) = mse_range_of(&u);
        assert!(lo < -0.95 && hi > 0.95, "{lo} {hi}");
    }

    #[test]
    fn range_rule_parses() {
        assert_eq!("mse".parse::<RangeRule>(), Ok(RangeRule::Mse));
        assert_eq!("minmax".parse::<RangeRule>(), Ok(RangeRule::MinMax));
        assert!("p99".parse::<RangeRule>().is_err());
    }

    #[test]
    fn ranges_track_min_and_max() {
        let mut r = Ranges::new(2);
        r.observe(&[vec![1.0, -2.0], vec![3.0]]);
        r.observe(&[vec![5.0, f32::NAN], vec![-1.0]]);
        assert_eq!(r.min, vec![-2.0, -1.0]);
        assert_eq!(r.max, vec![5.0, 3.0]);
    }
}
