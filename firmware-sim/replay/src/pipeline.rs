//! The per-frame firmware loop, shared verbatim by the QEMU firmware and its host build. Each
//! frame is one call of the core's [`depth_frame_probed`] (`depthor_core::pipeline`) over:
//!
//! 1. **RGB**: [`ReplayCamera`] (an [`depthor_core::hal::RgbCamera`]) fills the RGB buffer.
//! 2. **dToF**: by default ([`ReplayLoop::with_vl53l5cx`]) the frame's zones are given to a
//!    simulated VL53L5CX ([`SimVl53l5cx`], an embedded-hal I2C device speaking ST's ULD protocol)
//!    and read back by the real driver [`Vl53l5cx`] (an [`depthor_core::hal::DtofSensor`]):
//!    initialised once (stand-in firmware upload, 8×8 or 4×4, 15 Hz continuous, start) before
//!    the first frame, then one data-ready poll and one results read per frame, so the bytes
//!    cross the register protocol a board's bus would carry. [`SimBus`] counts the bytes and the
//!    clock ticks spent inside the simulation, so the driver's own cost can be told apart.
//!    [`ReplayLoop::new`] keeps the zone-bridge path ([`ZoneBridgeDevice`] read by
//!    [`ZoneBridgeSensor`]).
//! 3. **Projection**: `project_to_sparse` writes the sparse depth map `S`.
//! 4. **Model**: the int8 [`Engine`] (prepared once by the caller, see [`crate::model`]) runs on
//!    the RGB frame and `S` and writes the dense depth map into [`Workspace::depth_m`].
//!
//! [`FrameOutput`] hashes the depth output (FNV-1a 64 over the `f32` bits, little endian) and
//! formats the line both builds print, so the host and the firmware can be compared bit for bit.
//!
//! The bridge driver is created per frame over a device holding that frame (the device borrows
//! the frame's zones and the driver owns the device); it reads the header registers again each
//! frame, which costs one 11-byte transaction. The VL53L5CX sends distances as mm × 4 in an
//! `i16`, so distances beyond ±8191 mm saturate, and a zone with status 255 (no target) comes
//! back with distance 0. A frame without one valid zone is
//! [`LoopError::Frame`] (exit 17): the core does not run the model without metric depth.

use depthor_core::drivers::vl53l5cx::sim::{self, SimVl53l5cx, SimZone};
use depthor_core::drivers::vl53l5cx::{Config, RangingMode, Resolution, Vl53l5cx};
use depthor_core::drivers::zone_bridge::{DeviceError, ZoneBridgeDevice, ZoneBridgeSensor};
use depthor_core::engine::{self, Engine, RunStats};
use depthor_core::hal::Error as _;
use depthor_core::hal::{ErrorKind, ZoneFrame};
use depthor_core::pipeline::{depth_frame_staged, FrameError};
use depthor_core::projection::{ProjectionError, ProjectionStats};
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::{I2c, Operation};

use crate::camera::ReplayCamera;
use crate::format::Image;

/// Caller-provided buffers of the loop (in the firmware: statics). The frame-sized buffers (RGB,
/// sparse and dense depth) are not here: they live in the engine's arena
/// ([`depthor_core::engine::Io::Arena`], [`crate::model::prepare`]).
#[derive(Debug)]
pub struct Workspace<'b, const N: usize> {
    /// Staging for the zone bridge device (the bridge MCU's memory in a real system).
    pub bridge_mm: &'b mut [f32; N],
    /// The zone frame the driver fills.
    pub zones: &'b mut ZoneFrame<N>,
}

/// Why the loop stopped before the end of the image.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum LoopError {
    /// The replay camera failed.
    Camera(ErrorKind),
    /// The dToF driver failed (its error's kind).
    Sensor(ErrorKind),
    /// The simulated bridge refused the image's geometry.
    Device(DeviceError),
    /// The VL53L5CX has 4×4 or 8×8 zones; the image has another grid.
    DtofGrid {
        /// Zone rows of the image.
        rows: u16,
        /// Zone columns of the image.
        cols: u16,
    },
    /// The image has more zones per frame than the workspace holds.
    ZoneCapacity {
        /// Zones per frame of the image.
        zones: usize,
        /// Zones the workspace holds.
        capacity: usize,
    },
    /// The RGB or sparse buffer is smaller than the image needs.
    Workspace(&'static str),
    /// Projection refused the calibration or the zones.
    Projection(ProjectionError),
    /// The engine failed (or was prepared for another input size than the image's).
    Engine(engine::Error),
    /// The core's pipeline refused the frame otherwise: no zone of it is valid
    /// ([`FrameError::NoValidZones`]), so there is no metric depth to complete.
    Frame(FrameError),
}

