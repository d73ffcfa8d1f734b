//! `radial_distance` (gap-tool library, docs/design.md): the sensor reports range along the zone's ray
//! where the simulator assumes planar z. Forward model: a zone at normalised grid position
//! `(r, c)` on a tangent grid spanning `fov_deg` looks along `(tan(h/2)·c, tan(v/2)·r, 1)`, so its
//! radial range is `k = sqrt(1 + tx² + ty²)` times z; the reported distance is
//! `d · (1 + fraction · (k − 1))` (`fraction` 1: fully radial; negative: z reported where radial
//! was assumed).
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::covariates::grid_position;
use crate::sim::error::{check_above, check_in, SimError};
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};

/// Parameters of the radial/z mismatch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadialDistance {
    /// Switch.
    pub enabled: bool,
    /// 1 = the sensor reports radial range; 0 = planar z (no effect).
    pub fraction: f32,
    /// Full field of view `[horizontal, vertical]` of the zone grid, degrees (VL53L5CX: 45°).
    pub fov_deg: [f32; 2],
}

impl Default for RadialDistance {
    /// Disabled; the VL53L5CX's 45° × 45°.
    fn default() -> Self {
        RadialDistance {
            enabled: false,
            fraction: 0.0,
            fov_deg: [45.0, 45.0],
        }
    }
}

impl RadialDistance {
    /// Factor applied to the distance of a zone at normalised grid position `[row, col]`.
    pub fn factor(&self, grid_pos: [f32; 2]) -> f32 {
        let tx = (self.fov_deg[0].to_radians() / 2.0).tan() * grid_pos[1];
        let ty = (self.fov_deg[1].to_radians() / 2.0).tan() * grid_pos[0];
        1.0 + self.fraction * ((1.0 + tx * tx + ty * ty).sqrt() - 1.0)
    }
}

impl ZoneEffect for RadialDistance {
    fn name(&self) -> &'static str {
        "radial_distance"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_in(self.name(), "fraction", self.fraction, [-1.0, 2.0], "")?;
        for (i, &f) in self.fov_deg.iter().enumerate() {
            check_above(self.name(), &format!("fov_deg[{i}]"), f, [0.0, 170.0], "°")?;
        }
        Ok(())
    }
    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, _rng: &mut Rng) {
        let (rows, cols) = (zones.rows, zones.cols);
        for (z, zone) in zones.zones.iter_mut().enumerate() {
            let (pos, _) = grid_position(z / cols, z % cols, rows, cols);
            if zone.has_target() {
                zone.distance_m *= self.factor(pos);
            }
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "radial_distance",
    physics: "the sensor reports range along the ray where the simulator assumes z: d·(1 + f·(√(1+tx²+ty²) − 1))",
    params: &[param("fraction", -1.0, 2.0)],
    stratum: Covariate::Radius,
    separating_data: "a flat wall facing the sensor at several distances (radial error ∝ d, grows toward corners)",
    start_unit: &[0.25],
    config: |c| &c.radial_distance,
    config_mut: |c| &mut c.radial_distance,
};

f32_params!(RadialDistance: fraction);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factor_hand_computed() {
        let r = RadialDistance {
            enabled: true,
            fraction: 1.0,
            fov_deg: [90.0, 90.0],
        };
        assert!((r.factor([0.0, 0.0]) - 1.0).abs() < 1e-6);
        // tan 45° = 1: a corner ray (1, 1, 1) is √3 long.
        assert!((r.factor([1.0, 1.0]) - 3f32.sqrt()).abs() < 1e-5);
        let half = RadialDistance { fraction: 0.5, ..r };
        assert!((half.factor([0.0, 1.0]) - (1.0 + 0.5 * (2f32.sqrt() - 1.0))).abs() < 1e-5);
    }
}
