//! Synthetic and re-simulated datasets: scene generator + dToF simulator → recording frames.
//!
//! Used by `depthor sim` (writing recordings), `depthor bench sim`, the quantizer's calibration
//! and the evaluation. Frame `i` of a run seeded `seed` uses the sub-stream `Rng::derive(seed, i)`
//! for both the scene and the sensor, so any frame can be regenerated on its own and the output
//! does not depend on the number of threads.

use crate::recording::{
    DistanceMeta, DtofFrame, DtofMeta, Frame, FrameMeta, Recording, RecordingError, RecordingMeta,
};
use crate::rng::Rng;
use crate::scene::{camera_for, render_scene, SceneConfig, SceneFrame};
use crate::sim::{simulate, SimConfig, SimError, SimInput, SimOutput};
use depthor_core::calibration::CameraIntrinsics;
use image::RgbImage;

/// Default image size (height, width) of each simulator preset (docs/design.md "Sensor presets";
/// `phone` is the paper's 912×684 portrait frame).
pub fn preset_size(preset: &str) -> Option<(u32, u32)> {
    match preset {
        "l5" => Some((480, 640)),
        "mcu" => Some((120, 160)),
        "phone" => Some((912, 684)),
        _ => None,
    }
}

/// Scene configuration matched to a preset's camera: landscape 4:3 presets keep the generator's
/// default field of view; `phone` is portrait, so its horizontal FoV is the narrow side of a
/// ≈ 65° (long side) phone camera: ≈ 48–54°.
pub fn scene_config_for(preset: &str) -> SceneConfig {
    let mut cfg = SceneConfig::default();
    if preset == "phone" {
        cfg.hfov_deg = [48.0, 54.0];
    }
    cfg
}

/// One simulated frame: the rendered scene and what the sensor reported.
#[derive(Clone, Debug)]
pub struct SynthFrame {
    /// The rendered scene (RGB, depth, labels, reflectance, normals, camera).
    pub scene: SceneFrame,
    /// The simulated zones.
    pub sim: SimOutput,
}

/// The per-frame seed of frame `index` in a run seeded `seed`.
pub fn frame_seed(seed: u64, index: u64) -> u64 {
    Rng::derive(seed, index).next_u64()
}

/// Renders scene `index` of run `seed` at `width × height` and simulates the sensor on it.
pub fn synth_frame(
    scene_cfg: &SceneConfig,
    sim_cfg: &SimConfig,
    seed: u64,
    index: u64,
    width: u32,
    height: u32,
) -> Result<SynthFrame, SimError> {
    let s = frame_seed(seed, index);
    let camera = camera_for(scene_cfg, s, width, height);
    let scene = render_scene(scene_cfg, s, camera);
    let sim = simulate(sim_cfg, &scene.sim_input(), s ^ 0x5EED_D70F)?;
    Ok(SynthFrame { scene, sim })
}

/// The recording header's `dtof` object for a simulator configuration at `width × height`: the
/// zone rectangles carry the geometry (so `fov_deg` is informative only, derived from the FoV
/// bounds through `camera`), distances are planar z, and `max_range_m` is the sensor's limit.
pub fn dtof_meta(cfg: &SimConfig, camera: &CameraIntrinsics) -> DtofMeta {
    let (w, h) = (camera.width as f32, camera.height as f32);
    let [top, bottom, left, right] = cfg.grid.fov_bounds;
    let fov = |span_px: f32, f: f32| 2.0 * (0.5 * span_px / f.max(1e-3)).atan().to_degrees();
    DtofMeta {
        rows: cfg.grid.rows,
        cols: cfg.grid.cols,
        fov_deg: [
            fov((right - left) * w, camera.fx),
            fov((bottom - top) * h, camera.fy),
        ],
        distance: DistanceMeta::Z,
        max_range_m: max_range_m(cfg),
        zone_rects_px: Some(cfg.grid.zone_rects_px(camera.width, camera.height)),
    }
}

/// Largest distance the configured sensor can report, metres.
pub fn max_range_m(cfg: &SimConfig) -> f32 {
    let mut m = cfg.range.limit_m;
    if cfg.anomalies.enabled {
        m = m.max(cfg.anomalies.noise_range_m[1]);
    }
    m
}

/// A recording header (no frames yet) for frames of `camera`'s size simulated under `cfg`.
pub fn recording_meta(cfg: &SimConfig, camera: &CameraIntrinsics) -> RecordingMeta {
    RecordingMeta::new(*camera, Some(dtof_meta(cfg, camera)), None)
}

/// The zones of a simulator output as a `dtof.json` frame.
pub fn dtof_frame(sim: &SimOutput) -> DtofFrame {
    DtofFrame {
        distance_mm: sim.distance_mm.clone(),
        status: sim.status.clone(),
        ..DtofFrame::default()
    }
}

/// A synthetic frame as a recording frame with id `id` (depth scaled by the simulator's
/// `depth_scale`, so the reference matches what the sensor saw).
pub fn to_recording_frame(id: &str, f: &SynthFrame) -> (FrameMeta, Frame) {
    let cam = f.scene.camera;
    let rgb = RgbImage::from_raw(cam.width, cam.height, f.scene.rgb.clone())
        .unwrap_or_else(|| RgbImage::new(cam.width, cam.height));
    let depth: Vec<f32> = f
        .scene
        .depth_m
        .iter()
        .map(|d| d * f.sim.depth_scale)
        .collect();
    (
        FrameMeta {
            id: id.to_string(),
            t_s: 0.0,
            camera: Some(cam),
        },
        Frame {
            id: id.to_string(),
            rgb,
            depth_m: Some(depth),
            labels: Some(f.scene.labels.clone()),
            dtof: Some(dtof_frame(&f.sim)),
        },
    )
}

