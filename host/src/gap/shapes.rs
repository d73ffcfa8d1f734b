//! The misspecified-shape benchmark (`depthor gap-bench --shapes`, docs/gap.md "Shape bench"):
//! each effect family injected with forward models that differ from the one the tool fits
//! (dropout with a logistic or step cut-off in range, dark loss below a brightness threshold or
//! along a quadratic ramp, border loss as a step or a linear ramp in radius, range noise growing
//! with d² or as a constant plus d, range bias growing with d² or only beyond the median range,
//! a periodic range error a quarter period off the library's phase or with a sawtooth profile).
//! The injection is this file's own code, applied to the "real" zones after a plain simulation:
//! it reads its own zone facts (mean reference depth, mean HSV value, grid radius) and never
//! calls the simulator's effect modules. Each shape is sized to the library form's mean effect
//! at a multiple of its unit (`units.rs`) on the same recording (mean loss probability, mean
//! added σ or mean |bias| over the valid zones), so "2×" means the same strength as the
//! library's 2× case; a dropout shape whose amplitude would exceed 1 moves its cut-off (10 %
//! of the zones per step) instead of being clamped. Each shape's own detection limit is measured
//! (`--calibrate-units --shapes`, [`calibrate`], committed as `host/data/gap_shape_units.json`)
//! and the bench runs at a multiple of it. A case is right when the tool's first finding is the
//! family's name. The confounded shapes ([`CONFOUNDED`], a loss of close returns) are right when
//! the first finding is attributed to range, alone or inseparable from grid radius.

use rayon::prelude::*;

use std::collections::BTreeMap;
use std::sync::OnceLock;

use super::bench::{at_size, gains_line, make_real, null_line};
use super::data::{GapData, GapFrame};
use super::effects::library;
use super::units::{ladder_search, needed, rung, CalibrateOptions, CalibratedUnit, UnitTable};
use super::{analyze, GapError, GapOptions};
use crate::rng::Rng;
use crate::scene::SceneFrame;
use crate::sim::covariates::zone_covariates;
use crate::sim::learned::TermKind;
use crate::sim::SimConfig;

/// One injected shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shape {
    /// The library family the tool should name.
    pub family: &'static str,
    /// Short name of the shape.
    pub name: &'static str,
    /// The forward model in words.
    pub what: &'static str,
    /// For a confounded shape ([`CONFOUNDED`]), the covariate that carries it: the case is right
    /// when the first finding is attributed to it (alone, or inseparable from a correlated one),
    /// whatever its name. `None`: right when the first finding is `family`.
    pub covariate: Option<&'static str>,
    /// With `covariate`: what the first finding must also change (a loss, bias or noise curve
    /// along the covariate, [`ANY_SHAPE`]); `None`: any kind.
    pub kind: Option<TermKind>,
    /// A periodic error's period, metres: the first finding's searched period must lie within
    /// [`PERIOD_TOLERANCE`] of it.
    pub period_m: Option<f32>,
}

/// Relative error of the searched period within which a periodic shape counts as named.
pub const PERIOD_TOLERANCE: f64 = 0.1;

const fn s(family: &'static str, name: &'static str, what: &'static str) -> Shape {
    Shape {
        family,
        name,
        what,
        covariate: None,
        kind: None,
        period_m: None,
    }
}

/// A periodic shape of period `period_m` (named `bin_wiggle` with that period).
const fn periodic(name: &'static str, what: &'static str, period_m: f32) -> Shape {
    Shape {
        period_m: Some(period_m),
        ..s("bin_wiggle", name, what)
    }
}

/// A shape of `kind` along `covariate` sized like `family` (equal mean effect): right when the
/// first finding is attributed to `covariate` and changes `kind`, whatever its name.
const fn along(
    family: &'static str,
    name: &'static str,
    what: &'static str,
    kind: TermKind,
    covariate: &'static str,
) -> Shape {
    Shape {
        covariate: Some(covariate),
        kind: Some(kind),
        ..s(family, name, what)
    }
}

/// Confounded shapes (issue 44 item 2): a loss driven by range whose evidence also shows along
/// grid radius, because near surfaces sit low in the image (range and radius correlated in the
/// frames). The tool must name it by range or report range and radius as inseparable, never
/// `border_dropout` alone. Sized like `range_dropout` (the library's range loss) at equal mean
/// loss.
pub const CONFOUNDED: [Shape; 2] = [
    along(
        "range_dropout",
        "near",
        "p = a·(1 − d/d50)₊: loss of close returns, falling with range to 0 at the median range",
        TermKind::Dropout,
        "range_m",
    ),
    along(
        "range_dropout",
        "near_step",
        "p = a below the 30th range percentile of the valid zones, 0 beyond",
        TermKind::Dropout,
        "range_m",
    ),
];

