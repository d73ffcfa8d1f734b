//! x86-64 micro-kernels (`core::arch` intrinsics behind `#[target_feature]`); callers check
//! [`super::isa::Isa::available`] first.

pub mod avx2;
pub mod avx512_vnni;
pub mod bins;
pub mod refine;
pub mod requant;
pub mod vmath;
