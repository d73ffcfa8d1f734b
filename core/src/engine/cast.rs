//! The one place with `unsafe`: typed views of arena and blob bytes. The arena base is aligned
//! to 16 by `Engine::new` and every planned offset is a multiple of 16, so the views below never
//! see a misaligned start; they still check and return `None` instead of assuming.

use crate::kernels::bins::BinChannel;
use crate::kernels::conv::ChannelQuant;
use crate::kernels::elementwise::{AddQuant, MulQuant, Rescale};
use crate::kernels::pool::MeanQuant;
use crate::kernels::resize::ResizeRescale;

/// Types for which every bit pattern is a valid value and that have no padding.
///
/// # Safety
/// Implementors must be `#[repr(C)]` (or primitive) structs of `i8`/`i16`/`i32`/`u32`/`i64`/
/// `f32` fields only, without padding.
pub(crate) unsafe trait Pod: Copy {}

// SAFETY: a primitive integer: every bit pattern is a value, no padding.
unsafe impl Pod for i8 {}
// SAFETY: a primitive integer: every bit pattern is a value, no padding.
unsafe impl Pod for i16 {}
// SAFETY: a primitive integer: every bit pattern is a value, no padding.
unsafe impl Pod for i32 {}
// SAFETY: a primitive integer: every bit pattern is a value, no padding.
unsafe impl Pod for u16 {}
// SAFETY: every bit pattern is an `f32` (NaNs included), no padding.
unsafe impl Pod for f32 {}
// SAFETY: `#[repr(C)]`, an i32 and two `#[repr(C)]` `Requant`s (two i32 each): 20 bytes, no
// padding (asserted below).
unsafe impl Pod for ChannelQuant {}
// SAFETY: `#[repr(C)]`, an i32 and an f32: 8 bytes, no padding (asserted below).
unsafe impl Pod for BinChannel {}
// SAFETY: `#[repr(C)]`, a `Requant` (two i32) and two i32: 16 bytes, no padding (asserted).
unsafe impl Pod for Rescale {}
// SAFETY: `#[repr(C)]`, `[i32; 3]` and three `Requant`s: 36 bytes, no padding (asserted).
unsafe impl Pod for AddQuant {}
// SAFETY: `#[repr(C)]`, `[i32; 3]` and a `Requant`: 20 bytes, no padding (asserted below).
unsafe impl Pod for MulQuant {}
// SAFETY: `#[repr(C)]`, two i32 and a `Requant`: 16 bytes, no padding (asserted below).
unsafe impl Pod for MeanQuant {}
// SAFETY: `#[repr(C)]`, i32, u32, i64, i64, i32, u32 in that order: every field at its natural
// alignment, 32 bytes, no padding (asserted below).
unsafe impl Pod for ResizeRescale {}
// The `Pod` structs' fields fill them exactly: a size equal to the sum of the fields' sizes
// means no padding byte (which a view could expose uninitialised).
const _: () = {
    use core::mem::size_of;
    assert!(size_of::<ChannelQuant>() == 4 + 2 * 8);
    assert!(size_of::<BinChannel>() == 4 + 4);
    assert!(size_of::<Rescale>() == 8 + 4 + 4);
    assert!(size_of::<AddQuant>() == 12 + 3 * 8);
    assert!(size_of::<MulQuant>() == 12 + 8);
    assert!(size_of::<MeanQuant>() == 4 + 4 + 8);
    assert!(size_of::<ResizeRescale>() == 4 + 4 + 8 + 8 + 4 + 4);
};

/// Views `b` as a slice of `T` (trailing bytes that do not fill a `T` are ignored); `None` if
/// `b` is not aligned for `T`.
pub(crate) fn view<T: Pod>(b: &[u8]) -> Option<&[T]> {
    // SAFETY: `T: Pod` accepts any bit pattern; `align_to` upholds alignment and bounds.
    let (pre, mid, _) = unsafe { b.align_to::<T>() };
    pre.is_empty().then_some(mid)
}

/// Mutable version of [`view`].
pub(crate) fn view_mut<T: Pod>(b: &mut [u8]) -> Option<&mut [T]> {
    // SAFETY: as in `view`; any value written through the view is a valid byte pattern.
    let (pre, mid, _) = unsafe { b.align_to_mut::<T>() };
    pre.is_empty().then_some(mid)
}