/// Shapes of any kind, covariate and direction (issue 44 items 3–4), chosen before any run
/// (never tuned on results): periodic errors of periods off the library's 0.3 m (the tool must
/// search the period), noise growing with scene brightness (ambient light) or with darkness,
/// noise at the grid border and noise falling with range, a loss rising with brightness (the
/// opposite of `dark_dropout`) and a bias on dark surfaces. Each is sized like the library
/// family of its kind (equal mean effect); a non-periodic one is right when the first finding
/// is attributed to its covariate and changes its kind, whatever its name (`learned` where the
/// library has no such family).
pub const ANY_SHAPE: [Shape; 9] = [
    periodic(
        "period_0.19",
        "bias = a·sin(2πd/0.19 m + 1) of the measured d: a short off-library period",
        0.19,
    ),
    periodic(
        "period_0.47",
        "bias = a·sin(2πd/0.47 m + 1) of the measured d: an off-library period",
        0.47,
    ),
    periodic(
        "period_1.3",
        "bias = a·sin(2πd/1.3 m + 1) of the measured d: a long off-library period",
        1.3,
    ),
    along(
        "range_noise",
        "bright_noise",
        "σ = a·V: noise growing with scene brightness (ambient light), not range",
        TermKind::Noise,
        "brightness",
    ),
    along(
        "range_noise",
        "dark_noise",
        "σ = a·(1 − V)²: noise growing on dark surfaces (weak signal)",
        TermKind::Noise,
        "brightness",
    ),
    along(
        "range_noise",
        "border_noise",
        "σ = a·r²: noise growing towards the grid border",
        TermKind::Noise,
        "grid_radius",
    ),
    along(
        "range_noise",
        "near_noise",
        "σ = a·exp(−d/1 m): noise falling with range",
        TermKind::Noise,
        "range_m",
    ),
    along(
        "dark_dropout",
        "bright_loss",
        "p = a·V²: loss rising with brightness (saturation), the opposite of dark_dropout",
        TermKind::Dropout,
        "brightness",
    ),
    along(
        "range_bias",
        "dark_bias",
        "bias = a·(1 − V)²: a distance bias on dark surfaces",
        TermKind::Bias,
        "brightness",
    ),
];

/// The shapes with a measured detection limit ([`calibrate`]): [`SHAPES`] and [`ANY_SHAPE`].
pub fn calibrated_shapes() -> impl Iterator<Item = Shape> {
    SHAPES.into_iter().chain(ANY_SHAPE)
}

/// Every shape, by family.
pub const SHAPES: [Shape; 13] = [
    s(
        "range_dropout",
        "logistic",
        "p = a·σ((d − d70)/0.15 m): a sharp cut-off at the 70th range percentile of the valid zones",
    ),
    s(
        "range_dropout",
        "step",
        "p = a beyond the 70th range percentile of the valid zones, 0 nearer",
    ),
    s(
        "dark_dropout",
        "threshold",
        "p = a below the 30th brightness percentile of the valid zones, 0 above",
    ),
    s(
        "dark_dropout",
        "ramp",
        "p = a·(1 − V/V60)₊²: a smooth quadratic ramp up to the 60th brightness percentile",
    ),
    s(
        "border_dropout",
        "step",
        "p = a at grid radius > 0.75, 0 inside",
    ),
    s(
        "border_dropout",
        "linear",
        "p = a·r: linear in the grid radius",
    ),
    s("range_noise", "quadratic", "σ = a·d²"),
    s("range_noise", "affine", "σ = a·(0.5 m + d)"),
    s("range_bias", "quadratic", "bias = a·d²"),
    s(
        "range_bias",
        "far_step",
        "bias = a beyond the median range, 0 nearer",
    ),
    s(
        "range_bias",
        "far_ramp",
        "bias = a·(d − d50)₊: growing beyond the median range",
    ),
    periodic(
        "quadrature",
        "bias = a·cos(2πd/0.3 m) of the measured d: the library's period, a quarter period off its phase",
        0.3,
    ),
    periodic(
        "sawtooth",
        "bias = a·(2·frac(d/0.3 m) − 1) of the measured d: a sawtooth over each 0.3 m bin",
        0.3,
    ),
];

/// What the injections read per zone (this file's own computation).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ZoneFacts {
    /// Mean reference depth over the zone's rectangle (0 without depth), metres.
    pub range_m: f32,
    /// Mean HSV value (max of R, G, B) / 255.
    pub v: f32,
    /// Distance from the grid centre, 0 at the centre, 1 at the corners.
    pub radius: f32,
}

