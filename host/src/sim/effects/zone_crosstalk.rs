//! `zone_crosstalk` (gap-tool library, docs/design.md): light of one zone leaks into its neighbours'
//! SPADs, blurring the returns across the grid. Forward model: every zone with a return reports
//! `(1 − coupling) · d + coupling · m`, with `m` the mean distance of its 4-neighbours that have a
//! return (before the blur); zones without such neighbours are unchanged.
use serde::{Deserialize, Serialize};

use super::{param, Covariate, EffectFit};
use crate::rng::Rng;
use crate::sim::error::{check_prob, SimError};
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};

/// Parameters of the crosstalk.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZoneCrosstalk {
    /// Switch.
    pub enabled: bool,
    /// Weight of the neighbours' mean, in [0, 1].
    pub coupling: f32,
}

impl ZoneCrosstalk {
    /// Blurs `distance` (row-major `rows × cols`, `valid[z]` weights whether zone `z` has a
    /// return, in [0, 1]) in place.
    pub fn blur(&self, rows: usize, cols: usize, distance: &mut [f32], valid: &[f32]) {
        let before = distance.to_vec();
        for z in 0..rows * cols {
            if valid[z] <= 0.0 {
                continue;
            }
            let (r, c) = (z / cols, z % cols);
            let (mut sum, mut w) = (0.0f32, 0.0f32);
            let mut add = |k: usize| {
                sum += valid[k] * before[k];
                w += valid[k];
            };
            if r > 0 {
                add(z - cols);
            }
            if r + 1 < rows {
                add(z + cols);
            }
            if c > 0 {
                add(z - 1);
            }
            if c + 1 < cols {
                add(z + 1);
            }
            if w > 0.0 {
                distance[z] = (1.0 - self.coupling) * before[z] + self.coupling * sum / w;
            }
        }
    }
}

impl ZoneEffect for ZoneCrosstalk {
    fn name(&self) -> &'static str {
        "zone_crosstalk"
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn validate(&self) -> Result<(), SimError> {
        check_prob(self.name(), "coupling", self.coupling)
    }
    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, _rng: &mut Rng) {
        let mut d: Vec<f32> = zones.zones.iter().map(|z| z.distance_m).collect();
        let valid: Vec<f32> = zones
            .zones
            .iter()
            .map(|z| f32::from(u8::from(z.has_target())))
            .collect();
        self.blur(zones.rows, zones.cols, &mut d, &valid);
        for (zone, d) in zones.zones.iter_mut().zip(d) {
            zone.distance_m = d;
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "zone_crosstalk",
    physics: "returns blur into neighbouring zones: (1 − c)·d + c·mean(neighbours)",
    params: &[param("coupling", 0.0, 1.0)],
    stratum: Covariate::Spread,
    separating_data: "an isolated near object on a far background (crosstalk reaches neighbours, mixing stays in the zone)",
    start_unit: &[0.05],
    config: |c| &c.zone_crosstalk,
    config_mut: |c| &mut c.zone_crosstalk,
};

f32_params!(ZoneCrosstalk: coupling);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blur_hand_computed() {
        // 1×3 grid: 1 m, 2 m, 4 m, the last without a return.
        let x = ZoneCrosstalk {
            enabled: true,
            coupling: 0.5,
        };
        let mut d = [1.0, 2.0, 4.0];
        x.blur(1, 3, &mut d, &[1.0, 1.0, 0.0]);
        assert_eq!(d, [1.5, 1.5, 4.0]);
    }
}
