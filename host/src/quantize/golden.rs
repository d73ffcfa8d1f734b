//! Reader of the Python export's golden tensors (`models/<variant>/golden/index.json`,
//! `depthor-golden/1`: raw little-endian f32 files named in the index).

use serde::Deserialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// One golden tensor.
#[derive(Clone, Debug, PartialEq)]
pub struct GoldenTensor {
    /// `input`, `output` or `intermediate`.
    pub role: String,
    /// Shape `[1, C, H, W]`.
    pub shape: Vec<usize>,
    /// Values.
    pub data: Vec<f32>,
}

#[derive(Deserialize)]
struct Index {
    format: String,
    tensors: Vec<Entry>,
}

#[derive(Deserialize)]
struct Entry {
    name: String,
    role: String,
    file: String,
    shape: Vec<usize>,
}

/// Why the golden set could not be read.
#[derive(Debug, thiserror::Error)]
pub enum GoldenError {
    /// A file could not be read.
    #[error("{0}: {1}")]
    Io(PathBuf, std::io::Error),
    /// index.json is malformed.
    #[error("{0}: {1}")]
    Index(PathBuf, String),
}

/// Reads every tensor listed in `index_path`, by value name.
pub fn read_golden(index_path: &Path) -> Result<HashMap<String, GoldenTensor>, GoldenError> {
    let text = std::fs::read(index_path).map_err(|e| GoldenError::Io(index_path.into(), e))?;
    let index: Index = serde_json::from_slice(&text)
        .map_err(|e| GoldenError::Index(index_path.into(), e.to_string()))?;
    if index.format != "depthor-golden/1" {
        return Err(GoldenError::Index(
            index_path.into(),
            format!("format {:?}, expected \"depthor-golden/1\"", index.format),
        ));
    }
    let dir = index_path.parent().unwrap_or(Path::new("."));
    let mut out = HashMap::new();
    for e in index.tensors {
        let p = dir.join(&e.file);
        let bytes = std::fs::read(&p).map_err(|err| GoldenError::Io(p.clone(), err))?;
        let n: usize = e.shape.iter().product();
        if bytes.len() != 4 * n {
            return Err(GoldenError::Index(
                p,
                format!("{} bytes, shape {:?} needs {}", bytes.len(), e.shape, 4 * n),
            ));
        }
        let data = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        out.insert(
            e.name,
            GoldenTensor {
                role: e.role,
                shape: e.shape,
                data,
            },
        );
    }
    Ok(out)
}