/// Zone facts of `f` for a `rows × cols` grid whose zone rectangles (`[y0, x0, y1, x1]`
/// pixels) are `rects`.
pub fn zone_facts(f: &GapFrame, rects: &[[f32; 4]], rows: usize, cols: usize) -> Vec<ZoneFacts> {
    let (w, h) = (f.width as i64, f.height as i64);
    rects
        .iter()
        .enumerate()
        .map(|(z, r)| {
            let (y0, x0) = ((r[0].floor() as i64).max(0), (r[1].floor() as i64).max(0));
            let (y1, x1) = ((r[2].ceil() as i64).min(h), (r[3].ceil() as i64).min(w));
            let (mut dsum, mut dn, mut vsum, mut vn) = (0.0f64, 0u32, 0.0f64, 0u32);
            for y in y0..y1 {
                for x in x0..x1 {
                    let i = (y * w + x) as usize;
                    let d = f.depth_m[i];
                    if d.is_finite() && d > 0.0 {
                        dsum += f64::from(d);
                        dn += 1;
                    }
                    let p = &f.rgb[3 * i..3 * i + 3];
                    vsum += f64::from(p[0].max(p[1]).max(p[2])) / 255.0;
                    vn += 1;
                }
            }
            let half = |n: usize| ((n as f32 - 1.0) / 2.0).max(0.5);
            let (gy, gx) = (
                ((z / cols) as f32 - half(rows)) / half(rows),
                ((z % cols) as f32 - half(cols)) / half(cols),
            );
            ZoneFacts {
                range_m: if dn > 0 {
                    (dsum / f64::from(dn)) as f32
                } else {
                    0.0
                },
                v: if vn > 0 {
                    (vsum / f64::from(vn)) as f32
                } else {
                    0.0
                },
                radius: ((gy * gy + gx * gx) / 2.0).sqrt(),
            }
        })
        .collect()
}

/// The `q`-quantile of `v` (0 when empty).
fn quantile(v: &mut [f32], q: f64) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    v[((q * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)]
}

/// Recording-level thresholds the shapes use, over the zones with depth that the plain
/// simulation left valid: the range cut-off (70th percentile), the median range, the near
/// cut-off (30th) and the end of the near ramp (50th) of the confounded shapes, the dark
/// threshold (30th brightness percentile), the end of the dark ramp (60th), the border radius
/// (0.75). `widen` steps move each dropout cut-off by 10 % of the zones (0.1 in radius) towards
/// more affected zones.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Thresholds {
    d70: f32,
    d50: f32,
    d30: f32,
    near: f32,
    v30: f32,
    v60: f32,
    r75: f32,
    /// Steps the dropout cut-offs were moved.
    pub widen: u8,
}

impl Thresholds {
    /// From the zones of every frame of `plain` (facts `facts`), cut-offs moved `widen` steps.
    pub fn of(plain: &GapData, facts: &[Vec<ZoneFacts>], widen: u8) -> Self {
        let all: Vec<&ZoneFacts> = plain
            .frames
            .iter()
            .zip(facts)
            .flat_map(|(f, zf)| {
                zf.iter()
                    .enumerate()
                    .filter(|(zi, z)| {
                        f.real_valid.get(*zi).copied().unwrap_or(false) && z.range_m > 0.0
                    })
                    .map(|(_, z)| z)
            })
            .collect();
        let mut d: Vec<f32> = all.iter().map(|z| z.range_m).collect();
        let mut v: Vec<f32> = all.iter().map(|z| z.v).collect();
        let k = f64::from(widen) * 0.1;
        Thresholds {
            d70: quantile(&mut d, (0.7 - k).max(0.0)),
            d50: quantile(&mut d, 0.5),
            d30: quantile(&mut d, (0.3 + k).min(1.0)),
            near: quantile(&mut d, (0.5 + k).min(1.0)).max(1e-3),
            v30: quantile(&mut v, (0.3 + k).min(1.0)),
            v60: quantile(&mut v, (0.6 + k).min(1.0)).max(1e-3),
            r75: (0.75 - k as f32).max(0.0),
            widen,
        }
    }
}

