//! The zone bridge driver over the simulated device, over a bus that fails, and over a bus that
//! returns garbage: it returns frames or errors, never panics.

use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};
use depthor_core::drivers::zone_bridge::{
    reg, Config, DeviceError, ZoneBridgeDevice, ZoneBridgeError, ZoneBridgeSensor, ADDRESS, CHIP_ID,
};
use depthor_core::hal::{DtofSensor, Error as _, ErrorKind, ZoneFrame};
use depthor_core::projection::project_to_sparse;
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::{self, I2c, Operation};
use proptest::prelude::*;

/// Counts the time the driver asked to wait.
#[derive(Default)]
struct CountingDelay {
    total_ns: u64,
    calls: u32,
}

impl DelayNs for CountingDelay {
    fn delay_ns(&mut self, ns: u32) {
        self.total_ns += u64::from(ns);
        self.calls += 1;
    }
}

fn geometry_8x8() -> DtofGeometry {
    DtofGeometry {
        rows: 8,
        cols: 8,
        fov_deg: [45.0, 63.5],
        distance: DistanceKind::Radial,
        max_range_m: 4.1,
    }
}

#[test]
fn frame_round_trip_over_the_device() {
    let mut distance = [0.0f32; 64];
    let mut status = [5u8; 64];
    for (i, (d, s)) in distance.iter_mut().zip(status.iter_mut()).enumerate() {
        *d = 100.0 + 50.0 * i as f32;
        *s = if i % 7 == 0 { 255 } else { 5 };
    }
    // Rounding to i16 mm: 1234.4 → 1234, 1234.6 → 1235, −2.5 → −3, NaN → 0, 1e9 → 32767.
    distance[1] = 1234.4;
    distance[2] = 1234.6;
    distance[3] = -2.5;
    distance[4] = f32::NAN;
    distance[5] = 1e9;
    let mut device = ZoneBridgeDevice::new(&geometry_8x8(), &distance, &status).unwrap();
    device.set_latency_polls(5);
    let mut sensor = ZoneBridgeSensor::new(device, CountingDelay::default());
    assert_eq!(sensor.geometry().rows, 0, "0×0 before init");
    let mut frame = ZoneFrame::<64>::new();
    frame.has_sigma = true;
    sensor.read_frame(&mut frame).unwrap();
    assert_eq!(sensor.geometry(), geometry_8x8());
    assert_eq!((frame.rows, frame.cols), (8, 8));
    assert!(!frame.has_sigma);
    let mut want = distance;
    want[1] = 1234.0;
    want[2] = 1235.0;
    want[3] = -3.0;
    want[4] = 0.0;
    want[5] = 32767.0;
    assert_eq!(frame.view().distance_mm, &want[..]);
    assert_eq!(frame.view().status, &status[..]);
    assert_eq!(sensor.frame_count().unwrap(), 1);
    let (device, delay) = sensor.release();
    // Five "not ready" polls, each followed by one 1 ms wait.
    assert_eq!(delay.calls, 5);
    assert_eq!(delay.total_ns, 5_000_000);
    assert_eq!(device.releases(), 1);
    assert!(!device.data_ready());
}

#[test]
fn times_out_when_no_frame_comes() {
    let d = [1000.0f32; 4];
    let s = [5u8; 4];
    let geometry = DtofGeometry {
        rows: 2,
        cols: 2,
        ..geometry_8x8()
    };
    let device = ZoneBridgeDevice::new(&geometry, &d, &s).unwrap();
    let config = Config {
        poll_interval_us: 500,
        timeout_us: 10_000,
        ..Config::default()
    };
    let mut sensor = ZoneBridgeSensor::with_config(device, CountingDelay::default(), config);
    let mut frame = ZoneFrame::<4>::new();
    sensor.read_frame(&mut frame).unwrap();
    let err = sensor.read_frame(&mut frame).unwrap_err();
    assert_eq!(err, ZoneBridgeError::Timeout);
    assert_eq!(err.kind(), ErrorKind::Timeout);
    // 10 000 / 500 + 1 = 21 polls with 20 waits of 500 µs between them.
    let (mut device, delay) = sensor.release();
    assert_eq!(delay.calls, 20);
    assert_eq!(delay.total_ns, 10_000_000);
    // A new frame (or repeat mode) makes the next read succeed.
    device.set_repeat(true);
    device.set_frame(&d, &s).unwrap();
    let mut sensor = ZoneBridgeSensor::with_config(device, CountingDelay::default(), config);
    for _ in 0..3 {
        sensor.read_frame(&mut frame).unwrap();
    }
    assert_eq!(sensor.frame_count().unwrap(), 5);
}

