//! # depthor-replay
//!
//! What the `firmware-sim` firmware and its host build share, so both run the same code:
//!
//! - [`format`]: the replay flash image (`DPTHRPLY` v1): layout, and a `no_std` parser that
//!   validates everything and never panics; its checksum is the core's
//!   [`depthor_core::blob::checksum::crc32`] (zlib's CRC-32, as for the model blob).
//! - [`camera`]: [`camera::ReplayCamera`], an [`depthor_core::hal::RgbCamera`] over the image.
//! - [`model`]: the embedded int8 blob (`mcu_lite` by default, 16-byte aligned) and the arena budget.
//! - [`frametime`]: instructions per frame over a set of frames (min, max, mean, spread), for the
//!   firmware's check on adversarial frames.
//! - [`pipeline`]: the per-frame loop (camera → VL53L5CX driver over the simulated sensor, or the
//!   zone bridge → projection → int8 engine)
//!   and the hash line both builds print.
//! - with the `std` feature: [`host`] (the host build of the loop), [`writer`] (`write_image`)
//!   and [`synthetic`] frames, plus the binaries `make-image` and `replay-host`.
//!
//! # Exit status of the firmware
//!
//! | code | meaning |
//! |---|---|
//! | 0 | every frame processed |
//! | 2–8 | the image is unusable: [`format::ImageError::exit_code`] (2 magic, 3 version, 4 header, 5 truncated, 6 trailing bytes, 7 CRC, 8 zone count) |
//! | 10–17 | the loop stopped: [`pipeline::LoopError::exit_code`] (10 camera, 11 dToF driver, 12 bridge device or a grid the VL53L5CX lacks, 13 zone capacity, 14 workspace, 15 projection, 16 engine, 17 no valid zone) |
//! | 101 | panic (a bug: nothing here should panic on any image) |
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]

pub mod camera;
pub mod format;
pub mod frametime;
#[cfg(any(test, feature = "std"))]
pub mod host;
pub mod model;
pub mod pipeline;
#[cfg(any(test, feature = "std"))]
pub mod synthetic;
#[cfg(any(test, feature = "std"))]
pub mod writer;

/// Exit status of a firmware panic.
pub const EXIT_PANIC: u8 = 101;
