//! Fuzzes `Engine::run` / `run_in_place` with arbitrary input buffers on a valid blob (the
//! micro test network, every op of the vocabulary) at four sizes: any RGB bytes, sparse depths
//! of any `f32` bit pattern (NaN, ±inf, negative, subnormal, huge), and buffers of the wrong
//! length.
//!
//! Input: `mode, [len deltas], rgb…, sparse…` (missing bytes read as 0). `mode` bit 0: run in
//! place; bit 1: take the three buffer lengths from the input (usually wrong); bits 2–3: how
//! the sparse values are made (raw `f32` bits, a palette of special values, one special value
//! everywhere, millimetres as `u16`); bits 4–5: the size, 4×4, 8×8, 4×16 or 12×16 (small, so
//! that an execution is cheap; 16 columns reach the 16-lane kernels' full vectors).
//!
//! Checks: nothing panics; a wrong length is an error; a run that succeeds writes only finite
//! depths, and the portable kernels and the fastest set this CPU has give the same bits.
#![no_main]

#[path = "common.rs"]
mod common;

use std::sync::{Mutex, OnceLock};

use common::{Bytes, MICRO_BLOB};
use depthor_core::engine::{required_arena_bytes, Engine};
use depthor_core::kernels::isa::Isa;
use libfuzzer_sys::fuzz_target;

const SPECIAL: [f32; 16] = [
    0.0,
    -0.0,
    f32::NAN,
    -f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    -1.0,
    f32::MIN_POSITIVE / 4.0, // subnormal
    f32::MAX,
    f32::MIN,
    1e-30,
    0.1,
    1.5,
    4.0,
    10.0,
    1e6,
];

/// The sizes `mode` bits 4–5 pick.
const SIZES: [(usize, usize); 4] = [(4, 4), (8, 8), (4, 16), (12, 16)];

/// One engine per size and kernel set (portable, then the fastest), prepared once per process
/// (planning is not what this target measures; `parse_blob` fuzzes it). Kept in a `static`,
/// so their leaked arenas stay reachable and LeakSanitizer does not report them at exit.
fn engines() -> Vec<[Engine<'static>; 2]> {
    SIZES
        .iter()
        .map(|&(h, w)| {
            let need = required_arena_bytes(MICRO_BLOB, h, w).expect("seed blob plans");
            [Isa::Portable, Isa::best()].map(|isa| {
                let arena: &'static mut [u8] = Box::leak(vec![0u8; need].into_boxed_slice());
                let mut e = Engine::with_size(MICRO_BLOB, arena, h, w).expect("seed blob prepares");
                e.set_kernels(isa).expect("available");
                e
            })
        })
        .collect()
}

static ENGINES: OnceLock<Mutex<Vec<[Engine<'static>; 2]>>> = OnceLock::new();

fuzz_target!(|input: &[u8]| {
    let mut b = Bytes::new(input);
    let mode = b.u8();
    {
        let mut all = ENGINES
            .get_or_init(|| Mutex::new(engines()))
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        let engines = &mut all[usize::from(mode >> 4) & 3];
        let (h, w) = engines[0].input_shape();
        let n = h * w;
        let (mut rgb_len, mut sparse_len, mut out_len) = (3 * n, n, n);
        if mode & 2 != 0 {
            // Near the right length most of the time, anything up to 4·n otherwise.
            let pick = |v: u16, right: usize| match v & 3 {
                0 => right + 1,
                1 => right.saturating_sub(1),
                2 => usize::from(v >> 2) % (4 * right + 1),
                _ => right,
            };
            rgb_len = pick(b.u16(), 3 * n);
            sparse_len = pick(b.u16(), n);
            out_len = pick(b.u16(), n);
        }
        let rgb: Vec<u8> = (0..rgb_len).map(|_| b.u8()).collect();
        let sparse: Vec<f32> = match (mode >> 2) & 3 {
            0 => (0..sparse_len).map(|_| b.f32()).collect(),
            1 => (0..sparse_len)
                .map(|_| SPECIAL[usize::from(b.u8() & 15)])
                .collect(),
            2 => vec![SPECIAL[usize::from(b.u8() & 15)]; sparse_len],
            _ => (0..sparse_len)
                .map(|_| f32::from(b.u16()) / 1000.0)
                .collect(),
        };
        let in_place = mode & 1 != 0;
        // In place, the depth buffer is the sparse values cut or padded to `out_len`.
        let lengths_ok = rgb.len() == 3 * n && out_len == n && (in_place || sparse.len() == n);
        let mut outputs = Vec::new();
        for e in engines.iter_mut() {
            let (result, out) = if in_place {
                let mut depth = sparse.clone();
                depth.resize(out_len, 0.0);
                (e.run_in_place(&rgb, &mut depth), depth)
            } else {
                let mut out = vec![0f32; out_len];
                (e.run(&rgb, &sparse, &mut out), out)
            };
            match result {
                Ok(_) => {
                    assert!(lengths_ok, "a buffer of the wrong length was accepted");
                    if let Some(v) = out.iter().find(|v| !v.is_finite()) {
                        panic!("non-finite depth {v} in the output");
                    }
                    outputs.push(out);
                }
                Err(err) => assert!(!lengths_ok, "valid buffers refused: {err}"),
            }
        }
        if let [a, b] = &outputs[..] {
            let same = a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
            assert!(same, "portable and {:?} kernels differ", Isa::best());
        }
    }
});