#[test]
fn shape_address_and_id_errors() {
    let d = [1000.0f32; 64];
    let s = [5u8; 64];
    let device = ZoneBridgeDevice::new(&geometry_8x8(), &d, &s).unwrap();
    let mut sensor = ZoneBridgeSensor::new(device.clone(), CountingDelay::default());
    let mut small = ZoneFrame::<16>::new();
    let err = sensor.read_frame(&mut small).unwrap_err();
    assert_eq!(
        err,
        ZoneBridgeError::BufferShape {
            zones: 64,
            capacity: 16
        }
    );
    assert_eq!(err.kind(), ErrorKind::BufferShape);

    let mut sensor = ZoneBridgeSensor::new(device.with_address(0x30), CountingDelay::default());
    let err = sensor.read_frame(&mut ZoneFrame::<64>::new()).unwrap_err();
    assert!(matches!(
        err,
        ZoneBridgeError::Bus(i2c::ErrorKind::NoAcknowledge(_))
    ));
    assert_eq!(err.kind(), ErrorKind::Bus);

    // The device refuses what the protocol cannot carry.
    let wide = DtofGeometry {
        rows: 300,
        ..geometry_8x8()
    };
    assert!(matches!(
        ZoneBridgeDevice::new(&wide, &d, &s),
        Err(DeviceError::UnsupportedGeometry(_))
    ));
    assert_eq!(
        ZoneBridgeDevice::new(&geometry_8x8(), &d[..10], &s).unwrap_err(),
        DeviceError::ZoneCount {
            expected: 64,
            got: 10
        }
    );
}

#[test]
fn device_register_map() {
    // Reads through the raw I2C interface, as a logic analyser would see them.
    let d = [1500.0f32, -1.0];
    let s = [5u8, 255];
    let geometry = DtofGeometry {
        rows: 1,
        cols: 2,
        fov_deg: [45.0, 30.25],
        distance: DistanceKind::Z,
        max_range_m: 4.0,
    };
    let mut dev = ZoneBridgeDevice::new(&geometry, &d, &s).unwrap();
    let mut header = [0u8; 13];
    dev.write_read(ADDRESS, &[0x00, 0x00], &mut header).unwrap();
    // ID, VERSION, ROWS, COLS, FOV_H 4500 LE, FOV_V 3025 LE, KIND z, MAX_RANGE 4000 LE,
    // STATUS ready, FRAME_COUNT 1.
    assert_eq!(
        header,
        [CHIP_ID, 1, 1, 2, 0x94, 0x11, 0xD1, 0x0B, 0, 0xA0, 0x0F, 1, 1]
    );
    let mut frame = [0u8; 7];
    dev.write_read(ADDRESS, &reg::FRAME.to_be_bytes(), &mut frame)
        .unwrap();
    // 1500 = 0x05DC, −1 = 0xFFFF; past the frame reads 0.
    assert_eq!(frame, [0xDC, 0x05, 5, 0xFF, 0xFF, 255, 0]);
    // Writes to read-only registers and one-byte writes are not acknowledged.
    assert!(dev.write(ADDRESS, &[0x00, 0x02, 9]).is_err());
    assert!(dev.write(ADDRESS, &[0x00]).is_err());
    dev.write(ADDRESS, &[0x00, 0x0B, 0x01]).unwrap();
    let mut st = [0xAAu8];
    dev.write_read(ADDRESS, &[0x00, 0x0B], &mut st).unwrap();
    assert_eq!(st, [0]);
}

#[test]
fn driver_feeds_projection() {
    // 2×2 zones over 90°, identity extrinsics, 640×480 camera with f = 200: zone centres land on
    // (220, 140), (420, 140), (220, 340), (420, 340) (see tests/projection.rs); zone 3 has no
    // target.
    let geometry = DtofGeometry {
        rows: 2,
        cols: 2,
        fov_deg: [90.0, 90.0],
        distance: DistanceKind::Z,
        max_range_m: 4.0,
    };
    let d = [1000.0f32, 2000.0, 3000.0, 0.0];
    let s = [5u8, 5, 9, 255];
    let device = ZoneBridgeDevice::new(&geometry, &d, &s).unwrap();
    let mut sensor = ZoneBridgeSensor::new(device, CountingDelay::default());
    let mut frame = ZoneFrame::<64>::new();
    sensor.read_frame(&mut frame).unwrap();
    let cal = Calibration {
        camera: CameraIntrinsics {
            width: 640,
            height: 480,
            fx: 200.0,
            fy: 200.0,
            cx: 320.0,
            cy: 240.0,
        },
        dtof: sensor.geometry(),
        dtof_to_camera: Extrinsics::IDENTITY,
        zone_rects_px: None,
    };
    let mut sparse = vec![0.0f32; 640 * 480];
    let stats = project_to_sparse(&cal, &frame.view(), &mut sparse).unwrap();
    assert_eq!((stats.projected, stats.invalid_status), (3, 1));
    assert_eq!(sparse[140 * 640 + 220], 1.0);
    assert_eq!(sparse[140 * 640 + 420], 2.0);
    assert_eq!(sparse[340 * 640 + 220], 3.0);
}

