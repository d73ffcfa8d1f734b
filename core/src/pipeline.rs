//! One frame end to end on caller buffers: camera and dToF through the [`crate::hal`] traits →
//! [`crate::projection`] → the int8 [`Engine`] → depth in metres or millimetres.
//!
//! ```
//! use depthor_core::calibration::Calibration;
//! use depthor_core::engine::Engine;
//! use depthor_core::hal::{DtofSensor, RgbCamera, ZoneFrame};
//! use depthor_core::pipeline::{depth_frame, DepthOut, FrameBuffers, FrameError};
//!
//! /// Per frame on a board: 64 zones, 120×160 RGB, depth out in millimetres.
//! fn frame(
//!     camera: &mut impl RgbCamera,
//!     sensor: &mut impl DtofSensor,
//!     cal: &Calibration,
//!     engine: &mut Engine,
//!     rgb: &mut [u8; 120 * 160 * 3],
//!     sparse_m: &mut [f32; 120 * 160],
//!     zones: &mut ZoneFrame<64>,
//!     depth_mm: &mut [u16; 120 * 160],
//! ) -> Result<(), FrameError> {
//!     let mut buffers = FrameBuffers { rgb, sparse_m, zones };
//!     depth_frame(camera, sensor, cal, engine, &mut buffers, DepthOut::Millimetres(depth_mm))?;
//!     Ok(())
//! }
//! ```
//!
//! The engine is built once, outside the loop, with [`Engine::new`] from a blob in flash and an
//! arena of [`crate::engine::required_arena_bytes`] bytes. Buffers per frame: `3·H·W` bytes of
//! RGB, `4·H·W` bytes of sparse depth, a [`ZoneFrame<N>`] (`17·N + 8` bytes) and the output.

use crate::calibration::Calibration;
use crate::engine::{self, Engine, RunStats};
use crate::hal::{DtofSensor, Error as _, ErrorKind, RgbCamera, RgbFrame, ZoneFrame};
use crate::projection::{project_to_sparse, ProjectionError, ProjectionStats};

/// Where [`depth_frame`] writes the dense depth (`H×W`).
#[derive(Debug)]
pub enum DepthOut<'o> {
    /// Metres.
    Metres(&'o mut [f32]),
    /// Millimetres, rounded and clamped to `0..=65535`.
    Millimetres(&'o mut [u16]),
}

impl DepthOut<'_> {
    /// Pixels the buffer holds.
    fn len(&self) -> usize {
        match self {
            DepthOut::Metres(o) => o.len(),
            DepthOut::Millimetres(o) => o.len(),
        }
    }

    /// Writes `depth_m` (metres) into the buffer's first `depth_m.len()` pixels.
    fn put(&mut self, depth_m: &[f32]) {
        match self {
            DepthOut::Metres(o) => {
                for (o, &m) in o.iter_mut().zip(depth_m) {
                    *o = m;
                }
            }
            DepthOut::Millimetres(o) => {
                for (o, &m) in o.iter_mut().zip(depth_m) {
                    *o = metres_to_mm(m);
                }
            }
        }
    }
}

/// Metres to millimetres as [`DepthOut::Millimetres`] writes them: `m · 1000 + 0.5` truncated,
/// clamped to `0..=65535` (NaN and negative values give 0).
pub fn metres_to_mm(m: f32) -> u16 {
    let mm = m * 1000.0 + 0.5;
    if mm >= 65535.0 {
        u16::MAX
    } else if mm >= 0.0 {
        mm as u16
    } else {
        0
    }
}

/// The caller's buffers for one frame; each may be longer than the frame needs.
#[derive(Debug)]
pub struct FrameBuffers<'b, const N: usize> {
    /// RGB888, at least `3·H·W` bytes (`H×W` = the calibration's camera size).
    pub rgb: &'b mut [u8],
    /// Sparse depth `S`, metres, at least `H·W` values; the engine's dense output in metres
    /// after [`depth_frame`] ([`Engine::run_in_place`]), before it is written to the output.
    pub sparse_m: &'b mut [f32],
    /// The zone frame the sensor fills.
    pub zones: &'b mut ZoneFrame<N>,
}

