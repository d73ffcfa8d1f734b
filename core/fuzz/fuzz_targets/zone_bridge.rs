//! Fuzzes the zone bridge driver's parsing of what the bus returns (`ZoneBridgeSensor::init`,
//! `read_frame`, `frame_count`) through a fake embedded-hal I2C bus whose every read returns
//! fuzz bytes and whose every transaction may fail.
//!
//! Input: `cfg, bytes…`. `cfg` bit 0: call `init` first; bits 1–2: frames to read (1–4); bit 3:
//! into a 64-zone frame instead of a 21 760-zone one; bits 4–7: `STATUS` polls before the
//! timeout (1–16). Then, per bus transaction, one control byte (`0xEE`: the transaction fails
//! with a NACK, `0xEF`: with arbitration loss) followed, for a read, by its data.
//!
//! Checks: nothing panics; a frame read successfully has the header's shape within the
//! capacity, integral millimetre distances in `i16` range, and the driver's geometry is the
//! header's.
#![no_main]

#[path = "common.rs"]
mod common;

use std::cell::RefCell;

use common::{Bytes, NoDelay};
use depthor_core::drivers::zone_bridge::{Config, ZoneBridgeSensor, MAX_ZONES};
use depthor_core::hal::{DtofSensor, ZoneFrame};
use embedded_hal::i2c::{self, ErrorKind, ErrorType, NoAcknowledgeSource, Operation};
use libfuzzer_sys::fuzz_target;

/// A bus that answers every read with the next fuzz bytes.
struct FuzzBus<'a> {
    bytes: Bytes<'a>,
    transactions: usize,
}

impl ErrorType for FuzzBus<'_> {
    type Error = ErrorKind;
}

impl i2c::I2c for FuzzBus<'_> {
    fn transaction(
        &mut self,
        _address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        self.transactions += 1;
        match self.bytes.u8() {
            0xEE => return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data)),
            0xEF => return Err(ErrorKind::ArbitrationLoss),
            _ => {}
        }
        for op in operations {
            if let Operation::Read(buf) = op {
                for byte in buf.iter_mut() {
                    *byte = self.bytes.u8();
                }
            }
        }
        Ok(())
    }
}

fn read<const N: usize>(
    sensor: &mut ZoneBridgeSensor<FuzzBus<'_>, NoDelay>,
    frames: usize,
    frame: &mut ZoneFrame<N>,
) {
    for _ in 0..frames {
        let before = sensor.geometry();
        match sensor.read_frame(frame) {
            Ok(()) => {
                let g = sensor.geometry();
                assert!(
                    before.rows == 0 || before == g,
                    "geometry changed between frames"
                );
                assert_eq!((frame.rows, frame.cols), (g.rows, g.cols));
                assert!(g.zones() >= 1 && g.zones() <= N.min(MAX_ZONES));
                assert!(g.fov_deg.iter().all(|v| *v > 0.0 && *v < 180.0));
                let view = frame.view();
                assert_eq!(view.distance_mm.len(), g.zones());
                for &d in view.distance_mm {
                    assert!(d == d.trunc() && (-32768.0..=32767.0).contains(&d), "{d}");
                }
            }
            Err(_) => {}
        }
        let _ = sensor.frame_count();
    }
}

thread_local! {
    /// The largest frame the protocol carries, allocated once (≈ 370 KB).
    static BIG: RefCell<Box<ZoneFrame<MAX_ZONES>>> = RefCell::new(Box::new(ZoneFrame::new()));
}

fuzz_target!(|input: &[u8]| {
    let mut b = Bytes::new(input);
    let cfg = b.u8();
    let polls = u32::from(cfg >> 4) + 1;
    let config = Config {
        poll_interval_us: 10,
        timeout_us: 10 * (polls - 1),
        ..Config::default()
    };
    let bus = FuzzBus {
        bytes: b,
        transactions: 0,
    };
    let mut sensor = ZoneBridgeSensor::with_config(bus, NoDelay, config);
    if cfg & 1 != 0 {
        if let Ok(g) = sensor.init() {
            assert_eq!(sensor.geometry(), g);
        }
    }
    let frames = usize::from((cfg >> 1) & 3) + 1;
    if cfg & 8 != 0 {
        let mut frame = ZoneFrame::<64>::new();
        read(&mut sensor, frames, &mut frame);
    } else {
        BIG.with(|big| read(&mut sensor, frames, &mut **big.borrow_mut()));
    }
    let (bus, _) = sensor.release();
    // init (1) + per frame: header (≤ 1), polls, ≤ 1360 chunk reads, release, frame count.
    assert!(bus.transactions <= 1 + 4 * (1 + polls as usize + 1360 + 2));
});