impl From<FrameError> for LoopError {
    fn from(e: FrameError) -> Self {
        match e {
            FrameError::Camera(k) => LoopError::Camera(k),
            FrameError::Sensor(k) => LoopError::Sensor(k),
            FrameError::Buffer(what) => LoopError::Workspace(what),
            FrameError::Projection(e) => LoopError::Projection(e),
            FrameError::Engine(e) => LoopError::Engine(e),
            other => LoopError::Frame(other),
        }
    }
}

impl LoopError {
    /// The firmware's exit status for this error (see the crate doc's table).
    pub fn exit_code(&self) -> u8 {
        match self {
            LoopError::Camera(_) => 10,
            LoopError::Sensor(_) => 11,
            LoopError::Device(_) | LoopError::DtofGrid { .. } => 12,
            LoopError::ZoneCapacity { .. } => 13,
            LoopError::Workspace(_) => 14,
            LoopError::Projection(_) => 15,
            LoopError::Engine(_) => 16,
            LoopError::Frame(_) => 17,
        }
    }
}

impl core::fmt::Display for LoopError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LoopError::Camera(k) => write!(f, "replay camera: {k}"),
            LoopError::Sensor(k) => write!(f, "dToF driver: {k}"),
            LoopError::Device(e) => write!(f, "zone bridge device: {e}"),
            LoopError::DtofGrid { rows, cols } => {
                write!(
                    f,
                    "the VL53L5CX has 4x4 or 8x8 zones, the image {rows}x{cols}"
                )
            }
            LoopError::ZoneCapacity { zones, capacity } => write!(
                f,
                "the image has {zones} zones per frame, this build holds {capacity}"
            ),
            LoopError::Workspace(what) => write!(f, "workspace too small: {what}"),
            LoopError::Projection(e) => write!(f, "projection: {e}"),
            LoopError::Engine(e) => write!(f, "engine: {e}"),
            LoopError::Frame(e) => write!(f, "frame: {e}"),
        }
    }
}

impl core::error::Error for LoopError {}

pub use depthor_core::pipeline::{Probe, Stage};

/// What [`ReplayLoop::process`] did with one frame (the output is in the workspace).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Processed {
    /// Frame index in the image.
    pub index: u32,
    /// Output pixels (`H · W`) of [`Engine::output_m`].
    pub pixels: usize,
    /// Projection counters.
    pub stats: ProjectionStats,
    /// What the engine did (ops, MACs).
    pub run: RunStats,
}

/// One frame's printable result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameOutput {
    /// Frame index in the image.
    pub index: u32,
    /// FNV-1a 64 of the depth output's `f32` bits, little endian ([`fnv1a64_f32`]).
    pub hash: u64,
    /// Projection counters.
    pub stats: ProjectionStats,
}

impl FrameOutput {
    /// Hashes the depth output `processed` left in `depth_m` (the engine's
    /// [`Engine::output_m`]).
    pub fn new(processed: &Processed, depth_m: &[f32]) -> Self {
        let out = depth_m.get(..processed.pixels).unwrap_or(depth_m);
        FrameOutput {
            index: processed.index,
            hash: fnv1a64_f32(out),
            stats: processed.stats,
        }
    }
}

impl core::fmt::Display for FrameOutput {
    /// `frame 3 depth_fnv1a64=0123456789abcdef points=52 skipped=12 collisions=0`: the line the
    /// firmware and the host print, compared bit for bit by the tests.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "frame {} depth_fnv1a64={:016x} points={} skipped={} collisions={}",
            self.index,
            self.hash,
            self.stats.projected,
            self.stats.skipped(),
            self.stats.collisions
        )
    }
}

