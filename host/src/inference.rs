//! Host wrapper around the core's int8 engine: owns a model blob and an arena sized by
//! `required_arena_bytes`, and runs frames. The default `mcu` model is embedded in the binary,
//! so `depthor demo` works on a fresh clone with no files to fetch.

use depthor_core::engine::{required_arena_bytes, Engine, Error as EngineError, RunStats};
use std::path::Path;

/// The embedded default model: `models/mcu/depthor.dblob` (120×160, 8×8 zones).
pub static MCU_BLOB: &[u8] = include_bytes!("../../models/mcu/depthor.dblob");

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
    /// The engine rejected the blob or the inputs.
    #[error("model: {0}")]
    Engine(#[from] EngineError),
}

impl Int8Model {
    /// The embedded `mcu` model at its native size.
    pub fn embedded_mcu() -> Result<Self, InferenceError> {
        Self::from_bytes(MCU_BLOB.to_vec(), None)
    }

    /// A model from a blob file, at its native size or at `size = (height, width)`.
    pub fn from_file(path: &Path, size: Option<(usize, usize)>) -> Result<Self, InferenceError> {
        let blob = std::fs::read(path).map_err(|source| InferenceError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(blob, size)
    }

    /// A model from blob bytes (validated here), at its native size or at `size`.
    pub fn from_bytes(blob: Vec<u8>, size: Option<(usize, usize)>) -> Result<Self, InferenceError> {
        let (height, width) = match size {
            Some(s) => s,
            None => depthor_core::blob::parse(&blob).map(|g| (g.height, g.width))?,
        };
        let need = required_arena_bytes(&blob, height, width)?;
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
