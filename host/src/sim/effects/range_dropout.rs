//! `range_dropout` (gap-tool library, docs/design.md): the returned signal falls as ρ/r², so the
//! probability that a zone detects nothing rises with range. Forward model: a zone with a return
//! at `d` metres is lost with probability `1 − exp(−k·d²)` (`k` = `loss_per_m2`): ≈ `k·d²` while
//! small, saturating at 1 far away.
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::error::check_in;
use crate::sim::error::SimError;
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};
use crate::sim::truth::ZoneEvents;

/// Parameters of the range-dependent dropout.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeDropout {
    /// Switch.
    pub enabled: bool,
    /// `k` in `p = 1 − exp(−k·d²)`, per square metre.
    pub loss_per_m2: f32,
}

impl RangeDropout {
    /// Probability that a return at `d` metres is lost.
    pub fn loss_probability(&self, d: f32) -> f32 {
        1.0 - (-self.loss_per_m2 * d * d).exp()
    }
}

impl ZoneEffect for RangeDropout {
    fn name(&self) -> &'static str {
        "range_dropout"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_in(
            self.name(),
            "loss_per_m2",
            self.loss_per_m2,
            [0.0, 100.0],
            " per m²",
        )
    }
    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        for zone in &mut zones.zones {
            let u = rng.f32();
            if zone.has_target() && u < self.loss_probability(zone.distance_m) {
                zone.lose(ZoneEvents::RANGE_LOSS);
            }
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "range_dropout",
    physics: "detection probability falls with range (signal ∝ ρ/r²): p_loss = 1 − exp(−k·d²)",
    params: &[param("loss_per_m2", 0.0, 0.5)],
    stratum: Covariate::Range,
    separating_data: "bright surfaces far away (range without darkness)",
    start_unit: &[0.01],
    config: |c| &c.range_dropout,
    config_mut: |c| &mut c.range_dropout,
};

f32_params!(RangeDropout: loss_per_m2);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loss_probability_hand_computed() {
        let r = RangeDropout {
            enabled: true,
            loss_per_m2: 0.1,
        };
        assert_eq!(r.loss_probability(0.0), 0.0);
        // 1 − e^(−0.1·4) = 1 − 0.670320 = 0.329680.
        assert!((r.loss_probability(2.0) - 0.329_68).abs() < 1e-5);
    }
}
