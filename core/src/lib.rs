#![doc = include_str!("../README.md")]
#![no_std]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

// In pipeline order (see the README); the blank lines keep rustfmt from sorting them.
// 1. Sensors.
pub mod hal;

pub mod drivers;

// 2. Zones → sparse depth.
pub mod calibration;

pub mod projection;

// 2b. Zones → dense depth without a network (joint bilateral upsampling).
pub mod interp;

// 3b. The learned blend of the network and the zone interpolations.
pub mod zone_gate;

// 3. The model: blob, engine, kernels.
pub mod blob;
pub mod engine;
mod fmath;
pub mod kernels;
mod ops;

// The one-frame chain of 1–3.
pub mod pipeline;

// 4. Against a reference.
pub mod metrics;