/// The shape's value at unit amplitude for zone `z` whose measured distance is `measured_m` (a
/// loss probability factor, a σ in metres per unit, or a signed bias in metres per unit).
pub fn unit_value(shape: &Shape, t: &Thresholds, z: &ZoneFacts, measured_m: f32) -> f32 {
    let d = z.range_m;
    let bin = measured_m / shape.period_m.unwrap_or(0.3);
    match (shape.family, shape.name) {
        ("range_noise", "bright_noise") => z.v,
        ("range_noise", "dark_noise") => (1.0 - z.v).powi(2),
        ("range_noise", "border_noise") => z.radius * z.radius,
        ("range_noise", "near_noise") => (-d).exp(),
        ("dark_dropout", "bright_loss") => z.v * z.v,
        ("range_bias", "dark_bias") => (1.0 - z.v).powi(2),
        ("bin_wiggle", "sawtooth") => 2.0 * (bin - bin.floor()) - 1.0,
        ("range_dropout", "logistic") => 1.0 / (1.0 + (-(d - t.d70) / 0.15).exp()),
        ("range_dropout", "near") => (1.0 - d / t.near).max(0.0),
        ("range_dropout", "near_step") => f32::from(u8::from(d < t.d30)),
        ("range_dropout", _) => f32::from(u8::from(d > t.d70)),
        ("dark_dropout", "threshold") => f32::from(u8::from(z.v < t.v30)),
        ("dark_dropout", _) => (1.0 - z.v / t.v60).max(0.0).powi(2),
        ("border_dropout", "step") => f32::from(u8::from(z.radius > t.r75)),
        ("border_dropout", _) => z.radius,
        ("range_noise", "quadratic") => d * d,
        ("range_noise", _) => 0.5 + d,
        ("range_bias", "quadratic") => d * d,
        ("range_bias", "far_step") => f32::from(u8::from(d > t.d50)),
        ("range_bias", _) => (d - t.d50).max(0.0),
        ("bin_wiggle", "quadrature") => (core::f32::consts::TAU * bin).cos(),
        ("bin_wiggle", _) => (core::f32::consts::TAU * bin + 1.0).sin(),
        _ => 0.0,
    }
}

/// The library form's per-zone effect (loss probability, σ, or |bias|) under `lib` for zone `z`
/// of frame `f` (the simulator's covariates `cov`, used only to size the shapes).
fn library_value(
    family: &str,
    lib: &SimConfig,
    z: &ZoneFacts,
    cov: &crate::sim::covariates::ZoneCovariates,
) -> f32 {
    let d = z.range_m;
    match family {
        "range_dropout" => lib.range_dropout.loss_probability(d),
        "dark_dropout" => lib.dark_dropout.loss_probability(cov),
        "border_dropout" => lib.border_dropout.loss_probability(cov.radius),
        "range_noise" => lib.range_noise.sigma(d),
        "range_bias" => (lib.range_bias.distance(d) - d).abs(),
        "bin_wiggle" => (lib.bin_wiggle.distance(d) - d).abs(),
        _ => 0.0,
    }
}

/// Amplitude `a` of `shape` whose mean effect over the valid zones of `plain` equals the library
/// form's at `size` × its unit.
pub fn amplitude(
    shape: &Shape,
    size: f64,
    base: &SimConfig,
    plain: &GapData,
    facts: &[Vec<ZoneFacts>],
    t: &Thresholds,
) -> Option<f32> {
    let mut lib = base.clone();
    let (family, v) = at_size(shape.family, size);
    library(family).set(&mut lib, Some(&v));
    let (rows, cols) = (usize::from(base.grid.rows), usize::from(base.grid.cols));
    let (mut lib_sum, mut unit_sum, mut n) = (0.0f64, 0.0f64, 0usize);
    for (f, zf) in plain.frames.iter().zip(facts) {
        let input = f.sim_input();
        let rects = base.grid.zone_rects_px(f.width, f.height);
        for (zi, z) in zf.iter().enumerate() {
            if !f.real_valid.get(zi).copied().unwrap_or(false) || z.range_m <= 0.0 {
                continue;
            }
            let r = rects[zi];
            let w = f.width as i64;
            let mut px = Vec::new();
            for y in (r[0].floor() as i64).max(0)..(r[2].ceil() as i64).min(f.height as i64) {
                for x in (r[1].floor() as i64).max(0)..(r[3].ceil() as i64).min(w) {
                    px.push((y * w + x) as u32);
                }
            }
            let cov = zone_covariates(&input, &px, 1.0, zi, rows, cols);
            lib_sum += f64::from(library_value(shape.family, &lib, z, &cov));
            unit_sum += f64::from(unit_value(shape, t, z, f.real_m[zi]).abs());
            n += 1;
        }
    }
    (n > 0 && unit_sum > 0.0).then(|| (lib_sum / unit_sum) as f32)
}

