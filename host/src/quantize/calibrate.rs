//! Calibration: simulated input frames (scene generator → dToF simulator → projection), the
//! activation range of every value over those frames, and the int8 parameters chosen from them.
//!
//! Ranges are the plain **minimum / maximum** over all calibration frames (no percentile
//! clipping), always widened to include 0 so zero padding and ReLU zeros are exact. Values whose
//! range the op fixes ignore calibration: `rgb`, `minmax_norm` and `sigmoid` outputs span [0, 1];
//! `sparse` spans [0, the bins head's `max_depth_m`]; `upsample_bilinear` and `pixel_shuffle`
//! keep their input's parameters (the engine requires it).

use super::net::{Net, OpKind, Storage, RGB, SPARSE};
use crate::scene::{camera_for, render_scene, SceneConfig};
use crate::sim::{preset, simulate, SimError, SimInput};
use depthor_core::calibration::{Calibration, DistanceKind, DtofGeometry, Extrinsics};
use depthor_core::hal::ZoneView;
use depthor_core::kernels::requant::QParams;
use depthor_core::projection::{project_to_sparse, ProjectionError};

/// Smallest activation range (real units) given to a value; keeps scales positive when a
/// value was constant over the calibration set.
pub const MIN_RANGE: f32 = 1e-6;

/// One network input: what a camera and a dToF sensor give the engine.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Rows.
    pub height: usize,
    /// Columns.
    pub width: usize,
    /// RGB888 interleaved, `H×W×3` (the engine's input).
    pub rgb: Vec<u8>,
    /// Projected dToF depth `H×W`, metres, 0 = no point.
    pub sparse_m: Vec<f32>,
}

impl Frame {
    /// The float network's `rgb` input: planar `[3,H,W]`, `byte/255`.
    pub fn rgb_planar(&self) -> Vec<f32> {
        let n = self.height * self.width;
        let mut v = vec![0f32; 3 * n];
        for (i, px) in self.rgb.chunks_exact(3).enumerate().take(n) {
            for c in 0..3 {
                v[c * n + i] = px[c] as f32 / 255.0;
            }
        }
        v
    }
}

/// Why calibration frames could not be made.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The simulator rejected its input or preset.
    #[error("dToF simulator: {0}")]
    Sim(#[from] SimError),
    /// Projection failed.
    #[error("projection: {0:?}")]
    Projection(ProjectionError),
}

/// `count` simulated frames at `height × width` for the sensor preset `preset_name` (`mcu`,
/// `phone`): scene `seed + k` rendered by [`render_scene`], its zones simulated by
/// [`simulate`], projected to a sparse map with the zone rectangles' centres.
pub fn simulated_frames(
    preset_name: &str,
    height: usize,
    width: usize,
    count: usize,
    seed: u64,
) -> Result<Vec<Frame>, FrameError> {
    let sim = preset(preset_name)?;
    let cfg = SceneConfig::default();
    let (w, h) = (width as u32, height as u32);
    (0..count as u64)
        .map(|k| {
            let s = seed.wrapping_add(k);
            let cam = camera_for(&cfg, s, w, h);
            let scene = render_scene(&cfg, s, cam);
            let input = SimInput {
                width: w,
                height: h,
                depth_m: &scene.depth_m,
                rgb: &scene.rgb,
                labels: Some(&scene.labels),
                reflectance: Some(&scene.reflectance),
                second_depth_m: Some(&scene.second_depth_m),
            };
            let zones = simulate(&sim, &input, s)?;
            let cal = Calibration {
                camera: cam,
                dtof: DtofGeometry {
                    rows: zones.rows,
                    cols: zones.cols,
                    fov_deg: [45.0, 45.0], // unused: the zone rectangles place the points
                    distance: DistanceKind::Z,
                    max_range_m: 10.0,
                },
                dtof_to_camera: Extrinsics::IDENTITY,
                zone_rects_px: Some(&zones.zone_rects_px),
            };
            let view = ZoneView {
                rows: zones.rows,
                cols: zones.cols,
                distance_mm: &zones.distance_mm,
                status: &zones.status,
            };
            let mut sparse_m = vec![0f32; height * width];
            project_to_sparse(&cal, &view, &mut sparse_m).map_err(FrameError::Projection)?;
            Ok(Frame {
                height,
                width,
                rgb: scene.rgb,
                sparse_m,
            })
        })
        .collect()
}

