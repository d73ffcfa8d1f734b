//! The int8 model blob (`docs/blob.md`): its byte [`format`], the [`checksum`] over its payload,
//! the validating [`parse()`]r that turns it into a [`parse::Graph`] without copying weights, or
//! reports a [`BlobError`]. The writer lives with the host's quantizer
//! (`host/src/quantize/blob_format.rs`): the core never allocates.

pub mod checksum;
pub mod error;
pub mod format;
pub mod parse;

pub use error::BlobError;
pub use parse::{parse, Graph, OpInfo, TensorInfo};
