//! The int8 model blob (`docs/blob.md`): its byte [`format`], the [`checksum`] over its payload,
//! the validating [`parse()`]r that turns it into a [`parse::Graph`] without copying weights, or
//! reports a [`BlobError`], and (feature `alloc`) its writer, `write`.

pub mod checksum;
pub mod error;
pub mod format;
pub mod parse;
#[cfg(feature = "alloc")]
pub mod write;

pub use error::BlobError;
pub use parse::{parse, Graph, OpInfo, TensorInfo};
