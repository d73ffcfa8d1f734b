//! Long-distance regions (paper §3.1 "Specific Abnormal Regions", item 3): the return weakens with
//! range, so the loss probability rises from 0 at the practical range to 1 at the theoretical
//! limit, and everything beyond the limit is lost (phone: 6 m practical, 8.1 m theoretical; l5:
//! nothing beyond its 4.1 m maximum recorded depth, so practical = limit = 4.1 m).

use serde::{Deserialize, Serialize};

use super::error::{check_above, invalid, SimError};
use super::frame::{Scene, ZoneEffect, ZoneGrid};
use super::truth::ZoneEvents;
use crate::rng::Rng;

/// Shape of the loss probability between the practical range and the limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Ramp {
    /// `p = t`, `t = (d − practical) / (limit − practical)`.
    Linear,
    /// `p = 3t² − 2t³`: gentle near both ends.
    Smoothstep,
}

/// Parameters of the range loss.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeAspect {
    /// Switch.
    pub enabled: bool,
    /// Below this distance (m) nothing is lost to range.
    pub practical_m: f32,
    /// Beyond this distance (m) everything is lost.
    pub limit_m: f32,
    /// Shape of the rise in between.
    pub ramp: Ramp,
}

impl Default for RangeAspect {
    /// Disabled; when enabled the paper's phone figures (§3.1: 8.1 m theoretical, "beyond 6 meters
    /// frequently lost"), linear rise.
    fn default() -> Self {
        RangeAspect {
            enabled: false,
            practical_m: 6.0,
            limit_m: 8.1,
            ramp: Ramp::Linear,
        }
    }
}

impl RangeAspect {
    /// Probability that a return at `d` metres is lost.
    pub fn loss_probability(&self, d: f32) -> f32 {
        if d <= self.practical_m {
            0.0
        } else if d >= self.limit_m {
            1.0
        } else {
            let t = (d - self.practical_m) / (self.limit_m - self.practical_m);
            match self.ramp {
                Ramp::Linear => t,
                Ramp::Smoothstep => t * t * (3.0 - 2.0 * t),
            }
        }
    }
}

impl ZoneEffect for RangeAspect {
    fn name(&self) -> &'static str {
        "range"
    }

    fn enabled(&self) -> bool {
        self.enabled
    }

    fn validate(&self) -> Result<(), SimError> {
        check_above(
            self.name(),
            "practical_m",
            self.practical_m,
            [0.0, 1000.0],
            " m",
        )?;
        check_above(self.name(), "limit_m", self.limit_m, [0.0, 1000.0], " m")?;
        if self.limit_m < self.practical_m {
            return Err(invalid(
                self.name(),
                "limit_m",
                format!(
                    "{} is below practical_m {} (allowed practical_m to 1000 m)",
                    self.limit_m, self.practical_m
                ),
            ));
        }
        Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loss_probability_hand_computed() {
        let mut r = RangeAspect {
            enabled: true,
            practical_m: 6.0,
            limit_m: 8.0,
            ramp: Ramp::Linear,
        };
        assert_eq!(r.loss_probability(5.9), 0.0);
        assert_eq!(r.loss_probability(7.0), 0.5);
        assert_eq!(r.loss_probability(7.5), 0.75);
        assert_eq!(r.loss_probability(8.0), 1.0);
        assert_eq!(r.loss_probability(9.0), 1.0);
        r.ramp = Ramp::Smoothstep;
        assert_eq!(r.loss_probability(7.0), 0.5);
        assert!((r.loss_probability(6.5) - 0.15625).abs() < 1e-6);
        // practical = limit: a hard cut (l5).
        r.practical_m = 4.1;
        r.limit_m = 4.1;
        assert_eq!(r.loss_probability(4.1), 0.0);
        assert_eq!(r.loss_probability(4.1001), 1.0);
    }
}
