//! The concealed-effect benchmark (`depthor gap-bench`): "real" recordings built from simulated
//! scenes and from the imported real RGB-D sets (`../shared/data/real`) with hidden effects switched
//! on (each library effect at 1×, 2× and 4× its measured minimum detectable size, `units.rs`; two
//! effects at once, confounders, an effect outside the library, and null cases), analysed
//! against the plain simulator configuration. Reports detection by size, top-1 attribution, false positives on nulls,
//! parameter error and held-out gain.

use std::path::Path;

use rayon::prelude::*;

use super::data::{GapData, GapFrame};
use super::effects::{library, UnknownEffect, ALL};
use super::stats::clopper_pearson_upper;
use super::{analyze, Analysis, GapError, GapOptions};
use crate::import::{self, ImportKind};
use crate::rng::Rng;
use crate::scene::{camera_for, render_scene, SceneConfig, SceneFrame};
use crate::sim::covariates::grid_position;
use crate::sim::{simulate, SimConfig};

/// A change applied to a "real" frame's zones after the simulator (an effect outside the library).
pub type PostEffect = dyn Fn(&mut GapFrame, &mut Rng) + Sync;

pub use super::units::unit_size;

/// Parameters of `name` at `size` × its unit ([`unit_size`]; integer parameters stay at their
/// unit).
pub fn sized(name: &str, size: f64) -> Result<Vec<f64>, UnknownEffect> {
    super::units::scale(name, &unit_size(name)?, size)
}

/// `(name, sized(name, size))` for the fixed case lists, whose names are the library's: a
/// misspelt one panics naming it.
pub(super) fn at_size(name: &'static str, size: f64) -> (&'static str, Vec<f64>) {
    (name, sized(name, size).unwrap_or_else(|e| panic!("{e}")))
}

/// The measurement seed of a case: `seed` mixed with its label (FNV-1a), so a single case
/// reproduces its value in a full run.
pub fn case_seed(seed: u64, label: &str) -> u64 {
    label.bytes().fold(seed ^ 0xCBF2_9CE4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3)
    })
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

/// The real RGB-D sets the benchmark reads from `data/real` (kind, folder).
pub const REAL_SETS: [(ImportKind, &str); 7] = [
    (ImportKind::Middlebury, "middlebury2014-Q"),
    (ImportKind::Nyu, "metric3d-nyu-demo"),
    (ImportKind::Redwood, "open3d-rgbd-testdata"),
    (ImportKind::Tum, "open3d-rgbd-testdata"),
    (ImportKind::Sun, "open3d-rgbd-testdata"),
    (ImportKind::NyuRaw, "open3d-rgbd-testdata"),
    (ImportKind::Arkit, "promptda-iphone-lidar"),
];

/// Resamples the `crop` (`[x0, y0, w, h]`, source pixels) of `f` to `width × height`: RGB box
/// averaged, depth nearest (no mixed depths at edges), mirrored left–right when `mirror`.
fn resample_frame(
    f: &import::ImportedFrame,
    crop: [f32; 4],
    mirror: bool,
    width: u32,
    height: u32,
) -> SceneFrame {
    let (sw, sh) = f.rgb.dimensions();
    let [x0, y0, cw, ch] = crop;
    let (sx, sy) = (cw / width as f32, ch / height as f32);
    let n = (width * height) as usize;
    let (mut rgb, mut depth) = (Vec::with_capacity(3 * n), Vec::with_capacity(n));
    for oy in 0..height {
        for ox in 0..width {
            let ux = if mirror { width - 1 - ox } else { ox };
            let (ax, ay) = (x0 + ux as f32 * sx, y0 + oy as f32 * sy);
            let (bx, by) = (ax + sx, ay + sy);
            let (ix0, iy0) = (ax.floor() as u32, ay.floor() as u32);
            let ix1 = (bx.ceil() as u32).clamp(ix0 + 1, sw);
            let iy1 = (by.ceil() as u32).clamp(iy0 + 1, sh);
            let mut acc = [0u32; 3];
            let mut cnt = 0u32;
            for y in iy0..iy1 {
                for x in ix0..ix1 {
                    let p = f.rgb.get_pixel(x, y).0;
                    for k in 0..3 {
                        acc[k] += u32::from(p[k]);
                    }
                    cnt += 1;
                }
            }
            for a in acc {
                rgb.push((a / cnt.max(1)) as u8);
            }
            let (cx, cy) = (
                (((ax + bx) / 2.0) as u32).min(sw - 1),
                (((ay + by) / 2.0) as u32).min(sh - 1),
            );
            let d = f.depth_m[(cy * sw + cx) as usize];
            depth.push(if d.is_finite() && d > 0.0 { d } else { 0.0 });
        }
    }
    let s = cw / width as f32;
    let camera = depthor_core::calibration::CameraIntrinsics {
        width,
        height,
        fx: f.camera.fx / s,
        fy: f.camera.fy / s,
        cx: (f.camera.cx - x0) / s,
        cy: (f.camera.cy - y0) / s,
    };
    SceneFrame {
        width,
        height,
        camera,
        rgb,
        depth_m: depth,
        second_depth_m: vec![0.0; n],
        reflectance: vec![0.0; n],
        labels: vec![0; n],
        normals: vec![[0.0, 0.0, 1.0]; n],
    }
}

