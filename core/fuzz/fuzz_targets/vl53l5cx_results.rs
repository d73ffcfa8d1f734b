//! Fuzzes the VL53L5CX driver's result-block parsing (`drivers::vl53l5cx::decode_results`): the
//! bytes read from index 0 of page 2 after data-ready (16-byte preamble, block headers and their
//! payloads, 8-byte footer, every 32-bit word byte-swapped), of any length, with corrupt headers.
//!
//! Input: `cfg, bytes…`. `cfg` bits 0–1 pick the zone count the driver expects: 0 = 16 (4×4),
//! 1 = 64 (8×8), 2 = the next byte (0–255, beyond the 64 the driver holds), 3 = the next two
//! bytes (`u16` LE). The rest of the input is the results buffer.
//!
//! Checks: nothing panics; an error is one of the typed `ResultsError`s (a buffer shorter than
//! preamble + footer is `TooShort` and nothing else is) and leaves the output untouched; a
//! decoded frame holds the expected zone count and the stream count of byte 0, every field is
//! within what its unit conversion can give (distance 0..=8191 mm, sigma ≤ 511 mm,
//! reflectance ≤ 127 %, rates ≤ `u32::MAX / 2048`), and zones beyond the zone count are zero.
#![no_main]

#[path = "common.rs"]
mod common;

use common::Bytes;
use depthor_core::drivers::vl53l5cx::{decode_results, ResultsData, ResultsError, MAX_ZONES};
use libfuzzer_sys::fuzz_target;

/// Preamble + footer: anything shorter is `TooShort`.
const MIN_LEN: usize = 16 + 8;

/// A frame full of non-zero values, to see that a refused buffer leaves it as it was.
fn sentinel() -> ResultsData {
    let mut r = ResultsData::new();
    r.zones = 99;
    r.stream_count = 7;
    r.silicon_temp_degc = -3;
    r.distance_mm = [1234; MAX_ZONES];
    r.target_status = [42; MAX_ZONES];
    r.range_sigma_mm = [17; MAX_ZONES];
    r.has.sigma = true;
    r
}

fuzz_target!(|input: &[u8]| {
    let mut b = Bytes::new(input);
    let zones = match b.u8() & 3 {
        0 => 16,
        1 => 64,
        2 => usize::from(b.u8()),
        _ => usize::from(b.u16()),
    };
    let buf = b.rest();
    let mut out = sentinel();
    match decode_results(buf, zones, &mut out) {
        Err(e) => {
            assert_eq!(out, sentinel(), "output written on {e:?}");
            assert_eq!(
                buf.len() < MIN_LEN,
                e == ResultsError::TooShort,
                "{e:?} for {} bytes",
                buf.len()
            );
            match e {
                ResultsError::Truncated { at } | ResultsError::Misaligned { at } => {
                    assert!(at >= 16 && at + 4 <= buf.len() - 8, "{e:?}");
                }
                ResultsError::TooShort
                | ResultsError::BadBlock { .. }
                | ResultsError::Missing { .. } => {}
            }
        }
        Ok(()) => {
            assert!(buf.len() >= MIN_LEN);
            assert_eq!(out.zones, zones as u8);
            assert_eq!(out.stream_count, buf[0]);
            // A decoded frame has a distance and a status block sized for `zones`.
            let z = zones.min(MAX_ZONES);
            for k in 0..MAX_ZONES {
                assert!((0..=8191).contains(&out.distance_mm[k]), "{k}");
                assert!(out.range_sigma_mm[k] <= 511, "{k}");
                assert!(out.reflectance[k] <= 127, "{k}");
                assert!(out.ambient_per_spad[k] <= u32::MAX / 2048, "{k}");
                assert!(out.signal_per_spad[k] <= u32::MAX / 2048, "{k}");
                if k >= z {
                    assert_eq!(out.distance_mm[k], 0, "{k}");
                    assert_eq!(out.target_status[k], 0, "{k}");
                    assert_eq!(out.nb_target_detected[k], 0, "{k}");
                    assert_eq!(out.nb_spads_enabled[k], 0, "{k}");
                    assert_eq!(out.ambient_per_spad[k], 0, "{k}");
                }
            }
            // Decoding is a function of the bytes: the same buffer decodes the same again.
            let mut again = ResultsData::new();
            assert_eq!(decode_results(buf, zones, &mut again), Ok(()));
            assert_eq!(again, out);
        }
    }
});
