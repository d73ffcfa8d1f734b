//! Rigid misregistration of the whole zone grid: the sensor measures the scene a fixed distance
//! away from where its zones are projected into the camera image (an extrinsic calibration error
//! that moves every zone alike, unlike `calibration_shift`, which moves only the background by
//! whole zones). The grid's sampling windows move by `shift_zones` zone cells (a cell is the FoV
//! bounds divided by the zone rows/columns) in the direction `direction_deg` (0° = +x, to the
//! right; 90° = +y, down), or in a direction drawn uniformly per frame when it is `null`; the
//! points stay at their nominal place in the image. Part of the evaluation grid's conditions
//! (0 to 1 zone, docs/eval.md).

use serde::{Deserialize, Serialize};

use super::error::{check_in, SimError};
use crate::rng::Rng;

/// Parameters of the rigid misregistration.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Misregistration {
    /// Switch.
    pub enabled: bool,
    /// Length of the shift, in zone cells.
    pub shift_zones: f32,
    /// Direction of the shift, degrees (0 = right, 90 = down); `null` = uniform per frame.
    #[serde(default)]
    pub direction_deg: Option<f32>,
}

/// Name of the aspect (its config field and random stream).
pub(crate) const NAME: &str = "misregistration";

impl Misregistration {
    /// Checks the parameters; errors name the field as `misregistration.<field>`.
    pub fn validate(&self) -> Result<(), SimError> {
        check_in(NAME, "shift_zones", self.shift_zones, [0.0, 8.0], " zones")?;
        if let Some(a) = self.direction_deg {
            check_in(NAME, "direction_deg", a, [-360.0, 360.0], "°")?;
        }
        Ok(())
    }

    /// The frame's shift `[dy, dx]` in pixels for zone cells of `cell_px` (`[height, width]`);
    /// draws one number whether on or not.
    pub(crate) fn offset_px(&self, cell_px: [f32; 2], rng: &mut Rng) -> [f32; 2] {
        let drawn = rng.range(0.0, 360.0);
        if !self.enabled {
            return [0.0, 0.0];
        }
        let (sin, cos) = self.direction_deg.unwrap_or(drawn).to_radians().sin_cos();
        [
            self.shift_zones * cell_px[0] * sin,
            self.shift_zones * cell_px[1] * cos,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_is_in_zone_cells_along_the_direction() {
        let m = Misregistration {
            enabled: true,
            shift_zones: 0.5,
            direction_deg: Some(90.0),
        };
        let [dy, dx] = m.offset_px([20.0, 10.0], &mut Rng::new(1));
        assert!((dy - 10.0).abs() < 1e-4 && dx.abs() < 1e-4, "{dy} {dx}");
        let random = Misregistration {
            direction_deg: None,
            ..m.clone()
        };
        let [dy, dx] = random.offset_px([20.0, 20.0], &mut Rng::new(1));
        assert!(((dy * dy + dx * dx).sqrt() - 10.0).abs() < 1e-3);
        let off = Misregistration::default();
        assert_eq!(off.offset_px([20.0, 10.0], &mut Rng::new(1)), [0.0, 0.0]);
        let bad = Misregistration {
            shift_zones: -1.0,
            ..m
        };
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.starts_with("misregistration.shift_zones"), "{e}");
    }
}
