//! `pipeline::depth_frame` under faulty sensors: the real zone-bridge dToF driver over an I2C bus
//! that NACKs, loses arbitration mid-frame, never raises `DATA_READY` (timeout) or serves frames
//! whose zones are all invalid, and a camera that delivers short frames or fails; then the same
//! for the VL53L5CX driver over the simulated VL53L5CX (NACK, arbitration loss in the results
//! read, no new frame, a corrupt result block header, a GO2 error in the data-ready word, all
//! zones without a target). Each fault is the right [`FrameError`], leaves the output untouched,
//! and the next good frame comes out bit-identical to a run that never saw a fault.

mod common;

use common::{frame, rgb_planar, tiny_net};
use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};
use depthor_core::drivers::vl53l5cx as vl53;
use depthor_core::drivers::zone_bridge::{reg, Config, ZoneBridgeDevice, ZoneBridgeSensor};
use depthor_core::engine::{required_arena_bytes, Engine};
use depthor_core::hal::{ErrorKind, ErrorType, RgbCamera, RgbFrame, ZoneFrame};
use depthor_core::pipeline::DepthOut;
use depthor_core::pipeline::{depth_frame, FrameBuffers, FrameError};
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::{self, I2c, NoAcknowledgeSource, Operation};
use std::cell::Cell;
use std::rc::Rc;

const H: usize = 12;
const W: usize = 16;

fn geometry() -> DtofGeometry {
    DtofGeometry {
        rows: 4,
        cols: 4,
        fov_deg: [60.0, 60.0],
        distance: DistanceKind::Z,
        max_range_m: 4.0,
    }
}

fn calibration() -> Calibration<'static> {
    Calibration {
        camera: CameraIntrinsics {
            width: W as u32,
            height: H as u32,
            fx: 12.0,
            fy: 12.0,
            cx: 8.0,
            cy: 6.0,
        },
        dtof: geometry(),
        dtof_to_camera: Extrinsics::IDENTITY,
        zone_rects_px: None,
    }
}

/// What the bus does on the next frame.
#[derive(Clone, Copy, Debug, PartialEq)]
enum BusFault {
    /// Works.
    None,
    /// Every transaction is not acknowledged (sensor unplugged, wrong address).
    Nack,
    /// `STATUS` says ready, then the `FRAME` read loses arbitration.
    ArbitrationLossMidFrame,
    /// The frame is read, then the write that releases it is not acknowledged.
    ReleaseNack,
    /// `STATUS` never shows `DATA_READY` (the sensor stopped ranging).
    NeverReady,
    /// Every zone record reads `target_status` 255 (covered sensor, nothing in range).
    AllZonesInvalid,
}

/// The simulated bridge behind a bus whose faults the test switches between frames.
struct FaultyBus<'a> {
    device: ZoneBridgeDevice<'a>,
    fault: Rc<Cell<BusFault>>,
}

impl i2c::ErrorType for FaultyBus<'_> {
    type Error = i2c::ErrorKind;
}

