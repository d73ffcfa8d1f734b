//! The int8 model blob: its byte [`format`], the [`checksum`] over its payload, and the
//! validating [`parse()`]r that turns it into a [`parse::Graph`] without copying weights.

pub mod checksum;
pub mod format;
pub mod parse;

pub use parse::{parse, Graph, OpInfo, TensorInfo};
