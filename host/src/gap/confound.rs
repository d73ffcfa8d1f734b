//! Confounded covariates (docs/gap.md "Confounded covariates"): an effect that acts along one
//! covariate (a loss, bias or noise curve over range, brightness or grid radius) can show its
//! evidence along another that is confounded with it in the recording: near surfaces sit low in
//! the image, so a loss of close returns also looks like a loss at the grid's lower border. The
//! association need not be linear (the upper border is far, the lower one near: Pearson r between
//! range and grid radius is small over all zones), so the trigger is the evidence itself: when a
//! direction-free curve of the chosen effect's kind over another covariate also reaches a
//! significant held-out gain alone, selection tests each covariate conditional on the other
//! (each represented by a direction-free curve of the kind, one fitted on top of the other, both
//! ways, cross-fitted and scored on held-out frames) and names the one that survives; when neither survives alone
//! both are reported as inseparable, with their correlation over the zones and the evidence
//! ([`Separation`]).

use super::model::Prepared;
use crate::sim::learned::{TermCovariate, TermKind};

/// Family name of the probe curve ([`crate::sim::learned::Term::family`]) that stands for "an
/// effect of the same kind along the other covariate" while it is tested.
pub const PROBE: &str = "confound_probe";

/// Family name of the probe curve that stands for the chosen effect's own covariate (a
/// direction-free curve of its kind: the family's form may be constrained in direction).
pub const PROBE_OWN: &str = "confound_probe_own";

/// The covariates a single-covariate effect can act along.
pub const COVARIATES: [TermCovariate; 3] = [
    TermCovariate::Range,
    TermCovariate::Brightness,
    TermCovariate::Radius,
];

/// A zone's value of `on` (range: the window's mean reference depth), `None` for a zone without
/// reference depth.
fn value(prep: &Prepared, z: usize, on: TermCovariate) -> Option<f64> {
    let c = &prep.cov[z];
    (c.mean_m > 0.0).then(|| f64::from(on.of(c.mean_m, c)))
}

/// Pearson correlation of covariates `a` and `b` over the zones of `frames` that have reference
/// depth (0 when either is constant or no zone has depth).
pub fn correlation(frames: &[Prepared], a: TermCovariate, b: TermCovariate) -> f64 {
    let (mut n, mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
    for p in frames {
        for z in 0..p.zones() {
            let (Some(x), Some(y)) = (value(p, z, a), value(p, z, b)) else {
                continue;
            };
            n += 1.0;
            sa += x;
            sb += y;
            saa += x * x;
            sbb += y * y;
            sab += x * y;
        }
    }
    if n < 2.0 {
        return 0.0;
    }
    let (va, vb) = (saa - sa * sa / n, sbb - sb * sb / n);
    if va <= 1e-12 || vb <= 1e-12 {
        return 0.0;
    }
    (sab - sa * sb / n) / (va * vb).sqrt()
}

/// The outcome of testing an effect's covariate against a correlated one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// The effect's own covariate survives given the other; the other adds nothing.
    Own,
    /// The other covariate survives given the effect's own; the effect is renamed after it.
    Other,
    /// Each adds significantly given the other: both carry evidence of their own.
    Both,
    /// Neither survives alone given the other: the data cannot tell them apart.
    Inseparable,
}

impl Verdict {
    /// From the conditional tests: `own` = (held-out gain, p) of the effect added on top of a
    /// curve over the other covariate, `other` = the curve added on top of the effect; a side
    /// survives when its p ≤ `alpha` and its gain ≥ `min_gain` (nats per zone).
    pub fn of(own: (f64, f64), other: (f64, f64), alpha: f64, min_gain: f64) -> Verdict {
        let survives = |(g, p): (f64, f64)| p <= alpha && g >= min_gain;
        match (survives(own), survives(other)) {
            (true, false) => Verdict::Own,
            (false, true) => Verdict::Other,
            (true, true) => Verdict::Both,
            (false, false) => Verdict::Inseparable,
        }
    }

    /// The verdict in `report.json` (`own`, `other`, `both`, `inseparable`).
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Own => "own",
            Verdict::Other => "other",
            Verdict::Both => "both",
            Verdict::Inseparable => "inseparable",
        }
    }
}

