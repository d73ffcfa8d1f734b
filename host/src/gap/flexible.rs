//! Flexible forms (docs/gap.md "Flexible forms"): for each effect family a curve over the
//! family's covariate, estimated in closed form on the fitting frames, beside the library's
//! parametric form. A real loss that cuts off sharply in range, a noise growing faster than
//! linearly or a bias only beyond some range has a shape the parametric forms cannot take; the
//! curve can, so the family whose covariate explains the residual still shows a held-out gain
//! and gets the name. The curves are [`crate::sim::learned::Term`]s: `depthor sim --config` runs
//! them.
//!
//! Estimation per family, on equal-count bins of the covariate over the fitting frames' zones
//! (the draws transformed by the current model, [`super::model::transform`]):
//! - dropout: `L_b = 1 − Σ observed valid / Σ predicted survival` in bin `b`, then weighted
//!   isotonic regression (non-decreasing in range and radius, non-increasing in brightness);
//! - bias and noise: per bin, the shift of the draws (or the extra Gaussian σ) that maximises
//!   the likelihood of the bin's valid real distances under the tool's kernel mixture (grid scan
//!   then golden section), then non-decreasing in range for noise.

use super::model::{transform, Prepared, T3_SCALE_OF_GAUSSIAN};
use super::stats::grid_golden_min;
use crate::sim::learned::{isotonic, Term, TermCovariate, TermKind};
use crate::sim::SimConfig;

/// Bins of a curve (its knots).
pub const BINS: usize = 6;

/// One flexible form: the family it stands for, what it changes, over which covariate, and the
/// direction its curve is constrained to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Form {
    /// The library family it is a flexible form of.
    pub family: &'static str,
    /// What the curve changes.
    pub kind: TermKind,
    /// Its covariate.
    pub on: TermCovariate,
    /// `Some(true)`: non-decreasing; `Some(false)`: non-increasing; `None`: free.
    pub monotone: Option<bool>,
}

/// The flexible forms, one per family that has one.
pub const FORMS: [Form; 5] = [
    Form {
        family: "range_dropout",
        kind: TermKind::Dropout,
        on: TermCovariate::Range,
        monotone: Some(true),
    },
    Form {
        family: "dark_dropout",
        kind: TermKind::Dropout,
        on: TermCovariate::Brightness,
        monotone: Some(false),
    },
    Form {
        family: "border_dropout",
        kind: TermKind::Dropout,
        on: TermCovariate::Radius,
        monotone: Some(true),
    },
    Form {
        family: "range_noise",
        kind: TermKind::Noise,
        on: TermCovariate::Range,
        monotone: Some(true),
    },
    Form {
        family: "range_bias",
        kind: TermKind::Bias,
        on: TermCovariate::Range,
        monotone: None,
    },
];

/// The flexible form of `family`, if it has one.
pub fn form(family: &str) -> Option<&'static Form> {
    FORMS.iter().find(|f| f.family == family)
}

/// What one zone of a fitting frame contributes.
struct ZoneObs {
    /// Covariate value.
    x: f32,
    /// Predicted survival probability (mean of the draws' `p`).
    p: f64,
    /// Observed: a valid real return.
    valid: bool,
    /// The real distance and the draws `(p, d, s)` with a return (valid zones with a predicted
    /// return; bias and noise curves only).
    fit: Option<(f64, Vec<DrawPds>)>,
}

/// A draw's survival probability, distance and extra noise scale.
type DrawPds = (f64, f64, f64);

