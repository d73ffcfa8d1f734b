//! The per-zone estimator: which single distance a zone reports from the depths under its iFoV
//! window. A dToF pixel bins photon arrival times into a histogram; what the sensor reports from
//! it depends on its firmware. DEPTHOR's simulator (paper §3.1 "Overall Distribution": "the
//! high-resolution sparse depth points … correspond to peak values within a defined iFoV") uses
//! the **peak**; other sensors report the mean of the return, its median, or the first return
//! strong enough to detect (the **nearest** surface). The evaluation grid (docs/eval.md) compares
//! the four.
//!
//! Applies where `overall_distribution` is on (zones measured over their window); with it off a
//! zone reports the pixel at its centre whatever the estimator.

use serde::{Deserialize, Serialize};

use super::error::{check_in, SimError};
use super::grid::{histogram_peak, PeakScratch};

/// How a zone's distance is estimated from the depths under its window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// Mean of the fullest histogram bin (`overall_distribution.bin_m` wide): DEPTHOR's choice.
    #[default]
    Peak,
    /// Mean of all depths in the window.
    Mean,
    /// Median (lower middle) of the depths in the window.
    Median,
    /// The nearest histogram bin holding at least `nearest_min_fraction` of the window (the first
    /// return above the detection threshold); its mean.
    Nearest,
}

/// Parameters of the per-zone estimator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZoneEstimator {
    /// Which estimator.
    pub estimator: Estimator,
    /// For `nearest`: the smallest fraction of the window's pixels a bin must hold to count as a
    /// return.
    pub nearest_min_fraction: f32,
}

impl Default for ZoneEstimator {
    /// The peak (DEPTHOR's simulator, every preset); `nearest` needs 10 % of the window.
    fn default() -> Self {
        ZoneEstimator {
            estimator: Estimator::Peak,
            nearest_min_fraction: 0.1,
        }
    }
}

/// Name of the aspect (its config field).
pub(crate) const NAME: &str = "zone_estimator";

impl ZoneEstimator {
    /// Checks the parameters; errors name the field as `zone_estimator.<field>`.
    pub fn validate(&self) -> Result<(), SimError> {
        check_in(
            NAME,
            "nearest_min_fraction",
            self.nearest_min_fraction,
            [0.0, 1.0],
            " of the window",
        )
    }

    /// The distance reported for `depths` (all > 0; reordered by `median`), histogram bins of
    /// `bin_m`; 0 when `depths` is empty.
    pub(crate) fn estimate(&self, depths: &mut [f32], bin_m: f32, s: &mut PeakScratch) -> f32 {
        if depths.is_empty() {
            return 0.0;
        }
        match self.estimator {
            Estimator::Peak => histogram_peak(depths, bin_m, s),
            Estimator::Mean => {
                (depths.iter().map(|&d| f64::from(d)).sum::<f64>() / depths.len() as f64) as f32
            }
            Estimator::Median => {
                let k = (depths.len() - 1) / 2;
                *depths.select_nth_unstable_by(k, f32::total_cmp).1
            }
            Estimator::Nearest => nearest_return(depths, bin_m, self.nearest_min_fraction),
        }
    }
}

/// Mean of the nearest `bin_m` bin (bins `[k·bin_m, (k+1)·bin_m)`) holding at least `min_fraction`
/// of `depths` (at least one depth); sorts `depths`.
fn nearest_return(depths: &mut [f32], bin_m: f32, min_fraction: f32) -> f32 {
    depths.sort_by(f32::total_cmp);
    let need = ((min_fraction * depths.len() as f32).ceil() as usize).max(1);
    let mut start = 0;
    while start < depths.len() {
        // Depths are > 0, so truncation is floor.
        let bin = (depths[start] / bin_m) as u64;
        let end = start + depths[start..].partition_point(|&d| (d / bin_m) as u64 == bin);
        if end - start >= need {
            let sum: f64 = depths[start..end].iter().map(|&d| f64::from(d)).sum();
            return (sum / (end - start) as f64) as f32;
        }
        start = end;
    }
    // No bin is full enough (a spread of single pixels): the fullest, as the peak would say.
    histogram_peak(depths, bin_m, &mut PeakScratch::default())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(e: Estimator, d: &[f32]) -> f32 {
        let z = ZoneEstimator {
            estimator: e,
            ..ZoneEstimator::default()
        };
        z.estimate(&mut d.to_vec(), 0.05, &mut PeakScratch::default())
    }

    #[test]
    fn the_four_estimators_on_a_box_in_front_of_a_wall() {
        // 6 pixels on a wall at 3.01 m, 3 on a box at 1.0 m, 1 stray pixel at 0.5 m.
        let d = [3.01, 3.01, 3.01, 3.01, 3.01, 3.01, 1.0, 1.0, 1.0, 0.5];
        assert!((est(Estimator::Peak, &d) - 3.01).abs() < 1e-5);
        // (6·3.01 + 3 + 0.5) / 10.
        assert!((est(Estimator::Mean, &d) - 2.156).abs() < 1e-5);
        // Sorted: 0.5, 1, 1, 1, 3.01 …: the lower middle (index 4) is 3.01.
        assert!((est(Estimator::Median, &d) - 3.01).abs() < 1e-5);
        // The stray pixel is 10 % of the window: it counts (≥ 10 %); with 20 % the box does.
        assert!((est(Estimator::Nearest, &d) - 0.5).abs() < 1e-5);
        let z = ZoneEstimator {
            estimator: Estimator::Nearest,
            nearest_min_fraction: 0.2,
        };
        let got = z.estimate(&mut d.to_vec(), 0.05, &mut PeakScratch::default());
        assert!((got - 1.0).abs() < 1e-5, "{got}");
        assert_eq!(est(Estimator::Mean, &[]), 0.0);
        assert_eq!(est(Estimator::Nearest, &[]), 0.0);
    }

    #[test]
    fn serde_names_and_bounds() {
        let z: ZoneEstimator =
            serde_json::from_str(r#"{"estimator": "median", "nearest_min_fraction": 0.1}"#)
                .unwrap();
        assert_eq!(z.estimator, Estimator::Median);
        let bad = ZoneEstimator {
            nearest_min_fraction: 1.5,
            ..ZoneEstimator::default()
        };
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.starts_with("zone_estimator.nearest_min_fraction"), "{e}");
    }
}
