//! Sensor presets (docs/design.md "Sensor presets"; figures from the paper's supplement "Details of dToF
//! Simulation Method"). Pixel figures are given at the paper's image size and stored as fractions,
//! so a preset applies to any image of the same aspect ratio (`mcu` is `l5` at 120×160).

use super::anomalies::Anomalies;
use super::dark::DarkAspect;
use super::effects::calibration_shift::CalibrationShift;
use super::error::SimError;
use super::grid::{GridConfig, OverallDistribution};
use super::halving::DepthHalving;
use super::range::{Ramp, RangeAspect};
use super::signal_loss::SignalLoss;
use super::surfaces::SurfaceAspect;
use super::SimConfig;

/// Names accepted by [`preset`].
pub const PRESETS: [&str; 3] = ["l5", "phone", "mcu"];

/// A grid from pixel figures measured on an `h × w` image.
fn grid_from_px(
    rows: u16,
    cols: u16,
    bounds_px: [f32; 4],
    ifov_px: [f32; 2],
    [h, w]: [f32; 2],
) -> GridConfig {
    let [t, b, l, r] = bounds_px;
    GridConfig {
        rows,
        cols,
        fov_bounds: [t / h, b / h, l / w, r / w],
        ifov: [ifov_px[0] / h, ifov_px[1] / w],
    }
}

/// ZJU-L5 (VL53L5CX, 8×8): supplement — bounds [-25, 405, 85, 535] and iFoV ≈ 52×56 px on the
/// 480×640 GT; max recorded depth 4.1 m; "signal loss in specific regions rather than returning
/// incorrect depth values", ≈ 30 % of zones lost; strict calibration, so no shift.
fn l5() -> SimConfig {
    let blank = Anomalies::default().blank_fraction;
    // The paper's ≈ 30 % random loss (ZJU-L5 masks) is shared with the 5 % blank zones:
    // 1 − (1 − p)(1 − blank) = 0.30.
    const L5_RANDOM_LOSS: f32 = 0.30;
    const L5_MAX_M: f32 = 4.1;
    let lossy = SurfaceAspect {
        enabled: true,
        p_loss: 1.0,
        ..SurfaceAspect::default()
    };
    SimConfig {
        grid: grid_from_px(
            8,
            8,
            [-25.0, 405.0, 85.0, 535.0],
            [52.0, 56.0],
            [480.0, 640.0],
        ),
        depth_halving: DepthHalving::default(),
        overall_distribution: OverallDistribution {
            enabled: true,
            ..OverallDistribution::default()
        },
        zone_estimator: Default::default(),
        misregistration: Default::default(),
        transparent: lossy.clone(),
        specular: lossy,
        // No L5 figure in the paper: the phone's V < 40 / p = 0.8.
        dark: DarkAspect {
            enabled: true,
            ..DarkAspect::default()
        },
        range: RangeAspect {
            enabled: true,
            practical_m: L5_MAX_M,
            limit_m: L5_MAX_M,
            ramp: Ramp::Linear,
        },
        signal_loss: SignalLoss {
            enabled: true,
            p_loss: 1.0 - (1.0 - L5_RANDOM_LOSS) / (1.0 - blank),
        },
        calibration_shift: CalibrationShift::default(),
        anomalies: Anomalies {
            enabled: true,
            noise_range_m: [0.02, L5_MAX_M],
            ..Anomalies::default()
        },
        radial_distance: Default::default(),
        range_bias: Default::default(),
        edge_mixing: Default::default(),
        multipath: Default::default(),
        zone_crosstalk: Default::default(),
        bin_wiggle: Default::default(),
        range_noise: Default::default(),
        range_dropout: Default::default(),
        dark_dropout: Default::default(),
        border_dropout: Default::default(),
        learned: Default::default(),
    }
}

/// Honor Magic6 Ultra (40 rows × 30 cols on a portrait 912×684 image): supplement — bounds
/// [30, 900, 40, 660], iFoV ≈ 21×21 px, 6 m practical / 8.1 m theoretical range, V < 40 lost with
/// p = 0.8, anomalies from semantic labels; §3.1 — background shift 0–2 zones.
fn phone() -> SimConfig {
    SimConfig {
        grid: grid_from_px(
            40,
            30,
            [30.0, 900.0, 40.0, 660.0],
            [21.0, 21.0],
            [912.0, 684.0],
        ),
        depth_halving: DepthHalving::default(),
        overall_distribution: OverallDistribution {
            enabled: true,
            ..OverallDistribution::default()
        },
        zone_estimator: Default::default(),
        misregistration: Default::default(),
        transparent: SurfaceAspect {
            enabled: true,
            ..SurfaceAspect::default()
        },
        specular: SurfaceAspect {
            enabled: true,
            ..SurfaceAspect::default()
        },
        dark: DarkAspect {
            enabled: true,
            ..DarkAspect::default()
        },
        range: RangeAspect {
            enabled: true,
            ..RangeAspect::default()
        },
        signal_loss: SignalLoss::default(),
        calibration_shift: CalibrationShift {
            enabled: true,
            ..CalibrationShift::default()
        },
        anomalies: Anomalies {
            enabled: true,
            ..Anomalies::default()
        },
        radial_distance: Default::default(),
        range_bias: Default::default(),
        edge_mixing: Default::default(),
        multipath: Default::default(),
        zone_crosstalk: Default::default(),
        bin_wiggle: Default::default(),
        range_noise: Default::default(),
        range_dropout: Default::default(),
        dark_dropout: Default::default(),
        border_dropout: Default::default(),
        learned: Default::default(),
    }
}

/// The preset `name`: `"l5"`, `"phone"` or `"mcu"` (the `l5` sensor; its fractions already fit
/// the 120×160 image).
pub fn preset(name: &str) -> Result<SimConfig, SimError> {
    match name {
        "l5" | "mcu" => Ok(l5()),
        "phone" => Ok(phone()),
        other => Err(SimError::UnknownPreset(other.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_validate_and_match_paper_pixels() {
        for name in PRESETS {
            preset(name).unwrap().validate().unwrap();
        }
        let l5 = preset("l5").unwrap();
        let r = l5.grid.zone_rects_px(640, 480);
        // Cell 0: rows −25…28.75 (430/8 = 53.75), cols 85…141.25 (450/8 = 56.25); centre
        // (1.875, 113.125); iFoV 52×56.
        let e = [1.875 - 26.0, 113.125 - 28.0, 1.875 + 26.0, 113.125 + 28.0];
        for k in 0..4 {
            assert!((r[0][k] - e[k]).abs() < 1e-3, "{:?} vs {e:?}", r[0]);
        }
        // mcu = l5 at a quarter of the size.
        let m = preset("mcu").unwrap().grid.zone_rects_px(160, 120);
        for (a, b) in m.iter().zip(&r) {
            for k in 0..4 {
                assert!((a[k] * 4.0 - b[k]).abs() < 1e-3);
            }
        }
        let p = preset("phone").unwrap().grid.zone_rects_px(684, 912);
        assert_eq!(p.len(), 1200);
        // Last zone: cell rows 878.25…900, cols 639.33…660; centre (889.125, 649.667).
        assert!(
            (p[1199][0] - (889.125 - 10.5)).abs() < 1e-3
                && (p[1199][3] - (649.6667 + 10.5)).abs() < 1e-3
        );
        assert!((l5.signal_loss.p_loss - 0.263_157_9).abs() < 1e-6);
        assert!(matches!(preset("nope"), Err(SimError::UnknownPreset(_))));
    }
}
