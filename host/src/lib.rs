//! # depthor-host
//!
//! The std side of depthor: recordings (`depthor-recording/1`), file-backed sensors, importers of
//! the real RGB-D sets, and the `depthor` command line.
pub mod reference;
pub mod rng;
