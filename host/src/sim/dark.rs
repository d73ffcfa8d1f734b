//! Low-reflectivity areas (paper §3.1 "Specific Abnormal Regions", item 2; supplement: "depth loss
//! 80 % for pixels with a V-channel value below 40 in the HSV color space"): dark surfaces absorb
//! the laser, so their zones lose the signal with some probability.
//!
//! A pixel is dark when its HSV V = max(R, G, B) is below `v_threshold`, or (with `use_label`) its
//! label is 3 (dark/absorbing). A zone is dark when at least `min_fraction` of its window is dark:
//! with the default 0.5 this is "the median V of the zone is below the threshold", robust to a few
//! bright or dark pixels, unlike the mean.

use serde::{Deserialize, Serialize};

use super::error::{check_in, check_prob, SimError};
use super::frame::{Scene, ZoneEffect, ZoneGrid};
use super::truth::ZoneEvents;
use crate::rng::Rng;

/// Label of dark/absorbing pixels (docs/recording.md, `labels.png`).
pub const LABEL_DARK: u8 = 3;

/// Parameters of the low-reflectivity loss.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DarkAspect {
    /// Switch.
    pub enabled: bool,
    /// A pixel with HSV V (0–255) below this is dark.
    pub v_threshold: f32,
    /// Also treat label 3 (dark/absorbing) pixels as dark.
    pub use_label: bool,
    /// Fraction of the window that must be dark for the zone to be dark.
    pub min_fraction: f32,
    /// Probability that a dark zone loses its signal.
    pub p_loss: f32,
}

impl Default for DarkAspect {
    /// Disabled; when enabled the paper's phone figures: V < 40 loses with p = 0.8 (supplement).
    fn default() -> Self {
        DarkAspect {
            enabled: false,
            v_threshold: 40.0,
            use_label: true,
            min_fraction: 0.5,
            p_loss: 0.8,
        }
    }
}

impl ZoneEffect for DarkAspect {
    fn name(&self) -> &'static str {
        "dark"
    }

    fn enabled(&self) -> bool {
        self.enabled
    }

    fn validate(&self) -> Result<(), SimError> {
        check_in(
            self.name(),
            "v_threshold",
            self.v_threshold,
            [0.0, 256.0],
            " (HSV V)",
        )?;
        check_prob(self.name(), "min_fraction", self.min_fraction)?;
        check_prob(self.name(), "p_loss", self.p_loss)
    }

    fn apply(&self, scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        for (z, zone) in zones.zones.iter_mut().enumerate() {
            let u = rng.f32();
            let w = scene.window(z);
            if w.is_empty() {
                continue;
            }
            let dark = w
                .iter()
                .filter(|&&i| {
                    let i = i as usize;
                    f32::from(scene.value_v(i)) < self.v_threshold
                        || (self.use_label && scene.label(i) == LABEL_DARK)
                })
                .count();
            let f = dark as f32 / w.len() as f32;
            if dark == 0 || f < self.min_fraction {
                continue;
            }
            zone.truth.events.insert(ZoneEvents::DARK);
            if u < self.p_loss {
                zone.lose(ZoneEvents::DARK_LOSS);
            }
        }
    }
}
