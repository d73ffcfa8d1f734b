//! `multipath` (gap-tool library, docs/design.md): transparent and specular surfaces add a longer light
//! path to the zone's histogram, pulling the reported distance farther. Forward model: a zone whose
//! window is a fraction `f` transparent/specular (labels 1, 2) reports `d · (1 + extra · min(1, 4f))`:
//! the farther return grows with the material's share and saturates once a quarter of the iFoV
//! sees it (its photons then dominate the histogram peak's neighbourhood).
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::covariates::{scene_covariates, ZoneCovariates};
use crate::sim::error::check_in;
use crate::sim::error::SimError;
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};

/// Parameters of the multipath lengthening.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Multipath {
    /// Switch.
    pub enabled: bool,
    /// Relative lengthening of a fully transparent/specular zone.
    pub extra: f32,
}

impl Multipath {
    /// The reported distance of a return at `d` metres in a zone with covariates `c`.
    pub fn distance(&self, d: f32, c: &ZoneCovariates) -> f32 {
        d * (1.0 + self.extra * (4.0 * c.nonlambertian_fraction).min(1.0))
    }
}

impl ZoneEffect for Multipath {
    fn name(&self) -> &'static str {
        "multipath"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_in(self.name(), "extra", self.extra, [0.0, 10.0], "")
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
    name: "multipath",
    physics:
        "transparent/specular surfaces return farther depth: d·(1 + extra·min(1, 4·f_material))",
    params: &[param("extra", 0.0, 1.0)],
    stratum: Covariate::Material,
    separating_data: "glass/mirrors in front of known-depth backgrounds",
    start_unit: &[0.1],
    config: |c| &c.multipath,
    config_mut: |c| &mut c.multipath,
};

f32_params!(Multipath: extra);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_hand_computed() {
        let m = Multipath {
            enabled: true,
            extra: 0.4,
        };
        let c = ZoneCovariates {
            nonlambertian_fraction: 0.1,
            ..ZoneCovariates::default()
        };
        // 4 · 0.1 = 0.4 → 2 · (1 + 0.4 · 0.4) = 2.32.
        assert!((m.distance(2.0, &c) - 2.32).abs() < 1e-6);
        let c = ZoneCovariates {
            nonlambertian_fraction: 0.5,
            ..c
        };
        assert!((m.distance(2.0, &c) - 2.8).abs() < 1e-6);
    }
}