/// FNV-1a 64 offset basis (Fowler–Noll–Vo, IETF draft-eastlake-fnv).
pub const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
/// FNV-1a 64 prime (same source).
pub const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a 64 over the little-endian bytes of each value's IEEE-754 bits (so `-0.0` and `0.0`,
/// or two NaN payloads, hash differently: this is a bit-exactness check).
pub fn fnv1a64_f32(values: &[f32]) -> u64 {
    let mut h = FNV_OFFSET;
    for v in values {
        for b in v.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(FNV_PRIME);
        }
    }
    h
}

/// Bytes the VL53L5CX path's I/O buffer needs (8×8 results, every ULD output).
pub const VL53_IO_BYTES: usize = 1440;

/// Traffic between the VL53L5CX driver and the simulated sensor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    /// I2C transactions.
    pub transactions: u32,
    /// Bytes written (register indices included).
    pub bytes_written: u32,
    /// Bytes read.
    pub bytes_read: u32,
    /// Clock ticks spent inside the simulated sensor (0 with a clock that reads 0).
    pub device_ticks: u64,
}

/// The simulated VL53L5CX behind a counter of bytes and of the clock ticks spent inside it.
#[derive(Debug)]
pub struct SimBus {
    dev: SimVl53l5cx,
    clock: fn() -> u64,
    stats: BusStats,
}

impl embedded_hal::i2c::ErrorType for SimBus {
    type Error = embedded_hal::i2c::ErrorKind;
}

impl I2c for SimBus {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        let s = &mut self.stats;
        s.transactions = s.transactions.wrapping_add(1);
        for op in operations.iter() {
            match op {
                Operation::Write(w) => {
                    s.bytes_written = s.bytes_written.wrapping_add(w.len() as u32)
                }
                Operation::Read(r) => s.bytes_read = s.bytes_read.wrapping_add(r.len() as u32),
            }
        }
        let t0 = (self.clock)();
        let r = self.dev.transaction(address, operations);
        self.stats.device_ticks += (self.clock)().wrapping_sub(t0);
        r
    }
}

/// The dToF path of the loop.
// One loop per run and no allocator to box into: the VL53L5CX variant's size is fine.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
enum Dtof<'a, D> {
    /// Zone bridge, a driver per frame.
    Bridge(D),
    /// VL53L5CX driver over the simulated sensor; `ready` once initialised and ranging.
    Vl53 {
        sensor: Vl53l5cx<'a, SimBus, D>,
        ready: bool,
    },
}

/// What the VL53L5CX path did: initialisation (once) and the last frame's read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Vl53Stats {
    /// Traffic of init, resolution, frequency, mode and start.
    pub init: BusStats,
    /// Clock ticks of the whole initialisation (driver and simulation).
    pub init_ticks: u64,
    /// Traffic of the last frame's `read_frame`.
    pub frame: BusStats,
}

