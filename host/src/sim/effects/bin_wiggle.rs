//! `bin_wiggle` (gap-tool library, docs/design.md): the histogram's time bins leave a periodic range
//! error. Forward model: `d' = d + amplitude_m · sin(2π d / period_m) + quadrature_m · cos(2π d /
//! period_m)`: the phase is unknown, so the error is fitted as two signed amplitudes, in phase and
//! in quadrature (one amplitude bounded at 0 with a fixed phase fitted a wiggle of the opposite
//! sign, or a quarter period off, to exactly zero). The period defaults to our bin width (0.3 m);
//! the gap tool searches it (`gap::periodic`, issue 44: a real error may repeat with another
//! period) before fitting the amplitudes.
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::error::{check_above, check_in, SimError};
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};

/// Parameters of the periodic range error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BinWiggle {
    /// Switch.
    pub enabled: bool,
    /// Signed amplitude of the sine term, metres.
    pub amplitude_m: f32,
    /// Signed amplitude of the cosine term (the phase the sine term does not cover), metres.
    #[serde(default)]
    pub quadrature_m: f32,
    /// Period in range, metres (ours: 0.3 m, a 2 ns bin).
    pub period_m: f32,
}

impl Default for BinWiggle {
    /// Disabled; 0.3 m period.
    fn default() -> Self {
        BinWiggle {
            enabled: false,
            amplitude_m: 0.0,
            quadrature_m: 0.0,
            period_m: 0.3,
        }
    }
}

impl BinWiggle {
    /// The effect's name (its [`FIT`] and configuration field).
    pub const NAME: &'static str = "bin_wiggle";

    /// The reported distance of a return at `d` metres.
    pub fn distance(&self, d: f32) -> f32 {
        let (s, c) = (core::f32::consts::TAU * d / self.period_m).sin_cos();
        (d + self.amplitude_m * s + self.quadrature_m * c).max(1e-3)
    }
}

impl ZoneEffect for BinWiggle {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_in(
            self.name(),
            "amplitude_m",
            self.amplitude_m,
            [-1.0, 1.0],
            " m",
        )?;
        check_in(
            self.name(),
            "quadrature_m",
            self.quadrature_m,
            [-1.0, 1.0],
            " m",
        )?;
        check_above(self.name(), "period_m", self.period_m, [0.0, 10.0], " m")
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
    name: BinWiggle::NAME,
    physics:
        "periodic range error: d + A·sin(2πd/P) + B·cos(2πd/P), period P searched over 0.1–2 m",
    params: &[
        param("amplitude_m", -0.1, 0.1),
        param("quadrature_m", -0.1, 0.1),
    ],
    stratum: Covariate::Range,
    separating_data: "a wall swept finely in range (periodic pattern)",
    start_unit: &[0.005, 0.0],
    config: |c| &c.bin_wiggle,
    config_mut: |c| &mut c.bin_wiggle,
};

f32_params!(BinWiggle: amplitude_m, quadrature_m);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_hand_computed() {
        let w = BinWiggle {
            enabled: true,
            amplitude_m: 0.02,
            quadrature_m: -0.01,
            period_m: 0.4,
        };
        // 2.1 m is a quarter period past 2.0 m: sin = 1, cos = 0; at 2.0 m sin = 0, cos = 1.
        assert!((w.distance(2.1) - 2.12).abs() < 1e-5);
        assert!((w.distance(2.0) - 1.99).abs() < 1e-5);
    }
}
