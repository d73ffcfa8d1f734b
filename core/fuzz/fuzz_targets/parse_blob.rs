//! Fuzzes the model blob: `parse` → `plan_with` / `required_arena_bytes_with` →
//! `Engine::with_memory` → `run` on arbitrary bytes, at a small size and under an arena and a
//! multiply-accumulate limit.
//!
//! Input: `mode, blob…`. Bit 0 of `mode` repairs the CRC, so mutations reach the validation
//! behind the checksum; bits 1–2 pick the plan (streamed, whole, budget); bits 3–5 pick the run
//! size (the blob's own, clamped to 32, or a smaller one). Nothing may panic; a blob that parses
//! must plan the same way twice and run within the arena it asked for.
#![no_main]

use depthor_core::blob::{checksum::crc32, format::HEADER_LEN, parse};
use depthor_core::engine::{plan_with, required_arena_bytes_with, Engine, Memory};
use libfuzzer_sys::fuzz_target;

/// Largest arena the target hands out (the firmware's budget is 384 KiB).
const ARENA_LIMIT: usize = 1 << 22;
/// Largest run the target executes, in multiply-accumulates (`mcu_lite` is 19.5 M at 120×160;
/// every run here is ≤ 32×32). A blob may validly ask for far more (outputs bounded by the
/// arena, taps by the blob): such runs are planned but not executed, so that an execution
/// stays cheap and a timeout means a hang, not a big network.
const MAC_LIMIT: u64 = 1 << 25;

fuzz_target!(|input: &[u8]| {
    let Some((&mode, rest)) = input.split_first() else {
        return;
    };
    let mut blob = rest.to_vec();
    if mode & 1 == 1 && blob.len() >= HEADER_LEN {
        let len = u32::from_le_bytes([blob[8], blob[9], blob[10], blob[11]]) as usize;
        let end = HEADER_LEN.saturating_add(len).min(blob.len());
        let c = crc32(&blob[HEADER_LEN..end]);
        blob[12..16].copy_from_slice(&c.to_le_bytes());
    }
    let Ok(g) = parse(&blob) else { return };
    let memory = match (mode >> 1) & 3 {
        0 | 3 => Memory::Streamed,
        1 => Memory::Whole,
        _ => Memory::Budget(ARENA_LIMIT / 4),
    };
    let (h, w) = match (mode >> 3) & 7 {
        0..=3 => (g.height.min(32), g.width.min(32)),
        4 => (8, 8),
        5 => (4, 4),
        6 => (1, 1),
        _ => (g.height.min(32), 0),
    };
    let Ok(plan) = plan_with(&g, h, w, memory) else {
        return;
    };
    let Ok(need) = required_arena_bytes_with(&blob, h, w, memory) else {
        panic!("plan_with succeeded, required_arena_bytes_with failed");
    };
    assert_eq!(need, plan.arena_bytes(), "two plans of one blob differ");
    if need > ARENA_LIMIT || plan.macs() > MAC_LIMIT {
        return;
    }
    let mut arena = vec![0u8; need];
    if let Ok(mut e) = Engine::with_memory(&blob, &mut arena, h, w, memory) {
        assert_eq!(e.input_shape(), (h, w));
        let rgb = vec![128u8; 3 * h * w];
        let sparse: Vec<f32> = (0..h * w)
            .map(|i| if i % 5 == 0 { 1.5 } else { 0.0 })
            .collect();
        let mut out = vec![0f32; h * w];
        let _ = e.run(&rgb, &sparse, &mut out);
    }
});