/// One frame through the zone bridge: the simulated bridge device over the frame's zones, the
/// bridge driver over it, then the core's one-frame pipeline (camera → driver → projection →
/// engine). Out of line: the device and driver stay out of the frame loop's stack frame.
#[inline(never)]
fn bridge_frame<D: DelayNs, const N: usize>(
    (camera, delay): (&mut ReplayCamera<'_>, &mut D),
    (cal, staged, status): (&depthor_core::calibration::Calibration<'_>, &[f32], &[u8]),
    engine: &mut Engine<'_>,
    zone_frame: &mut ZoneFrame<N>,
    probe: &mut impl Probe,
) -> Result<Result<depthor_core::pipeline::FrameReport, FrameError>, LoopError> {
    let device = ZoneBridgeDevice::new(&cal.dtof, staged, status).map_err(LoopError::Device)?;
    let mut sensor = ZoneBridgeSensor::new(device, delay);
    Ok(depth_frame_staged(
        camera,
        &mut sensor,
        cal,
        engine,
        zone_frame,
        probe,
    ))
}

/// Initialises the VL53L5CX (firmware upload, configuration) and starts it ranging at 15 Hz.
/// Out of line: the driver's initialisation buffers stay out of the frame loop's stack frame,
/// under which the engine runs.
#[inline(never)]
fn start_vl53l5cx<D: DelayNs>(
    sensor: &mut Vl53l5cx<'_, SimBus, D>,
    resolution: Resolution,
) -> Result<(), LoopError> {
    let sensor_err =
        |e: depthor_core::drivers::vl53l5cx::Vl53l5cxError<_>| LoopError::Sensor(e.kind());
    sensor.init().map_err(sensor_err)?;
    sensor.set_resolution(resolution).map_err(sensor_err)?;
    sensor.set_ranging_frequency_hz(15).map_err(sensor_err)?;
    sensor
        .set_ranging_mode(RangingMode::Continuous)
        .map_err(sensor_err)?;
    sensor.start_ranging().map_err(sensor_err)?;
    Ok(())
}

/// The replay loop over one image; `D` is the delay the dToF driver sleeps with between polls.
#[derive(Debug)]
pub struct ReplayLoop<'a, D> {
    image: Image<'a>,
    camera: ReplayCamera<'a>,
    dtof: Dtof<'a, D>,
    clock: fn() -> u64,
    vl53: Vl53Stats,
    next: u32,
}

fn no_clock() -> u64 {
    0
}

impl<'a, D: DelayNs> ReplayLoop<'a, D> {
    /// A loop at the image's first frame reading zones through the zone bridge.
    pub fn new(image: Image<'a>, delay: D) -> Self {
        ReplayLoop {
            image,
            camera: ReplayCamera::new(image),
            dtof: Dtof::Bridge(delay),
            clock: no_clock,
            vl53: Vl53Stats::default(),
            next: 0,
        }
    }

    /// A loop at the image's first frame reading zones through the VL53L5CX driver over the
    /// simulated sensor (with the stand-in ST buffers); `io` is the driver's I/O buffer (at
    /// least [`VL53_IO_BYTES`]), `clock` a tick counter for [`BusStats::device_ticks`]. The
    /// sensor is initialised before the first frame.
    pub fn with_vl53l5cx(image: Image<'a>, delay: D, io: &'a mut [u8], clock: fn() -> u64) -> Self {
        let bus = SimBus {
            dev: SimVl53l5cx::new(),
            clock,
            stats: BusStats::default(),
        };
        let sensor = Vl53l5cx::new(bus, delay, sim::stand_in_buffers(), io, Config::default());
        ReplayLoop {
            image,
            camera: ReplayCamera::new(image),
            dtof: Dtof::Vl53 {
                sensor,
                ready: false,
            },
            clock,
            vl53: Vl53Stats::default(),
            next: 0,
        }
    }

    /// Index of the frame the next [`ReplayLoop::process`] reads.
    pub fn next_index(&self) -> u32 {
        self.next
    }

    /// The VL53L5CX path's figures (all zero on the bridge path or before the first frame).
    pub fn vl53_stats(&self) -> Vl53Stats {
        self.vl53
    }

    /// Reads the next frame's sensors into the engine's staging areas (RGB; zones projected
    /// into the sparse map) and runs `engine` (prepared for the image's size with
    /// [`crate::model::prepare`]); the dense depth is then [`Engine::output_m`]. `Ok(None)` after
    /// the last frame. This is the part of a frame the firmware times.
    ///
    /// A frame without one valid zone is [`LoopError::Frame`] (the model does not run); it is
    /// consumed, so a caller may go on with the next frame. Any other error leaves the loop at
    /// the frame that failed.
    pub fn process<const N: usize>(
        &mut self,
        engine: &mut Engine<'_>,
        ws: &mut Workspace<'_, N>,
    ) -> Result<Option<Processed>, LoopError> {
        self.process_probed(engine, ws, &mut ())
    }

    /// [`ReplayLoop::process`], telling `probe` where each stage begins.
    #[inline(never)]
    pub fn process_probed<const N: usize>(
        &mut self,
        engine: &mut Engine<'_>,
        ws: &mut Workspace<'_, N>,
        probe: &mut impl Probe,
    ) -> Result<Option<Processed>, LoopError> {
        let index = self.next;
        let Some(frame) = self.image.frame(index) else {
            return Ok(None);
        };
        let cal = self.image.calibration();
        let pixels = cal.camera.width as usize * cal.camera.height as usize;
        if engine.input_shape() != (cal.camera.height as usize, cal.camera.width as usize) {
            return Err(LoopError::Engine(engine::Error::ShapeMismatch {
                what: "engine input size",
                expected: pixels,
                found: engine.input_shape().0 * engine.input_shape().1,
            }));
        }

        let zones = frame.zones();
        let staged = ws
            .bridge_mm
            .get_mut(..zones)
            .ok_or(LoopError::ZoneCapacity { zones, capacity: N })?;
        let zone_frame = &mut *ws.zones;
        let report = match &mut self.dtof {
            Dtof::Bridge(delay) => {
                // The frame's zones are latched into the simulated bridge, which the real
                // driver reads.
                for (d, mm) in staged.iter_mut().zip(frame.distance_mm()) {
                    *d = f32::from(mm);
                }
                bridge_frame(
                    (&mut self.camera, delay),
                    (&cal, &*staged, frame.status),
                    engine,
                    zone_frame,
                    probe,
                )?
            }
            Dtof::Vl53 { sensor, ready } => {
                if !*ready {
                    let resolution = match (cal.dtof.rows, cal.dtof.cols) {
                        (4, 4) => Resolution::R4x4,
                        (8, 8) => Resolution::R8x8,
                        (rows, cols) => return Err(LoopError::DtofGrid { rows, cols }),
                    };
                    let t0 = (self.clock)();
                    start_vl53l5cx(sensor, resolution)?;
                    self.vl53.init_ticks = (self.clock)().wrapping_sub(t0);
                    self.vl53.init = core::mem::take(&mut sensor.i2c_mut().stats);
                    *ready = true;
                }
                // The frame's zones are what the simulated sensor measures next.
                let mut sim_zones = [SimZone::NONE; 64];
                for ((z, mm), &status) in sim_zones
                    .iter_mut()
                    .zip(frame.distance_mm())
                    .zip(frame.status)
                {
                    z.distance_mm = mm;
                    z.status = status;
                }
                sensor.i2c_mut().dev.set_zones(&sim_zones);
                sensor.i2c_mut().stats = BusStats::default();
                let report =
                    depth_frame_staged(&mut self.camera, sensor, &cal, engine, zone_frame, probe);
                self.vl53.frame = sensor.i2c().stats;
                report
            }
        }
        .map_err(|e| {
            let e = LoopError::from(e);
            // A frame the core refused (no valid zone) is consumed like a processed one: a
            // caller that goes on gets the next frame (the sensor has moved on too).
            if matches!(e, LoopError::Frame(_)) {
                self.next += 1;
            }
            e
        })?;
        self.next += 1;
        Ok(Some(Processed {
            index,
            pixels,
            stats: report.projection,
            run: report.run,
        }))
    }

    /// Runs every remaining frame, calling `emit` with each frame's output.
    pub fn run_all<const N: usize>(
        &mut self,
        engine: &mut Engine<'_>,
        ws: &mut Workspace<'_, N>,
        mut emit: impl FnMut(&FrameOutput),
    ) -> Result<u32, LoopError> {
        let mut frames = 0;
        while let Some(p) = self.process(engine, ws)? {
            emit(&FrameOutput::new(
                &p,
                engine.output_m().map_err(LoopError::Engine)?,
            ));
            frames += 1;
        }
        Ok(frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{prepare, ARENA_BUDGET_BYTES, MCU_BLOB};
    use crate::synthetic::{mcu_calibration, mcu_frames};
    use crate::writer::image_bytes;
    use core::mem::MaybeUninit;
    use depthor_core::engine::Memory;
    use depthor_core::projection::project_to_sparse;

    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }

    #[test]
    fn fnv1a64_known_values() {
        // Empty input is the offset basis. One 0.0 is four zero bytes: each step is h *= prime.
        assert_eq!(fnv1a64_f32(&[]), FNV_OFFSET);
        let mut h = FNV_OFFSET;
        for _ in 0..4 {
            h = h.wrapping_mul(FNV_PRIME);
        }
        assert_eq!(fnv1a64_f32(&[0.0]), h);
        // 1.0 = 0x3F800000 → bytes 00 00 80 3F; -0.0 differs from 0.0.
        assert_ne!(fnv1a64_f32(&[-0.0]), fnv1a64_f32(&[0.0]));
        // The published FNV-1a 64 of the one byte "a" is af63dc4c8601ec8c: checks the constants.
        let mut h = FNV_OFFSET ^ 0x61;
        h = h.wrapping_mul(FNV_PRIME);
        assert_eq!(h, 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn loop_projects_the_zones_the_image_holds() {
        let cal = mcu_calibration();
        let frames = mcu_frames(3);
        let bytes = image_bytes(&cal, &frames).unwrap();
        let image = Image::parse(&bytes).unwrap();
        let (mut bridge, mut zones) = ([0f32; 64], ZoneFrame::<64>::new());
        let mut ws = Workspace {
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut slot = MaybeUninit::uninit();
        let engine = prepare(&mut slot, MCU_BLOB, &mut arena, 120, 160).unwrap();
        let mut arena2 = vec![0u8; ARENA_BUDGET_BYTES];
        let budget = Memory::Budget(ARENA_BUDGET_BYTES);
        let mut direct_engine =
            Engine::with_memory(MCU_BLOB, &mut arena2, 120, 160, budget).unwrap();
        let mut replay = ReplayLoop::new(image, NoDelay);
        for (i, f) in frames.iter().enumerate() {
            let p = replay.process(engine, &mut ws).unwrap().unwrap();
            assert_eq!(p.index as usize, i);
            // The zones went through the bridge.
            let want: Vec<f32> = f.distance_mm.iter().map(|&d| f32::from(d)).collect();
            assert_eq!(ws.zones.view().distance_mm, &want[..]);
            assert_eq!(ws.zones.view().status, &f.status[..]);
            // Same as projecting the zones directly.
            let mut direct = vec![0f32; 19_200];
            let stats = project_to_sparse(&cal, &ws.zones.view(), &mut direct).unwrap();
            assert_eq!(p.stats, stats);
            // Synthetic frames: one 255, one status 4, one zero distance → 3 skipped.
            assert_eq!(stats.skipped(), 3);
            // The depth is the engine's on these inputs, and it is what the line hashes.
            let mut want_depth = vec![0f32; 19_200];
            let run = direct_engine.run(&f.rgb, &direct, &mut want_depth).unwrap();
            assert_eq!(p.run, run);
            assert!(run.macs > 0);
            // (The loop's engine took its RGB and sparse depth in its arena.)
            let out = engine.output_m().unwrap();
            assert_eq!(fnv1a64_f32(out), fnv1a64_f32(&want_depth));
            assert_eq!(FrameOutput::new(&p, out).hash, fnv1a64_f32(&want_depth));
        }
        assert_eq!(replay.process(engine, &mut ws).unwrap(), None);
    }

    #[test]
    fn vl53l5cx_path_reads_the_zones_through_the_uld_protocol() {
        let cal = mcu_calibration();
        let frames = mcu_frames(3);
        let bytes = image_bytes(&cal, &frames).unwrap();
        let image = Image::parse(&bytes).unwrap();
        let (mut bridge, mut zones) = ([0f32; 64], ZoneFrame::<64>::new());
        let mut ws = Workspace {
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut slot = MaybeUninit::uninit();
        let engine = prepare(&mut slot, MCU_BLOB, &mut arena, 120, 160).unwrap();
        let mut io = vec![0u8; VL53_IO_BYTES];
        let mut replay = ReplayLoop::with_vl53l5cx(image, NoDelay, &mut io, || 0);
        for f in &frames {
            replay.process(engine, &mut ws).unwrap().unwrap();
            // Zones with a target come through (mm × 4 in an i16: 12 m saturates at 8191 mm);
            // "no target" reads distance 0.
            let want: Vec<f32> = f
                .distance_mm
                .iter()
                .zip(&f.status)
                .map(|(&d, &s)| {
                    if s == 255 {
                        0.0
                    } else {
                        f32::from(d.min(8191))
                    }
                })
                .collect();
            assert_eq!(ws.zones.view().distance_mm, &want[..]);
            assert_eq!(ws.zones.view().status, &f.status[..]);
            let s = replay.vl53_stats();
            // One data-ready poll (2 + 4 bytes) and one results read (2 + 1440 bytes).
            assert_eq!(s.frame.transactions, 2);
            assert_eq!(s.frame.bytes_read, 4 + 1440);
            assert_eq!(s.frame.bytes_written, 4);
            assert!(s.init.bytes_written > 86_016, "{:?}", s.init);
        }
        assert_eq!(replay.process(engine, &mut ws).unwrap(), None);
    }

    #[test]
    fn vl53l5cx_path_refuses_grids_it_does_not_have() {
        let mut cal = mcu_calibration();
        cal.dtof.rows = 6;
        cal.dtof.cols = 6;
        let frames: Vec<_> = (0..1)
            .map(|i| crate::synthetic::frame(i, 6, 6, 120, 160))
            .collect();
        let bytes = image_bytes(&cal, &frames).unwrap();
        let image = Image::parse(&bytes).unwrap();
        let (mut bridge, mut zones) = ([0f32; 64], ZoneFrame::<64>::new());
        let mut ws = Workspace {
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut slot = MaybeUninit::uninit();
        let engine = prepare(&mut slot, MCU_BLOB, &mut arena, 120, 160).unwrap();
        let mut io = vec![0u8; VL53_IO_BYTES];
        let err = ReplayLoop::with_vl53l5cx(image, NoDelay, &mut io, || 0)
            .process(engine, &mut ws)
            .unwrap_err();
        assert_eq!(err, LoopError::DtofGrid { rows: 6, cols: 6 });
        assert_eq!(err.exit_code(), 12);
    }

    #[test]
    fn a_frame_without_valid_zones_is_refused_and_consumed() {
        let cal = mcu_calibration();
        let mut frames = mcu_frames(3);
        frames[1].status.fill(255);
        let bytes = image_bytes(&cal, &frames).unwrap();
        let image = Image::parse(&bytes).unwrap();
        let (mut bridge, mut zones) = ([0f32; 64], ZoneFrame::<64>::new());
        let mut ws = Workspace {
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut slot = MaybeUninit::uninit();
        let engine = prepare(&mut slot, MCU_BLOB, &mut arena, 120, 160).unwrap();
        let mut io = vec![0u8; VL53_IO_BYTES];
        let mut replay = ReplayLoop::with_vl53l5cx(image, NoDelay, &mut io, || 0);
        assert_eq!(replay.process(engine, &mut ws).unwrap().unwrap().index, 0);
        assert_eq!(replay.next_index(), 1);
        let err = replay.process(engine, &mut ws).unwrap_err();
        assert!(
            matches!(
                err,
                LoopError::Frame(FrameError::NoValidZones { zones: 64 })
            ),
            "{err:?}"
        );
        assert_eq!(err.exit_code(), 17);
        // The refused frame is consumed: the next call reads frame 2, then the image ends.
        assert_eq!(replay.next_index(), 2);
        assert_eq!(replay.process(engine, &mut ws).unwrap().unwrap().index, 2);
        assert_eq!(replay.process(engine, &mut ws).unwrap(), None);
    }

    #[test]
    fn small_workspace_is_an_error() {
        let bytes = image_bytes(&mcu_calibration(), &mcu_frames(1)).unwrap();
        let image = Image::parse(&bytes).unwrap();
        let (mut bridge, mut zones) = ([0f32; 16], ZoneFrame::<16>::new());
        let mut ws = Workspace {
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut slot = MaybeUninit::uninit();
        let engine = prepare(&mut slot, MCU_BLOB, &mut arena, 120, 160).unwrap();
        let err = ReplayLoop::new(image, NoDelay)
            .process(engine, &mut ws)
            .unwrap_err();
        assert_eq!(
            err,
            LoopError::ZoneCapacity {
                zones: 64,
                capacity: 16
            }
        );
        assert_eq!(err.exit_code(), 13);
    }
}

#[cfg(test)]
mod engine_size_tests {
    use super::*;
    use crate::model::{prepare, ARENA_BUDGET_BYTES, MCU_BLOB};
    use crate::synthetic::{mcu_calibration, mcu_frames};
    use crate::writer::image_bytes;
    use core::mem::MaybeUninit;

    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }

    #[test]
    fn engine_prepared_for_another_size_is_an_error() {
        let bytes = image_bytes(&mcu_calibration(), &mcu_frames(1)).unwrap();
        let image = Image::parse(&bytes).unwrap();
        let (mut bridge, mut zones) = ([0f32; 64], ZoneFrame::<64>::new());
        let mut ws = Workspace {
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut slot = MaybeUninit::uninit();
        let engine = prepare(&mut slot, MCU_BLOB, &mut arena, 64, 64).unwrap();
        let err = ReplayLoop::new(image, NoDelay)
            .process(engine, &mut ws)
            .unwrap_err();
        assert!(matches!(err, LoopError::Engine(_)), "{err:?}");
        assert_eq!(err.exit_code(), 16);
    }
}
