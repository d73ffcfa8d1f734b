//! Thin root package of the depthor workspace: its `tests/` hold cross-crate tests.
//! The product lives in `depthor-core` (no_std) and `depthor-host` (std, CLI `depthor`).
#![no_std]
pub use depthor_core as core_crate;
