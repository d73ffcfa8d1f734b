//! # depthor-host
//!
//! The std side of depthor: recordings (`depthor-recording/1`), file-backed sensors, importers of
//! the real RGB-D sets, and the `depthor` command line.
pub mod atomic;
pub mod baselines;
pub mod dataset;
pub mod evaluation;
pub mod gap;
pub mod import;
pub mod inference;
mod json_field;
pub mod models;
pub mod plot;
pub mod quantize;
pub mod recording;
pub mod reference;
pub mod rng;
pub mod scene;
pub mod sensors;
pub mod sim;
pub mod viz;
