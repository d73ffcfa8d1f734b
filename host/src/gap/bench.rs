//! The concealed-effect benchmark (`depthor gap-bench`): "real" recordings built from simulated
//! scenes with hidden effects switched on (each library effect at 1×, 2× and 4× a unit size, two
//! effects at once, an effect outside the library, and null cases), analysed against the plain
//! simulator configuration. Reports detection by size, top-1 attribution, false positives on
//! nulls, parameter error and held-out gain.

use rayon::prelude::*;

use super::data::{GapData, GapFrame};
use super::{analyze, effects, Analysis, GapError, GapOptions};
use crate::rng::Rng;
use crate::scene::{camera_for, render_scene, SceneConfig, SceneFrame};
use crate::sim::{simulate, SimConfig};

/// A change applied to a "real" frame's zones after the simulator (an effect outside the library).
pub type PostEffect = dyn Fn(&mut GapFrame, &mut Rng) + Sync;

/// Unit ("1×") size of each effect's parameters: our estimate of its minimum detectable size with
/// ~20 held-out 8×8 frames (the first parameter is the one whose recovery is scored).
pub fn unit_size(name: &str) -> Option<Vec<f64>> {
    Some(match name {
        "range_dropout" => vec![0.01],
        "dark_dropout" => vec![0.15],
        "border_dropout" => vec![0.2],
        "calibration_shift" => vec![1.0, 0.25],
        "radial_distance" => vec![0.25],
        "range_bias" => vec![0.01, 0.0],
        "range_noise" => vec![0.005],
        "multipath" => vec![0.1],
        "edge_mixing" => vec![0.05],
        "zone_crosstalk" => vec![0.05],
        "bin_wiggle" => vec![0.005],
        _ => return None,
    })
}

/// Parameters of `name` at `size` × its unit (integer parameters stay at their unit).
pub fn sized(name: &str, size: f64) -> Option<Vec<f64>> {
    let c = effects::candidate(name)?;
    let u = unit_size(name)?;
    Some(
        u.iter()
            .zip(c.params)
            .map(|(v, s)| {
                if s.integer {
                    *v
                } else {
                    (v * size).clamp(s.lo, s.hi)
                }
            })
            .collect(),
    )
}

/// Renders `n` scenes of `width × height` (scene seeds `seed..seed + n`), in parallel.
pub fn render_scenes(n: usize, width: u32, height: u32, seed: u64) -> Vec<SceneFrame> {
    let cfg = SceneConfig::default();
    (0..n as u64)
        .into_par_iter()
        .map(|i| {
            let s = seed + i;
            render_scene(&cfg, s, camera_for(&cfg, s, width, height))
        })
        .collect()
}

/// A "real" recording: the `scenes` measured by the simulator under `hidden` (seeds from
/// `seed`), then `post` applied to each frame's zones (an effect outside the library).
pub fn make_real(
    scenes: &[SceneFrame],
    hidden: &SimConfig,
    seed: u64,
    post: Option<&PostEffect>,
) -> Result<GapData, GapError> {
    let frames = scenes
        .par_iter()
        .enumerate()
        .map(|(i, s)| {
            let mut f = GapFrame {
                id: format!("{i:06}"),
                t_s: i as f64 / 10.0,
                width: s.width,
                height: s.height,
                depth_m: s.depth_m.clone(),
                rgb: s.rgb.clone(),
                labels: Some(s.labels.clone()),
                real_valid: Vec::new(),
                real_m: Vec::new(),
            };
            let out = simulate(
                hidden,
                &f.sim_input(),
                Rng::derive(seed, i as u64).next_u64(),
            )?;
            f.real_valid = (0..out.status.len()).map(|z| out.is_valid(z)).collect();
            f.real_m = out.distance_mm.iter().map(|d| d / 1000.0).collect();
            if let Some(p) = post {
                p(&mut f, &mut Rng::derive(seed ^ 0x9057, i as u64));
            }
            Ok(f)
        })
        .collect::<Result<Vec<_>, GapError>>()?;
    Ok(GapData {
        frames,
        grid: (hidden.grid.rows, hidden.grid.cols),
        max_range_m: hidden.anomalies.noise_range_m[1].max(4.0),
    })
}

