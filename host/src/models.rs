//! The shipped models on disk. `models/<variant>/` holds `depthor.dblob` (int8 blob for the
//! core), `depthor.nnef.tgz` (the float network for tract) and `prior.nnef.tgz` (the monocular
//! prior alone). Commands take `--model mcu`, `--model phone` or a directory with those files.

use std::path::{Path, PathBuf};

/// The variants shipped in `models/`.
pub const VARIANTS: [&str; 2] = ["mcu", "phone"];

/// Where one model's files are.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ModelFiles {
    /// The model directory.
    pub dir: PathBuf,
    /// Variant name (the directory name): also the simulator preset its inputs come from.
    pub variant: String,
}

/// A `--model` argument that names neither a directory nor a shipped variant.
#[derive(Debug, thiserror::Error)]
#[error("model {given:?}: not a directory and not a shipped variant ({}); looked in {}", VARIANTS.join(", "), looked.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "))]
pub struct UnknownModel {
    /// The argument.
    pub given: String,
    /// Directories tried.
    pub looked: Vec<PathBuf>,
}

impl ModelFiles {
    /// Resolves `name_or_dir`: an existing directory, else `models/<variant>` under the current
    /// directory, else under the source tree this binary was built from.
    pub fn resolve(name_or_dir: &str) -> Result<Self, UnknownModel> {
        let given = Path::new(name_or_dir);
        let mut looked = vec![given.to_path_buf()];
        if !given.is_dir() && VARIANTS.contains(&name_or_dir) {
            looked.push(Path::new("models").join(name_or_dir));
            looked.push(
                Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("../models")
                    .join(name_or_dir),
            );
        }
        let dir = looked
            .iter()
            .find(|p| p.is_dir())
            .cloned()
            .ok_or_else(|| UnknownModel {
                given: name_or_dir.to_string(),
                looked: looked.clone(),
            })?;
        let variant = dir.file_name().map_or_else(
            || name_or_dir.to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        Ok(ModelFiles { dir, variant })
    }

    /// The int8 blob (core).
    pub fn blob(&self) -> PathBuf {
        self.dir.join("depthor.dblob")
    }

    /// The float network (tract).
    pub fn nnef(&self) -> PathBuf {
        self.dir.join("depthor.nnef.tgz")
    }

    /// The monocular prior alone (tract).
    pub fn prior_nnef(&self) -> PathBuf {
        self.dir.join("prior.nnef.tgz")
    }

    /// Simulator preset for this model's inputs: the variant name when it is a shipped one,
    /// else `mcu`.
    pub fn preset(&self) -> &str {
        VARIANTS
            .iter()
            .find(|v| **v == self.variant)
            .copied()
            .unwrap_or("mcu")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolves_variants_and_rejects_unknown_names() {
        let m = ModelFiles::resolve("mcu").unwrap();
        assert_eq!(m.variant, "mcu");
        assert!(m.blob().is_file());
        assert_eq!(m.preset(), "mcu");
        let e = ModelFiles::resolve("nano").unwrap_err().to_string();
        assert!(e.contains("\"nano\"") && e.contains("mcu, phone"), "{e}");
    }
}
