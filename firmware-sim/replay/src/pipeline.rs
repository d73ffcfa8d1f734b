//! The per-frame firmware loop, shared verbatim by the QEMU firmware and its host build. Each
//! frame is one call of the core's [`depth_frame_probed`] (`depthor_core::pipeline`) over:
//!
//! 1. **RGB**: [`ReplayCamera`] (an [`depthor_core::hal::RgbCamera`]) fills the RGB buffer.
//! 2. **dToF**: the frame's zones are latched into a simulated zone bridge
//!    ([`ZoneBridgeDevice`], an embedded-hal I2C device) and read back by the real driver
//!    [`ZoneBridgeSensor`] (an [`depthor_core::hal::DtofSensor`]), so the bytes cross the same
//!    register protocol a board's bus would carry.
//! 3. **Projection**: `project_to_sparse` writes the sparse depth map `S`.
//! 4. **Model**: the int8 [`Engine`] (prepared once by the caller, see [`crate::model`]) runs on
//!    the RGB frame and `S` and writes the dense depth map into [`Workspace::depth_m`].
//!
//! [`FrameOutput`] hashes the depth output (FNV-1a 64 over the `f32` bits, little endian) and
//! formats the line both builds print, so the host and the firmware can be compared bit for bit.
//!
//! The driver is created per frame over a device holding that frame (the device borrows the
//! frame's zones and the driver owns the device); it reads the header registers again each
//! frame, which costs one 11-byte transaction. A frame without one valid zone is
//! [`LoopError::Frame`] (exit 17): the core does not run the model without metric depth.

use depthor_core::drivers::zone_bridge::{DeviceError, ZoneBridgeDevice, ZoneBridgeSensor};
use depthor_core::engine::{self, Engine, RunStats};
use depthor_core::hal::{ErrorKind, ZoneFrame};
use depthor_core::pipeline::{depth_frame_probed, DepthOut, FrameBuffers, FrameError};
use depthor_core::projection::{ProjectionError, ProjectionStats};
use embedded_hal::delay::DelayNs;

use crate::camera::ReplayCamera;
use crate::format::Image;

/// Caller-provided buffers of the loop (in the firmware: statics). Each may be larger than the
/// image needs; the loop uses the leading part.
#[derive(Debug)]
pub struct Workspace<'b, const N: usize> {
    /// RGB888 frame, at least `3 · H · W` bytes.
    pub rgb: &'b mut [u8],
    /// Sparse depth `S` in metres, at least `H · W` values; it holds the dense depth after a
    /// frame (the engine runs in place on it).
    pub sparse_m: &'b mut [f32],
    /// Dense depth the model writes, in metres, at least `H · W` values.
    pub depth_m: &'b mut [f32],
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
            LoopError::Device(_) => 12,
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
    /// Output pixels (`H · W`) at the start of [`Workspace::depth_m`].
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
    /// Hashes the depth output `processed` left in `depth_m` ([`Workspace::depth_m`]).
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

/// The replay loop over one image; `D` is the delay the dToF driver sleeps with between polls.
#[derive(Debug)]
pub struct ReplayLoop<'a, D> {
    image: Image<'a>,
    camera: ReplayCamera<'a>,
    delay: D,
    next: u32,
}

impl<'a, D: DelayNs> ReplayLoop<'a, D> {
    /// A loop at the image's first frame.
    pub fn new(image: Image<'a>, delay: D) -> Self {
        ReplayLoop {
            image,
            camera: ReplayCamera::new(image),
            delay,
            next: 0,
        }
    }

    /// Reads the next frame's sensors, projects its zones into `ws.sparse_m` and runs `engine`
    /// (prepared for the image's size) into `ws.depth_m`; `Ok(None)` after the last frame. This
    /// is the part of a frame the firmware times.
    pub fn process<const N: usize>(
        &mut self,
        engine: &mut Engine<'_>,
        ws: &mut Workspace<'_, N>,
    ) -> Result<Option<Processed>, LoopError> {
        self.process_probed(engine, ws, &mut ())
    }

    /// [`ReplayLoop::process`], telling `probe` where each stage begins.
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

