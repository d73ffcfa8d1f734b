//! aarch64 micro-kernels (`core::arch::aarch64` intrinsics, and `asm!` for `SDOT`, whose
//! intrinsics are not stable yet); callers check [`super::isa::Isa::available`] first.

pub mod bins;
pub mod depthwise;
pub mod dotprod;
pub mod elementwise;
pub mod joint_bilateral;
pub mod neon;
pub mod pack;
pub mod pool;
pub mod refine;
pub mod requant;
pub mod resize;
pub mod vmath;
pub mod zone_gate;
