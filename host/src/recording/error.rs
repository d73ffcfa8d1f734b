//! The one error type of recording I/O: always names the file and the field.

use std::fmt;
use std::path::{Path, PathBuf};

/// A recording could not be read or written.
///
/// Displays as one line, `<path>: <field>: <message>`, e.g.
/// `rec/frames/000003/dtof.json: distance_mm: expected 64 values, found 63`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}: {field}: {message}", path.display())]
pub struct RecordingError {
    /// The file or directory concerned.
    pub path: PathBuf,
    /// The field inside it (`camera.fx`, `frames[3].id`, `distance_mm[5]`), or the aspect of the
    /// file (`color type`, `size`, `JSON syntax`, `read`).
    pub field: String,
    /// What is wrong, one line.
    pub message: String,
}

impl RecordingError {
    /// Builds an error; line breaks in `message` are folded so the error stays one line.
    pub fn new(
        path: impl Into<PathBuf>,
        field: impl Into<String>,
        message: impl fmt::Display,
    ) -> Self {
        let one_line = |s: String| s.split_whitespace().collect::<Vec<_>>().join(" ");
        RecordingError {
            path: path.into(),
            field: one_line(field.into()),
            message: one_line(message.to_string()),
        }
    }

    /// An I/O failure on `path` while doing `what` (`read`, `write`, `create`…).
    pub(crate) fn io(path: &Path, what: &str, e: std::io::Error) -> Self {
        RecordingError::new(path, what, e)
    }

    /// Attaches `path` to a field-level problem found by validation.
    pub(crate) fn at(path: &Path, invalid: Invalid) -> Self {
        RecordingError::new(path, invalid.field, invalid.message)
    }
}

/// A problem with one field, before the file it came from is known.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct Invalid {
    /// Field path (`camera.fx`, `frames[2].t_s`).
    pub field: String,
    /// What is wrong.
    pub message: String,
}

impl Invalid {
    /// A problem with `field`.
    pub fn new(field: impl Into<String>, message: impl fmt::Display) -> Self {
        Invalid {
            field: field.into(),
            message: message.to_string(),
        }
    }
}
