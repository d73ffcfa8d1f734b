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

/// The 12×16 test network's blob (every op of the vocabulary; `core/tests/common`), committed
/// as the fuzzing seed: unit tests of the parser and the engine run on it (small enough for
/// Miri).
#[cfg(test)]
pub(crate) static TEST_BLOB: &[u8] = include_bytes!("../../fuzz/seeds/tiny_net.dblob");
