//! `range_noise` (gap-tool library, docs/design.md): timing jitter whose effect grows as the signal
//! falls with range. Forward model: the reported distance gets zero-mean Gaussian noise of standard
//! deviation `sigma_per_m · d` (kept above 1 mm).
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::error::check_in;
use crate::sim::error::SimError;
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};

/// Parameters of the range noise.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeNoise {
    /// Switch.
    pub enabled: bool,
    /// Standard deviation per metre of range (0.01 = 1 cm at 1 m, 3 cm at 3 m).
    pub sigma_per_m: f32,
}

impl RangeNoise {
    /// Standard deviation (metres) of the noise on a return at `d` metres.
    pub fn sigma(&self, d: f32) -> f32 {
        self.sigma_per_m * d
    }
}

impl ZoneEffect for RangeNoise {
    fn name(&self) -> &'static str {
        "range_noise"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_in(
            self.name(),
            "sigma_per_m",
            self.sigma_per_m,
            [0.0, 10.0],
            "",
        )
    }
    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        for zone in &mut zones.zones {
            let n = rng.normal();
            if zone.has_target() {
                zone.distance_m = (zone.distance_m + self.sigma(zone.distance_m) * n).max(1e-3);
            }
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "range_noise",
    physics: "noise growing with range: Gaussian with σ = sigma_per_m·d",
    params: &[param("sigma_per_m", 0.0, 0.2)],
    stratum: Covariate::Range,
    separating_data: "repeated frames of a static scene at several ranges",
    start_unit: &[0.005],
    config: |c| &c.range_noise,
    config_mut: |c| &mut c.range_noise,
};

f32_params!(RangeNoise: sigma_per_m);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigma_hand_computed() {
        let n = RangeNoise {
            enabled: true,
            sigma_per_m: 0.01,
        };
        assert!((n.sigma(3.0) - 0.03).abs() < 1e-7);
    }
}
