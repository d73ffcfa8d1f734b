//! Sensor drivers on embedded-hal 1.0 buses that implement the [`crate::hal`] traits.
//!
//! - [`zone_bridge`]: the "depthor zone bridge" I2C protocol, host-side driver
//!   ([`zone_bridge::ZoneBridgeSensor`]) and device-side simulator
//!   ([`zone_bridge::ZoneBridgeDevice`]).
//! - [`vl53l5cx`]: ST's VL53L5CX over ST's ULD protocol ([`vl53l5cx::Vl53l5cx`]) and a simulated
//!   sensor ([`vl53l5cx::sim::SimVl53l5cx`]).

pub mod vl53l5cx;
pub mod zone_bridge;