/// One conditional test of an accepted effect's covariate against a correlated covariate.
#[derive(Clone, Debug, PartialEq)]
pub struct Separation {
    /// The effect first chosen (before the test).
    pub effect: String,
    /// The effect named after the test (differs from `effect` when the other covariate won).
    pub named: String,
    /// What it changes.
    pub kind: TermKind,
    /// The first effect's covariate.
    pub covariate: TermCovariate,
    /// The correlated covariate.
    pub other: TermCovariate,
    /// Pearson r between them over the zones.
    pub correlation: f64,
    /// Cross-fitted held-out gain (nats per zone) and p of a curve over `covariate` added on
    /// top of a curve over `other` (both direction-free, of the effect's kind).
    pub own_given_other: (f64, f64),
    /// The same for a curve over `other` added on top of a curve over `covariate`.
    pub other_given_own: (f64, f64),
    /// The outcome.
    pub verdict: Verdict,
}

impl Separation {
    /// The covariates the named effect is attributed to: its own, or both when inseparable.
    pub fn covariates(&self) -> Vec<&'static str> {
        match self.verdict {
            Verdict::Own => vec![self.covariate.name()],
            Verdict::Other => vec![self.other.name()],
            Verdict::Both | Verdict::Inseparable => {
                vec![self.covariate.name(), self.other.name()]
            }
        }
    }

    /// The evidence in words.
    pub fn evidence(&self) -> String {
        let (go, po) = self.own_given_other;
        let (gt, pt) = self.other_given_own;
        let tests = format!(
            "{} and {} both carry the evidence (Pearson r over the zones {:+.2}); {} given {}: {go:+.4} nats/zone held out (p = {po:.4}); {} given {}: {gt:+.4} (p = {pt:.4})",
            self.covariate.name(),
            self.other.name(),
            self.correlation,
            self.covariate.name(),
            self.other.name(),
            self.other.name(),
            self.covariate.name(),
        );
        let what = match self.verdict {
            Verdict::Own => format!("{} survives, {} does not", self.covariate.name(), self.other.name()),
            Verdict::Other => format!(
                "{} survives, {} does not: named {} (along {})",
                self.other.name(),
                self.covariate.name(),
                self.named,
                self.other.name()
            ),
            Verdict::Both => "each adds evidence given the other".to_string(),
            Verdict::Inseparable => format!(
                "neither survives alone: {:?} along {} and along {} are inseparable in these frames",
                self.kind,
                self.covariate.name(),
                self.other.name()
            ),
        };
        format!("{tests}: {what}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::covariates::ZoneCovariates;

    fn frame(zones: &[(f32, f32)]) -> Prepared {
        Prepared {
            rows: 1,
            cols: zones.len(),
            draws: Vec::new(),
            k: 0,
            cov: zones
                .iter()
                .map(|&(d, r)| ZoneCovariates {
                    mean_m: d,
                    radius: r,
                    ..ZoneCovariates::default()
                })
                .collect(),
            draw_cov: Vec::new(),
            real: vec![None; zones.len()],
            t_s: 0.0,
        }
    }

    #[test]
    fn correlation_over_zones_with_depth() {
        // Radius falls with range (near surfaces low in the image); the zone without depth is
        // left out.
        let f = frame(&[(0.5, 1.0), (1.0, 0.8), (2.0, 0.4), (3.0, 0.1), (0.0, 0.0)]);
        let r = correlation(
            std::slice::from_ref(&f),
            TermCovariate::Range,
            TermCovariate::Radius,
        );
        assert!(r < -0.95, "{r}");
        assert_eq!(
            correlation(&[f], TermCovariate::Range, TermCovariate::Brightness),
            0.0
        );
    }

    #[test]
    fn verdicts_follow_the_conditional_tests() {
        let (sig, weak) = ((0.01, 0.001), (0.0005, 0.3));
        assert_eq!(Verdict::of(sig, weak, 0.01, 0.002), Verdict::Own);
        assert_eq!(Verdict::of(weak, sig, 0.01, 0.002), Verdict::Other);
        assert_eq!(Verdict::of(sig, sig, 0.01, 0.002), Verdict::Both);
        assert_eq!(Verdict::of(weak, weak, 0.01, 0.002), Verdict::Inseparable);
        // Significant but below the smallest gain worth a finding.
        assert_eq!(
            Verdict::of((0.001, 0.0001), weak, 0.01, 0.002),
            Verdict::Inseparable
        );
    }
}
