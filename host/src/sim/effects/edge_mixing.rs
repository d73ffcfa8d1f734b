//! `edge_mixing` (gap-tool library, docs/design.md): a zone straddling a depth edge sees two returns and
//! reports a mix instead of the dominant peak. Forward model: `d' = d + weight · (mean − d)`, with
//! `mean` the mean depth over the zone's window (no effect on zones of one surface).
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::covariates::{scene_covariates, ZoneCovariates};
use crate::sim::error::{check_prob, SimError};
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};

/// Parameters of the edge mixing.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EdgeMixing {
    /// Switch.
    pub enabled: bool,
    /// Weight of the window's mean depth in the reported distance, in [0, 1].
    pub weight: f32,
}

impl EdgeMixing {
    /// The reported distance of a return at `d` metres in a zone with covariates `c`.
    pub fn distance(&self, d: f32, c: &ZoneCovariates) -> f32 {
        if c.mean_m > 0.0 {
            d + self.weight * (c.mean_m - d)
        } else {
            d
        }
    }
}

impl ZoneEffect for EdgeMixing {
    fn name(&self) -> &'static str {
        "edge_mixing"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_prob(self.name(), "weight", self.weight)
    }
    fn apply(&self, scene: &Scene<'_>, zones: &mut ZoneGrid, _rng: &mut Rng) {
        let cov = scene_covariates(scene, zones);
        for (zone, c) in zones.zones.iter_mut().zip(&cov) {
            if zone.has_target() {
                zone.distance_m = self.distance(zone.distance_m, c);
            }
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "edge_mixing",
    physics: "zones straddling depth edges report a mix of the returns: d + w·(mean − d)",
    params: &[param("weight", 0.0, 1.0)],
    stratum: Covariate::Spread,
    separating_data: "depth edges with large and small depth steps at zone-centred positions",
    start_unit: &[0.05],
    config: |c| &c.edge_mixing,
    config_mut: |c| &mut c.edge_mixing,
};

f32_params!(EdgeMixing: weight);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_hand_computed() {
        let e = EdgeMixing {
            enabled: true,
            weight: 0.25,
        };
        let c = ZoneCovariates {
            mean_m: 3.0,
            ..ZoneCovariates::default()
        };
        assert!((e.distance(1.0, &c) - 1.5).abs() < 1e-6);
        assert_eq!(e.distance(1.0, &ZoneCovariates::default()), 1.0);
    }
}