fn observations(
    form: &Form,
    model: &SimConfig,
    base: &SimConfig,
    frames: &[Prepared],
    idx: &[usize],
) -> Vec<ZoneObs> {
    let mut out = Vec::new();
    for &f in idx {
        let prep = &frames[f];
        let draws = transform(model, base, prep, [0, 0]);
        let z_n = prep.zones();
        for z in 0..z_n {
            let c = &prep.cov[z];
            let (mut sp, mut sd) = (0.0f64, 0.0f64);
            for k in 0..prep.k {
                let d = &draws[k * z_n + z];
                sp += f64::from(d.p);
                sd += f64::from(d.p) * f64::from(d.d);
            }
            let mean_d = if sp > 0.0 { sd / sp } else { 0.0 };
            // Range: where the draws put the return (what the forward model reads), else the
            // window's mean reference depth.
            let x = match form.on {
                TermCovariate::Range if sp > 0.0 => mean_d as f32,
                TermCovariate::Range if c.mean_m > 0.0 => c.mean_m,
                TermCovariate::Range => continue,
                TermCovariate::Brightness => c.brightness,
                TermCovariate::Radius => c.radius,
            };
            let real = prep.real[z];
            let fit = real
                .filter(|_| sp > 0.0 && form.kind != TermKind::Dropout)
                .map(|y| {
                    let ds = (0..prep.k)
                        .map(|k| draws[k * z_n + z])
                        .filter(|d| d.p > 0.0)
                        .map(|d| (f64::from(d.p), f64::from(d.d), f64::from(d.s)))
                        .collect();
                    (f64::from(y), ds)
                });
            out.push(ZoneObs {
                x,
                p: sp / prep.k as f64,
                valid: real.is_some(),
                fit,
            });
        }
    }
    out
}

/// Negative log-likelihood of the real distances of `bin` under their draws shifted by `bias`
/// with `sd` of extra Gaussian noise: the tool's Student-t₃ kernel mixture (kernel floor
/// `kernel_m`) without its outlier term, floored at 1e-9 per zone.
fn bin_nll(bin: &[ZoneObs], kernel_m: f64, bias: f64, sd: f64) -> f64 {
    let extra = f64::from(T3_SCALE_OF_GAUSSIAN) * sd;
    bin.iter()
        .filter_map(|o| o.fit.as_ref())
        .map(|(y, ds)| {
            let (mut num, mut den) = (0.0, 0.0);
            for &(p, d, s) in ds {
                let sc = (kernel_m * kernel_m + s * s + extra * extra).sqrt();
                let z = (y - d - bias) / sc;
                num += p * (1.0 + z * z / 3.0).powi(-2) / sc;
                den += p;
            }
            -(num / f64::max(den, 1e-12) + 1e-9).ln()
        })
        .sum()
}

/// Estimates `form`'s curve on frames `idx` on top of `model` (the draws simulated under
/// `base`), with kernel floor `kernel_m`; `None` when the frames give fewer than two bins.
pub fn estimate(
    form: &Form,
    model: &SimConfig,
    base: &SimConfig,
    frames: &[Prepared],
    idx: &[usize],
    kernel_m: f64,
) -> Option<Term> {
    let mut obs = observations(form, model, base, frames, idx);
    if form.kind != TermKind::Dropout {
        obs.retain(|o| o.fit.is_some());
    }
    obs.sort_by(|a, b| a.x.total_cmp(&b.x));
    let n = obs.len();
    if n < 2 * BINS {
        return None;
    }
    let (mut knots, mut values, mut weights) = (Vec::new(), Vec::new(), Vec::new());
    for b in 0..BINS {
        let bin = &obs[b * n / BINS..(b + 1) * n / BINS];
        let x = bin.iter().map(|o| f64::from(o.x)).sum::<f64>() / bin.len() as f64;
        if knots.last().is_some_and(|&k: &f32| x as f32 <= k) {
            continue; // ties: a covariate with few distinct values
        }
        let (v, w) = match form.kind {
            TermKind::Dropout => {
                let pred: f64 = bin.iter().map(|o| o.p).sum();
                let seen = bin.iter().filter(|o| o.valid).count() as f64;
                let loss = if pred > 0.0 {
                    (1.0 - seen / pred).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (loss, pred)
            }
            TermKind::Bias => {
                let nll = |b: f64| bin_nll(bin, kernel_m, b, 0.0);
                (grid_golden_min(nll, -0.3, 0.3, 24, 16).0, bin.len() as f64)
            }
            TermKind::Noise => {
                let nll = |sd: f64| bin_nll(bin, kernel_m, 0.0, sd);
                (grid_golden_min(nll, 0.0, 0.5, 24, 16).0, bin.len() as f64)
            }
        };
        knots.push(x as f32);
        values.push(v);
        weights.push(w);
    }
    if knots.len() < 2 {
        return None;
    }
    let values = match form.monotone {
        Some(true) => isotonic(&values, &weights),
        Some(false) => {
            let neg: Vec<f64> = values.iter().map(|v| -v).collect();
            isotonic(&neg, &weights).into_iter().map(|v| -v).collect()
        }
        None => values,
    };
    Some(Term {
        family: Some(form.family.to_string()),
        kind: form.kind,
        on: form.on,
        knots,
        values: values.into_iter().map(|v| v as f32).collect(),
    })
}

/// `model` with `term` as the learned term of its family (replacing one there), switched on.
pub fn with_term(model: &SimConfig, term: Term) -> SimConfig {
    let mut m = model.clone();
    if let Some(f) = term.family.clone() {
        remove(&mut m, &f);
    }
    m.learned.enabled = true;
    m.learned.terms.push(term);
    m
}

/// Removes `family`'s learned term from `model` (switching the learned effect off when none is
/// left).
pub fn remove(model: &mut SimConfig, family: &str) {
    model
        .learned
        .terms
        .retain(|t| t.family.as_deref() != Some(family));
    model.learned.enabled &= !model.learned.terms.is_empty();
}

/// `family`'s learned term in `model`, if any.
pub fn term<'m>(model: &'m SimConfig, family: &str) -> Option<&'m Term> {
    model
        .learned
        .terms
        .iter()
        .find(|t| t.family.as_deref() == Some(family))
}