/// A frame of an existing recording resampled to `width × height`: centre-cropped to the target
/// aspect ratio, RGB area-averaged (bilinear for upsampling), depth and labels nearest-neighbour
/// (never mixing depths across an edge), intrinsics cropped and scaled to match.
#[derive(Clone, Debug)]
pub struct Resampled {
    /// Intrinsics at the new size.
    pub camera: CameraIntrinsics,
    /// RGB at the new size.
    pub rgb: RgbImage,
    /// Reference depth in metres (0 = unknown).
    pub depth_m: Vec<f32>,
    /// Material labels, when the source had them.
    pub labels: Option<Vec<u8>>,
}

impl Resampled {
    /// The simulator input of this frame at its new size.
    pub fn sim_input(&self) -> SimInput<'_> {
        SimInput::observed(
            self.rgb.width(),
            self.rgb.height(),
            &self.depth_m,
            self.rgb.as_raw(),
            self.labels.as_deref(),
        )
    }
}

/// The centred crop `(x0, y0, width, height)` of a `sw × sh` image with the aspect ratio of
/// `width × height`: the region [`resample_frame`] scales to the target size.
pub fn centre_crop(sw: u32, sh: u32, width: u32, height: u32) -> (u32, u32, u32, u32) {
    let target = width as f64 / height as f64;
    let (cw, ch) = if sw as f64 / sh as f64 > target {
        (((sh as f64 * target).round() as u32).clamp(1, sw), sh)
    } else {
        (sw, ((sw as f64 / target).round() as u32).clamp(1, sh))
    };
    ((sw - cw) / 2, (sh - ch) / 2, cw, ch)
}

/// Resamples frame `frame` (camera `cam`) to `width × height` (see [`Resampled`]).
pub fn resample_frame(
    cam: &CameraIntrinsics,
    rgb: &RgbImage,
    depth_m: &[f32],
    labels: Option<&[u8]>,
    width: u32,
    height: u32,
) -> Resampled {
    let (sw, sh) = (cam.width, cam.height);
    let (x0, y0, cw, ch) = centre_crop(sw, sh, width, height);
    let cropped = image::imageops::crop_imm(rgb, x0, y0, cw, ch).to_image();
    let filter = if cw >= width {
        image::imageops::FilterType::Triangle
    } else {
        image::imageops::FilterType::CatmullRom
    };
    let rgb = image::imageops::resize(&cropped, width, height, filter);
    let (sx, sy) = (width as f32 / cw as f32, height as f32 / ch as f32);
    let nearest = |x: u32, y: u32| -> usize {
        let u =
            (x0 as u64 + ((2 * x as u64 + 1) * cw as u64) / (2 * width as u64)).min(sw as u64 - 1);
        let v =
            (y0 as u64 + ((2 * y as u64 + 1) * ch as u64) / (2 * height as u64)).min(sh as u64 - 1);
        (v * sw as u64 + u) as usize
    };
    let mut depth = Vec::with_capacity(width as usize * height as usize);
    let mut lab = labels.map(|_| Vec::with_capacity(width as usize * height as usize));
    for y in 0..height {
        for x in 0..width {
            let i = nearest(x, y);
            depth.push(depth_m.get(i).copied().unwrap_or(0.0));
            if let (Some(out), Some(src)) = (lab.as_mut(), labels) {
                out.push(src.get(i).copied().unwrap_or(0));
            }
        }
    }
    // Pixel centres at integers: u' = (u − x0 + 0.5)·sx − 0.5.
    let camera = CameraIntrinsics {
        width,
        height,
        fx: cam.fx * sx,
        fy: cam.fy * sy,
        cx: (cam.cx - x0 as f32 + 0.5) * sx - 0.5,
        cy: (cam.cy - y0 as f32 + 0.5) * sy - 0.5,
    };
    Resampled {
        camera,
        rgb,
        depth_m: depth,
        labels: lab,
    }
}

/// Simulates frame `i` of `rec` under `cfg` at `width × height` (the recording must carry
/// reference depth); reflectance is not recorded, so the simulator derives brightness from the
/// RGB (HSV V). Returns the resampled frame and the simulated zones.
pub fn simulate_recording_frame(
    rec: &Recording,
    i: usize,
    cfg: &SimConfig,
    seed: u64,
    width: u32,
    height: u32,
) -> Result<(Resampled, SimOutput), DatasetError> {
    let frame = rec.read_frame(i)?;
    let Some(depth) = frame.depth_m.as_deref() else {
        return Err(DatasetError::NoReference {
            path: rec.frame_file(i, "depth.png"),
        });
    };
    let r = resample_frame(
        &rec.camera(i),
        &frame.rgb,
        depth,
        frame.labels.as_deref(),
        width,
        height,
    );
    let sim = simulate(cfg, &r.sim_input(), frame_seed(seed, i as u64))?;
    Ok((r, sim))
}

/// Errors of dataset generation.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// Reading the source recording failed.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The simulator rejected its configuration or input.
    #[error("simulator: {0}")]
    Sim(#[from] SimError),
    /// A frame has no reference depth to simulate from.
    #[error("{}: depth.png: no reference depth in this frame (needed to simulate the sensor)", path.display())]
    NoReference {
        /// The missing depth file.
        path: std::path::PathBuf,
    },
}