/// An effect outside the library: phantom cover-glass returns at 5–10 cm on 15 % of the zones
/// that lost their target.
pub fn phantom_cover_glass(f: &mut GapFrame, rng: &mut Rng) {
    for (v, d) in f.real_valid.iter_mut().zip(f.real_m.iter_mut()) {
        let (u, w) = (rng.f32(), rng.f32());
        if !*v && u < 0.15 {
            *v = true;
            *d = 0.05 + 0.05 * w;
        }
    }
}

/// One benchmark case.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Label (`range_dropout@2x`, `null`, …).
    pub label: String,
    /// Hidden library effects and their parameters.
    pub hidden: Vec<(&'static str, Vec<f64>)>,
    /// Size multiple (0 for nulls).
    pub size: f64,
    /// Whether the phantom cover-glass (outside the library) is added.
    pub outside: bool,
}

/// The outcome of one case.
#[derive(Clone, Debug, PartialEq)]
pub struct CaseResult {
    /// The case.
    pub case: Case,
    /// Effects the tool named, most important first.
    pub named: Vec<String>,
    /// Fitted parameters of the first hidden effect when named.
    pub fitted: Option<Vec<f64>>,
    /// Held-out gain of the whole fit, nats per zone (before − after).
    pub gain: f64,
    /// Number of significant residual slices left after the fit.
    pub unexplained_slices: usize,
}

impl CaseResult {
    /// Whether every hidden effect was named.
    pub fn detected(&self) -> bool {
        self.case
            .hidden
            .iter()
            .all(|(n, _)| self.named.iter().any(|m| m == n))
    }
    /// Whether the top finding is a hidden effect.
    pub fn top1(&self) -> bool {
        self.named
            .first()
            .is_some_and(|n| self.case.hidden.iter().any(|(h, _)| h == n))
    }
    /// Named effects that were not hidden.
    pub fn false_positives(&self) -> usize {
        self.named
            .iter()
            .filter(|n| !self.case.hidden.iter().any(|(h, _)| h == *n))
            .count()
    }
    /// Relative error of the first continuous parameter of the first hidden effect.
    pub fn param_error(&self) -> Option<f64> {
        let (name, truth) = self.case.hidden.first()?;
        let fitted = self.fitted.as_ref()?;
        let c = effects::candidate(name)?;
        let i = c.params.iter().position(|p| !p.integer)?;
        let i = if *name == "calibration_shift" { 1 } else { i };
        Some((fitted[i] - truth[i]).abs() / truth[i].abs().max(1e-9))
    }
}

/// Runs one case on `scenes` against `base`.
pub fn run_case(
    scenes: &[SceneFrame],
    base: &SimConfig,
    case: &Case,
    opts: &GapOptions,
    seed: u64,
) -> Result<(CaseResult, Analysis), GapError> {
    let mut hidden = base.clone();
    for (n, v) in &case.hidden {
        effects::set(&mut hidden, n, Some(v));
    }
    let post: Option<&PostEffect> = if case.outside {
        Some(&phantom_cover_glass)
    } else {
        None
    };
    let real = make_real(scenes, &hidden, seed, post)?;
    let a = analyze(&real, base, opts, &|_| {})?;
    let named: Vec<String> = a
        .selection
        .findings
        .iter()
        .map(|f| f.effect.clone())
        .collect();
    let fitted = case
        .hidden
        .first()
        .filter(|(n, _)| named.iter().any(|m| m == n))
        .map(|(n, _)| effects::get(&a.selection.model, n));
    Ok((
        CaseResult {
            case: case.clone(),
            named,
            fitted,
            gain: a.fit_before.heldout_nll_per_zone - a.fit_after.heldout_nll_per_zone,
            unexplained_slices: a.slices_after.iter().filter(|s| s.significant).count(),
        },
        a,
    ))
}

