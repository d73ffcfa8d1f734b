//! Fuzzes the whole VL53L5CX driver path (`Vl53l5cx::init`, `set_resolution`, the DCI setters
//! and getters, `start_ranging`, `read_frame` = `check_data_ready` + `get_ranging_data`,
//! `stop_ranging`) against a fuzzed I2C bus: the simulated sensor (`vl53l5cx::sim`) behind a
//! bus whose every transaction may fail, or whose reads may be corrupted or replaced by fuzz
//! bytes (so mutations reach the checks behind valid answers, not only the first id check).
//!
//! Input: `cfg, arg, skip (u16 LE), zones (u32 LE), control…`.
//! - `cfg` bit 0: run `init` through the bus (else start from a sensor initialised once per
//!   process, which keeps most executions off the 86 KB firmware upload); bit 1: 8×8 (else 4×4);
//!   bits 2–3: frames to read (1–4); bit 4: read into a 16-zone frame (else 64); bit 5:
//!   `stop_ranging` after the frames, then one more read (must be `NotRanging`); bit 6: set the
//!   ranging frequency to `arg` Hz, integration time and mode, and read them back; bit 7: an I/O
//!   buffer of `8 × arg` bytes (else 1 452).
//! - `skip`: bus transactions passed through untouched before the control bytes start.
//! - `zones`: seed of the zones the sensor reports.
//! - then one control byte per transaction: `0x00` passes it through; `0xEE` / `0xEF` fail it
//!   (NACK, arbitration loss); `0xFF` passes it, then fills every read with the next fuzz bytes;
//!   any other value `c` passes it, then XORs `c` into one byte of each read (at the next `u16`
//!   LE, modulo the length). Past the end of the input every control byte is `0x00`.
//!
//! Checks: nothing panics and every call returns (bounded polls); every error is a typed
//! `Vl53l5cxError`, a bus error only where the bus failed; when the bus was never faulted and
//! the parameters are valid every call succeeds and each frame is the sensor's zones
//! (distance and status); a frame read successfully has the resolution's shape and distances
//! that are integral millimetres in 0..=8191; reading after `stop_ranging` is `NotRanging`.
#![no_main]

#[path = "common.rs"]
mod common;

use common::{Bytes, NoDelay};
use depthor_core::drivers::vl53l5cx::sim::{self, SimVl53l5cx, SimZone};
use depthor_core::drivers::vl53l5cx::{Config, RangingMode, Resolution, Vl53l5cx, Vl53l5cxError};
use depthor_core::hal::{DtofSensor, ZoneFrame};
use embedded_hal::i2c::{self, ErrorKind, ErrorType, NoAcknowledgeSource, Operation};
use libfuzzer_sys::fuzz_target;

/// The simulated sensor behind a bus driven by the fuzz input.
struct FuzzBus<'a> {
    sim: SimVl53l5cx,
    bytes: Bytes<'a>,
    /// Transactions still passed through untouched.
    skip: usize,
    transactions: usize,
    /// Transactions failed by the fuzz input.
    failed: usize,
    /// Transactions failed, corrupted or replaced by the fuzz input.
    faults: usize,
}

impl ErrorType for FuzzBus<'_> {
    type Error = ErrorKind;
}

impl i2c::I2c for FuzzBus<'_> {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), ErrorKind> {
        self.transactions += 1;
        let c = if self.skip > 0 {
            self.skip -= 1;
            0
        } else {
            self.bytes.u8()
        };
        if c != 0 {
            self.faults += 1;
        }
        match c {
            0xEE => {
                self.failed += 1;
                return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data));
            }
            0xEF => {
                self.failed += 1;
                return Err(ErrorKind::ArbitrationLoss);
            }
            _ => {}
        }
        let got = self.sim.transaction(address, ops);
        for op in ops.iter_mut() {
            if let Operation::Read(buf) = op {
                match c {
                    0 => {}
                    0xFF => buf.iter_mut().for_each(|b| *b = self.bytes.u8()),
                    c => {
                        let at = usize::from(self.bytes.u16());
                        if !buf.is_empty() {
                            let n = buf.len();
                            buf[at % n] ^= c;
                        }
                    }
                }
            }
        }
        got
    }
}

/// The zones the sensor reports: distances 0..=8191 mm (what the wire's mm × 4 holds), some
/// zones without a target.
fn zones(seed: u32) -> [SimZone; 64] {
    core::array::from_fn(|k| {
        let x = (k as u32 ^ seed).wrapping_mul(0x9E37_79B9).rotate_left(7) ^ seed;
        if x % 11 == 3 {
            SimZone::NONE
        } else {
            SimZone {
                distance_mm: (x % 8192) as i16,
                status: (x >> 13) as u8 % 16,
                sigma_mm: (x >> 5) as u16 % 512,
                signal_kcps: x >> 12,
                ambient_kcps: x >> 20,
            }
        }
    })
}

thread_local! {
    /// A sensor after a clean `init` (firmware uploaded, calibration and configuration sent).
    static WARM: SimVl53l5cx = {
        let mut io = [0u8; 1452];
        let mut tof = Vl53l5cx::new(
            SimVl53l5cx::new(),
            NoDelay,
            sim::stand_in_buffers(),
            &mut io,
            Config::default(),
        );
        tof.init().expect("init on the simulated sensor");
        tof.release().0
    };
}