        // The frame's zones are latched into the simulated bridge, which the real driver reads.
        let zones = frame.zones();
        let staged = ws
            .bridge_mm
            .get_mut(..zones)
            .ok_or(LoopError::ZoneCapacity { zones, capacity: N })?;
        for (d, mm) in staged.iter_mut().zip(frame.distance_mm()) {
            *d = f32::from(mm);
        }
        let device =
            ZoneBridgeDevice::new(&cal.dtof, &*staged, frame.status).map_err(LoopError::Device)?;
        let mut sensor = ZoneBridgeSensor::new(device, &mut self.delay);
        let depth = ws
            .depth_m
            .get_mut(..pixels)
            .ok_or(LoopError::Workspace("depth buffer"))?;
        let mut buffers = FrameBuffers {
            rgb: &mut *ws.rgb,
            sparse_m: &mut *ws.sparse_m,
            zones: &mut *ws.zones,
        };
        // Camera → driver → projection → engine (prepared once, outside the loop): the core's
        // one-frame pipeline.
        let report = depth_frame_probed(
            &mut self.camera,
            &mut sensor,
            &cal,
            engine,
            &mut buffers,
            DepthOut::Metres(depth),
            probe,
        )
        .map_err(LoopError::from)?;
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
            emit(&FrameOutput::new(&p, ws.depth_m));
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
        let (mut rgb, mut sparse) = (vec![0u8; 57_600], vec![0f32; 19_200]);
        let mut depth = vec![0f32; 19_200];
        let (mut bridge, mut zones) = ([0f32; 64], ZoneFrame::<64>::new());
        let mut ws = Workspace {
            rgb: &mut rgb,
            sparse_m: &mut sparse,
            depth_m: &mut depth,
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut engine = prepare(MCU_BLOB, &mut arena, 120, 160).unwrap();
        let mut arena2 = vec![0u8; ARENA_BUDGET_BYTES];
        let mut direct_engine = prepare(MCU_BLOB, &mut arena2, 120, 160).unwrap();
        let mut replay = ReplayLoop::new(image, NoDelay);
        for (i, f) in frames.iter().enumerate() {
            let p = replay.process(&mut engine, &mut ws).unwrap().unwrap();
            assert_eq!(p.index as usize, i);
            // The RGB went through the camera unchanged, the zones through the bridge.
            assert_eq!(&ws.rgb[..], &f.rgb[..]);
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
            assert_eq!(fnv1a64_f32(ws.depth_m), fnv1a64_f32(&want_depth));
            assert_eq!(
                FrameOutput::new(&p, ws.depth_m).hash,
                fnv1a64_f32(&want_depth)
            );
            // The engine ran in place on the sparse buffer: it ends holding the dense depth.
            assert_eq!(fnv1a64_f32(ws.sparse_m), fnv1a64_f32(&want_depth));
            assert_ne!(fnv1a64_f32(&direct), fnv1a64_f32(&want_depth));
        }
        assert_eq!(replay.process(&mut engine, &mut ws).unwrap(), None);
    }

    #[test]
    fn small_workspace_is_an_error() {
        let bytes = image_bytes(&mcu_calibration(), &mcu_frames(1)).unwrap();
        let image = Image::parse(&bytes).unwrap();
        let (mut rgb, mut sparse) = (vec![0u8; 57_600], vec![0f32; 19_200]);
        let mut depth = vec![0f32; 19_200];
        let (mut bridge, mut zones) = ([0f32; 16], ZoneFrame::<16>::new());
        let mut ws = Workspace {
            rgb: &mut rgb,
            sparse_m: &mut sparse,
            depth_m: &mut depth,
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut engine = prepare(MCU_BLOB, &mut arena, 120, 160).unwrap();
        let err = ReplayLoop::new(image, NoDelay)
            .process(&mut engine, &mut ws)
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

    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }

    #[test]
    fn engine_prepared_for_another_size_is_an_error() {
        let bytes = image_bytes(&mcu_calibration(), &mcu_frames(1)).unwrap();
        let image = Image::parse(&bytes).unwrap();
        let (mut rgb, mut sparse) = (vec![0u8; 57_600], vec![0f32; 19_200]);
        let mut depth = vec![0f32; 19_200];
        let (mut bridge, mut zones) = ([0f32; 64], ZoneFrame::<64>::new());
        let mut ws = Workspace {
            rgb: &mut rgb,
            sparse_m: &mut sparse,
            depth_m: &mut depth,
            bridge_mm: &mut bridge,
            zones: &mut zones,
        };
        let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
        let mut engine = prepare(MCU_BLOB, &mut arena, 64, 64).unwrap();
        let err = ReplayLoop::new(image, NoDelay)
            .process(&mut engine, &mut ws)
            .unwrap_err();
        assert!(matches!(err, LoopError::Engine(_)), "{err:?}");
        assert_eq!(err.exit_code(), 16);
    }
}