/// Running minimum and maximum of every value of a network.
#[derive(Clone, Debug, PartialEq)]
pub struct Ranges {
    /// Per value: smallest element seen (`+∞` before any frame).
    pub min: Vec<f32>,
    /// Per value: largest element seen (`−∞` before any frame).
    pub max: Vec<f32>,
}

impl Ranges {
    /// Empty ranges for `n` values.
    pub fn new(n: usize) -> Ranges {
        Ranges {
            min: vec![f32::INFINITY; n],
            max: vec![f32::NEG_INFINITY; n],
        }
    }

    /// Widens the ranges with one float run's values.
    pub fn observe(&mut self, values: &[Vec<f32>]) {
        for ((lo, hi), v) in self.min.iter_mut().zip(&mut self.max).zip(values) {
            for &x in v {
                if x.is_finite() {
                    *lo = lo.min(x);
                    *hi = hi.max(x);
                }
            }
        }
    }
}

/// Asymmetric int8 parameters covering `[lo, hi]` widened to include 0:
/// `scale = (hi − lo)/255`, `zero_point = round(−128 − lo/scale)`.
pub fn affine_params(lo: f32, hi: f32) -> QParams {
    let lo = if lo.is_finite() { lo.min(0.0) } else { 0.0 };
    let hi = if hi.is_finite() { hi.max(0.0) } else { 0.0 };
    let scale = (hi - lo).max(MIN_RANGE) / 255.0;
    let zero_point = (-128.0 - lo / scale).round().clamp(-128.0, 127.0) as i32;
    QParams { scale, zero_point }
}

/// The blob parameters of every value of `net` from calibrated `ranges` (rules in the module
/// doc). f32 values get scale 1, zero point 0 (ignored by the engine).
pub fn choose_qparams(net: &Net, ranges: &Ranges) -> Vec<QParams> {
    let unit = affine_params(0.0, 1.0);
    let max_depth = net
        .ops
        .iter()
        .find_map(|o| match &o.kind {
            OpKind::BinsHead { attrs, .. } => Some(attrs.max_depth),
            _ => None,
        })
        .unwrap_or(ranges.max[SPARSE]);
    let mut qs: Vec<QParams> = Vec::with_capacity(net.values.len());
    qs.push(unit); // rgb
    qs.push(affine_params(0.0, max_depth));
    debug_assert_eq!((RGB, SPARSE), (0, 1));
    for op in &net.ops {
        let v = op.output;
        let q = if net.values[v].storage == Storage::F32 {
            QParams {
                scale: 1.0,
                zero_point: 0,
            }
        } else {
            match op.kind {
                OpKind::MinMaxNorm(_) | OpKind::Sigmoid => unit,
                OpKind::Upsample(_) | OpKind::PixelShuffle(_) => qs[op.inputs[0]],
                _ => affine_params(ranges.min[v], ranges.max[v]),
            }
        };
        qs.push(q);
    }
    qs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn affine_params_by_hand() {
        // [0, 2.55]: scale 0.01, 0 at code −128.
        let q = affine_params(0.0, 2.55);
        assert!((q.scale - 0.01).abs() < 1e-7);
        assert_eq!(q.zero_point, -128);
        // [−1, 1.55]: scale 0.01, 0 at −128 + 100 = −28.
        let q = affine_params(-1.0, 1.55);
        assert_eq!(q.zero_point, -28);
        assert_eq!(q.quantize(0.0), -28);
        // A positive-only range still includes 0; a constant zero range keeps a positive scale.
        assert_eq!(affine_params(1.0, 2.55).zero_point, -128);
        assert!(affine_params(0.0, 0.0).scale > 0.0);
    }

    #[test]
    fn ranges_track_min_and_max() {
        let mut r = Ranges::new(2);
        r.observe(&[vec![1.0, -2.0], vec![3.0]]);
        r.observe(&[vec![5.0, f32::NAN], vec![-1.0]]);
        assert_eq!(r.min, vec![-2.0, -1.0]);
        assert_eq!(r.max, vec![5.0, 3.0]);
    }
}
