//! Calibration errors (paper §3.1 "Calibration Errors": "foreground points generally project with
//! high precision, while background points often experience a noticeable shift … we select a
//! percentile from GT as the threshold, treat points above it as background, and apply a random
//! shift (within 0–2 dToF pixels)").
//!
//! Per frame: a quantile `q` is drawn uniformly in `percentile` and the threshold is the `q`-quantile
//! of the zones' ground-truth peaks (the points; zones without depth are left out). A shift
//! `(dr, dc)` is drawn uniformly in `{−max..max}` per axis. Every background zone (peak deeper
//! than the threshold) then takes the measurement of zone `(r + dr, c + dc)`, or no target when
//! that zone is off the grid (its content lies outside the simulated sensor). Foreground zones
//! are untouched.

use serde::{Deserialize, Serialize};

use super::{param, value, Covariate, EffectFit, EffectParams, ParamSpec};
use crate::rng::Rng;
use crate::sim::error::{check_ordered, check_prob, invalid, SimError};
use crate::sim::frame::{Scene, ZoneEffect, ZoneGrid};
use crate::sim::truth::ZoneEvents;

/// Parameters of the background shift.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationShift {
    /// Switch.
    pub enabled: bool,
    /// Probability that a frame is shifted at all.
    pub frame_probability: f32,
    /// `[lo, hi]` range of the depth quantile used as background threshold.
    pub percentile: [f32; 2],
    /// Largest shift in zones `[rows, cols]`.
    pub max_shift_zones: [u8; 2],
}

impl Default for CalibrationShift {
    /// Disabled; when enabled every frame, quantile in [0.2, 0.4], up to 2 zones per axis.
    fn default() -> Self {
        CalibrationShift {
            enabled: false,
            frame_probability: 1.0,
            percentile: [0.2, 0.4],
            max_shift_zones: [2, 2],
        }
    }
}

/// Lower `q`-quantile (nearest rank) of the sorted values: `sorted[floor(q·(n−1))]`.
fn quantile(sorted: &[f32], q: f32) -> f32 {
    let k = ((q * (sorted.len() - 1) as f32).floor() as usize).min(sorted.len() - 1);
    sorted[k]
}

impl ZoneEffect for CalibrationShift {
    fn name(&self) -> &'static str {
        "calibration_shift"
    }

    fn enabled(&self) -> bool {
        self.enabled
    }

    fn validate(&self) -> Result<(), SimError> {
        check_prob(self.name(), "frame_probability", self.frame_probability)?;
        check_ordered(self.name(), "percentile", self.percentile, [0.0, 1.0], "")?;
        for (i, &m) in self.max_shift_zones.iter().enumerate() {
            if m > 64 {
                return Err(invalid(
                    self.name(),
                    &format!("max_shift_zones[{i}]"),
                    format!("{m} is out of range (allowed 0 to 64 zones)"),
                ));
            }
        }
        Ok(())
    }

    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        let u_frame = rng.f32();
        let q = rng.range(self.percentile[0], self.percentile[1]);
        let [mr, mc] = self.max_shift_zones.map(i64::from);
        let dr = rng.below((2 * mr + 1) as u64) as i64 - mr;
        let dc = rng.below((2 * mc + 1) as u64) as i64 - mc;
        if u_frame >= self.frame_probability {
            return;
        }
        let mut peaks: Vec<f32> = zones
            .zones
            .iter()
            .map(|z| z.truth.peak_m)
            .filter(|&p| p > 0.0)
            .collect();
        if peaks.is_empty() {
            return;
        }
        peaks.sort_by(f32::total_cmp);
        let threshold = quantile(&peaks, q);
        let before: Vec<f32> = zones.zones.iter().map(|z| z.distance_m).collect();
        let (rows, cols) = (zones.rows as i64, zones.cols as i64);
        for (k, zone) in zones.zones.iter_mut().enumerate() {
            if zone.truth.peak_m <= threshold {
                continue;
            }
            zone.truth.events.insert(ZoneEvents::BACKGROUND);
            if dr == 0 && dc == 0 {
                continue;
            }
            let (r, c) = (k as i64 / cols + dr, k as i64 % cols + dc);
            zone.distance_m = if (0..rows).contains(&r) && (0..cols).contains(&c) {
                before[(r * cols + c) as usize]
            } else {
                0.0
            };
            zone.truth.shift = [dr as i8, dc as i8];
            zone.truth.events.insert(ZoneEvents::SHIFTED);
        }
    }
}

/// Fit description for the gap tool ([`super::ALL`]).
pub const FIT: EffectFit = EffectFit {
    name: "calibration_shift",
    physics:
        "zone grid misregistered against the camera: background zones report a neighbour's depth",
    params: &[
        ParamSpec {
            field: "max_shift_zones",
            lo: 1.0,
            hi: 2.0,
            integer: true,
        },
        param("frame_probability", 0.0, 1.0),
    ],
    stratum: Covariate::Spread,
    separating_data: "frames with a near object in front of a far background at several positions",
    start_unit: &[1.0, 0.25],
    config: |c| &c.calibration_shift,
    config_mut: |c| &mut c.calibration_shift,
};

impl EffectParams for CalibrationShift {
    fn switch(&mut self) -> &mut bool {
        &mut self.enabled
    }
    fn values(&self) -> Vec<f32> {
        vec![f32::from(self.max_shift_zones[0]), self.frame_probability]
    }
    fn set_values(&mut self, v: &[f64]) {
        let m = value(v, 0).round().clamp(0.0, 64.0) as u8;
        self.max_shift_zones = [m, m];
        self.frame_probability = value(v, 1);
    }
}

#[cfg(test)]
mod tests {
    use super::quantile;

    #[test]
    fn quantile_nearest_rank() {
        let s = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile(&s, 0.0), 1.0);
        assert_eq!(quantile(&s, 0.2), 1.0);
        assert_eq!(quantile(&s, 0.25), 2.0);
        assert_eq!(quantile(&s, 0.4), 2.0);
        assert_eq!(quantile(&s, 1.0), 5.0);
    }
}
