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
use depthor_core::engine::{self, Engine, Io, Memory};

/// 16-byte alignment wrapper for embedded bytes.
#[repr(C, align(16))]
pub struct Align16<B: ?Sized>(pub B);

static ALIGNED_BLOB: &Align16<[u8]> =
    &Align16(*include_bytes!(concat!(env!("OUT_DIR"), "/model.dblob")));

/// The embedded int8 model blob (16-byte aligned; `mcu_lite` unless the build names another).
pub static MCU_BLOB: &[u8] = &ALIGNED_BLOB.0;

/// Arena bytes the default blob (`mcu_lite`) needs at 120×160 with the firmware's plan
/// ([`prepare`]: [`Memory::Budget`], [`Io::Arena`], so the RGB, sparse and dense depth maps are
/// inside), rounded up to 16; the tests fail if the need grows past it or shrinks well below it.
pub const MCU_LITE_ARENA_BYTES: usize = 289_200;

/// Arena bytes the firmware reserves: [`MCU_LITE_ARENA_BYTES`] for the default blob; for another,
/// 384 KiB (the internal-SRAM goal, docs/design.md; `mcu`'s smallest plan needs 384 191 B,
/// `core/tests/arena_budget.rs`) plus 75 KiB for the f32 output area at 120×160 (`mcu`'s
/// refinement writes the output, which is then not a tensor of the plan:
/// [`depthor_core::engine::Plan::output_tail_bytes`]); unless the build sets
/// `DEPTHOR_ARENA_KIB`.
/// [`Engine::init_in`] reports `ArenaTooSmall` when a blob needs more.
pub const ARENA_BUDGET_BYTES: usize = match option_env!("DEPTHOR_ARENA_KIB") {
    Some(kib) => parse_kib(kib) * 1024,
    None if DEFAULT_BLOB => MCU_LITE_ARENA_BYTES,
    None => (384 + 75) * 1024,
};

/// Whether the embedded blob is the default `mcu_lite` (`build.rs`).
const DEFAULT_BLOB: bool = matches!(env!("DEPTHOR_DEFAULT_BLOB").as_bytes(), b"1");

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

/// Prepares the engine once, in `slot` (the firmware's `static`: the engine never sits on the
/// stack, [`Engine::init_in`]), for the replay image's `height × width` with the fastest plan
/// that fits [`ARENA_BUDGET_BYTES`] ([`Memory::Budget`]) and the frame buffers in the arena
/// ([`Io::Arena`]: the loop captures and projects into [`Engine::staging`] and reads
/// [`Engine::output_m`]).
pub fn prepare<'s, 'a>(
    slot: &'s mut MaybeUninit<Engine<'a>>,
    blob: &'a [u8],
    arena: &'a mut [u8],
    height: u16,
    width: u16,
) -> Result<&'s mut Engine<'a>, engine::Error> {
    let (h, w) = (usize::from(height), usize::from(width));
    Engine::init_in(
        slot,
        blob,
        arena,
        h,
        w,
        Memory::Budget(ARENA_BUDGET_BYTES),
        Io::Arena,
    )
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

    /// The firmware's arena is what the default blob needs, no more: a plan that grows fails
    /// here (and the firmware with `ArenaTooSmall`), one that shrinks asks for the constant to
    /// follow.
    #[test]
    fn arena_reservation_fits_the_default_blob_tightly() {
        if !DEFAULT_BLOB || option_env!("DEPTHOR_ARENA_KIB").is_some() {
            return;
        }
        let budget = Memory::Budget(ARENA_BUDGET_BYTES);
        let need = engine::required_arena_bytes_io(MCU_BLOB, 120, 160, budget, Io::Arena).unwrap();
        assert!(
            need <= MCU_LITE_ARENA_BYTES,
            "mcu_lite arena grew: {need} B"
        );
        assert!(
            MCU_LITE_ARENA_BYTES - need < 1024,
            "mcu_lite arena shrank to {need} B: lower MCU_LITE_ARENA_BYTES"
        );
        // The staging areas cost nothing: the same bytes as with the caller's buffers.
        let caller = engine::required_arena_bytes_with(MCU_BLOB, 120, 160, budget).unwrap();
        assert_eq!(need, caller);
    }
}
