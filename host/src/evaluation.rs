//! What `depthor eval` and `depthor demo` share: input frames at the model's size (rendered
//! scenes with a simulated sensor, or a recording's frames with its own zones, or simulated ones
//! when it has none), the methods compared on them and their per-frame predictions.
//!
//! Methods: the core's int8 model, the float network in tract, and the baselines run on the same
//! projected dToF points: nearest zone, bilinear zones, joint bilateral upsampling guided by the
//! RGB, and the monocular prior fitted to the points by least-squares scale and shift in inverse
//! depth (the paper's "DAv2-RS" protocol with our prior). A model folder with a
//! `zone_gate.bin` adds the int8 model blended with the bilinear and joint bilateral zones by
//! that gate (`depthor_core::zone_gate`).

use depthor_core::calibration::CameraIntrinsics;
use depthor_core::metrics::{Metrics, MetricsAccumulator};
use depthor_core::projection::{for_each_point, ProjectedPoint, ProjectionError};
use image::RgbImage;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::baselines::{self, SparseFrame};
use crate::dataset::{dtof_frame, dtof_meta, resample_frame, scene_config_for, synth_frame};
use crate::inference::{InferenceError, Int8Model};
use crate::models::ModelFiles;
use crate::plot::PlotError;
use crate::recording::{CalibrationData, Recording, RecordingError};
use crate::reference::prior::{fit_scale_shift, PriorReference};
use crate::reference::{FloatReference, ReferenceError};
use crate::sim::{preset, simulate, SimConfig, SimError, SimOutput};
use crate::viz::{depth_image, draw_points, Overlay};

pub mod grid;
pub mod output;

