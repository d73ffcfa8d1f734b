//! Host wrapper around the core's int8 engine: owns a model blob and an arena sized by
//! `required_arena_bytes`, and runs frames. The `mcu_lite` (the demo's default) and `mcu` int8
//! blobs are embedded in the binary, so `depthor demo` works on a fresh clone with no files to
//! fetch.

use depthor_core::blob::BlobError;
use depthor_core::engine::{required_arena_bytes, Engine, Error as EngineError, RunStats};
use std::path::Path;

/// The embedded `mcu` model: `models/mcu/depthor.dblob` (120×160, 8×8 zones).
pub static MCU_BLOB: &[u8] = include_bytes!("../../models/mcu/depthor.dblob");

/// The embedded `mcu_lite` model, the demo's default: `models/mcu_lite/depthor.dblob` (120×160,
/// 8×8 zones; issue 16's mcu budget).
pub static MCU_LITE_BLOB: &[u8] = include_bytes!("../../models/mcu_lite/depthor.dblob");

/// The blob embedded for `variant`, if one is.
pub fn embedded_blob(variant: &str) -> Option<&'static [u8]> {
    match variant {
        "mcu" => Some(MCU_BLOB),
        "mcu_lite" => Some(MCU_LITE_BLOB),
        _ => None,
    }
}

/// Largest input (height × width) a blob may ask for: 16 Mpx.
pub const MAX_INPUT_PIXELS: usize = 1 << 24;

/// Extra arena bytes so the engine can align its base.
const ALIGN_SLACK: usize = 64;

/// An int8 model ready to run at a fixed input size.
#[derive(Debug)]
pub struct Int8Model {
    blob: Vec<u8>,
    arena: Vec<u8>,
    height: usize,
    width: usize,
}

/// Errors of the host wrapper.
#[derive(Debug, thiserror::Error)]
pub enum InferenceError {
    /// The blob file could not be read.
    #[error("{}: cannot read model blob: {source}", path.display())]
    Read {
        /// The blob path.
        path: std::path::PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The engine rejected a blob given as bytes, or the inputs.
    #[error("model: {}", engine_detail(.0))]
    Engine(EngineError),
    /// The engine rejected the blob file at `path`: `<path>: byte <offset>: <what>`.
    #[error("{}: {}", path.display(), engine_detail(error))]
    Blob {
        /// The blob path.
        path: std::path::PathBuf,
        /// The engine's reason (its offset is in the message).
        error: EngineError,
    },
}

// No `#[from]`: a source would make `{:#}` print the engine's message a second time.
impl From<EngineError> for InferenceError {
    fn from(e: EngineError) -> Self {
        InferenceError::Engine(e)
    }
}

/// One line for an engine error: a blob problem as `byte <offset>: <what>`, the others as the
/// engine says them.
pub fn engine_detail(e: &EngineError) -> String {
    match e {
        EngineError::Blob(BlobError::Bad { offset, what }) => format!("byte {offset}: {what}"),
        EngineError::Blob(BlobError::BadChecksum { stored, computed }) => format!(
            "byte 12: payload CRC-32 {computed:#010x} differs from the header's {stored:#010x}"
        ),
        EngineError::Blob(BlobError::UnsupportedVersion { found }) => {
            format!("byte 4: format version {found} is not supported (allowed 1)")
        }
        other => other.to_string(),
    }
}

impl Int8Model {
    /// The model embedded for `variant` ([`embedded_blob`]) at its native size; `None` where
    /// none is.
    pub fn embedded(variant: &str) -> Option<Result<Self, InferenceError>> {
        embedded_blob(variant).map(|b| Self::from_bytes(b.to_vec(), None))
    }

    /// A model from a blob file, at its native size or at `size = (height, width)`.
    pub fn from_file(path: &Path, size: Option<(usize, usize)>) -> Result<Self, InferenceError> {
        let blob = std::fs::read(path).map_err(|source| InferenceError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(blob, size).map_err(|e| match e {
            InferenceError::Engine(error) => InferenceError::Blob {
                path: path.to_path_buf(),
                error,
            },
            other => other,
        })
    }

    /// A model from blob bytes (validated here), at its native size or at `size`.
    pub fn from_bytes(blob: Vec<u8>, size: Option<(usize, usize)>) -> Result<Self, InferenceError> {
        let (height, width) = match size {
            Some(s) => s,
            None => depthor_core::blob::parse(&blob)
                .map(|g| (g.height, g.width))
                .map_err(EngineError::Blob)?,
        };
        // Bounded before planning, so a header claiming a huge input is refused at once.
        if height == 0 || width == 0 || height.saturating_mul(width) > MAX_INPUT_PIXELS {
            return Err(InferenceError::Engine(EngineError::Blob(BlobError::Bad {
                offset: 16,
                what: "input height × width out of range (allowed 1 to 16 Mpx)",
            })));
        }
        let need = required_arena_bytes(&blob, height, width)?;
        if need as u64 > crate::sim::memory_limit_bytes() {
            return Err(InferenceError::Engine(EngineError::ArenaTooSmall {
                need,
                have: crate::sim::memory_limit_bytes() as usize,
            }));
        }
        let mut model = Int8Model {
            blob,
            arena: vec![0u8; need + ALIGN_SLACK],
            height,
            width,
        };
        // Validate once, so later runs fail only on their inputs.
        model.engine()?;
        Ok(model)
    }

    /// Input size `(height, width)`.
    pub fn input_shape(&self) -> (usize, usize) {
        (self.height, self.width)
    }

    /// Arena bytes the engine needs at this size.
    pub fn arena_bytes(&self) -> usize {
        self.arena.len() - ALIGN_SLACK
    }

    /// Model blob size in bytes.
    pub fn blob_bytes(&self) -> usize {
        self.blob.len()
    }

    /// SHA-256 of the blob, lower-case hex (names the exact model in eval summaries).
    pub fn blob_sha256(&self) -> String {
        use sha2::Digest;
        sha2::Sha256::digest(&self.blob)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }

    /// Bytes of int8 weights in the blob (validated at construction, so 0 only for a model
    /// without convolutions).
    pub fn int8_weight_bytes(&self) -> usize {
        depthor_core::blob::parse(&self.blob).map_or(0, |g| g.int8_weight_bytes())
    }

    fn engine(&mut self) -> Result<Engine<'_>, EngineError> {
        Engine::with_size(&self.blob, &mut self.arena, self.height, self.width)
    }

    /// Prepares the engine once and hands it to `f`, which may run many frames on it (what a
    /// device does; [`Int8Model::run`] prepares per call).
    pub fn with_engine<R>(
        &mut self,
        f: impl FnOnce(&mut Engine<'_>) -> R,
    ) -> Result<R, InferenceError> {
        let mut engine = self.engine()?;
        Ok(f(&mut engine))
    }

    /// Runs one frame: RGB888 (H·W·3) and sparse depth in metres (H·W) → dense depth (H·W, m).
    pub fn run(
        &mut self,
        rgb: &[u8],
        sparse_m: &[f32],
    ) -> Result<(Vec<f32>, RunStats), InferenceError> {
        let mut out = vec![0.0f32; self.height * self.width];
        let stats = self.engine()?.run(rgb, sparse_m, &mut out)?;
        Ok((out, stats))
    }
}