impl I2c for FaultyBus<'_> {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        let index = match ops.first() {
            Some(Operation::Write([hi, lo, ..])) => Some(u16::from_be_bytes([*hi, *lo])),
            _ => None,
        };
        match self.fault.get() {
            BusFault::Nack => {
                return Err(i2c::ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address))
            }
            BusFault::ArbitrationLossMidFrame if index.is_some_and(|i| i >= reg::FRAME) => {
                return Err(i2c::ErrorKind::ArbitrationLoss)
            }
            BusFault::ReleaseNack if index == Some(reg::STATUS) && ops.len() == 1 => {
                return Err(i2c::ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data))
            }
            BusFault::NeverReady if index == Some(reg::STATUS) && ops.len() == 2 => {
                if let Operation::Read(buf) = &mut ops[1] {
                    buf.fill(0);
                }
                return Ok(());
            }
            _ => {}
        }
        self.device.transaction(address, ops)?;
        if let (BusFault::AllZonesInvalid, Some(i)) = (self.fault.get(), index) {
            if i >= reg::FRAME {
                // Records are 3 bytes from FRAME on and reads start on a record.
                let skip = usize::from(i - reg::FRAME) % 3;
                for op in ops.iter_mut() {
                    if let Operation::Read(buf) = op {
                        for b in buf.iter_mut().skip((2 + 3 - skip) % 3).step_by(3) {
                            *b = 255;
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

struct NoDelay;

impl DelayNs for NoDelay {
    fn delay_ns(&mut self, _ns: u32) {}
}

/// What the camera does on the next frame.
#[derive(Clone, Copy, Debug, PartialEq)]
enum CameraFault {
    None,
    /// Reports (and delivers) one row fewer than the calibration's size.
    ShortFrame,
    /// The DMA stopped early: the driver sees a short transfer and says so.
    ShortTransfer,
    /// No frame in time.
    Timeout,
}

struct FlakyCamera {
    rgb: Vec<u8>,
    fault: CameraFault,
    captures: u32,
}

impl ErrorType for FlakyCamera {
    type Error = ErrorKind;
}

impl RgbCamera for FlakyCamera {
    fn resolution(&self) -> (u32, u32) {
        match self.fault {
            CameraFault::ShortFrame => (W as u32, H as u32 - 1),
            _ => (W as u32, H as u32),
        }
    }
    fn capture(&mut self, f: &mut RgbFrame<'_>) -> Result<(), ErrorKind> {
        self.captures += 1;
        match self.fault {
            CameraFault::ShortFrame => {
                // Would fill only H-1 rows if the pipeline let it.
                let n = 3 * W * (H - 1);
                f.data[..n].copy_from_slice(&self.rgb[..n]);
                Ok(())
            }
            CameraFault::ShortTransfer => {
                f.data[..3 * W].copy_from_slice(&self.rgb[..3 * W]);
                Err(ErrorKind::BadData)
            }
            CameraFault::Timeout => Err(ErrorKind::Timeout),
            CameraFault::None => {
                f.data.copy_from_slice(&self.rgb);
                Ok(())
            }
        }
    }
}

#[test]
fn each_fault_is_the_right_frame_error_and_the_next_good_frame_is_normal() {
    let net = tiny_net(H, W);
    let (rgb, _) = frame(H, W);
    let blob = net.to_blob(&net.run_float(&rgb_planar(&rgb, H, W), &frame(H, W).1));
    let mut arena = vec![0u8; required_arena_bytes(&blob, H, W).unwrap() + 64];
    let mut engine = Engine::new(&blob, &mut arena).unwrap();
    let cal = calibration();

    // Zone k at 1 m + 0.1 m·k, zone 5 without a target.
    let distance: Vec<f32> = (0..16).map(|k| 1000.0 + 100.0 * k as f32).collect();
    let status: Vec<u8> = (0..16).map(|k| if k == 5 { 255 } else { 5 }).collect();
    let mut device = ZoneBridgeDevice::new(&geometry(), &distance, &status).unwrap();
    device.set_repeat(true); // a free-running sensor watching a still scene
    let bus_fault = Rc::new(Cell::new(BusFault::None));
    let bus = FaultyBus {
        device,
        fault: bus_fault.clone(),
    };
    let config = Config {
        timeout_us: 5_000,
        ..Config::default()
    };
    let mut sensor = ZoneBridgeSensor::with_config(bus, NoDelay, config);
    let mut camera = FlakyCamera {
        rgb: rgb.clone(),
        fault: CameraFault::None,
        captures: 0,
    };

    let (mut rgb_buf, mut sparse_buf) = (vec![0u8; 3 * H * W], vec![0f32; H * W]);
    let mut zones = ZoneFrame::<16>::new();
    let mut step = |bus: BusFault, cam: CameraFault, engine: &mut Engine<'_>| {
        bus_fault.set(bus);
        camera.fault = cam;
        let mut out = vec![f32::from_bits(0x7fc0_dead); H * W];
        let r = depth_frame(
            &mut camera,
            &mut sensor,
            &cal,
            engine,
            &mut FrameBuffers {
                rgb: &mut rgb_buf,
                sparse_m: &mut sparse_buf,
                zones: &mut zones,
            },
            DepthOut::Metres(&mut out),
        );
        (r.map(|rep| rep.projection.projected), out)
    };

    // The very first frame fails at init (nothing on the bus), the next one inits and runs.
    let (r, out) = step(BusFault::Nack, CameraFault::None, &mut engine);
    assert_eq!(r, Err(FrameError::Sensor(ErrorKind::Bus)));
    assert!(
        out.iter().all(|v| v.to_bits() == 0x7fc0_dead),
        "output written"
    );
    let (r, reference) = step(BusFault::None, CameraFault::None, &mut engine);
    assert_eq!(r, Ok(15), "15 of 16 zones have a target");
    let reference: Vec<u32> = reference.iter().map(|v| v.to_bits()).collect();

    let faults = [
        (
            BusFault::Nack,
            CameraFault::None,
            FrameError::Sensor(ErrorKind::Bus),
        ),
        (
            BusFault::ArbitrationLossMidFrame,
            CameraFault::None,
            FrameError::Sensor(ErrorKind::Bus),
        ),
        (
            BusFault::ReleaseNack,
            CameraFault::None,
            FrameError::Sensor(ErrorKind::Bus),
        ),
        (
            BusFault::NeverReady,
            CameraFault::None,
            FrameError::Sensor(ErrorKind::Timeout),
        ),
        (
            BusFault::AllZonesInvalid,
            CameraFault::None,
            FrameError::NoValidZones { zones: 16 },
        ),
        (
            BusFault::None,
            CameraFault::ShortFrame,
            FrameError::Camera(ErrorKind::BufferShape),
        ),
        (
            BusFault::None,
            CameraFault::ShortTransfer,
            FrameError::Camera(ErrorKind::BadData),
        ),
        (
            BusFault::None,
            CameraFault::Timeout,
            FrameError::Camera(ErrorKind::Timeout),
        ),
    ];
    // Each fault twice in a row, then a good frame; the whole list twice.
    for round in 0..2 {
        for &(bus, cam, want) in &faults {
            for _ in 0..2 {
                let (r, out) = step(bus, cam, &mut engine);
                assert_eq!(r, Err(want), "round {round}: {bus:?} / {cam:?}");
                assert!(
                    out.iter().all(|v| v.to_bits() == 0x7fc0_dead),
                    "{bus:?} / {cam:?}: output written"
                );
            }
            let (r, out) = step(BusFault::None, CameraFault::None, &mut engine);
            assert_eq!(r, Ok(15), "after {bus:?} / {cam:?}");
            let bits: Vec<u32> = out.iter().map(|v| v.to_bits()).collect();
            assert!(
                bits == reference,
                "after {bus:?} / {cam:?}: the good frame differs"
            );
        }
    }
    // The short-frame camera was never asked to capture into a buffer of the wrong size.
    assert!(camera.captures > 0);
    assert_eq!(
        FrameError::NoValidZones { zones: 16 }.to_string(),
        "dToF sensor: none of the 16 zones is valid"
    );
}

/// What the VL53L5CX's bus does on the next frame.
#[derive(Clone, Copy, Debug, PartialEq)]
enum VlFault {
    None,
    /// Every transaction is not acknowledged.
    Nack,
    /// The data-ready poll succeeds, the results read loses arbitration.
    ArbitrationLossInResults,
    /// The stream count never moves (the sensor stopped ranging).
    NeverReady,
    /// The first block header of the results reads as a distance block of 0x7FF zones.
    CorruptHeader,
    /// The data-ready word carries a GO2 error (bit 7 of byte 3, code in byte 2).
    McuError,
    /// Every zone reports no target.
    AllZonesInvalid,
}

struct FaultyVl53 {
    dev: vl53::sim::SimVl53l5cx,
    zones: [vl53::sim::SimZone; 64],
    fault: Rc<Cell<VlFault>>,
}

impl i2c::ErrorType for FaultyVl53 {
    type Error = i2c::ErrorKind;
}

impl I2c for FaultyVl53 {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        let fault = self.fault.get();
        let results_read = match ops {
            [Operation::Write([0, 0]), Operation::Read(r)] => Some(r.len()),
            _ => None,
        };
        if results_read == Some(4) {
            let none = [vl53::sim::SimZone::NONE; 64];
            let zones = if fault == VlFault::AllZonesInvalid {
                &none
            } else {
                &self.zones
            };
            self.dev.set_zones(zones);
        }
        match (fault, results_read) {
            (VlFault::Nack, _) => {
                return Err(i2c::ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address))
            }
            (VlFault::ArbitrationLossInResults, Some(n)) if n > 4 => {
                return Err(i2c::ErrorKind::ArbitrationLoss)
            }
            (VlFault::NeverReady, Some(4)) => {
                if let [_, Operation::Read(r)] = ops {
                    r.fill(0);
                }
                return Ok(());
            }
            _ => {}
        }
        self.dev.transaction(address, ops)?;
        if let [_, Operation::Read(r)] = ops {
            match (fault, results_read) {
                (VlFault::CorruptHeader, Some(n)) if n > 4 => {
                    r[16..20].copy_from_slice(&[0xD3, 0x3C, 0x7F, 0xF2]);
                }
                (VlFault::McuError, Some(4)) => r.copy_from_slice(&[r[0], 0, 0x42, 0x80]),
                _ => {}
            }
        }
        Ok(())
    }
}

#[test]
fn vl53l5cx_faults_are_the_right_frame_error_and_the_next_good_frame_is_normal() {
    let net = tiny_net(H, W);
    let (rgb, _) = frame(H, W);
    let blob = net.to_blob(&net.run_float(&rgb_planar(&rgb, H, W), &frame(H, W).1));
    let mut arena = vec![0u8; required_arena_bytes(&blob, H, W).unwrap() + 64];
    let mut engine = Engine::new(&blob, &mut arena).unwrap();
    let cal = calibration();

    // 4×4 mode; zone k at 1 m + 0.1 m·k, zone 5 without a target.
    let zones: [vl53::sim::SimZone; 64] = std::array::from_fn(|k| {
        if k == 5 {
            vl53::sim::SimZone::NONE
        } else {
            vl53::sim::SimZone {
                distance_mm: 1000 + 100 * k as i16,
                status: 5,
                sigma_mm: 3,
                signal_kcps: 200,
                ambient_kcps: 2,
            }
        }
    });
    let fault = Rc::new(Cell::new(VlFault::None));
    let mut dev = vl53::sim::SimVl53l5cx::new();
    dev.set_latency_polls(1);
    let bus = FaultyVl53 {
        dev,
        zones,
        fault: fault.clone(),
    };
    let mut io = [0u8; 600];
    let config = vl53::Config {
        frame_timeout_us: 5_000,
        ..vl53::Config::default()
    };
    let mut sensor =
        vl53::Vl53l5cx::new(bus, NoDelay, vl53::sim::stand_in_buffers(), &mut io, config);
    sensor.init().unwrap();
    sensor.set_ranging_frequency_hz(30).unwrap();
    sensor.start_ranging().unwrap();
    let mut camera = FlakyCamera {
        rgb: rgb.clone(),
        fault: CameraFault::None,
        captures: 0,
    };
    let (mut rgb_buf, mut sparse_buf) = (vec![0u8; 3 * H * W], vec![0f32; H * W]);
    let mut zone_frame = ZoneFrame::<16>::new();
    let mut step = |f: VlFault, engine: &mut Engine<'_>| {
        fault.set(f);
        let mut out = vec![f32::from_bits(0x7fc0_dead); H * W];
        let r = depth_frame(
            &mut camera,
            &mut sensor,
            &cal,
            engine,
            &mut FrameBuffers {
                rgb: &mut rgb_buf,
                sparse_m: &mut sparse_buf,
                zones: &mut zone_frame,
            },
            DepthOut::Metres(&mut out),
        );
        (r.map(|rep| rep.projection.projected), out)
    };
    let (r, reference) = step(VlFault::None, &mut engine);
    assert_eq!(r, Ok(15), "15 of 16 zones have a target");
    let reference: Vec<u32> = reference.iter().map(|v| v.to_bits()).collect();
    let faults = [
        (VlFault::Nack, FrameError::Sensor(ErrorKind::Bus)),
        (
            VlFault::ArbitrationLossInResults,
            FrameError::Sensor(ErrorKind::Bus),
        ),
        (VlFault::NeverReady, FrameError::Sensor(ErrorKind::Timeout)),
        (
            VlFault::CorruptHeader,
            FrameError::Sensor(ErrorKind::BadData),
        ),
        (VlFault::McuError, FrameError::Sensor(ErrorKind::BadData)),
        (
            VlFault::AllZonesInvalid,
            FrameError::NoValidZones { zones: 16 },
        ),
    ];
    for round in 0..2 {
        for &(f, want) in &faults {
            for _ in 0..2 {
                let (r, out) = step(f, &mut engine);
                assert_eq!(r, Err(want), "round {round}: {f:?}");
                assert!(
                    out.iter().all(|v| v.to_bits() == 0x7fc0_dead),
                    "{f:?}: output written"
                );
            }
            let (r, out) = step(VlFault::None, &mut engine);
            assert_eq!(r, Ok(15), "after {f:?}");
            let bits: Vec<u32> = out.iter().map(|v| v.to_bits()).collect();
            assert!(bits == reference, "after {f:?}: the good frame differs");
        }
    }
}
