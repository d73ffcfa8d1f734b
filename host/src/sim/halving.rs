//! Depth halving (supplement "Details of dToF Simulation Method": on Hypersim, "if 60 % or more of
//! the depth values in an image exceed 6 meters, all depth values are halved", after Sun et al. on
//! TartanAir). It rescues over-deep synthetic scenes; our scene generator builds realistic indoor
//! depths, so it is off by default. The factor applied is reported as `SimOutput::depth_scale`:
//! the caller must scale its ground truth by it too.

use serde::{Deserialize, Serialize};

use super::error::{check_above, check_prob, SimError};
use super::SimInput;

/// Parameters of the depth halving.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepthHalving {
    /// Switch.
    pub enabled: bool,
    /// Depth (m) a pixel must exceed to count as far.
    pub threshold_m: f32,
    /// Fraction of known pixels that must be far for the frame to be scaled.
    pub min_fraction: f32,
    /// Factor applied to all depths of such a frame.
    pub factor: f32,
}

impl Default for DepthHalving {
    /// Disabled; when enabled the paper's 60 % beyond 6 m → × 0.5.
    fn default() -> Self {
        DepthHalving {
            enabled: false,
            threshold_m: 6.0,
            min_fraction: 0.6,
            factor: 0.5,
        }
    }
}

/// Name of the aspect (its config field).
pub(crate) const HALVING: &str = "depth_halving";

impl DepthHalving {
    /// Checks the parameters; errors name the field as `depth_halving.<field>`.
    pub fn validate(&self) -> Result<(), SimError> {
        check_above(
            HALVING,
            "threshold_m",
            self.threshold_m,
            [0.0, 1000.0],
            " m",
        )?;
        check_prob(HALVING, "min_fraction", self.min_fraction)?;
        check_above(HALVING, "factor", self.factor, [0.0, 1.0], "")
    }

    /// The factor for this frame's depths: `factor` when enabled and at least `min_fraction` of
    /// the known (> 0) depths exceed `threshold_m`, else 1.
    pub fn scale(&self, input: &SimInput<'_>) -> f32 {
        if !self.enabled {
            return 1.0;
        }
        let (mut known, mut far) = (0usize, 0usize);
        for &d in input.depth_m {
            if d.is_finite() && d > 0.0 {
                known += 1;
                far += usize::from(d > self.threshold_m);
            }
        }
        if known > 0 && far as f32 >= self.min_fraction * known as f32 {
            self.factor
        } else {
            1.0
        }
    }
}
