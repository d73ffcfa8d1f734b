//! Cortex-M micro-kernels (stable `asm!` under `target_feature = "dsp"`).

pub mod dsp;
