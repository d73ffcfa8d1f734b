//! Cortex-M micro-kernels (stable `asm!`, built with core's `arm-dsp` feature).

pub mod bins;
pub mod bytes;
pub mod dsp;
pub mod mul;
pub mod pack;
pub mod refine;
pub mod resize;
