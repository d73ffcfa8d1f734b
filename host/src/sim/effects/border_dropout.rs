//! `border_dropout` (gap-tool library, docs/design.md): vignetting and illumination roll-off toward the
//! zone grid's corners. Forward model: a zone at normalised radius `r` (0 at the grid centre, 1 at
//! a corner) is lost with probability `p_corner · r^exponent`.
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::covariates::grid_position;
use crate::sim::error::{check_above, check_prob, SimError};
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};
use crate::sim::truth::ZoneEvents;

/// Parameters of the radial dropout.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BorderDropout {
    /// Switch.
    pub enabled: bool,
    /// Loss probability at the grid's corners.
    pub p_corner: f32,
    /// Steepness of the roll-off (4: cos⁴-like vignetting).
    pub exponent: f32,
}

impl Default for BorderDropout {
    /// Disabled; quartic roll-off.
    fn default() -> Self {
        BorderDropout {
            enabled: false,
            p_corner: 0.0,
            exponent: 4.0,
        }
    }
}

impl BorderDropout {
    /// Probability that a zone at normalised radius `radius` is lost.
    pub fn loss_probability(&self, radius: f32) -> f32 {
        (self.p_corner * radius.max(0.0).powf(self.exponent)).min(1.0)
    }
}

impl ZoneEffect for BorderDropout {
    fn name(&self) -> &'static str {
        "border_dropout"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_prob(self.name(), "p_corner", self.p_corner)?;
        check_above(self.name(), "exponent", self.exponent, [0.0, 64.0], "")
    }
    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        let (rows, cols) = (zones.rows, zones.cols);
        for (z, zone) in zones.zones.iter_mut().enumerate() {
            let u = rng.f32();
            let (_, r) = grid_position(z / cols, z % cols, rows, cols);
            if zone.has_target() && u < self.loss_probability(r) {
                zone.lose(ZoneEvents::SIGNAL_LOSS);
            }
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "border_dropout",
    physics: "vignetting / illumination roll-off toward the grid's corners: p_loss = p_corner·r⁴",
    params: &[param("p_corner", 0.0, 1.0)],
    stratum: Covariate::Radius,
    separating_data: "near, bright targets filling the corner zones",
    start_unit: &[0.2],
    config: |c| &c.border_dropout,
    config_mut: |c| &mut c.border_dropout,
};

f32_params!(BorderDropout: p_corner);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loss_probability_hand_computed() {
        let b = BorderDropout {
            enabled: true,
            p_corner: 0.8,
            exponent: 4.0,
        };
        assert_eq!(b.loss_probability(0.0), 0.0);
        assert!((b.loss_probability(0.5) - 0.05).abs() < 1e-6);
        assert!((b.loss_probability(1.0) - 0.8).abs() < 1e-6);
    }
}
