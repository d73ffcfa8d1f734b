//! `learned`: sim-to-real physics the effect library does not name in its own form, fitted from
//! data by the gap tool (`depthor gap`, docs/gap.md "Flexible forms"): each term is a
//! piecewise-linear curve over one zone covariate (range, brightness or grid radius) that adds a
//! loss probability, a distance bias or a noise standard deviation. `depthor sim --config` runs
//! the terms like any effect: per zone, after the library's effects.

use serde::{Deserialize, Serialize};

use super::covariates::{scene_covariates, ZoneCovariates};
use super::error::SimError;
use super::frame::{Scene, ZoneEffect, ZoneGrid};
use super::truth::ZoneEvents;
use crate::rng::Rng;

/// What a term changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TermKind {
    /// Probability that a valid zone loses its return.
    Dropout,
    /// Metres added to the distance.
    Bias,
    /// Standard deviation (metres) of Gaussian noise added to the distance.
    Noise,
}

/// The covariate a term is a curve over.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TermCovariate {
    /// The zone's distance, metres.
    Range,
    /// Mean HSV value / 255 over the zone's window.
    Brightness,
    /// Distance from the grid centre (0 centre, 1 corner).
    Radius,
}

impl TermCovariate {
    /// The covariate's value for a return at `d` metres in a zone with covariates `c`.
    pub fn of(self, d: f32, c: &ZoneCovariates) -> f32 {
        match self {
            TermCovariate::Range => d,
            TermCovariate::Brightness => c.brightness,
            TermCovariate::Radius => c.radius,
        }
    }

    /// The gap tool's covariate of the same quantity.
    pub fn covariate(self) -> super::covariates::Covariate {
        use super::covariates::Covariate;
        match self {
            TermCovariate::Range => Covariate::Range,
            TermCovariate::Brightness => Covariate::Brightness,
            TermCovariate::Radius => Covariate::Radius,
        }
    }

    /// Name in reports (the gap tool's covariate names).
    pub fn name(self) -> &'static str {
        match self {
            TermCovariate::Range => "range_m",
            TermCovariate::Brightness => "brightness",
            TermCovariate::Radius => "grid_radius",
        }
    }
}

/// One curve: `values[i]` at `knots[i]` (increasing), linear between, constant beyond.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Term {
    /// The library family this curve is a flexible form of (the gap tool's name for it), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub family: Option<String>,
    /// What it changes.
    pub kind: TermKind,
    /// Over which covariate.
    pub on: TermCovariate,
    /// Covariate values, increasing.
    pub knots: Vec<f32>,
    /// Curve values at the knots (loss probabilities in [0, 1], metres otherwise).
    pub values: Vec<f32>,
}

impl Term {
    /// The curve at `x`.
    pub fn at(&self, x: f32) -> f32 {
        interpolate(&self.knots, &self.values, x)
    }

    /// `Err` naming the field when the knots are not increasing and finite, the lengths differ
    /// or are zero, or a value is out of its range.
    pub fn check(&self) -> Result<(), &'static str> {
        if self.knots.is_empty() || self.knots.len() != self.values.len() {
            return Err("learned.terms[].knots and values: same non-zero length");
        }
        if self.knots.iter().any(|k| !k.is_finite()) || self.knots.windows(2).any(|w| w[0] >= w[1])
        {
            return Err("learned.terms[].knots: finite and increasing");
        }
        let ok = |v: f32| match self.kind {
            TermKind::Dropout => (0.0..=1.0).contains(&v),
            TermKind::Bias => v.is_finite() && v.abs() <= 10.0,
            TermKind::Noise => v.is_finite() && (0.0..=10.0).contains(&v),
        };
        if self.values.iter().all(|&v| ok(v)) {
            Ok(())
        } else {
            Err("learned.terms[].values: loss in [0, 1], bias within ±10 m, noise in [0, 10] m")
        }
    }
}

/// Piecewise-linear interpolation of `(knots, values)` at `x`, constant beyond the ends (0 for
/// an empty curve).
pub fn interpolate(knots: &[f32], values: &[f32], x: f32) -> f32 {
    let n = knots.len().min(values.len());
    if n == 0 {
        return 0.0;
    }
    if x <= knots[0] {
        return values[0];
    }
    if x >= knots[n - 1] {
        return values[n - 1];
    }
    let i = knots[..n].partition_point(|&k| k <= x).clamp(1, n - 1);
    let (k0, k1) = (knots[i - 1], knots[i]);
    let t = (x - k0) / (k1 - k0);
    values[i - 1] + t * (values[i] - values[i - 1])
}

/// The learned terms (off by default).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Learned {
    /// Whether the terms apply.
    #[serde(default)]
    pub enabled: bool,
    /// The curves.
    #[serde(default)]
    pub terms: Vec<Term>,
}

impl Learned {
    /// Probability that a return at `d` in a zone with covariates `c` is lost:
    /// `1 − Π (1 − L_t)` over the dropout terms.
    pub fn loss_probability(&self, d: f32, c: &ZoneCovariates) -> f32 {
        let keep: f32 = self
            .terms
            .iter()
            .filter(|t| t.kind == TermKind::Dropout)
            .map(|t| 1.0 - t.at(t.on.of(d, c)).clamp(0.0, 1.0))
            .product();
        1.0 - keep
    }

    /// The distance with every bias term added (at least 1 mm).
    pub fn distance(&self, d: f32, c: &ZoneCovariates) -> f32 {
        let b: f32 = self
            .terms
            .iter()
            .filter(|t| t.kind == TermKind::Bias)
            .map(|t| t.at(t.on.of(d, c)))
            .sum();
        (d + b).max(1e-3)
    }

