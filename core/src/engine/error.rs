//! The engine's error type: everything `Engine::new`, `required_arena_bytes` and `Engine::run`
//! can report. Errors are `Copy` so embedded callers can store and match them freely.

use crate::blob::BlobError;
use crate::engine::plan::PlanError;
use crate::kernels::KernelError;

/// Why the engine refused a blob, an arena or a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// The arena is smaller than the plan needs.
    ArenaTooSmall {
        /// Bytes the plan needs (including alignment slack).
        need: usize,
        /// Bytes the caller gave.
        have: usize,
    },
    /// The blob is malformed at `offset`.
    BadBlob {
        /// Byte offset into the blob.
        offset: usize,
        /// What was wrong there.
        what: &'static str,
    },
    /// The payload CRC-32 does not match the header.
    BadChecksum {
        /// CRC stored in the header.
        stored: u32,
        /// CRC computed over the payload.
        computed: u32,
    },
    /// The blob's format version is not one this core reads.
    UnsupportedVersion {
        /// Version found in the header.
        found: u16,
    },
    /// A caller buffer has the wrong length for the engine's input size.
    ShapeMismatch {
        /// Which buffer.
        what: &'static str,
        /// Elements expected.
        expected: usize,
        /// Elements given.
        found: usize,
    },
    /// The graph cannot be planned at the requested size.
    Plan(PlanError),
    /// A kernel refused its operands (a bug in validation if it ever happens).
    Kernel {
        /// Index of the op in the blob.
        op: usize,
        /// The kernel's reason.
        error: KernelError,
    },
}

impl From<BlobError> for Error {
    fn from(e: BlobError) -> Self {
        match e {
            BlobError::Bad { offset, what } => Error::BadBlob { offset, what },
            BlobError::BadChecksum { stored, computed } => Error::BadChecksum { stored, computed },
            BlobError::UnsupportedVersion { found } => Error::UnsupportedVersion { found },
        }
    }
}

impl From<PlanError> for Error {
    fn from(e: PlanError) -> Self {
        Error::Plan(e)
    }
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::ArenaTooSmall { need, have } => {
                write!(f, "arena too small: need {need} bytes, have {have}")
            }
            Error::BadBlob { offset, what } => write!(f, "bad model blob at byte {offset}: {what}"),
            Error::BadChecksum { stored, computed } => {
                write!(
                    f,
                    "model blob checksum mismatch: header {stored:#010x}, payload {computed:#010x}"
                )
            }
            Error::UnsupportedVersion { found } => {
                write!(f, "unsupported model blob version {found}")
            }
            Error::ShapeMismatch {
                what,
                expected,
                found,
            } => {
                write!(f, "{what}: expected {expected} elements, found {found}")
            }
            Error::Plan(e) => write!(f, "cannot plan the graph: {e}"),
            Error::Kernel { op, error } => write!(f, "op {op}: {error}"),
        }
    }
}

impl core::error::Error for Error {}