/// Applies `shape` at amplitude `a` to the zones of `f` (facts `zf`): dropout clears a valid
/// zone with probability `min(a·u, 1)`, noise adds `a·u·N(0, 1)`, bias and wiggle add `a·u`.
pub fn inject(
    shape: &Shape,
    a: f32,
    t: &Thresholds,
    zf: &[ZoneFacts],
    f: &mut GapFrame,
    rng: &mut Rng,
) {
    for (zi, z) in zf.iter().enumerate() {
        if !f.real_valid.get(zi).copied().unwrap_or(false) {
            continue;
        }
        let u = unit_value(shape, t, z, f.real_m[zi]);
        match shape.family {
            "range_noise" => f.real_m[zi] = (f.real_m[zi] + a * u * rng.normal()).max(1e-3),
            "range_bias" | "bin_wiggle" => f.real_m[zi] = (f.real_m[zi] + a * u).max(1e-3),
            _ => {
                if rng.f32() < (a * u).min(1.0) {
                    f.real_valid[zi] = false;
                }
            }
        }
    }
}

/// One shape case (or a null: `shape` None).
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeCase {
    /// Label (`real:range_dropout/logistic@2x#0`, `null#3`).
    pub label: String,
    /// The injected shape.
    pub shape: Option<Shape>,
    /// Size multiple of the shape's unit (its measured detection limit).
    pub size: f64,
    /// The shape's unit as a multiple of the library form's unit ([`shape_unit`]).
    pub unit: f64,
    /// Scene set name (`sim`, `real`).
    pub scenes: &'static str,
}

/// The outcome of one shape case.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeResult {
    /// The case.
    pub case: ShapeCase,
    /// The amplitude injected.
    pub amplitude: f32,
    /// Steps the dropout cut-off was moved to keep the loss probability ≤ 1.
    pub widen: u8,
    /// Effects named, most important first.
    pub named: Vec<String>,
    /// The covariates the first finding is attributed to (both of an inseparable pair); empty
    /// without a finding.
    pub first_covariates: Vec<String>,
    /// What the first finding changes (a loss, bias or noise curve; `None` for an effect
    /// without one kind and covariate, or without a finding).
    pub first_kind: Option<TermKind>,
    /// The first finding's searched period (a periodic error), metres.
    pub first_period_m: Option<f64>,
    /// Whether report.json would say the held-out frames can reach significance.
    pub conclusive: bool,
    /// Held-out gain of each accepted finding, nats per zone.
    pub finding_gains: Vec<f64>,
}

impl ShapeResult {
    /// The first finding is the family's name (a periodic shape: with its period within
    /// [`PERIOD_TOLERANCE`]); for a shape along a covariate, the first finding is attributed to
    /// the shape's covariate (alone or inseparable from another) and changes the shape's kind.
    pub fn top1(&self) -> bool {
        self.case.shape.is_some_and(|s| match s.covariate {
            Some(c) => {
                self.first_covariates.iter().any(|x| x == c)
                    && s.kind.is_none_or(|k| self.first_kind == Some(k))
            }
            None => {
                self.named.first().is_some_and(|n| n == s.family)
                    && s.period_m.is_none_or(|p| {
                        self.first_period_m.is_some_and(|q| {
                            (q - f64::from(p)).abs() <= PERIOD_TOLERANCE * f64::from(p)
                        })
                    })
            }
        })
    }
}

/// Runs one case: a plain simulation of `scenes`, the shape injected, the tool run against
/// `base`; also returns the tool's analysis.
pub fn run_shape_case(
    scenes: &[SceneFrame],
    base: &SimConfig,
    case: &ShapeCase,
    opts: &GapOptions,
    seed: u64,
) -> Result<(ShapeResult, super::Analysis), GapError> {
    let mut real = make_real(scenes, base, seed, None)?;
    let (rows, cols) = (usize::from(base.grid.rows), usize::from(base.grid.cols));
    let facts: Vec<Vec<ZoneFacts>> = real
        .frames
        .par_iter()
        .map(|f| zone_facts(f, &base.grid.zone_rects_px(f.width, f.height), rows, cols))
        .collect();
    let mut t = Thresholds::of(&real, &facts, 0);
    let mut a = 0.0;
    if let Some(shape) = &case.shape {
        let size = case.size * case.unit;
        a = amplitude(shape, size, base, &real, &facts, &t).unwrap_or(0.0);
        while shape.family.ends_with("_dropout") && a > 1.0 && t.widen < 6 {
            t = Thresholds::of(&real, &facts, t.widen + 1);
            a = amplitude(shape, size, base, &real, &facts, &t).unwrap_or(0.0);
        }
        for (i, (f, zf)) in real.frames.iter_mut().zip(&facts).enumerate() {
            inject(
                shape,
                a,
                &t,
                zf,
                f,
                &mut Rng::derive(seed ^ 0x5_4A9E, i as u64),
            );
        }
    }
    let an = analyze(&real, base, opts, &|_| {})?;
    let r = ShapeResult {
        case: case.clone(),
        amplitude: a,
        widen: t.widen,
        named: an
            .selection
            .findings
            .iter()
            .map(|f| f.effect.clone())
            .collect(),
        first_covariates: an.selection.findings.first().map_or(Vec::new(), |f| {
            an.selection
                .attributed_covariates(&f.effect)
                .into_iter()
                .map(String::from)
                .collect()
        }),
        first_kind: an.selection.findings.first().and_then(|f| {
            super::select::kind_and_covariate(&f.effect, &an.selection.estimate).map(|k| k.0)
        }),
        first_period_m: an
            .selection
            .findings
            .first()
            .and_then(|f| f.params.get("period_m").copied()),
        conclusive: an.power.conclusive,
        finding_gains: an
            .selection
            .findings
            .iter()
            .map(|f| f.heldout_gain)
            .collect(),
    };
    Ok((r, an))
}

