//! The model both builds run: the int8 blob `models/mcu_lite/depthor.dblob` (or the one the
//! build-time variable `DEPTHOR_MODEL_BLOB` names, e.g. `models/mcu/depthor.dblob`; see
//! `build.rs`), embedded with
//! `include_bytes!` (in the firmware it lies in flash, in `.rodata`), and the arena size the
//! firmware reserves for it.
//!
//! The blob parser reads every field through byte slices (`from_le_bytes`), so it needs no
//! alignment of the blob in memory; its parameters are 16-byte aligned *relative to the blob
//! start* (see `depthor_core::blob::format`), and [`MCU_BLOB`] is placed on a 16-byte boundary so
//! that they are also 16-byte aligned in memory, should a kernel ever read them by words.

use core::mem::MaybeUninit;
use depthor_core::engine::{self, Engine, Memory};

/// 16-byte alignment wrapper for embedded bytes.
#[repr(C, align(16))]
pub struct Align16<B: ?Sized>(pub B);

static ALIGNED_BLOB: &Align16<[u8]> =
    &Align16(*include_bytes!(concat!(env!("OUT_DIR"), "/model.dblob")));

/// The embedded int8 model blob (16-byte aligned; `mcu_lite` unless the build names another).
pub static MCU_BLOB: &[u8] = &ALIGNED_BLOB.0;

/// Arena bytes the firmware reserves: 384 KiB (the internal-SRAM goal, docs/design.md) unless
/// the build sets `DEPTHOR_ARENA_KIB`; the default `mcu_lite` blob needs 366 015 B at 120×160,
/// `mcu`'s smallest plan 384 175 B (`core/tests/arena_budget.rs`). [`Engine::with_memory`]
/// reports `ArenaTooSmall` when a blob needs more.
pub const ARENA_BUDGET_BYTES: usize = match option_env!("DEPTHOR_ARENA_KIB") {
    Some(kib) => parse_kib(kib) * 1024,
    None => 384 * 1024,
};

/// `DEPTHOR_ARENA_KIB` as a number (a build error if it is not one).
const fn parse_kib(s: &str) -> usize {
    let b = s.as_bytes();
    assert!(!b.is_empty(), "DEPTHOR_ARENA_KIB: empty");
    let mut n = 0usize;
    let mut i = 0;
    while i < b.len() {
        assert!(
            b[i].is_ascii_digit(),
            "DEPTHOR_ARENA_KIB: not a number of KiB"
        );
        n = n * 10 + (b[i] - b'0') as usize;
        i += 1;
    }
    n
}

/// Prepares the engine once for the replay image's `height × width` with the fastest plan that
/// fits [`ARENA_BUDGET_BYTES`] ([`Memory::Budget`]).
pub fn prepare<'a>(
    blob: &'a [u8],
    arena: &'a mut [u8],
    height: u16,
    width: u16,
) -> Result<Engine<'a>, engine::Error> {
    let (h, w) = (usize::from(height), usize::from(width));
    Engine::with_memory(blob, arena, h, w, Memory::Budget(ARENA_BUDGET_BYTES))
}

/// As [`prepare`], building the engine in `slot` (the firmware's `static`, so the engine never
/// sits on the stack: [`Engine::init_in`]).
pub fn prepare_in<'s, 'a>(
    slot: &'s mut MaybeUninit<Engine<'a>>,
    blob: &'a [u8],
    arena: &'a mut [u8],
    height: u16,
    width: u16,
) -> Result<&'s mut Engine<'a>, engine::Error> {
    let (h, w) = (usize::from(height), usize::from(width));
    Engine::init_in(slot, blob, arena, h, w, Memory::Budget(ARENA_BUDGET_BYTES))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blob_is_aligned_and_fits_the_budgets() {
        assert_eq!(MCU_BLOB.as_ptr() as usize % 16, 0);
        // docs/design.md: mcu weights ≤ 512 KiB (the blob holds the weights plus the graph).
        assert!(MCU_BLOB.len() <= 512 * 1024, "{}", MCU_BLOB.len());
        let need = engine::required_arena_bytes(MCU_BLOB, 120, 160).unwrap();
        assert!(need <= ARENA_BUDGET_BYTES, "{need}");
    }
}
