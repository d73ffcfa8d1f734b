//! `range_bias` (gap-tool library, docs/design.md): offset and scale error of the reported distance
//! (e.g. an uncalibrated cover-glass delay or clock error). Forward model:
//! `d' = offset_m + (1 + scale) · d`, kept above 1 mm.
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::error::{check_in, SimError};
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};

/// Parameters of the distance bias.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeBias {
    /// Switch.
    pub enabled: bool,
    /// Constant offset, metres.
    pub offset_m: f32,
    /// Relative scale error (0.02 = 2 % long).
    pub scale: f32,
}

impl RangeBias {
    /// The reported distance for a true return at `d` metres.
    pub fn distance(&self, d: f32) -> f32 {
        (self.offset_m + (1.0 + self.scale) * d).max(1e-3)
    }
}

impl ZoneEffect for RangeBias {
    fn name(&self) -> &'static str {
        "range_bias"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_in(self.name(), "offset_m", self.offset_m, [-5.0, 5.0], " m")?;
        check_in(self.name(), "scale", self.scale, [-0.5, 0.5], "")
    }
    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, _rng: &mut Rng) {
        for zone in &mut zones.zones {
            if zone.has_target() {
                zone.distance_m = self.distance(zone.distance_m);
            }
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "range_bias",
    physics: "offset and scale error of the reported distance: d' = offset + (1 + scale)·d",
    params: &[param("offset_m", -0.3, 0.3), param("scale", -0.2, 0.2)],
    stratum: Covariate::Range,
    separating_data: "a flat wall at several distances (offset vs scale) seen centred",
    start_unit: &[0.01, 0.0],
    config: |c| &c.range_bias,
    config_mut: |c| &mut c.range_bias,
};

f32_params!(RangeBias: offset_m, scale);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_hand_computed() {
        let b = RangeBias {
            enabled: true,
            offset_m: 0.05,
            scale: 0.02,
        };
        assert!((b.distance(2.0) - 2.09).abs() < 1e-6);
        let neg = RangeBias {
            offset_m: -1.0,
            ..b
        };
        assert_eq!(neg.distance(0.5), 1e-3);
    }
}