type Error = Vl53l5cxError<ErrorKind>;

/// Checks an error against what the bus did; returns whether the call succeeded.
fn check<T>(r: &Result<T, Error>, bus: &FuzzBus<'_>, clean: bool, what: &str) -> bool {
    match r {
        Ok(_) => true,
        Err(e) => {
            assert!(!clean, "{what} failed on a clean bus: {e:?}");
            if let Vl53l5cxError::Bus { .. } = e {
                assert!(
                    bus.failed > 0,
                    "{what}: bus error the bus did not give: {e:?}"
                );
            }
            false
        }
    }
}

fn read<const N: usize>(
    tof: &mut Vl53l5cx<'_, FuzzBus<'_>, NoDelay>,
    frames: usize,
    clean: bool,
    expect: &[SimZone; 64],
) {
    let mut frame = ZoneFrame::<N>::new();
    for _ in 0..frames {
        let r = tof.read_frame(&mut frame);
        let faulted = tof.i2c().faults > 0;
        if !check(&r, tof.i2c(), clean && !faulted, "read_frame") {
            continue;
        }
        let side = tof.resolution().side();
        assert_eq!((frame.rows, frame.cols), (side, side));
        let zones = usize::from(side * side);
        assert!(zones <= N);
        for k in 0..zones {
            let d = frame.distance_mm[k];
            assert!(d == d.trunc() && (0.0..=8191.0).contains(&d), "{k}: {d}");
            if clean && !faulted {
                let z = expect[k];
                if z.status == 255 {
                    assert_eq!(frame.status[k], 255, "{k}");
                } else {
                    assert_eq!(frame.status[k], z.status, "{k}");
                    assert_eq!(d, f32::from(z.distance_mm), "{k}");
                }
            }
        }
    }
}

fuzz_target!(|input: &[u8]| {
    let mut b = Bytes::new(input);
    let cfg = b.u8();
    let arg = b.u8();
    let skip = usize::from(b.u16());
    let expect = zones(b.u32());
    let mut sim = if cfg & 1 != 0 {
        SimVl53l5cx::new()
    } else {
        WARM.with(|w| w.clone())
    };
    sim.set_zones(&expect);
    let bus = FuzzBus {
        sim,
        bytes: b,
        skip,
        transactions: 0,
        failed: 0,
        faults: 0,
    };
    let eight = cfg & 2 != 0;
    let resolution = if eight {
        Resolution::R8x8
    } else {
        Resolution::R4x4
    };
    let small_io = cfg & 0x80 != 0;
    let mut io = vec![0u8; if small_io { 8 * usize::from(arg) } else { 1452 }];
    let config = Config {
        poll_interval_us: 1000,
        frame_timeout_us: 20_000,
        ..Config::default()
    };
    let mut tof = Vl53l5cx::new(bus, NoDelay, sim::stand_in_buffers(), &mut io, config);
    // Parameters the driver accepts: a clean bus must then give a clean run.
    let max_hz = if eight { 15 } else { 60 };
    let settings = cfg & 0x40 != 0;
    let valid =
        !small_io && !(settings && !(1..=max_hz).contains(&arg)) && !(eight && cfg & 0x10 != 0);
    macro_rules! step {
        ($what:literal, $call:expr) => {{
            let r = $call;
            let clean = valid && tof.i2c().faults == 0;
            check(&r, tof.i2c(), clean, $what)
        }};
    }
    if cfg & 1 != 0 && !step!("init", tof.init()) {
        return;
    }
    if eight && !step!("set_resolution", tof.set_resolution(resolution)) {
        return;
    }
    if settings {
        step!(
            "set_ranging_frequency_hz",
            tof.set_ranging_frequency_hz(arg)
        );
        step!("set_integration_time_ms", tof.set_integration_time_ms(10));
        step!(
            "set_ranging_mode",
            tof.set_ranging_mode(RangingMode::Continuous)
        );
        let hz = tof.ranging_frequency_hz();
        if step!("ranging_frequency_hz", hz) && valid && tof.i2c().faults == 0 {
            assert_eq!(hz.ok(), Some(arg));
        }
        let ms = tof.integration_time_ms();
        if step!("integration_time_ms", ms) && valid && tof.i2c().faults == 0 {
            assert_eq!(ms.ok(), Some(10));
        }
    }
    step!("start_ranging", tof.start_ranging());
    let frames = usize::from((cfg >> 2) & 3) + 1;
    let clean = valid && tof.i2c().faults == 0;
    if cfg & 0x10 != 0 {
        // An 8×8 session into a 16-zone frame is `BufferShape` (`valid` is false then).
        read::<16>(&mut tof, frames, clean, &expect);
    } else {
        read::<64>(&mut tof, frames, clean, &expect);
    }
    if cfg & 0x20 != 0 {
        step!("stop_ranging", tof.stop_ranging());
        let r = tof.read_frame(&mut ZoneFrame::<64>::new());
        assert!(matches!(r, Err(Vl53l5cxError::NotRanging)), "{r:?}");
    }
    let (bus, _) = tof.release();
    // init ≈ 400 transactions with every poll answered at once; each poll loop ≤ 501 reads.
    assert!(bus.transactions < 200_000, "{}", bus.transactions);
});
