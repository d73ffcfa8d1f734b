//! # depthor-core
//!
//! `#![no_std]`, allocation-free depth completion for a small direct time-of-flight (dToF) sensor
//! beside an RGB camera (DEPTHOR, ICCV 2025). Every buffer comes from the caller.
//!
//! The pipeline, per frame, in the order of the modules below:
//! 1. [`hal`]: the board's [`hal::DtofSensor`] fills a [`hal::ZoneFrame`], its
//!    [`hal::RgbCamera`] fills an [`hal::RgbFrame`]. [`drivers`] holds embedded-hal drivers that
//!    implement those traits (the I2C [`drivers::zone_bridge`]).
//! 2. [`projection`]: zones → sparse depth at camera resolution through the [`calibration`].
//! 3. prior → fusion → bins → refinement: the [`engine`] runs the int8 model [`blob`] (format in
//!    [`blob::format`]) op by op with the [`kernels`] — conv/elementwise/resize/pool in int8
//!    (TFLite int8 arithmetic), then [`kernels::bins`] and [`kernels::refine`] in f32 — inside
//!    one caller-provided arena planned by [`engine::plan()`].
//! 4. [`metrics`]: δ1–3, AbsRel, RMSE, log10, MAE and EWMAE against a reference.
//!
//! [`pipeline::depth_frame`] chains 1–3 for one frame on the caller's buffers (its module doc
//! shows the per-frame call on a board); the engine alone:
//!
//! ```
//! use depthor_core::engine::{required_arena_bytes, Engine, Error};
//!
//! /// One frame at 120×160: RGB888 in, sparse dToF depth in metres in, dense depth out.
//! fn depth_frame(blob: &[u8], arena: &mut [u8], rgb: &[u8], sparse_m: &[f32], out_m: &mut [f32]) -> Result<u64, Error> {
//!     let need = required_arena_bytes(blob, 120, 160)?; // known before anything runs
//!     assert!(arena.len() >= need);
//!     let mut engine = Engine::new(blob, arena)?; // validates, plans, caches constants once
//!     let stats = engine.run(rgb, sparse_m, out_m)?; // per frame: no allocation, no re-validation
//!     Ok(stats.macs)
//! }
//! ```
#![no_std]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod blob;
pub mod calibration;
pub mod drivers;
pub mod engine;
mod fmath;
pub mod hal;
pub mod kernels;
pub mod metrics;
pub mod pipeline;
pub mod projection;
