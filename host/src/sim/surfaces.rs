//! Non-Lambertian surfaces (paper §3.1 "Specific Abnormal Regions", item 1): photons pass through
//! transparent objects (label 1) or are mirrored by specular ones (label 2), so the zone either
//! loses its signal or returns a farther surface. Zones are classified with the material labels;
//! without labels no zone is non-Lambertian.

use serde::{Deserialize, Serialize};

use super::error::{check_ordered, check_prob, SimError};
use super::frame::{Scene, ZoneEffect, ZoneGrid};
use super::grid::{histogram_peak, PeakScratch};
use super::truth::ZoneEvents;
use crate::rng::Rng;

/// Label of transparent pixels (docs/recording.md, `labels.png`).
pub const LABEL_TRANSPARENT: u8 = 1;
/// Label of specular / mirror pixels (docs/recording.md, `labels.png`).
pub const LABEL_SPECULAR: u8 = 2;

/// Parameters of one non-Lambertian material (`transparent` or `specular` in [`super::SimConfig`]).
///
/// A zone whose window is at least `min_fraction` of the material loses its signal with
/// probability `p_loss`; otherwise it returns the surface behind: the histogram peak of
/// `second_depth_m` over the material's pixels, or — where the input has no second depth there —
/// its own distance times a factor drawn uniformly in `farther_factor`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceAspect {
    /// Switch.
    pub enabled: bool,
    /// Fraction of the zone's window that must carry the label.
    pub min_fraction: f32,
    /// Probability that such a zone loses its signal (else it returns the farther surface).
    pub p_loss: f32,
    /// `[lo, hi]` factor applied to the zone's distance when no second depth is known (≥ 1).
    pub farther_factor: [f32; 2],
}

impl Default for SurfaceAspect {
    /// Disabled; when enabled: majority of the window, loss or farther return with equal chance
    /// (paper: "randomly determine the type of anomaly", no figure), farther by 1.25–2× (ours: a
    /// mirror at distance d shows surfaces at least d beyond it only when they face it; 2× is the
    /// mirror facing a wall at its own distance).
    fn default() -> Self {
        SurfaceAspect {
            enabled: false,
            min_fraction: 0.5,
            p_loss: 0.5,
            farther_factor: [1.25, 2.0],
        }
    }
}

impl SurfaceAspect {
    /// Checks the parameters; errors name the field as `<aspect>.<field>`.
    pub(crate) fn check(&self, aspect: &str) -> Result<(), SimError> {
        check_prob(aspect, "min_fraction", self.min_fraction)?;
        check_prob(aspect, "p_loss", self.p_loss)?;
        check_ordered(
            aspect,
            "farther_factor",
            self.farther_factor,
            [1.0, 100.0],
            "",
        )?;
        Ok(())
    }
}

/// One material's effect: the parameters bound to its label, name and events.
pub(crate) struct Surface<'a> {
    /// Config field name (`transparent` or `specular`).
    pub name: &'static str,
    /// Material label.
    pub label: u8,
    /// Parameters.
    pub cfg: &'a SurfaceAspect,
    /// Classification flag, loss flag, farther-return flag.
    pub events: [ZoneEvents; 3],
}

impl<'a> Surface<'a> {
    /// The transparent-material effect.
    pub fn transparent(cfg: &'a SurfaceAspect) -> Self {
        Surface {
            name: "transparent",
            label: LABEL_TRANSPARENT,
            cfg,
            events: [
                ZoneEvents::TRANSPARENT,
                ZoneEvents::TRANSPARENT_LOSS,
                ZoneEvents::TRANSPARENT_BEHIND,
            ],
        }
    }

    /// The specular-material effect.
    pub fn specular(cfg: &'a SurfaceAspect) -> Self {
        Surface {
            name: "specular",
            label: LABEL_SPECULAR,
            cfg,
            events: [
                ZoneEvents::SPECULAR,
                ZoneEvents::SPECULAR_LOSS,
                ZoneEvents::SPECULAR_FARTHER,
            ],
        }
    }
}

impl ZoneEffect for Surface<'_> {
    fn name(&self) -> &'static str {
        self.name
    }

    fn enabled(&self) -> bool {
        self.cfg.enabled
    }

    fn validate(&self) -> Result<(), SimError> {
        self.cfg.check(self.name)
    }

    fn apply(&self, scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        let [is, lost, farther] = self.events;
        let mut scratch = PeakScratch::default();
        let mut behind = Vec::new();
        for (z, zone) in zones.zones.iter_mut().enumerate() {
            let (u_loss, u_factor) = (rng.f32(), rng.f32());
            let f = scene.label_fraction(z, self.label);
            if f == 0.0 || f < self.cfg.min_fraction {
                continue;
            }
            zone.truth.events.insert(is);
            if u_loss < self.cfg.p_loss {
                zone.lose(lost);
                continue;
            }
            behind.clear();
            behind.extend(
                scene
                    .window(z)
                    .iter()
                    .map(|&i| i as usize)
                    .filter(|&i| scene.label(i) == self.label)
                    .map(|i| scene.second_depth(i))
                    .filter(|&d| d > 0.0),
            );
            let d = histogram_peak(&behind, scene.bin_m, &mut scratch);
            let [lo, hi] = self.cfg.farther_factor;
            if d > 0.0 {
                zone.distance_m = d;
                zone.truth.events.insert(farther);
            } else if zone.has_target() {
                zone.distance_m *= lo + (hi - lo) * u_factor;
                zone.truth.events.insert(farther);
            }
        }
    }
}
