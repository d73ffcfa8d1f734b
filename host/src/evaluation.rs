//! What `depthor eval` and `depthor demo` share: input frames at the model's size (rendered
//! scenes with a simulated sensor, or a recording's frames with its own zones, or simulated ones
//! when it has none), the methods compared on them and their per-frame predictions.
//!
//! Methods: the core's int8 model, the float network in tract, and the baselines run on the same
//! projected dToF points: nearest zone, bilinear zones, joint bilateral upsampling guided by the
//! RGB, and the monocular prior fitted to the points by least-squares scale and shift in inverse
//! depth (the paper's "DAv2-RS" protocol with our prior).

use anyhow::{Context, Result};
use depthor_core::calibration::CameraIntrinsics;
use depthor_core::metrics::Metrics;
use depthor_core::projection::{for_each_point, ProjectedPoint};
use image::RgbImage;
use std::path::Path;
use std::time::Instant;

use crate::baselines::{self, SparseFrame};
use crate::dataset::{dtof_frame, dtof_meta, resample_frame, scene_config_for, synth_frame};
use crate::inference::Int8Model;
use crate::models::ModelFiles;
use crate::recording::{CalibrationData, Recording};
use crate::reference::prior::{fit_scale_shift, PriorReference};
use crate::reference::FloatReference;
use crate::sim::{preset, simulate, SimConfig, SimInput, SimOutput};
use crate::viz::{depth_image, mosaic, render_projection, Overlay};

/// One input frame at the model's size.
#[derive(Clone, Debug)]
pub struct EvalFrame {
    /// Frame id (recording id, or the rendered scene's index).
    pub id: String,
    /// RGB at the model's size.
    pub rgb: RgbImage,
    /// Reference depth, metres (0 = none).
    pub reference_m: Vec<f32>,
    /// dToF points projected into this image.
    pub points: Vec<ProjectedPoint>,
    /// Zone rows of the sensor.
    pub rows: u16,
    /// Zone columns of the sensor.
    pub cols: u16,
}

impl EvalFrame {
    /// Image width.
    pub fn width(&self) -> u32 {
        self.rgb.width()
    }

    /// Image height.
    pub fn height(&self) -> u32 {
        self.rgb.height()
    }

    /// The sparse depth map the model reads (metres, 0 = no point; the nearer point wins).
    pub fn sparse_m(&self) -> Vec<f32> {
        let w = self.width() as usize;
        let mut sparse = vec![0.0f32; w * self.height() as usize];
        for p in &self.points {
            let i = p.y as usize * w + p.x as usize;
            if let Some(s) = sparse.get_mut(i) {
                if *s == 0.0 || p.depth_m < *s {
                    *s = p.depth_m;
                }
            }
        }
        sparse
    }

    /// The points as the baselines take them.
    pub fn sparse_frame(&self) -> SparseFrame<'_> {
        SparseFrame {
            width: self.width(),
            height: self.height(),
            rows: self.rows,
            cols: self.cols,
            points: &self.points,
        }
    }
}

/// The projected points of a simulator output (its zone rectangles in `camera` pixels).
pub fn sim_points(
    cfg: &SimConfig,
    sim: &SimOutput,
    camera: &CameraIntrinsics,
) -> Result<Vec<ProjectedPoint>> {
    let meta = dtof_meta(cfg, camera);
    let cal = CalibrationData::new(&(*camera).into(), &meta, None);
    let frame = dtof_frame(sim);
    let mut points = Vec::new();
    for_each_point(&cal.as_core(), &frame.view(&meta), |p| points.push(p))?;
    Ok(points)
}

/// Scene `index` of run `seed`, rendered at `width × height` with preset `preset_name`'s sensor.
pub fn rendered_frame(
    preset_name: &str,
    seed: u64,
    index: u64,
    width: u32,
    height: u32,
) -> Result<EvalFrame> {
    let cfg = preset(preset_name)?;
    let f = synth_frame(
        &scene_config_for(preset_name),
        &cfg,
        seed,
        index,
        width,
        height,
    )?;
    let rgb = RgbImage::from_raw(width, height, f.scene.rgb.clone()).context("scene size")?;
    let points = sim_points(&cfg, &f.sim, &f.scene.camera)?;
    Ok(EvalFrame {
        id: format!("{index:06}"),
        rgb,
        reference_m: f
            .scene
            .depth_m
            .iter()
            .map(|d| d * f.sim.depth_scale)
            .collect(),
        points,
        rows: cfg.grid.rows,
        cols: cfg.grid.cols,
    })
}

/// A recording read frame by frame at a model's size.
pub struct RecordingFrames {
    rec: Recording,
    cfg: SimConfig,
}

impl RecordingFrames {
    /// Opens `dir`; `preset_name` simulates the sensor for frames without dToF.
    pub fn open(dir: &Path, preset_name: &str) -> Result<Self> {
        Ok(RecordingFrames {
            rec: Recording::open(dir)?,
            cfg: preset(preset_name)?,
        })
    }

