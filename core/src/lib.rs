//! # depthor-core
//!
//! `#![no_std]`, allocation-free depth completion for a small direct time-of-flight (dToF) sensor
//! beside an RGB camera (DEPTHOR, ICCV 2025). Every buffer comes from the caller.
//!
//! The pipeline, per frame, in the order of the modules below:
//! 1. [`hal`]: the board's [`hal::DtofSensor`] fills a [`hal::ZoneFrame`], its
//!    [`hal::RgbCamera`] fills an [`hal::RgbFrame`].
//! 2. [`projection`]: zones → sparse depth at camera resolution through the [`calibration`].
//! 3. prior → fusion → bins → refinement: the int8 engine (see the model-path issue).
//! 4. [`metrics`]: δ1–3, AbsRel, RMSE, log10, MAE and EWMAE against a reference.
#![no_std]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod blob;
pub mod calibration;
pub mod engine;
pub mod hal;
pub mod kernels;
pub mod metrics;
pub mod projection;
