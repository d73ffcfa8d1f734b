//! Random anomalies (paper §3.1 "Random Anomalies": "approximately 5 % noise points and 5 % blank
//! points. The depth values of the noise points were randomly assigned within the theoretical
//! detection range"). Every zone whose point lies in the image, whatever its state, independently
//! becomes a noise zone with probability `noise_fraction` (distance uniform in `noise_range_m`) or
//! a blank zone with probability `blank_fraction`. Zones centred outside the image have no point
//! in the sparse map and stay without target.

use serde::{Deserialize, Serialize};

use super::error::{check_ordered, check_prob, invalid, SimError};
use super::frame::{Scene, ZoneEffect, ZoneGrid};
use super::truth::ZoneEvents;
use crate::rng::Rng;

/// Parameters of the random anomalies.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Anomalies {
    /// Switch.
    pub enabled: bool,
    /// Probability that a zone reports noise.
    pub noise_fraction: f32,
    /// Probability that a zone is blanked.
    pub blank_fraction: f32,
    /// `[lo, hi]` metres: the detection range noise distances are drawn from.
    pub noise_range_m: [f32; 2],
}

impl Default for Anomalies {
    /// Disabled; when enabled the paper's 5 % + 5 % with the phone's range: 2 cm (the VL53L5CX
    /// datasheet's minimum, assumed for both sensors) to the 8.1 m theoretical limit.
    fn default() -> Self {
        Anomalies {
            enabled: false,
            noise_fraction: 0.05,
            blank_fraction: 0.05,
            noise_range_m: [0.02, 8.1],
        }
    }
}

impl ZoneEffect for Anomalies {
    fn name(&self) -> &'static str {
        "anomalies"
    }

    fn enabled(&self) -> bool {
        self.enabled
    }

    fn validate(&self) -> Result<(), SimError> {
        check_prob(self.name(), "noise_fraction", self.noise_fraction)?;
        check_prob(self.name(), "blank_fraction", self.blank_fraction)?;
        if self.noise_fraction + self.blank_fraction > 1.0 {
            return Err(invalid(
                self.name(),
                "blank_fraction",
                format!(
                    "noise_fraction + blank_fraction = {} (allowed at most 1)",
                    self.noise_fraction + self.blank_fraction
                ),
            ));
        }
        check_ordered(
            self.name(),
            "noise_range_m",
            self.noise_range_m,
            [0.001, 1000.0],
            " m",
        )?;
        Ok(())
    }

    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        let [lo, hi] = self.noise_range_m;
        for zone in &mut zones.zones {
            let (u, v) = (rng.f32(), rng.f32());
            if zone.truth.events.contains(ZoneEvents::OUT_OF_IMAGE) {
                continue;
            }
            if u < self.noise_fraction {
                zone.distance_m = lo + (hi - lo) * v;
                zone.truth.events.insert(ZoneEvents::NOISE);
            } else if u < self.noise_fraction + self.blank_fraction {
                zone.distance_m = 0.0;
                zone.truth.events.insert(ZoneEvents::BLANK);
            }
        }
    }
}
