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

// SAFETY: primitives and `#[repr(C)]` structs of 4- and 8-byte integer / float fields, no
// padding (`ResizeRescale`: i32, u32, i64, i64, i32, u32 = 32 bytes).
unsafe impl Pod for i8 {}
unsafe impl Pod for i16 {}
unsafe impl Pod for i32 {}
unsafe impl Pod for f32 {}
unsafe impl Pod for ChannelQuant {}
unsafe impl Pod for BinChannel {}
unsafe impl Pod for Rescale {}
unsafe impl Pod for AddQuant {}
unsafe impl Pod for MulQuant {}
unsafe impl Pod for MeanQuant {}
unsafe impl Pod for ResizeRescale {}
// Its fields fill it exactly (4 + 4 + 8 + 8 + 4 + 4): no padding for `Pod`.
const _: () = assert!(core::mem::size_of::<ResizeRescale>() == 32);

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