    /// Frames in the recording.
    pub fn len(&self) -> usize {
        self.rec.len()
    }

    /// Whether the recording has no frames.
    pub fn is_empty(&self) -> bool {
        self.rec.len() == 0
    }

    /// Frame `i` resampled to `width × height`: its zones projected at the recording's own
    /// resolution and mapped onto the resampled image, or the preset's sensor simulated on its
    /// reference depth when it has no dToF.
    pub fn frame(&self, i: usize, width: u32, height: u32) -> Result<EvalFrame> {
        let (w, h) = (width, height);
        let frame = self.rec.read_frame(i)?;
        let cam = self.rec.camera(i);
        let depth = frame
            .depth_m
            .clone()
            .unwrap_or_else(|| vec![0.0; (cam.width * cam.height) as usize]);
        let r = resample_frame(&cam, &frame.rgb, &depth, frame.labels.as_deref(), w, h);
        let meta = self.rec.meta().dtof.as_ref();
        let (points, rows, cols) = match (&frame.dtof, self.rec.calibration(i), meta) {
            (Some(d), Some(cal), Some(meta)) => {
                let (sx, sy) = (r.camera.fx / cam.fx, r.camera.fy / cam.fy);
                let mut pts = Vec::new();
                for_each_point(&cal.as_core(), &d.view(meta), |p| {
                    let u = (p.u - cam.cx) * sx + r.camera.cx;
                    let v = (p.v - cam.cy) * sy + r.camera.cy;
                    let (x, y) = ((u + 0.5).floor(), (v + 0.5).floor());
                    if x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32 {
                        pts.push(ProjectedPoint {
                            u,
                            v,
                            x: x as u32,
                            y: y as u32,
                            ..p
                        });
                    }
                })?;
                (pts, meta.rows, meta.cols)
            }
            _ => {
                let sim = simulate(
                    &self.cfg,
                    &SimInput {
                        width: w,
                        height: h,
                        depth_m: &r.depth_m,
                        rgb: r.rgb.as_raw(),
                        labels: r.labels.as_deref(),
                        reflectance: None,
                        second_depth_m: None,
                    },
                    i as u64,
                )?;
                let pts = sim_points(&self.cfg, &sim, &r.camera)?;
                (pts, self.cfg.grid.rows, self.cfg.grid.cols)
            }
        };
        Ok(EvalFrame {
            id: frame.id,
            rgb: r.rgb,
            reference_m: r.depth_m,
            points,
            rows,
            cols,
        })
    }
}

/// A depth method compared by `depthor eval`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The int8 model in the core.
    Int8,
    /// The float network in tract.
    Float,
    /// Nearest-zone fill.
    Nearest,
    /// Bilinear interpolation of the zone depths.
    Bilinear,
    /// Joint bilateral upsampling guided by the RGB.
    JointBilateral,
    /// The monocular prior fitted to the points (scale and shift in inverse depth).
    PriorFit,
}

impl Method {
    /// Every method, models first.
    pub const ALL: [Method; 6] = [
        Method::Int8,
        Method::Float,
        Method::Nearest,
        Method::Bilinear,
        Method::JointBilateral,
        Method::PriorFit,
    ];

    /// Short key used in CSV and JSON.
    pub fn key(self) -> &'static str {
        match self {
            Method::Int8 => "int8",
            Method::Float => "float",
            Method::Nearest => "nearest",
            Method::Bilinear => "bilinear",
            Method::JointBilateral => "joint_bilateral",
            Method::PriorFit => "prior_fit",
        }
    }

    /// Name for tables.
    pub fn label(self) -> &'static str {
        match self {
            Method::Int8 => "int8 model (core)",
            Method::Float => "float model (tract)",
            Method::Nearest => "nearest zone",
            Method::Bilinear => "bilinear zones",
            Method::JointBilateral => "joint bilateral",
            Method::PriorFit => "prior + LS fit",
        }
    }

    /// Whether this is a baseline (not the model itself).
    pub fn is_baseline(self) -> bool {
        !matches!(self, Method::Int8 | Method::Float)
    }
}

/// One method's answer on one frame.
#[derive(Clone, Debug)]
pub struct Prediction {
    /// Which method.
    pub method: Method,
    /// Depth, metres, `H × W`.
    pub depth_m: Vec<f32>,
    /// Wall time of this method on this frame, seconds.
    pub seconds: f64,
}

/// Runs every method on frames at one model's size.
pub struct Evaluator {
    int8: Int8Model,
    float: Option<FloatReference>,
    prior: Option<PriorReference>,
    depth_range_m: (f32, f32),
}

