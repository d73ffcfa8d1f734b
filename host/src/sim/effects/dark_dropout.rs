//! `dark_dropout` (gap-tool library, docs/design.md): low-reflectance surfaces return too few photons.
//! Forward model: a zone whose window has mean brightness `b` (HSV V / 255, the reflectance proxy
//! available in every recording) is lost with probability `p_black · max(0, 1 − b / knee)`: the
//! darker the zone, the likelier the loss, nothing above `knee`.
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::covariates::{scene_covariates, ZoneCovariates};
use crate::sim::error::{check_above, check_prob, SimError};
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};
use crate::sim::truth::ZoneEvents;

/// Parameters of the brightness-dependent dropout.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DarkDropout {
    /// Switch.
    pub enabled: bool,
    /// Loss probability of a black zone (b = 0).
    pub p_black: f32,
    /// Brightness at and above which nothing is lost.
    pub knee: f32,
}

impl Default for DarkDropout {
    /// Disabled; knee at full brightness (loss ∝ darkness).
    fn default() -> Self {
        DarkDropout {
            enabled: false,
            p_black: 0.0,
            knee: 1.0,
        }
    }
}

impl DarkDropout {
    /// Probability that a zone with covariates `c` is lost.
    pub fn loss_probability(&self, c: &ZoneCovariates) -> f32 {
        self.p_black * (1.0 - c.brightness / self.knee).max(0.0)
    }
}

impl ZoneEffect for DarkDropout {
    fn name(&self) -> &'static str {
        "dark_dropout"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_prob(self.name(), "p_black", self.p_black)?;
        check_above(self.name(), "knee", self.knee, [0.0, 1.0], " (brightness)")
    }
    fn apply(&self, scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        let cov = scene_covariates(scene, zones);
        for (zone, c) in zones.zones.iter_mut().zip(&cov) {
            let u = rng.f32();
            if zone.has_target() && u < self.loss_probability(c) {
                zone.lose(ZoneEvents::DARK_LOSS);
            }
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "dark_dropout",
    physics: "low-reflectance surfaces return too few photons: p_loss = p_black·(1 − b/knee)₊",
    params: &[param("p_black", 0.0, 1.0)],
    stratum: Covariate::Brightness,
    separating_data: "dark surfaces close by (darkness without range)",
    start_unit: &[0.15],
    config: |c| &c.dark_dropout,
    config_mut: |c| &mut c.dark_dropout,
};

f32_params!(DarkDropout: p_black);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loss_probability_hand_computed() {
        let d = DarkDropout {
            enabled: true,
            p_black: 0.6,
            knee: 0.5,
        };
        let c = |b| ZoneCovariates {
            brightness: b,
            ..ZoneCovariates::default()
        };
        assert!((d.loss_probability(&c(0.0)) - 0.6).abs() < 1e-6);
        assert!((d.loss_probability(&c(0.25)) - 0.3).abs() < 1e-6);
        assert_eq!(d.loss_probability(&c(0.8)), 0.0);
    }
}