/// Why a frame failed; nothing is written to the output after a failure before the model ran.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum FrameError {
    /// The camera failed (its error's kind).
    Camera(ErrorKind),
    /// The dToF sensor failed (its error's kind).
    Sensor(ErrorKind),
    /// A buffer is shorter than the frame needs.
    Buffer(&'static str),
    /// The calibration or the zones cannot be projected.
    Projection(ProjectionError),
    /// The engine refused the inputs (e.g. prepared for another size) or failed.
    Engine(engine::Error),
    /// No zone of the frame could be used (no target, an invalid status or a bad distance on
    /// every zone, e.g. a covered sensor): there is no metric depth to complete, so the model
    /// is not run and the output is untouched.
    NoValidZones {
        /// Zones the sensor reported.
        zones: u32,
    },
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::Camera(k) => write!(f, "camera: {k}"),
            FrameError::Sensor(k) => write!(f, "dToF sensor: {k}"),
            FrameError::Buffer(what) => write!(f, "{what} is too small for the frame"),
            FrameError::Projection(e) => write!(f, "projection: {e}"),
            FrameError::Engine(e) => write!(f, "model: {e}"),
            FrameError::NoValidZones { zones } => {
                write!(f, "dToF sensor: none of the {zones} zones is valid")
            }
        }
    }
}

impl From<engine::Error> for FrameError {
    fn from(e: engine::Error) -> Self {
        FrameError::Engine(e)
    }
}

/// What one frame did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameReport {
    /// Zones projected and skipped.
    pub projection: ProjectionStats,
    /// Ops and MACs the model ran.
    pub run: RunStats,
}

/// The stages of [`depth_frame`], in order, as reported to a [`Probe`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// RGB capture through the camera HAL.
    Camera,
    /// Zone read through the dToF sensor HAL.
    Dtof,
    /// Zones → sparse depth.
    Projection,
    /// The int8 model: RGB + sparse depth → dense depth.
    Model,
    /// The frame is done (no stage runs after this mark).
    Done,
}

impl Stage {
    /// Short lowercase name (`camera`, `dtof`, `projection`, `model`, `done`).
    pub fn name(self) -> &'static str {
        match self {
            Stage::Camera => "camera",
            Stage::Dtof => "dtof",
            Stage::Projection => "projection",
            Stage::Model => "model",
            Stage::Done => "done",
        }
    }
}

/// Observes stage boundaries inside [`depth_frame_probed`] (a firmware reads its cycle or
/// instruction counter here); `()` observes nothing.
pub trait Probe {
    /// Called as `stage` begins ([`Stage::Done`]: after the last one ended).
    fn mark(&mut self, stage: Stage);
}

impl Probe for () {
    fn mark(&mut self, _stage: Stage) {}
}

/// [`depth_frame_probed`] for an engine built with [`crate::engine::Io::Arena`]: the camera
/// captures into the engine's RGB staging area and the zones are projected into its sparse one
/// ([`Engine::staging`]), so the caller holds no frame buffer, only `zones`; the dense depth is
/// left in the engine ([`Engine::output_m`], or in millimetres [`Engine::output_mm`]) until the
/// next frame. The same bits as [`depth_frame`].
pub fn depth_frame_staged<C: RgbCamera, S: DtofSensor, const N: usize>(
    camera: &mut C,
    sensor: &mut S,
    cal: &Calibration,
    engine: &mut Engine<'_>,
    zones: &mut ZoneFrame<N>,
    probe: &mut impl Probe,
) -> Result<FrameReport, FrameError> {
    let (w, h) = (cal.camera.width, cal.camera.height);
    let pixels = (w as usize)
        .checked_mul(h as usize)
        .ok_or(FrameError::Buffer("camera size"))?;
    if engine.input_shape() != (h as usize, w as usize) {
        return Err(FrameError::Engine(engine::Error::ShapeMismatch {
            what: "engine input size",
            expected: pixels,
            found: engine.input_shape().0 * engine.input_shape().1,
        }));
    }
    probe.mark(Stage::Camera);
    if camera.resolution() != (w, h) {
        return Err(FrameError::Camera(ErrorKind::BufferShape));
    }
    let staging = engine.staging()?;
    camera
        .capture(&mut RgbFrame {
            width: w,
            height: h,
            data: staging.rgb,
        })
        .map_err(|e| FrameError::Camera(e.kind()))?;
    probe.mark(Stage::Dtof);
    read_zones(sensor, zones)?;
    probe.mark(Stage::Projection);
    let staging = engine.staging()?;
    let projection =
        project_to_sparse(cal, &zones.view(), staging.sparse_m).map_err(FrameError::Projection)?;
    if projection.projected == 0 {
        return Err(FrameError::NoValidZones {
            zones: projection.zones,
        });
    }
    probe.mark(Stage::Model);
    let run = engine.run_staged()?;
    probe.mark(Stage::Done);
    Ok(FrameReport { projection, run })
}