impl Evaluator {
    /// An evaluator of `int8` alone (with its baselines), or also of the float network and the
    /// prior when `float` is given (both at the int8 model's size); `depth_range_m` clamps the
    /// prior fit.
    pub fn new(
        int8: Int8Model,
        float: Option<(FloatReference, PriorReference)>,
        depth_range_m: (f32, f32),
    ) -> Self {
        let (float, prior) = float.map_or((None, None), |(f, p)| (Some(f), Some(p)));
        Evaluator {
            int8,
            float,
            prior,
            depth_range_m,
        }
    }

    /// Loads a model's int8 blob and, when `with_float`, its float network and prior (tract).
    pub fn load(files: &ModelFiles, with_float: bool, depth_range_m: (f32, f32)) -> Result<Self> {
        let int8 = Int8Model::from_file(&files.blob(), None)?;
        let (h, w) = int8.input_shape();
        let float = if with_float {
            Some((
                FloatReference::load(&files.nnef(), h as u32, w as u32)?,
                PriorReference::load(&files.prior_nnef(), h as u32, w as u32)?,
            ))
        } else {
            None
        };
        Ok(Self::new(int8, float, depth_range_m))
    }

    /// The int8 model (sizes, blob).
    pub fn int8(&self) -> &Int8Model {
        &self.int8
    }

    /// The methods this evaluator runs, in [`Method::ALL`] order.
    pub fn methods(&self) -> Vec<Method> {
        Method::ALL
            .into_iter()
            .filter(|m| !matches!(m, Method::Float | Method::PriorFit) || self.float.is_some())
            .collect()
    }

    /// Every method's prediction on `frame` (which must be at the model's size).
    pub fn predict(&mut self, frame: &EvalFrame) -> Result<Vec<Prediction>> {
        let sparse = frame.sparse_m();
        let rgb = frame.rgb.as_raw();
        let mut out = Vec::new();
        let timed =
            |method: Method, f: &mut dyn FnMut() -> Result<Vec<f32>>| -> Result<Prediction> {
                let t = Instant::now();
                let depth_m = f()?;
                Ok(Prediction {
                    method,
                    depth_m,
                    seconds: t.elapsed().as_secs_f64(),
                })
            };
        out.push(timed(Method::Int8, &mut || {
            Ok(self.int8.run(rgb, &sparse)?.0)
        })?);
        if let Some(float) = &self.float {
            out.push(timed(Method::Float, &mut || Ok(float.run(rgb, &sparse)?))?);
        }
        let s = frame.sparse_frame();
        out.push(timed(Method::Nearest, &mut || {
            Ok(baselines::nearest_fill(&s))
        })?);
        out.push(timed(Method::Bilinear, &mut || {
            Ok(baselines::bilinear_zones(&s))
        })?);
        out.push(timed(Method::JointBilateral, &mut || {
            Ok(baselines::joint_bilateral(&s, rgb))
        })?);
        if let Some(prior) = &self.prior {
            let (lo, hi) = self.depth_range_m;
            out.push(timed(Method::PriorFit, &mut || {
                let d_inv = prior.run(rgb)?;
                Ok(fit_scale_shift(
                    &d_inv,
                    frame.width() as usize,
                    &frame.points,
                    lo,
                    hi,
                ))
            })?);
        }
        Ok(out)
    }
}

/// A fixed-width table of metrics, one row per `(label, metrics)`, with a header.
pub fn metrics_table(rows: &[(&str, Metrics)]) -> String {
    let mut t = format!(
        "{:<20} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}\n",
        "method", "δ1", "δ2", "δ3", "Rel", "RMSE", "log10", "EWMAE"
    );
    for (name, m) in rows {
        t += &format!(
            "{:<20} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3}\n",
            name, m.delta1, m.delta2, m.delta3, m.abs_rel, m.rmse, m.log10, m.ewmae
        );
    }
    t
}

/// RGB with the dToF points | reference | `pred` | |pred − reference| (0–1 m) | `extra` (if any),
/// depths coloured on one scale from 0 to the largest reference depth.
pub fn comparison_mosaic(f: &EvalFrame, pred: &[f32], extra: Option<&[f32]>) -> RgbImage {
    let (w, h) = (f.width(), f.height());
    let hi = f
        .reference_m
        .iter()
        .copied()
        .fold(0.0f32, f32::max)
        .max(1.0);
    let err: Vec<f32> = pred
        .iter()
        .zip(&f.reference_m)
        .map(|(p, r)| if *r > 0.0 { (p - r).abs() + 1e-6 } else { 0.0 })
        .collect();
    let overlay = Overlay {
        lo_m: 0.0,
        hi_m: hi,
        ..Overlay::auto(w, h, &f.points)
    };
    let mut panels = vec![
        render_projection(&f.rgb, &f.points, &overlay),
        depth_image(&f.reference_m, w, h, 0.0, hi),
        depth_image(pred, w, h, 0.0, hi),
        depth_image(&err, w, h, 0.0, 1.0),
    ];
    if let Some(x) = extra {
        panels.push(depth_image(x, w, h, 0.0, hi));
    }
    mosaic(&panels, 4)
}