/// A hand-written bus that answers from a script: each transaction either fails with the
/// scripted error or fills its reads with the next scripted bytes (zeros when the script ends).
struct ScriptedBus {
    bytes: Vec<u8>,
    pos: usize,
    fail_at: Vec<usize>,
    transactions: usize,
}

impl i2c::ErrorType for ScriptedBus {
    type Error = i2c::ErrorKind;
}

impl I2c for ScriptedBus {
    fn transaction(&mut self, _addr: u8, ops: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        let n = self.transactions;
        self.transactions += 1;
        if self.fail_at.contains(&n) {
            return Err(i2c::ErrorKind::ArbitrationLoss);
        }
        for op in ops {
            if let Operation::Read(buf) = op {
                for b in buf.iter_mut() {
                    *b = self.bytes.get(self.pos).copied().unwrap_or(0);
                    self.pos += 1;
                }
            }
        }
        Ok(())
    }
}

/// A plausible header (ID, version 1, 2×3 zones, 45°×45°, z, 4 m) so that garbage reaches the
/// frame path too.
const GOOD_HEADER: [u8; 11] = [CHIP_ID, 1, 2, 3, 0x94, 0x11, 0x94, 0x11, 0, 0xA0, 0x0F];

#[test]
fn scripted_bus_errors_map_to_bus_kind() {
    // Header OK, then the first STATUS poll fails.
    let mut bytes = GOOD_HEADER.to_vec();
    bytes.push(1);
    let bus = ScriptedBus {
        bytes,
        pos: 0,
        fail_at: vec![1],
        transactions: 0,
    };
    let mut sensor = ZoneBridgeSensor::new(bus, CountingDelay::default());
    let err = sensor.read_frame(&mut ZoneFrame::<8>::new()).unwrap_err();
    assert_eq!(err, ZoneBridgeError::Bus(i2c::ErrorKind::ArbitrationLoss));
    assert_eq!(err.kind(), ErrorKind::Bus);
    // Wrong ID.
    let bus = ScriptedBus {
        bytes: vec![0x42; 11],
        pos: 0,
        fail_at: vec![],
        transactions: 0,
    };
    let mut sensor = ZoneBridgeSensor::new(bus, CountingDelay::default());
    let err = sensor.read_frame(&mut ZoneFrame::<8>::new()).unwrap_err();
    assert_eq!(err, ZoneBridgeError::WrongId(0x42));
    assert_eq!(err.kind(), ErrorKind::BadData);
}

proptest! {
    #[test]
    fn garbage_bus_never_panics(
        good_header in any::<bool>(),
        garbage in proptest::collection::vec(any::<u8>(), 0..200),
        fail_at in proptest::collection::vec(0usize..12, 0..3),
    ) {
        let mut bytes = if good_header { GOOD_HEADER.to_vec() } else { Vec::new() };
        bytes.extend_from_slice(&garbage);
        let bus = ScriptedBus { bytes, pos: 0, fail_at, transactions: 0 };
        let config = Config { poll_interval_us: 1000, timeout_us: 5000, ..Config::default() };
        let mut sensor = ZoneBridgeSensor::with_config(bus, CountingDelay::default(), config);
        let mut frame = ZoneFrame::<16>::new();
        for _ in 0..3 {
            match sensor.read_frame(&mut frame) {
                Ok(()) => {
                    let g = sensor.geometry();
                    prop_assert_eq!((frame.rows, frame.cols), (g.rows, g.cols));
                    prop_assert!(frame.len() <= 16);
                    prop_assert!(g.fov_deg.iter().all(|f| *f > 0.0 && *f < 180.0));
                }
                Err(e) => {
                    let _ = e.kind();
                    let _ = e.to_string();
                }
            }
        }
    }
}