/// Every shape at `size` × its unit (`unit(shape)`, a multiple of the library form's unit) on
/// each scene set in `sets`, `repeats` times (own seeds), and `nulls` null cases per set.
pub fn shape_cases(
    sets: &[&'static str],
    size: f64,
    repeats: usize,
    nulls: usize,
    unit: impl Fn(&Shape) -> f64,
) -> Vec<ShapeCase> {
    let mut v = Vec::new();
    for &set in sets {
        let pre = if set == "sim" {
            String::new()
        } else {
            format!("{set}:")
        };
        for r in 0..repeats {
            for sh in SHAPES.into_iter().chain(CONFOUNDED).chain(ANY_SHAPE) {
                v.push(ShapeCase {
                    label: format!("{pre}{}/{}@{size}x#{r}", sh.family, sh.name),
                    shape: Some(sh),
                    size,
                    unit: unit(&sh),
                    scenes: set,
                });
            }
        }
        for k in 0..nulls {
            v.push(ShapeCase {
                label: format!("{pre}null#{k}"),
                shape: None,
                size: 0.0,
                unit: 1.0,
                scenes: set,
            });
        }
    }
    v
}

/// The shape's key in the unit table (`family/name`).
pub fn key(shape: &Shape) -> String {
    format!("{}/{}", shape.family, shape.name)
}

/// The committed shape units (`host/data/gap_shape_units.json`, written by `depthor gap-bench
/// --calibrate-units --shapes`); empty when it does not parse.
pub fn calibrated() -> &'static UnitTable {
    static T: OnceLock<UnitTable> = OnceLock::new();
    T.get_or_init(|| {
        serde_json::from_str(include_str!("../../data/gap_shape_units.json")).unwrap_or_default()
    })
}

/// The shape's unit (its measured detection limit) as a multiple of the library form's unit;
/// 1 when the committed table lacks it.
pub fn shape_unit(shape: &Shape) -> f64 {
    shape_unit_in(calibrated(), shape)
}

/// The shape's unit in `table` (a `--calibrate-units --shapes` table); 1 when it lacks it.
pub fn shape_unit_in(table: &UnitTable, shape: &Shape) -> f64 {
    table
        .units
        .get(&key(shape))
        .and_then(|u| u.params.first().copied())
        .unwrap_or(1.0)
}

/// The most a shape's unit may be, as a multiple of the library form's unit (the top of the
/// calibration ladder).
pub const MAX_UNIT: f64 = 16.0;

/// Measures each shape's detection limit: the smallest multiple of the library form's unit at
/// which the tool names the shape's family first in ≥ `opts.threshold` of the recordings made
/// from `scene_sets` (one per trial; seeds disjoint from the benchmark's), by the ladder of
/// [`ladder_search`] from 1 up to [`MAX_UNIT`], with the same knobs as the library's units
/// ([`units::calibrate`](super::units::calibrate)). `progress` gets a line per rung.
pub fn calibrate(
    base: &SimConfig,
    scene_sets: &[Vec<SceneFrame>],
    shapes: &[Shape],
    opts: &CalibrateOptions,
    mut progress: impl FnMut(&str),
) -> Result<BTreeMap<String, CalibratedUnit>, GapError> {
    let k = scene_sets.len();
    let mut out = BTreeMap::new();
    for sh in shapes {
        let mut ladder = Vec::new();
        let (multiple, bracketed) = ladder_search(
            1.0,
            opts.step,
            MAX_UNIT,
            opts.refine,
            |m| -> Result<bool, GapError> {
                let (hits, runs) = rung(k, opts.threshold, |t| {
                    let label = format!("calibrate:{}@{m:.4}#{t}", key(sh));
                    let case = ShapeCase {
                        label: label.clone(),
                        shape: Some(*sh),
                        size: m,
                        unit: 1.0,
                        scenes: "sim",
                    };
                    let seed = super::bench::case_seed(opts.seed, &label);
                    Ok::<_, GapError>(
                        run_shape_case(&scene_sets[t], base, &case, &opts.gap, seed)?
                            .0
                            .top1(),
                    )
                })?;
                progress(&format!(
                    "{} × {m:.3}: named first in {hits} of {runs}",
                    key(sh)
                ));
                ladder.push((m, hits, runs));
                Ok(hits >= needed(k, opts.threshold))
            },
        )?;
        out.insert(
            key(sh),
            CalibratedUnit {
                params: vec![multiple],
                multiple,
                ladder,
                bracketed,
                reference_gain_nats: None,
            },
        );
    }
    Ok(out)
}