/// Frames of the real RGB-D sets under `root` (`data/real`) as scenes of `size` (`None`: each
/// image at its native resolution, with its own camera): each image twice, first its largest
/// centred crop of the target aspect (native: the whole image), then a mirrored 80 % crop toward
/// its lower right. The two views of an image are `m` frames apart (`m` images), so with an even
/// `m` both fall on the same side of the even/odd train/test split. No material labels (all
/// diffuse). Sets that fail to load are skipped and named in the returned notes.
pub fn real_scenes(root: &Path, size: Option<(u32, u32)>) -> (Vec<SceneFrame>, Vec<String>) {
    let mut imgs = Vec::new();
    let mut notes = Vec::new();
    for (kind, folder) in REAL_SETS {
        match import::load(kind, &root.join(folder)) {
            Ok(set) => imgs.extend(set.frames),
            Err(e) => notes.push(format!("{folder} ({}): skipped: {e}", kind.cli_name())),
        }
    }
    if imgs.len() % 2 == 1 {
        imgs.pop();
    }
    let view = |f: &import::ImportedFrame, zoom: f32, at: f32, mirror: bool| {
        let (sw, sh) = (f.rgb.width() as f32, f.rgb.height() as f32);
        let (width, height) = size.unwrap_or((
            ((sw * zoom).round() as u32).max(1),
            ((sh * zoom).round() as u32).max(1),
        ));
        let aspect = width as f32 / height as f32;
        let (cw, ch) = if sw / sh > aspect {
            (sh * aspect, sh)
        } else {
            (sw, sw / aspect)
        };
        let (cw, ch) = if size.is_some() {
            (cw * zoom, ch * zoom)
        } else {
            (cw, ch)
        };
        let crop = [(sw - cw) * at, (sh - ch) * at, cw, ch];
        resample_frame(f, crop, mirror, width, height)
    };
    let mut out: Vec<SceneFrame> = imgs.par_iter().map(|f| view(f, 1.0, 0.5, false)).collect();
    out.extend(
        imgs.par_iter()
            .map(|f| view(f, 0.8, 0.8, true))
            .collect::<Vec<_>>(),
    );
    (out, notes)
}

/// `scenes` with their far surfaces darkened (RGB × clamp(1.5 m / z, 0.12, 1)): brightness falls
/// with range, the confounder of `range_dropout` and `dark_dropout`.
pub fn dark_far(scenes: &[SceneFrame]) -> Vec<SceneFrame> {
    scenes
        .par_iter()
        .map(|s| {
            let mut s = s.clone();
            for (i, &d) in s.depth_m.iter().enumerate() {
                let f = if d > 0.0 {
                    (1.5 / d).clamp(0.12, 1.0)
                } else {
                    1.0
                };
                for c in &mut s.rgb[3 * i..3 * i + 3] {
                    *c = (f32::from(*c) * f).round() as u8;
                }
            }
            s
        })
        .collect()
}

/// Which scenes a case's "real" recording is built from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SceneSet {
    /// Rendered scenes ([`render_scenes`]).
    #[default]
    Sim,
    /// Imported real RGB-D frames ([`real_scenes`]).
    Real,
    /// Rendered scenes with far surfaces darkened ([`dark_far`]).
    DarkFar,
}