/// Name of a finding fitted from the residual alone (physics outside the library).
pub const LEARNED: &str = "learned";

/// The kinds of a residual curve: a loss, a bias or a noise curve.
pub const RESIDUAL_KINDS: [TermKind; 3] = [TermKind::Dropout, TermKind::Bias, TermKind::Noise];

/// The covariates a residual curve may run over.
pub const RESIDUAL_COVARIATES: [TermCovariate; 3] = [
    TermCovariate::Range,
    TermCovariate::Brightness,
    TermCovariate::Radius,
];

/// The forms a residual curve may take (issue 44 item 3): every kind ([`RESIDUAL_KINDS`]) over
/// every covariate ([`RESIDUAL_COVARIATES`]), in either direction. Where a library family
/// that `offered` says is a candidate has the same kind and covariate, the family covers its
/// own direction (it is fitted there, under its name): the residual curve then takes only the
/// other one (a loss falling with range beside `range_dropout`'s rising one, noise falling with
/// range beside `range_noise`), and none where the family's curve is direction-free
/// (`range_bias`). Elsewhere the curve is direction-free, so no direction is favoured.
pub fn residual_forms(offered: impl Fn(&str) -> bool) -> Vec<Form> {
    let mut v = Vec::new();
    for kind in RESIDUAL_KINDS {
        for on in RESIDUAL_COVARIATES {
            let free = Form {
                family: LEARNED,
                kind,
                on,
                monotone: None,
            };
            let family = FORMS
                .iter()
                .find(|f| f.kind == kind && f.on == on && offered(f.family));
            match family.map(|f| f.monotone) {
                None => v.push(free),
                Some(Some(up)) => v.push(Form {
                    monotone: Some(!up),
                    ..free
                }),
                Some(None) => {}
            }
        }
    }
    v
}

/// The residual term in words: what it changes, which way, along which covariate.
pub fn describe(t: &Term) -> String {
    let (first, last) = (
        t.values.first().copied().unwrap_or(0.0),
        t.values.last().copied().unwrap_or(0.0),
    );
    let way = if last >= first { "rising" } else { "falling" };
    let what = match t.kind {
        TermKind::Dropout => format!(
            "extra loss of returns {way} with {} ({first:.3} → {last:.3})",
            t.on.name()
        ),
        TermKind::Bias => format!(
            "distance bias {way} with {} ({:+.1} → {:+.1} cm)",
            t.on.name(),
            100.0 * first,
            100.0 * last
        ),
        TermKind::Noise => format!(
            "extra noise {way} with {} ({:.1} → {:.1} cm)",
            t.on.name(),
            100.0 * first,
            100.0 * last
        ),
    };
    format!("outside the library: {what}")
}
