//! The one place with `unsafe`: typed views of arena and blob bytes. The arena base is aligned
//! to 16 by `Engine::new` and every planned offset is a multiple of 16, so the views below never
//! see a misaligned start; they still check and return `None` instead of assuming.

use crate::kernels::bins::BinChannel;
use crate::kernels::conv::ChannelQuant;
use crate::kernels::elementwise::{AddQuant, MulQuant, Rescale};
use crate::kernels::pool::MeanQuant;

/// Types for which every bit pattern is a valid value and that have no padding.
///
/// # Safety
/// Implementors must be `#[repr(C)]` (or primitive) structs of `i8`/`i16`/`i32`/`f32` fields
/// only.
pub(crate) unsafe trait Pod: Copy {}

// SAFETY: primitives and `#[repr(C)]` structs of 4-byte integer / float fields, no padding.
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
