//! Fuzzes `parse` → `required_arena_bytes` → `Engine::with_size` → `run` on arbitrary bytes.
//! The first byte chooses whether the CRC is repaired, so mutations reach the validation behind
//! the checksum. Nothing may panic.
#![no_main]

use depthor_core::blob::{checksum::crc32, format::HEADER_LEN, parse};
use depthor_core::engine::{required_arena_bytes, Engine};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    let Some((&mode, rest)) = input.split_first() else { return };
    let mut blob = rest.to_vec();
    if mode & 1 == 1 && blob.len() >= HEADER_LEN {
        let len = u32::from_le_bytes([blob[8], blob[9], blob[10], blob[11]]) as usize;
        let end = HEADER_LEN.saturating_add(len).min(blob.len());
        let c = crc32(&blob[HEADER_LEN..end]);
        blob[12..16].copy_from_slice(&c.to_le_bytes());
    }
    let Ok(g) = parse(&blob) else { return };
    let (h, w) = (g.height.min(32), g.width.min(32));
    let Ok(need) = required_arena_bytes(&blob, h, w) else { return };
    if need > 1 << 24 {
        return;
    }
    let mut arena = vec![0u8; need];
    if let Ok(mut e) = Engine::with_size(&blob, &mut arena, h, w) {
        let rgb = vec![128u8; 3 * h * w];
        let sparse = vec![1.5f32; h * w];
        let mut out = vec![0f32; h * w];
        let _ = e.run(&rgb, &sparse, &mut out);
    }
});
