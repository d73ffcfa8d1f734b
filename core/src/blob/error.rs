//! The blob reader's error type: what [`parse()`](super::parse()) reports. `Copy`, so embedded
//! callers can store and match it; the engine reports it as `engine::Error::Blob`.

/// Why a model blob was refused (layout: `docs/blob.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum BlobError {
    /// The blob is malformed at `offset`.
    Bad {
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
}

impl core::fmt::Display for BlobError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BlobError::Bad { offset, what } => write!(f, "bad model blob at byte {offset}: {what}"),
            BlobError::BadChecksum { stored, computed } => write!(
                f,
                "model blob checksum mismatch: header {stored:#010x}, payload {computed:#010x}"
            ),
            BlobError::UnsupportedVersion { found } => {
                write!(f, "unsupported model blob version {found}")
            }
        }
    }
}

impl core::error::Error for BlobError {}