/// `sensor.read_frame(zones)`, out of line: a driver's buffers stay out of the frame of
/// [`depth_frame_staged`], under which the engine runs (a microcontroller's stack high-water).
#[inline(never)]
fn read_zones<S: DtofSensor, const N: usize>(
    sensor: &mut S,
    zones: &mut ZoneFrame<N>,
) -> Result<(), FrameError> {
    sensor
        .read_frame(zones)
        .map_err(|e| FrameError::Sensor(e.kind()))
}

/// Captures RGB, reads the zones, projects them and runs the model into `out` (`H×W`).
///
/// Faults are per frame: a camera of another resolution than the calibration's is
/// [`FrameError::Camera`]`(`[`ErrorKind::BufferShape`]`)` before it captures; a driver error is
/// [`FrameError::Camera`] or [`FrameError::Sensor`] with its kind (bus, timeout, …); a frame
/// without one usable zone is [`FrameError::NoValidZones`]. In every case `out` is untouched
/// and the next call starts afresh.
pub fn depth_frame<C: RgbCamera, S: DtofSensor, const N: usize>(
    camera: &mut C,
    sensor: &mut S,
    cal: &Calibration,
    engine: &mut Engine<'_>,
    buffers: &mut FrameBuffers<'_, N>,
    out: DepthOut<'_>,
) -> Result<FrameReport, FrameError> {
    depth_frame_probed(camera, sensor, cal, engine, buffers, out, &mut ())
}

/// [`depth_frame`], telling `probe` where each [`Stage`] begins.
pub fn depth_frame_probed<C: RgbCamera, S: DtofSensor, const N: usize>(
    camera: &mut C,
    sensor: &mut S,
    cal: &Calibration,
    engine: &mut Engine<'_>,
    buffers: &mut FrameBuffers<'_, N>,
    out: DepthOut<'_>,
    probe: &mut impl Probe,
) -> Result<FrameReport, FrameError> {
    let (w, h) = (cal.camera.width, cal.camera.height);
    let pixels = (w as usize)
        .checked_mul(h as usize)
        .ok_or(FrameError::Buffer("camera size"))?;
    probe.mark(Stage::Camera);
    let rgb = buffers
        .rgb
        .get_mut(..pixels.saturating_mul(3))
        .ok_or(FrameError::Buffer("RGB buffer"))?;
    if camera.resolution() != (w, h) {
        // A short (or long) frame would leave stale rows or overrun the calibration's size.
        return Err(FrameError::Camera(ErrorKind::BufferShape));
    }
    camera
        .capture(&mut RgbFrame {
            width: w,
            height: h,
            data: rgb,
        })
        .map_err(|e| FrameError::Camera(e.kind()))?;
    probe.mark(Stage::Dtof);
    sensor
        .read_frame(buffers.zones)
        .map_err(|e| FrameError::Sensor(e.kind()))?;
    probe.mark(Stage::Projection);
    let sparse = buffers
        .sparse_m
        .get_mut(..pixels)
        .ok_or(FrameError::Buffer("sparse depth buffer"))?;
    let projection =
        project_to_sparse(cal, &buffers.zones.view(), sparse).map_err(FrameError::Projection)?;
    if projection.projected == 0 {
        return Err(FrameError::NoValidZones {
            zones: projection.zones,
        });
    }
    probe.mark(Stage::Model);
    let rgb = buffers
        .rgb
        .get(..pixels.saturating_mul(3))
        .ok_or(FrameError::Buffer("RGB buffer"))?;
    if out.len() != pixels {
        let what = match out {
            DepthOut::Metres(_) => "out_depth_m",
            DepthOut::Millimetres(_) => "out_depth_mm",
        };
        return Err(FrameError::Engine(engine::Error::ShapeMismatch {
            what,
            expected: pixels,
            found: out.len(),
        }));
    }
    let run = engine.run_in_place(rgb, sparse)?;
    let mut out = out;
    out.put(sparse);
    probe.mark(Stage::Done);
    Ok(FrameReport { projection, run })
}