impl SceneSet {
    /// Short name (table).
    pub fn name(self) -> &'static str {
        match self {
            SceneSet::Sim => "sim",
            SceneSet::Real => "real",
            SceneSet::DarkFar => "dark-far",
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
    /// Scenes the "real" recording is built from.
    pub scenes: SceneSet,
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
    /// Held-out gain of each accepted finding (conditional on the others), nats per zone.
    pub finding_gains: Vec<f64>,
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
        let i = library(name).params.iter().position(|p| !p.integer)?;
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
        hidden.set_effect(n, Some(v))?;
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
        .map(|(n, _)| library(n).get(&a.selection.estimate));
    Ok((
        CaseResult {
            case: case.clone(),
            named,
            fitted,
            gain: a.fit_before.heldout_nll_per_zone - a.fit_after.heldout_nll_per_zone,
            unexplained_slices: a.slices_after.iter().filter(|s| s.significant).count(),
            finding_gains: a
                .selection
                .findings
                .iter()
                .map(|f| f.heldout_gain)
                .collect(),
        },
        a,
    ))
}

/// One case per library effect and size in `sizes` on `scenes` (effects in `skip` left out).
fn sized_cases(sizes: &[f64], scenes: SceneSet, skip: &[&str]) -> Vec<Case> {
    let mut v = Vec::new();
    for c in ALL {
        if skip.contains(&c.name) {
            continue;
        }
        for &s in sizes {
            v.push(Case {
                label: label(scenes, &format!("{}@{s}x", c.name)),
                hidden: vec![at_size(c.name, s)],
                size: s,
                outside: false,
                scenes,
            });
        }
    }
    v
}

fn label(scenes: SceneSet, l: &str) -> String {
    match scenes {
        SceneSet::Sim => l.to_string(),
        s => format!("{}:{l}", s.name()),
    }
}

/// `n` null cases on `scenes`.
fn null_cases(n: usize, scenes: SceneSet) -> Vec<Case> {
    (0..n)
        .map(|k| Case {
            label: label(scenes, &format!("null#{k}")),
            hidden: vec![],
            size: 0.0,
            outside: false,
            scenes,
        })
        .collect()
}

/// A case hiding `hidden` (each at 4× its unit unless given) on `scenes`.
fn multi(l: &str, hidden: Vec<(&'static str, Vec<f64>)>, scenes: SceneSet) -> Case {
    Case {
        label: label(scenes, l),
        hidden,
        size: 4.0,
        outside: false,
        scenes,
    }
}

/// The standard cases on rendered scenes: every effect at `sizes`, `nulls` null cases, pairs,
/// confounders and one effect outside the library.
pub fn standard_cases(sizes: &[f64], nulls: usize) -> Vec<Case> {
    let mut v = sized_cases(sizes, SceneSet::Sim, &[]);
    v.extend(null_cases(nulls, SceneSet::Sim));
    for (a, b) in [
        ("range_dropout", "range_bias"),
        ("dark_dropout", "edge_mixing"),
        ("multipath", "range_noise"),
    ] {
        v.push(multi(
            &format!("{a}+{b}@4x"),
            vec![at_size(a, 4.0), at_size(b, 4.0)],
            SceneSet::Sim,
        ));
    }
    v.extend(confounder_cases());
    v.push(Case {
        label: "outside:cover_glass".into(),
        hidden: vec![],
        size: 0.0,
        outside: true,
        scenes: SceneSet::Sim,
    });
    v
}

/// Confounders: on scenes whose far surfaces are dark, `range_dropout` and `dark_dropout` each
/// hidden alone (the tool must pick the right one); and `radial_distance` whose mean error a
/// calibration has absorbed into a range scale (`range_bias.scale = −mean(k − 1)·fraction` over
/// the grid): the residual is then the radial pattern alone.
pub fn confounder_cases() -> Vec<Case> {
    let (_, radial) = at_size("radial_distance", 4.0);
    let scale = -absorbed_scale(radial.first().copied().unwrap_or(0.0));
    vec![
        multi(
            "range_dropout@4x",
            vec![at_size("range_dropout", 4.0)],
            SceneSet::DarkFar,
        ),
        multi(
            "dark_dropout@4x",
            vec![at_size("dark_dropout", 4.0)],
            SceneSet::DarkFar,
        ),
        multi(
            "absorbed:radial_distance@4x",
            vec![
                ("radial_distance", radial),
                ("range_bias", vec![0.0, scale]),
            ],
            SceneSet::Sim,
        ),
    ]
}

/// Mean of `factor − 1` over the 8×8 grid for a `radial_distance` of `fraction` (45° FoV).
pub fn absorbed_scale(fraction: f64) -> f64 {
    let r = crate::sim::effects::radial_distance::RadialDistance {
        enabled: true,
        fraction: fraction as f32,
        ..Default::default()
    };
    let mut acc = 0.0;
    for z in 0..64 {
        let (pos, _) = grid_position(z / 8, z % 8, 8, 8);
        acc += f64::from(r.factor(pos)) - 1.0;
    }
    acc / 64.0
}

/// Cases on the imported real RGB-D frames: every effect but `multipath` (the real sets have no
/// material labels) at `sizes`, `nulls` null cases and one pair.
pub fn real_cases(sizes: &[f64], nulls: usize) -> Vec<Case> {
    let mut v = sized_cases(sizes, SceneSet::Real, &["multipath"]);
    v.extend(null_cases(nulls, SceneSet::Real));
    v.push(multi(
        "range_dropout+range_bias@4x",
        vec![at_size("range_dropout", 4.0), at_size("range_bias", 4.0)],
        SceneSet::Real,
    ));
    v
}

/// Markdown table of `results`: one row per case; then per scene set and size, detection rate,
/// top-1 attribution and parameter error; nulls' false-positive rate per scene set; and how many
/// accepted findings improved the held-out NLL.
pub fn table(results: &[CaseResult]) -> String {
    let mut s = String::from("| case | hidden | named | detected | top-1 | param err | held-out gain (nats/zone) | findings with gain > 0 | unexplained slices |\n|---|---|---|---|---|---|---|---|---|\n");
    let yn = |r: &CaseResult, b: bool| {
        if r.case.hidden.is_empty() {
            "—"
        } else if b {
            "yes"
        } else {
            "no"
        }
    };
    for r in results {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {:.4} | {}/{} | {} |\n",
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
            yn(r, r.detected()),
            yn(r, r.top1()),
            r.param_error()
                .map_or("—".into(), |e| format!("{:.0} %", 100.0 * e)),
            r.gain,
            r.finding_gains.iter().filter(|&&g| g > 0.0).count(),
            r.finding_gains.len(),
            r.unexplained_slices
        ));
    }
    s.push_str("\n| scenes | size | cases | detection rate | top-1 attribution | param error ≤ 25 % | median param error |\n|---|---|---|---|---|---|---|\n");
    for set in [SceneSet::Sim, SceneSet::Real, SceneSet::DarkFar] {
        let mut sizes: Vec<f64> = results
            .iter()
            .filter(|r| r.case.hidden.len() == 1 && r.case.scenes == set && !r.case.outside)
            .map(|r| r.case.size)
            .collect();
        sizes.sort_by(f64::total_cmp);
        sizes.dedup();
        for sz in sizes {
            let rs: Vec<&CaseResult> = results
                .iter()
                .filter(|r| {
                    r.case.hidden.len() == 1
                        && r.case.size == sz
                        && !r.case.outside
                        && r.case.scenes == set
                })
                .collect();
            let n = rs.len() as f64;
            let det = rs.iter().filter(|r| r.detected()).count() as f64;
            let top = rs.iter().filter(|r| r.top1()).count() as f64;
            let mut errs: Vec<f64> = rs.iter().filter_map(|r| r.param_error()).collect();
            let perr = errs.iter().filter(|&&e| e <= 0.25).count() as f64;
            errs.sort_by(f64::total_cmp);
            let med = if errs.is_empty() {
                "—".to_string()
            } else {
                format!("{:.0} %", 100.0 * errs[errs.len() / 2])
            };
            s.push_str(&format!(
                "| {} | {sz}× | {} | {:.0} % | {:.0} % | {:.0} % | {med} |\n",
                set.name(),
                rs.len(),
                100.0 * det / n,
                100.0 * top / n,
                100.0 * perr / n
            ));
        }
    }
    s.push('\n');
    let is_null = |r: &&CaseResult| r.case.hidden.is_empty() && !r.case.outside;
    let fp_line = |what: &str, nulls: &[&CaseResult]| {
        let fp = nulls.iter().filter(|r| r.false_positives() > 0).count();
        null_line(what, nulls.len(), fp)
    };
    let mut sets = 0;
    for set in [SceneSet::Sim, SceneSet::Real, SceneSet::DarkFar] {
        let nulls: Vec<&CaseResult> = results
            .iter()
            .filter(is_null)
            .filter(|r| r.case.scenes == set)
            .collect();
        if !nulls.is_empty() {
            sets += 1;
            s.push_str(&fp_line(set.name(), &nulls));
        }
    }
    if sets > 1 {
        let nulls: Vec<&CaseResult> = results.iter().filter(is_null).collect();
        s.push_str(&fp_line("all", &nulls));
    }
    s.push_str(&gains_line(
        results.iter().flat_map(|r| r.finding_gains.iter().copied()),
    ));
    s
}