/// The standard cases: every effect at `sizes`, `nulls` null cases, one pair, one outside-library.
pub fn standard_cases(sizes: &[f64], nulls: usize) -> Vec<Case> {
    let mut v = Vec::new();
    for c in effects::LIBRARY {
        for &s in sizes {
            if let Some(p) = sized(c.name, s) {
                v.push(Case {
                    label: format!("{}@{s}x", c.name),
                    hidden: vec![(c.name, p)],
                    size: s,
                    outside: false,
                });
            }
        }
    }
    for k in 0..nulls {
        v.push(Case {
            label: format!("null#{k}"),
            hidden: vec![],
            size: 0.0,
            outside: false,
        });
    }
    if let (Some(a), Some(b)) = (sized("range_dropout", 4.0), sized("range_bias", 4.0)) {
        v.push(Case {
            label: "range_dropout+range_bias@4x".into(),
            hidden: vec![("range_dropout", a), ("range_bias", b)],
            size: 4.0,
            outside: false,
        });
    }
    v.push(Case {
        label: "outside:cover_glass".into(),
        hidden: vec![],
        size: 0.0,
        outside: true,
    });
    v
}

/// Markdown table of `results`: per size, detection rate, top-1 attribution, median parameter
/// error and mean gain; then nulls' false-positive rate and the special cases.
pub fn table(results: &[CaseResult]) -> String {
    let mut s = String::from("| case | hidden | named | detected | top-1 | param err | held-out gain (nats/zone) | unexplained slices |\n|---|---|---|---|---|---|---|---|\n");
    for r in results {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {:.4} | {} |\n",
            r.case.label,
            r.case
                .hidden
                .iter()
                .map(|h| h.0)
                .collect::<Vec<_>>()
                .join("+"),
            if r.named.is_empty() {
                "—".into()
            } else {
                r.named.join(", ")
            },
            if r.case.hidden.is_empty() {
                "—"
            } else if r.detected() {
                "yes"
            } else {
                "no"
            },
            if r.case.hidden.is_empty() {
                "—"
            } else if r.top1() {
                "yes"
            } else {
                "no"
            },
            r.param_error()
                .map_or("—".into(), |e| format!("{:.0} %", 100.0 * e)),
            r.gain,
            r.unexplained_slices
        ));
    }
    s.push_str("\n| size | cases | detection rate | top-1 attribution | param error ≤ 25 % |\n|---|---|---|---|---|\n");
    let mut sizes: Vec<f64> = results
        .iter()
        .filter(|r| r.case.hidden.len() == 1)
        .map(|r| r.case.size)
        .collect();
    sizes.sort_by(f64::total_cmp);
    sizes.dedup();
    for sz in sizes {
        let rs: Vec<&CaseResult> = results
            .iter()
            .filter(|r| r.case.hidden.len() == 1 && r.case.size == sz && !r.case.outside)
            .collect();
        let n = rs.len() as f64;
        let det = rs.iter().filter(|r| r.detected()).count() as f64;
        let top = rs.iter().filter(|r| r.top1()).count() as f64;
        let perr = rs
            .iter()
            .filter(|r| r.param_error().is_some_and(|e| e <= 0.25))
            .count() as f64;
        s.push_str(&format!(
            "| {sz}× | {} | {:.0} % | {:.0} % | {:.0} % |\n",
            rs.len(),
            100.0 * det / n,
            100.0 * top / n,
            100.0 * perr / n
        ));
    }
    let nulls: Vec<&CaseResult> = results
        .iter()
        .filter(|r| r.case.hidden.is_empty() && !r.case.outside)
        .collect();
    if !nulls.is_empty() {
        let fp = nulls.iter().filter(|r| r.false_positives() > 0).count();
        s.push_str(&format!(
            "\nNulls: {} cases, {} with a false positive ({:.0} %).\n",
            nulls.len(),
            fp,
            100.0 * fp as f64 / nulls.len() as f64
        ));
    }
    s
}
