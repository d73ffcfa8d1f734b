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
    /// The blob was refused by the reader ([`crate::blob::parse()`]): malformed at an offset,
    /// a checksum mismatch or an unsupported version.
    Blob(BlobError),
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
    /// A staged-I/O call (`Engine::staging`, `Engine::run_staged`, `Engine::output_m`,
    /// `Engine::output_mm`) on an engine not built with `Io::Arena` (or whose output is not
    /// f32).
    NotStaged,
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
        Error::Blob(e)
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
            Error::Blob(e) => write!(f, "{e}"),
            Error::ShapeMismatch {
                what,
                expected,
                found,
            } => {
                write!(f, "{what}: expected {expected} elements, found {found}")
            }
            Error::Plan(e) => write!(f, "cannot plan the graph: {e}"),
            Error::Kernel { op, error } => write!(f, "op {op}: {error}"),
            Error::NotStaged => f.write_str("the engine was not built for inputs in its arena"),
        }
    }
}

impl core::error::Error for Error {}
