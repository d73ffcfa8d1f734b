//! Sensor drivers on embedded-hal 1.0 buses that implement the [`crate::hal`] traits.
//!
//! - [`zone_bridge`]: the "depthor zone bridge" I2C protocol, host-side driver
//!   ([`zone_bridge::ZoneBridgeSensor`]) and device-side simulator
//!   ([`zone_bridge::ZoneBridgeDevice`]).

pub mod zone_bridge;
