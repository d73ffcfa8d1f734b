//! Fuzzes the zone gate (`depthor_core::zone_gate`): any file bytes into `ZoneGate::parse`
//! (raw, or the shipped phone_lite gate with bytes overwritten), then `run` on images up to
//! 32×32 with arbitrary `f32` candidates and RGB, and buffers of the wrong size.
//!
//! Input: `mode, width, height, flags`, then for mode bit 0 = 0: `u16 length` and that many file
//! bytes; for bit 0 = 1: up to 8 `(u16 offset, u8 value)` edits of the shipped file; then the
//! candidates (`f32` each) and the RGB bytes (missing bytes read as 0). `flags` bit 0: scratch
//! one value short; bit 1: output one value long.
//!
//! Checks the module's promises: nothing panics; a file `parse` accepts has its MAC count and
//! scratch size; a run with finite candidates writes finite depths between the smallest and
//! the largest candidate of each pixel; a refused run leaves the output untouched.
#![no_main]

#[path = "common.rs"]
mod common;

use common::Bytes;
use depthor_core::zone_gate::{GateError, ZoneGate, CANDIDATES};
use libfuzzer_sys::fuzz_target;

static SHIPPED: &[u8] = include_bytes!("../../../models/phone_lite/zone_gate.bin");

fuzz_target!(|input: &[u8]| {
    let mut b = Bytes::new(input);
    let mode = b.u8();
    let (width, height) = (usize::from(b.u8() % 33), usize::from(b.u8() % 33));
    let flags = b.u8();
    let mut edited;
    let file: &[u8] = if mode & 1 == 0 {
        let n = usize::from(b.u16());
        b.take(n)
    } else {
        edited = SHIPPED.to_vec();
        for _ in 0..(mode >> 1) % 9 {
            let at = usize::from(b.u16()) % edited.len();
            edited[at] = b.u8();
        }
        &edited
    };
    let gate = match ZoneGate::parse(file) {
        Ok(g) => g,
        Err(_) => return,
    };
    let _ = gate.macs(width, height);
    let pixels = width * height;
    let cands: Vec<Vec<f32>> = (0..CANDIDATES)
        .map(|_| (0..pixels).map(|_| b.f32()).collect())
        .collect();
    let rgb: Vec<u8> = (0..3 * pixels).map(|_| b.u8()).collect();
    let need = gate.scratch_floats(width, height);
    let mut scratch = vec![0.0f32; need.saturating_sub(usize::from(flags & 1 != 0))];
    let mut out = vec![-7.0f32; pixels + usize::from(flags & 2 != 0)];
    let refs = [&cands[0][..], &cands[1][..], &cands[2][..]];
    match gate.run(refs, &rgb, (width, height), &mut scratch, &mut out) {
        Ok(()) => {
            for p in 0..pixels {
                let c = [cands[0][p], cands[1][p], cands[2][p]];
                if c.iter().all(|v| v.is_finite()) {
                    let lo = c.iter().fold(f32::INFINITY, |a, &v| a.min(v));
                    let hi = c.iter().fold(f32::NEG_INFINITY, |a, &v| a.max(v));
                    let slack = 1e-5 * lo.abs().max(hi.abs()) + 1e-30;
                    assert!(out[p].is_finite(), "pixel {p}: {} from {c:?}", out[p]);
                    assert!(
                        out[p] >= lo - slack && out[p] <= hi + slack,
                        "pixel {p}: {} outside {c:?}",
                        out[p]
                    );
                }
            }
        }
        Err(e) => {
            assert!(matches!(
                e,
                GateError::ImageSize | GateError::BufferSize | GateError::ScratchSize
            ));
            assert!(out.iter().all(|&v| v == -7.0), "a refused run wrote");
        }
    }
});