/// The table line of `n` null cases, `fp` of them with a finding, with the one-sided 95 %
/// Clopper–Pearson upper bound of the false-positive rate.
pub fn null_line(what: &str, n: usize, fp: usize) -> String {
    format!(
        "Nulls ({what}): {n} cases, {fp} with a false positive ({:.1} %; one-sided 95 % Clopper–Pearson upper bound {:.1} %).\n",
        100.0 * fp as f64 / n.max(1) as f64,
        100.0 * clopper_pearson_upper(fp, n, 0.05)
    )
}

/// The table line counting accepted findings (their held-out `gains`) that improved the
/// held-out NLL.
pub fn gains_line(gains: impl Iterator<Item = f64>) -> String {
    let gains: Vec<f64> = gains.collect();
    format!(
        "Accepted findings with a positive held-out gain: {} of {}.\n",
        gains.iter().filter(|&&g| g > 0.0).count(),
        gains.len()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dark_far_darkens_with_range_and_absorbed_scale_is_the_grid_mean() {
        let mut s = render_scenes(1, 16, 12, 3).remove(0);
        s.depth_m[0] = 0.5;
        s.depth_m[1] = 6.0;
        s.rgb[..6].copy_from_slice(&[200, 100, 50, 200, 100, 50]);
        let d = dark_far(std::slice::from_ref(&s)).remove(0);
        // Near (1.5 / 0.5 > 1): unchanged; far: × 1.5 / 6 = 0.25.
        assert_eq!(&d.rgb[..3], &[200, 100, 50]);
        assert_eq!(&d.rgb[3..6], &[50, 25, 13]);
        // The mean radial lengthening over the grid: positive, linear in the fraction, and the
        // mean of the per-zone factors.
        let a = absorbed_scale(1.0);
        assert!(a > 0.0 && (absorbed_scale(0.5) - a / 2.0).abs() < 1e-6);
        let r = crate::sim::effects::radial_distance::RadialDistance {
            enabled: true,
            fraction: 1.0,
            ..Default::default()
        };
        let corner = f64::from(r.factor(grid_position(0, 0, 8, 8).0)) - 1.0;
        assert!(a < corner);
    }

    #[test]
    fn standard_cases_cover_every_effect_size_and_special_case() {
        let v = standard_cases(&[1.0, 2.0, 4.0], 20);
        assert_eq!(
            v.iter()
                .filter(|c| c.hidden.is_empty() && !c.outside)
                .count(),
            20
        );
        assert_eq!(
            v.iter()
                .filter(|c| c.hidden.len() == 1 && c.scenes == SceneSet::Sim)
                .count(),
            3 * ALL.len()
        );
        assert!(v.iter().any(|c| c.outside));
        assert!(v.iter().any(|c| c.scenes == SceneSet::DarkFar));
        let r = real_cases(&[1.0], 3);
        assert!(r
            .iter()
            .all(|c| c.scenes == SceneSet::Real && c.label.starts_with("real:")));
        assert!(!r
            .iter()
            .any(|c| c.hidden.iter().any(|h| h.0 == "multipath")));
    }
}