/// Markdown tables of `results`: one row per case; top-1 attribution per scene set and family;
/// false positives on the nulls with a one-sided 95 % upper bound; findings with a positive
/// held-out gain.
pub fn shape_table(results: &[ShapeResult]) -> String {
    let mut s = String::from(
        "| case | shape | unit (× library's) | amplitude | cut-off moved | named | top-1 | conclusive | findings with gain > 0 |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {}/{} |\n",
            r.case.label,
            r.case.shape.map_or("—", |x| x.what),
            r.case
                .shape
                .map_or("—".into(), |_| format!("{:.2}", r.case.unit)),
            r.case
                .shape
                .map_or("—".into(), |_| format!("{:.4}", r.amplitude)),
            if r.widen > 0 {
                format!("{} × 10 %", r.widen)
            } else {
                "—".into()
            },
            if r.named.is_empty() {
                "—".into()
            } else {
                r.named.join(", ")
            },
            if r.case.shape.is_none() {
                "—"
            } else if r.top1() {
                "yes"
            } else {
                "no"
            },
            if r.conclusive { "yes" } else { "no" },
            r.finding_gains.iter().filter(|&&g| g > 0.0).count(),
            r.finding_gains.len(),
        ));
    }
    let mut sets: Vec<&str> = results.iter().map(|r| r.case.scenes).collect();
    sets.dedup();
    s.push_str("\n| scenes | family | cases | top-1 attribution |\n|---|---|---|---|\n");
    for set in &sets {
        let mut fams: Vec<&str> = SHAPES.iter().map(|x| x.family).collect();
        fams.dedup();
        fams.extend(["confounded", "any shape", "all"]);
        for fam in fams {
            let rs: Vec<&ShapeResult> = results
                .iter()
                .filter(|r| r.case.scenes == *set)
                .filter(|r| {
                    r.case.shape.is_some_and(|x| match fam {
                        "all" => true,
                        "confounded" => CONFOUNDED.contains(&x),
                        "any shape" => ANY_SHAPE.contains(&x),
                        _ => x.family == fam && SHAPES.contains(&x),
                    })
                })
                .collect();
            if rs.is_empty() {
                continue;
            }
            let top = rs.iter().filter(|r| r.top1()).count();
            s.push_str(&format!(
                "| {set} | {fam} | {} | {:.0} % ({top}) |\n",
                rs.len(),
                100.0 * top as f64 / rs.len() as f64
            ));
        }
    }
    s.push('\n');
    for set in sets.iter().copied().chain(std::iter::once("all")) {
        let nulls: Vec<&ShapeResult> = results
            .iter()
            .filter(|r| r.case.shape.is_none() && (set == "all" || r.case.scenes == set))
            .collect();
        if nulls.is_empty() {
            continue;
        }
        let fp = nulls.iter().filter(|r| !r.named.is_empty()).count();
        s.push_str(&null_line(set, nulls.len(), fp));
    }
    s.push_str(&gains_line(
        results.iter().flat_map(|r| r.finding_gains.iter().copied()),
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(depth: f32, v: u8) -> GapFrame {
        let (w, h) = (16u32, 16u32);
        let n = (w * h) as usize;
        GapFrame {
            id: "0".into(),
            t_s: 0.0,
            width: w,
            height: h,
            depth_m: vec![depth; n],
            rgb: vec![v; 3 * n],
            labels: None,
            real_valid: vec![true; 4],
            real_m: vec![depth; 4],
        }
    }

    fn rects() -> Vec<[f32; 4]> {
        vec![
            [0.0, 0.0, 8.0, 8.0],
            [0.0, 8.0, 8.0, 16.0],
            [8.0, 0.0, 16.0, 8.0],
            [8.0, 8.0, 16.0, 16.0],
        ]
    }

    #[test]
    fn facts_are_the_zone_means_and_corners_have_radius_one() {
        let f = frame(2.5, 102);
        let z = zone_facts(&f, &rects(), 2, 2);
        assert!(z
            .iter()
            .all(|z| (z.range_m - 2.5).abs() < 1e-6 && (z.v - 0.4).abs() < 1e-6));
        assert!(z.iter().all(|z| (z.radius - 1.0).abs() < 1e-6), "{z:?}");
    }

    #[test]
    fn every_calibrated_shape_has_a_committed_unit() {
        for sh in calibrated_shapes() {
            let u = calibrated().units.get(&key(&sh));
            assert!(u.is_some_and(|u| u.bracketed), "{}", key(&sh));
            assert!((shape_unit(&sh) - u.unwrap().multiple).abs() < 1e-12);
        }
    }

    #[test]
    fn confounded_shapes_lose_close_returns() {
        let t = Thresholds {
            d30: 1.5,
            near: 2.0,
            ..Thresholds::default()
        };
        let at = |sh: &Shape, d: f32| {
            let z = ZoneFacts {
                range_m: d,
                v: 0.5,
                radius: 0.5,
            };
            unit_value(sh, &t, &z, d)
        };
        let [ramp, step] = &CONFOUNDED;
        assert_eq!(
            (at(ramp, 0.5), at(ramp, 1.0), at(ramp, 3.0)),
            (0.75, 0.5, 0.0)
        );
        assert_eq!((at(step, 1.0), at(step, 2.0)), (1.0, 0.0));
        assert!(CONFOUNDED.iter().all(|s| s.covariate == Some("range_m")));
    }

    #[test]
    fn shapes_differ_from_the_library_forms_and_injections_do_what_they_say() {
        let t = Thresholds {
            d70: 3.0,
            d50: 2.0,
            d30: 1.5,
            near: 2.0,
            v30: 0.2,
            v60: 0.5,
            r75: 0.75,
            widen: 0,
        };
        let near = ZoneFacts {
            range_m: 1.0,
            v: 0.9,
            radius: 0.2,
        };
        let far = ZoneFacts {
            range_m: 5.0,
            v: 0.1,
            radius: 0.9,
        };
        for sh in SHAPES.iter().filter(|s| s.family != "bin_wiggle") {
            let (a, b) = (
                unit_value(sh, &t, &near, 1.0),
                unit_value(sh, &t, &far, 5.0),
            );
            assert!(
                b > a,
                "{} / {}: far or dark or outer zones get more",
                sh.family,
                sh.name
            );
        }
        // Steps are exactly 0 / 1: not the library's smooth forms.
        let step = SHAPES.iter().find(|x| x.name == "step").unwrap();
        assert_eq!(
            (
                unit_value(step, &t, &near, 1.0),
                unit_value(step, &t, &far, 5.0)
            ),
            (0.0, 1.0)
        );
        let mut f = frame(5.0, 20);
        let zf = vec![far; 4];
        let bias = SHAPES.iter().find(|x| x.name == "far_step").unwrap();
        inject(bias, 0.05, &t, &zf, &mut f, &mut Rng::new(1));
        assert!(f.real_m.iter().all(|&d| (d - 5.05).abs() < 1e-6));
        let drop = SHAPES.iter().find(|x| x.family == "dark_dropout").unwrap();
        inject(drop, 1.0, &t, &zf, &mut f, &mut Rng::new(1));
        assert!(f.real_valid.iter().all(|v| !v), "p = 1 clears every zone");
        // The periodic shapes follow the measured distance over 0.3 m bins: a quarter period
        // off the library's sine (cos), and a sawtooth rising across each bin.
        let q = SHAPES.iter().find(|x| x.name == "quadrature").unwrap();
        let saw = SHAPES.iter().find(|x| x.name == "sawtooth").unwrap();
        for (m, cos, tooth) in [(0.6, 1.0, -1.0), (0.675, 0.0, -0.5), (0.75, -1.0, 0.0)] {
            assert!((unit_value(q, &t, &near, m) - cos).abs() < 1e-5, "{m}");
            assert!((unit_value(saw, &t, &near, m) - tooth).abs() < 1e-4, "{m}");
        }
        let mut f = frame(2.0, 20);
        f.real_m = vec![0.6; 4];
        inject(q, 0.01, &t, &zf, &mut f, &mut Rng::new(1));
        assert!(f.real_m.iter().all(|&d| (d - 0.61).abs() < 1e-6));
        let cases = shape_cases(&["sim", "real"], 2.0, 2, 3, |s| {
            if s.family == "range_noise" {
                1.5
            } else {
                1.0
            }
        });
        assert_eq!(
            cases.len(),
            2 * (2 * (SHAPES.len() + CONFOUNDED.len() + ANY_SHAPE.len()) + 3)
        );
        assert!(cases
            .iter()
            .filter(|c| c.shape.is_some_and(|s| s.family == "range_noise"))
            .all(|c| c.unit == 1.5));
        assert!(cases
            .iter()
            .all(|c| c.scenes == "sim" || c.label.starts_with("real:")));
    }
}