/// Why frames could not be made, a model not loaded or run, or a figure not written. The
/// wrapped errors keep their own message and source chain.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// The simulator or its preset.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Reading a recording.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// Projecting the zones.
    #[error(transparent)]
    Projection(#[from] ProjectionError),
    /// Loading or running the int8 model.
    #[error(transparent)]
    Inference(#[from] InferenceError),
    /// Loading or running the float network or the prior.
    #[error(transparent)]
    Reference(#[from] ReferenceError),
    /// Drawing a figure.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// A prediction and its reference differ in size.
    #[error("metrics: {0}")]
    Metrics(depthor_core::metrics::MetricsError),
    /// A rendered scene's RGB does not have `width × height` pixels.
    #[error("scene size")]
    SceneSize,
    /// The model's zone gate file could not be read.
    #[error("zone gate {path}: {source}")]
    ZoneGateRead {
        /// The gate file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The model's zone gate file is malformed, or refused a frame.
    #[error("zone gate {path}: {detail:?}")]
    ZoneGate {
        /// The gate file.
        path: String,
        /// What the core's parser or run said.
        detail: depthor_core::zone_gate::GateError,
    },
    /// The float network was asked of the embedded `mcu` model, which has none.
    #[error(
        "model mcu: no models/mcu folder found (looked in {looked}); the embedded int8 blob has \
         no float network: pass --no-float, or --models-dir DIR (or DEPTHOR_MODELS) with mcu/"
    )]
    NoFloat {
        /// The model folders searched, comma-separated.
        looked: String,
    },
    /// An image could not be written.
    #[error("{}: cannot write", path.display())]
    WriteImage {
        /// The file.
        path: PathBuf,
        /// Why.
        source: image::ImageError,
    },
    /// A text file could not be written.
    #[error("{}: cannot write", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

type Result<T, E = EvalError> = std::result::Result<T, E>;

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
    /// The reference at the dataset's own resolution, over the region the model's input was
    /// cropped from (recordings only; `depthor eval --native` scores on it).
    pub native: Option<NativeReference>,
}

/// A frame's reference depth at the recording's resolution, cropped to the model's aspect ratio
/// exactly as the model's input was (centred crop, [`crate::dataset::resample_frame`]).
#[derive(Clone, Debug)]
pub struct NativeReference {
    /// Crop width, pixels of the recording.
    pub width: u32,
    /// Crop height.
    pub height: u32,
    /// Reference depth over the crop, metres (0 = none), row-major.
    pub depth_m: Vec<f32>,
}

/// Bilinear upsampling (or downsampling) of a `w × h` depth map to `out_w × out_h`, pixel
/// centres aligned (`x_src = (x + 0.5) · w / out_w − 0.5`, clamped at the borders).
pub fn resize_bilinear(src: &[f32], w: u32, h: u32, out_w: u32, out_h: u32) -> Vec<f32> {
    let (w, h) = (w as usize, h as usize);
    let coord = |i: u32, n_out: u32, n: usize| -> (usize, usize, f32) {
        let x = ((i as f32 + 0.5) * n as f32 / n_out as f32 - 0.5).clamp(0.0, (n - 1) as f32);
        let x0 = x.floor() as usize;
        (x0, (x0 + 1).min(n - 1), x - x0 as f32)
    };
    let mut out = Vec::with_capacity(out_w as usize * out_h as usize);
    for y in 0..out_h {
        let (y0, y1, fy) = coord(y, out_h, h);
        for x in 0..out_w {
            let (x0, x1, fx) = coord(x, out_w, w);
            let top = src[y0 * w + x0] * (1.0 - fx) + src[y0 * w + x1] * fx;
            let bottom = src[y1 * w + x0] * (1.0 - fx) + src[y1 * w + x1] * fx;
            out.push(top * (1.0 - fy) + bottom * fy);
        }
    }
    out
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
    let cal = CalibrationData::new(camera, &meta, None);
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
    let rgb = RgbImage::from_raw(width, height, f.scene.rgb.clone()).ok_or(EvalError::SceneSize)?;
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
        native: None,
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

    /// Whether the frames have colour images (`false` for zone-only recordings).
    pub fn has_rgb(&self) -> bool {
        self.rec.meta().rgb
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
    /// reference depth (seed `i`) when it has no dToF.
    pub fn frame(&self, i: usize, width: u32, height: u32) -> Result<EvalFrame> {
        let src = self.source(i, width, height)?;
        let meta = self.rec.meta().dtof.as_ref();
        let (Some(d), Some(cal), Some(meta)) = (&src.dtof, self.rec.calibration(i), meta) else {
            return src.simulated(&self.cfg, i as u64);
        };
        let (w, h) = (width, height);
        let (cam, r) = (&src.camera, &src.resampled);
        let (sx, sy) = (r.camera.fx / cam.fx, r.camera.fy / cam.fy);
        let mut points = Vec::new();
        for_each_point(&cal.as_core(), &d.view(meta), |p| {
            let u = (p.u - cam.cx) * sx + r.camera.cx;
            let v = (p.v - cam.cy) * sy + r.camera.cy;
            let (x, y) = ((u + 0.5).floor(), (v + 0.5).floor());
            if x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32 {
                points.push(ProjectedPoint {
                    u,
                    v,
                    x: x as u32,
                    y: y as u32,
                    ..p
                });
            }
        })?;
        Ok(src.into_eval_frame(points, meta.rows, meta.cols))
    }

    /// Frame `i` resampled to `width × height`, before any zones: what
    /// [`SourceFrame::simulated`] puts simulated zones on (the evaluation grid simulates every
    /// condition on the same source frame).
    pub fn source(&self, i: usize, width: u32, height: u32) -> Result<SourceFrame> {
        let (w, h) = (width, height);
        let frame = self.rec.read_frame(i)?;
        let cam = self.rec.camera(i);
        let depth = frame
            .depth_m
            .clone()
            .unwrap_or_else(|| vec![0.0; (cam.width * cam.height) as usize]);
        let resampled = resample_frame(&cam, &frame.rgb, &depth, frame.labels.as_deref(), w, h);
        let native = frame.depth_m.as_ref().map(|d| {
            let (x0, y0, cw, ch) = crate::dataset::centre_crop(cam.width, cam.height, w, h);
            let depth_m = (y0..y0 + ch)
                .flat_map(|y| (x0..x0 + cw).map(move |x| (y * cam.width + x) as usize))
                .map(|i| d.get(i).copied().unwrap_or(0.0))
                .collect();
            NativeReference {
                width: cw,
                height: ch,
                depth_m,
            }
        });
        Ok(SourceFrame {
            id: frame.id,
            camera: cam,
            resampled,
            native,
            dtof: frame.dtof,
        })
    }
}

/// A recording's frame at a model's size, before its zones are projected or simulated.
#[derive(Clone, Debug)]
pub struct SourceFrame {
    /// Frame id.
    pub id: String,
    /// The recording's camera for this frame (its own resolution).
    pub camera: CameraIntrinsics,
    /// RGB, reference depth and labels at the model's size, with the camera at that size.
    pub resampled: crate::dataset::Resampled,
    /// The reference at the recording's resolution over the crop (see [`NativeReference`]).
    pub native: Option<NativeReference>,
    /// The recording's own zones, if it has them.
    pub dtof: Option<crate::recording::DtofFrame>,
}

impl SourceFrame {
    /// The frame with zones simulated by `cfg` (frame seed `seed`) on its resampled reference
    /// depth, labels and RGB; the recording's own zones, if any, are not used.
    pub fn simulated(&self, cfg: &SimConfig, seed: u64) -> Result<EvalFrame> {
        let r = &self.resampled;
        let sim = simulate(cfg, &r.sim_input(), seed)?;
        let points = sim_points(cfg, &sim, &r.camera)?;
        Ok(self
            .clone()
            .into_eval_frame(points, cfg.grid.rows, cfg.grid.cols))
    }

    fn into_eval_frame(self, points: Vec<ProjectedPoint>, rows: u16, cols: u16) -> EvalFrame {
        EvalFrame {
            id: self.id,
            rgb: self.resampled.rgb,
            reference_m: self.resampled.depth_m,
            points,
            rows,
            cols,
            native: self.native,
        }
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
    /// The int8 model, the joint bilateral and the bilinear zones blended by the model's
    /// learned zone gate (core).
    Gate,
}

impl Method {
    /// Every method, models first.
    pub const ALL: [Method; 7] = [
        Method::Int8,
        Method::Gate,
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
            Method::Gate => "int8_gate",
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
            Method::Gate => "int8 + zone gate (core)",
        }
    }

    /// Whether this is a baseline (not the model itself).
    pub fn is_baseline(self) -> bool {
        !matches!(self, Method::Int8 | Method::Float | Method::Gate)
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
    gate: Option<LoadedGate>,
    depth_range_m: (f32, f32),
}

/// A zone gate file's bytes (checked by the core's parser when loaded) and its path.
struct LoadedGate {
    path: PathBuf,
    bytes: Vec<u8>,
}

impl LoadedGate {
    fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| EvalError::ZoneGateRead {
            path: path.display().to_string(),
            source: e,
        })?;
        let gate = LoadedGate {
            path: path.to_path_buf(),
            bytes,
        };
        gate.parse()?;
        Ok(gate)
    }

    fn error(&self, detail: depthor_core::zone_gate::GateError) -> EvalError {
        EvalError::ZoneGate {
            path: self.path.display().to_string(),
            detail,
        }
    }

    fn parse(&self) -> Result<depthor_core::zone_gate::ZoneGate<'_>> {
        depthor_core::zone_gate::ZoneGate::parse(&self.bytes).map_err(|e| self.error(e))
    }

    /// The blend of `[net, joint bilateral, bilinear]` on a `width × height` frame.
    fn run(
        &self,
        candidates: [&[f32]; 3],
        rgb: &[u8],
        width: usize,
        height: usize,
    ) -> Result<Vec<f32>> {
        let gate = self.parse()?;
        let mut scratch = vec![0.0f32; gate.scratch_floats(width, height)];
        let mut out = vec![0.0f32; width * height];
        gate.run(candidates, rgb, (width, height), &mut scratch, &mut out)
            .map_err(|e| self.error(e))?;
        Ok(out)
    }
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
            gate: None,
            depth_range_m,
        }
    }

    /// Adds the zone gate at `path` (its method then runs on every frame).
    pub fn with_zone_gate(mut self, path: &Path) -> Result<Self> {
        self.gate = Some(LoadedGate::load(path)?);
        Ok(self)
    }

    /// Loads a model's int8 blob and, when `with_float`, its float network and prior (tract).
    pub fn load(files: &ModelFiles, with_float: bool, depth_range_m: (f32, f32)) -> Result<Self> {
        if files.embedded && with_float {
            return Err(EvalError::NoFloat {
                looked: crate::models::search_dirs()
                    .iter()
                    .map(|d| d.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
        // A resolved embedded model always has its blob; otherwise the path names the problem.
        let embedded = files.embedded.then(|| Int8Model::embedded(&files.variant));
        let int8 = match embedded.flatten() {
            Some(m) => m?,
            None => Int8Model::from_file(&files.blob(), None)?,
        };
        let (h, w) = int8.input_shape();
        let float = if with_float {
            Some((
                FloatReference::load(&files.nnef(), h as u32, w as u32)?,
                PriorReference::load(&files.prior_nnef(), h as u32, w as u32)?,
            ))
        } else {
            None
        };
        let eval = Self::new(int8, float, depth_range_m);
        let gate = files.zone_gate();
        if !files.embedded && gate.is_file() {
            return eval.with_zone_gate(&gate);
        }
        Ok(eval)
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
            .filter(|m| *m != Method::Gate || self.gate.is_some())
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
        if let Some(gate) = &self.gate {
            let get = |m: Method| out.iter().find(|p: &&Prediction| p.method == m);
            let (net, jbu, bil) = (
                get(Method::Int8),
                get(Method::JointBilateral),
                get(Method::Bilinear),
            );
            if let (Some(net), Some(jbu), Some(bil)) = (net, jbu, bil) {
                let t = Instant::now();
                let depth_m = gate.run(
                    [&net.depth_m, &jbu.depth_m, &bil.depth_m],
                    rgb,
                    frame.width() as usize,
                    frame.height() as usize,
                )?;
                // The gate's time includes the two interpolations it reads.
                let seconds = t.elapsed().as_secs_f64() + jbu.seconds + bil.seconds;
                out.insert(
                    1,
                    Prediction {
                        method: Method::Gate,
                        depth_m,
                        seconds,
                    },
                );
            }
        }
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
    let w = rows
        .iter()
        .map(|(name, _)| name.chars().count())
        .max()
        .unwrap_or(0)
        .max(20);
    let mut t = format!(
        "{:<w$} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}\n",
        "method", "δ1", "δ2", "δ3", "Rel", "RMSE", "log10", "EWMAE"
    );
    for (name, m) in rows {
        t += &format!(
            "{:<w$} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3}\n",
            name, m.delta1, m.delta2, m.delta3, m.abs_rel, m.rmse, m.log10, m.ewmae
        );
    }
    t
}

/// The comparison figure of one frame and the numbers behind it: RGB with the dToF points |
/// reference | `pred` (`label`) | `extra` (`extra_label`, if any: `depthor eval` gives the frame's
/// best baseline) on one Turbo depth scale from the 2nd to the 98th percentile of the reference,
/// with its colour bar in metres; then |pred − reference| (and |extra − reference|) on Viridis
/// from 0 to the larger of their 98th percentiles, one scale for both, with its bar. A legend
/// under the RGB says what the points are. The CSV has one row per panel:
/// `panel,colour_map,lo_m,hi_m,valid_pixels,median_m`.
pub fn comparison_mosaic(
    f: &EvalFrame,
    pred: (&str, &[f32]),
    extra: Option<(&str, &[f32])>,
) -> Result<(RgbImage, String)> {
    use crate::plot::{figure, robust_range, ColourMap, Panel};
    let (w, h) = (f.width(), f.height());
    let (lo, hi) = robust_range(&f.reference_m, 0.02, 0.98)
        .or_else(|| robust_range(pred.1, 0.02, 0.98))
        .unwrap_or((0.0, 1.0));
    let abs_err = |d: &[f32]| -> Vec<f32> {
        d.iter()
            .zip(&f.reference_m)
            .map(|(p, r)| if *r > 0.0 { (p - r).abs() } else { f32::NAN })
            .collect()
    };
    let shown: Vec<(&str, &[f32])> = std::iter::once(pred).chain(extra).collect();
    let errs: Vec<Vec<f32>> = shown.iter().map(|(_, d)| abs_err(d)).collect();
    let err_hi = errs
        .iter()
        .filter_map(|e| robust_range(e, 0.0, 0.98))
        .fold(0.01f32, |a, r| a.max(r.1));
    let overlay = Overlay {
        lo_m: lo,
        hi_m: hi,
        ..Overlay::auto(w, h, &f.points)
    };
    let depth = |d: &[f32]| depth_image(d, w, h, lo, hi);
    let legend = vec![
        (
            ColourMap::Turbo.at(0.5),
            "disc: a zone's point, coloured by its depth (depth bar)".to_string(),
        ),
        (
            image::Rgb([0, 0, 0]),
            "black in depth panels: no depth".to_string(),
        ),
    ];
    let mut panels = vec![
        Panel::new(
            format!("RGB + {}×{} dToF zones", f.rows, f.cols),
            draw_points(&f.rgb, &f.points, &overlay),
        )
        .with_legend(legend),
        Panel::new("reference depth", depth(&f.reference_m)),
    ];
    for (label, d) in &shown {
        panels.push(Panel::new(*label, depth(d)));
    }
    if let Some(last) = panels.last_mut() {
        *last = last
            .clone()
            .with_bar(ColourMap::Turbo, lo, hi, "depth (m), black = none");
    }
    for ((label, _), err) in shown.iter().zip(&errs) {
        let err_img = RgbImage::from_fn(w, h, |x, y| {
            let e = err[(y * w + x) as usize];
            if e.is_finite() {
                ColourMap::Viridis.of(e, 0.0, err_hi)
            } else {
                image::Rgb([255, 255, 255])
            }
        });
        let name = label.split(" (").next().unwrap_or(label);
        panels.push(Panel::new(format!("|{name} − reference|"), err_img));
    }
    if let Some(last) = panels.last_mut() {
        *last = last.clone().with_bar(
            ColourMap::Viridis,
            0.0,
            err_hi,
            "abs. error (m), white = no ref.",
        );
    }
    let img = figure(&format!("frame {} ({w}×{h})", f.id), &panels, 240)?;
    let median = |d: &[f32]| {
        let mut v: Vec<f32> = d
            .iter()
            .copied()
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect();
        v.sort_by(f32::total_cmp);
        (v.len(), v.get(v.len() / 2).copied().unwrap_or(f32::NAN))
    };
    let mut csv = String::from("panel,colour_map,lo_m,hi_m,valid_pixels,median_m\n");
    let mut row = |name: &str, map: &str, lo: f32, hi: f32, d: &[f32]| {
        let (n, m) = median(d);
        csv += &format!("{name},{map},{lo:.4},{hi:.4},{n},{m:.4}\n");
    };
    row("reference", "turbo", lo, hi, &f.reference_m);
    for (label, d) in &shown {
        row(label, "turbo", lo, hi, d);
    }
    for (i, err) in errs.iter().enumerate() {
        let name = if i == 0 {
            "abs_error"
        } else {
            "abs_error_extra"
        };
        row(name, "viridis", 0.0, err_hi, err);
    }
    Ok((img, csv))
}

/// Writes [`comparison_mosaic`]'s picture at `path` and its CSV beside it.
pub fn write_mosaic(
    path: &Path,
    f: &EvalFrame,
    pred: (&str, &[f32]),
    extra: Option<(&str, &[f32])>,
) -> Result<()> {
    let (img, csv) = comparison_mosaic(f, pred, extra)?;
    img.save(path).map_err(|source| EvalError::WriteImage {
        path: path.to_path_buf(),
        source,
    })?;
    let csv_path = path.with_extension("csv");
    std::fs::write(&csv_path, csv).map_err(|source| EvalError::Write {
        path: csv_path,
        source,
    })
}

/// How metrics over several frames are combined (docs/eval.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Aggregate {
    /// Each metric computed per image, then averaged over the images that have valid pixels
    /// (the published protocol, and the training code's `metrics()`).
    Image,
    /// Every valid pixel of every frame pooled into one set, then each metric computed once.
    Pixel,
}

impl Aggregate {
    /// `image` or `pixel`, as written in outputs.
    pub fn key(self) -> &'static str {
        match self {
            Aggregate::Image => "image",
            Aggregate::Pixel => "pixel",
        }
    }

    /// One line for people saying how the figures were combined.
    pub fn describe(self) -> &'static str {
        match self {
            Aggregate::Image => "per-image mean (each metric per frame, then averaged over frames)",
            Aggregate::Pixel => "pooled pixels (every valid pixel of every frame counted once)",
        }
    }
}

/// One method's metrics over a set of frames, kept both ways so either aggregate can be asked.
#[derive(Clone, Debug)]
pub struct MetricsSet {
    pooled: MetricsAccumulator,
    images: Vec<Metrics>,
}

impl MetricsSet {
    /// An empty set; reference depths must be below `max_depth_m` to count.
    pub fn new(max_depth_m: f32) -> Self {
        MetricsSet {
            pooled: MetricsAccumulator::new(max_depth_m),
            images: Vec::new(),
        }
    }

    /// Adds one frame's accumulator (one image).
    pub fn add_image(&mut self, frame: &MetricsAccumulator) {
        self.pooled.merge(frame);
        self.images.push(frame.finish());
    }

    /// Adds every image of `other`.
    pub fn merge(&mut self, other: &MetricsSet) {
        self.pooled.merge(&other.pooled);
        self.images.extend_from_slice(&other.images);
    }

    /// The metrics, combined as `how` says. With [`Aggregate::Image`] each field is the mean
    /// over the images with valid pixels (EWMAE over those where it is defined); `count` and
    /// `invalid_pred` are totals either way.
    pub fn finish(&self, how: Aggregate) -> Metrics {
        let pooled = self.pooled.finish();
        if how == Aggregate::Pixel {
            return pooled;
        }
        let scored: Vec<&Metrics> = self.images.iter().filter(|m| m.count > 0).collect();
        let mean = |f: &dyn Fn(&Metrics) -> f64| {
            let v: Vec<f64> = scored
                .iter()
                .map(|m| f(m))
                .filter(|x| x.is_finite())
                .collect();
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        Metrics {
            count: pooled.count,
            delta1: mean(&|m| m.delta1),
            delta2: mean(&|m| m.delta2),
            delta3: mean(&|m| m.delta3),
            abs_rel: mean(&|m| m.abs_rel),
            rmse: mean(&|m| m.rmse),
            log10: mean(&|m| m.log10),
            mae: mean(&|m| m.mae),
            ewmae: mean(&|m| m.ewmae),
            invalid_pred: pooled.invalid_pred,
        }
    }

    /// Images added.
    pub fn images(&self) -> usize {
        self.images.len()
    }
}

#[cfg(test)]
mod aggregate_tests {
    use super::*;

    #[test]
    fn image_mean_weights_frames_equally_and_pixel_pool_weights_pixels() {
        // Frame A: 1 pixel off by 1 m; frame B: 3 exact pixels.
        let mut a = MetricsAccumulator::new(10.0);
        a.add_map(&[3.0], &[2.0], 1, 1).unwrap();
        let mut b = MetricsAccumulator::new(10.0);
        b.add_map(&[2.0; 3], &[2.0; 3], 3, 1).unwrap();
        let mut set = MetricsSet::new(10.0);
        set.add_image(&a);
        set.add_image(&b);
        let img = set.finish(Aggregate::Image);
        let pix = set.finish(Aggregate::Pixel);
        assert!((img.rmse - 0.5).abs() < 1e-12, "{img:?}"); // (1 + 0) / 2
        assert!((pix.rmse - 0.5).abs() < 1e-12, "{pix:?}"); // sqrt(1 / 4)
        assert!((img.mae - 0.5).abs() < 1e-12); // (1 + 0) / 2
        assert!((pix.mae - 0.25).abs() < 1e-12); // 1 / 4
        assert_eq!((img.count, pix.count), (4, 4));
    }

    #[test]
    fn bilinear_resize_keeps_constants_and_aligns_centres() {
        assert_eq!(resize_bilinear(&[2.0; 4], 2, 2, 5, 3), vec![2.0; 15]);
        // 2 → 4 columns: centres at −0.25, 0.25, 0.75, 1.25 of the source, clamped.
        let up = resize_bilinear(&[0.0, 1.0], 2, 1, 4, 1);
        assert_eq!(up, vec![0.0, 0.25, 0.75, 1.0]);
    }
}