    /// Standard deviation of the added noise at `d`: the noise terms in quadrature.
    pub fn sigma(&self, d: f32, c: &ZoneCovariates) -> f32 {
        self.terms
            .iter()
            .filter(|t| t.kind == TermKind::Noise)
            .map(|t| t.at(t.on.of(d, c)).max(0.0).powi(2))
            .sum::<f32>()
            .sqrt()
    }

    /// `Err` naming the first bad field.
    pub fn check(&self) -> Result<(), &'static str> {
        self.terms.iter().try_for_each(Term::check)
    }
}

impl ZoneEffect for Learned {
    fn name(&self) -> &'static str {
        "learned"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        self.check().map_err(|what| {
            let (field, reason) = what.split_once(": ").unwrap_or(("learned", what));
            SimError::InvalidConfig {
                field: field.into(),
                reason: reason.into(),
            }
        })
    }
    fn apply(&self, scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        let cov = scene_covariates(scene, zones);
        for (zone, c) in zones.zones.iter_mut().zip(&cov) {
            let (n, u) = (rng.normal(), rng.f32());
            if !zone.has_target() {
                continue;
            }
            let d = self.distance(zone.distance_m, c);
            zone.distance_m = (d + self.sigma(d, c) * n).max(1e-3);
            if u < self.loss_probability(zone.distance_m, c) {
                zone.lose(ZoneEvents::LEARNED_LOSS);
            }
        }
    }
}

/// Weighted isotonic (non-decreasing) regression of `y` with weights `w` (pool adjacent
/// violators); zero-weight points take their neighbours' level.
pub fn isotonic(y: &[f64], w: &[f64]) -> Vec<f64> {
    // Blocks of (level, weight, count).
    let mut blocks: Vec<(f64, f64, usize)> = Vec::with_capacity(y.len());
    for (&yi, &wi) in y.iter().zip(w) {
        let wi = wi.max(0.0);
        blocks.push((yi, wi, 1));
        while blocks.len() > 1 {
            let n = blocks.len();
            let (b, a) = (blocks[n - 1], blocks[n - 2]);
            let violates = if a.1 > 0.0 && b.1 > 0.0 {
                a.0 > b.0
            } else {
                true // merge zero-weight points into their neighbour
            };
            if !violates {
                break;
            }
            let wt = a.1 + b.1;
            let level = if wt > 0.0 {
                (a.0 * a.1 + b.0 * b.1) / wt
            } else {
                a.0
            };
            blocks.truncate(n - 2);
            blocks.push((level, wt, a.2 + b.2));
        }
    }
    blocks
        .into_iter()
        .flat_map(|(l, _, c)| std::iter::repeat_n(l, c))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_is_linear_between_knots_and_flat_beyond() {
        let (k, v) = ([1.0, 2.0, 4.0], [0.0, 0.2, 0.6]);
        assert_eq!(interpolate(&k, &v, 0.5), 0.0);
        assert!((interpolate(&k, &v, 1.5) - 0.1).abs() < 1e-6);
        assert!((interpolate(&k, &v, 3.0) - 0.4).abs() < 1e-6);
        assert_eq!(interpolate(&k, &v, 9.0), 0.6);
        assert_eq!(interpolate(&[], &[], 1.0), 0.0);
    }

    #[test]
    fn isotonic_pools_violators_by_weight() {
        assert_eq!(
            isotonic(&[1.0, 3.0, 2.0, 4.0], &[1.0; 4]),
            vec![1.0, 2.5, 2.5, 4.0]
        );
        let r = isotonic(&[5.0, 1.0], &[1.0, 3.0]);
        assert!((r[0] - 2.0).abs() < 1e-12 && (r[1] - 2.0).abs() < 1e-12);
        assert_eq!(isotonic(&[0.0, 9.0, 1.0], &[1.0, 0.0, 1.0]).len(), 3);
    }

    #[test]
    fn terms_combine_and_check() {
        let c = ZoneCovariates::default();
        let l = Learned {
            enabled: true,
            terms: vec![
                Term {
                    family: None,
                    kind: TermKind::Dropout,
                    on: TermCovariate::Range,
                    knots: vec![1.0, 3.0],
                    values: vec![0.0, 0.5],
                },
                Term {
                    family: None,
                    kind: TermKind::Dropout,
                    on: TermCovariate::Range,
                    knots: vec![1.0],
                    values: vec![0.5],
                },
                Term {
                    family: None,
                    kind: TermKind::Bias,
                    on: TermCovariate::Range,
                    knots: vec![0.0, 2.0],
                    values: vec![0.0, 0.1],
                },
                Term {
                    family: None,
                    kind: TermKind::Noise,
                    on: TermCovariate::Range,
                    knots: vec![0.0],
                    values: vec![0.03],
                },
                Term {
                    family: None,
                    kind: TermKind::Noise,
                    on: TermCovariate::Range,
                    knots: vec![0.0],
                    values: vec![0.04],
                },
            ],
        };
        assert!((l.loss_probability(3.0, &c) - 0.75).abs() < 1e-6);
        assert!((l.distance(1.0, &c) - 1.05).abs() < 1e-6);
        assert!((l.sigma(1.0, &c) - 0.05).abs() < 1e-6);
        assert!(l.check().is_ok());
        let mut bad = l.clone();
        bad.terms[0].knots = vec![3.0, 1.0];
        assert!(bad.check().unwrap_err().contains("increasing"));
        bad.terms[0].knots = vec![1.0, 3.0];
        bad.terms[0].values = vec![0.0, 1.5];
        assert!(bad.check().unwrap_err().contains("values"));
    }
}
