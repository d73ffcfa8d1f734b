//! The shipped models on disk. `models/<variant>/` holds `depthor.dblob` (int8 blob for the
//! core), `depthor.nnef.tgz` (the float network for tract) and `prior.nnef.tgz` (the monocular
//! prior alone). Commands take `--model mcu_lite` (the demo's default), `--model mcu`, `--model
//! phone_lite`, `--model phone` or a directory with those files.
//!
//! A variant name is looked up, in order, in the folder given by `--models-dir` (or the
//! `DEPTHOR_MODELS` environment variable), beside the binary (`<bin>/models`,
//! `<bin>/../share/depthor/models`), under the current folder (`models/`) and in the source tree
//! the binary was built from (when it still exists). `mcu_lite` and `mcu` need none of them for
//! their int8 blobs: those are embedded in the binary ([`crate::inference::embedded_blob`]).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The folder `--models-dir` / `DEPTHOR_MODELS` named, set once by the command line.
static MODELS_DIR: OnceLock<PathBuf> = OnceLock::new();

/// Makes `dir` the first place variant names are looked up (`--models-dir`). A second call is
/// ignored.
pub fn set_models_dir(dir: PathBuf) {
    let _ = MODELS_DIR.set(dir);
}

/// The folders that may hold `<variant>/`, in lookup order.
pub fn search_dirs() -> Vec<PathBuf> {
    let mut dirs = Vec::new();
    if let Some(d) = MODELS_DIR.get() {
        dirs.push(d.clone());
    } else if let Some(d) = std::env::var_os("DEPTHOR_MODELS") {
        dirs.push(PathBuf::from(d));
    }
    if let Some(bin) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        dirs.push(bin.join("models"));
        dirs.push(bin.join("../share/depthor/models"));
    }
    dirs.push(PathBuf::from("models"));
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
    if source.is_dir() {
        dirs.push(source);
    }
    dirs
}

/// The variants shipped in `models/`.
pub const VARIANTS: [&str; 4] = ["mcu_lite", "mcu", "phone_lite", "phone"];

/// The simulator preset (sensor and image size) of each shipped variant.
const PRESETS: [(&str, &str); 4] = [
    ("mcu_lite", "mcu"),
    ("mcu", "mcu"),
    ("phone_lite", "phone"),
    ("phone", "phone"),
];

/// Where one model's files are.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ModelFiles {
    /// The model directory.
    pub dir: PathBuf,
    /// Variant name (the directory name), for output paths and summaries.
    pub variant: String,
    /// The network the folder holds: `graph.json`'s `variant` where it names a shipped one
    /// (a candidate folder such as `runs/cand1` exported as `phone_lite`), else [`Self::variant`].
    /// Decides the simulator preset of the model's inputs.
    pub network: String,
    /// No folder was found and the variant's int8 blob is embedded in the binary (`mcu_lite`,
    /// `mcu`; the float network and the prior are not available).
    pub embedded: bool,
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
    /// Resolves `name_or_dir`: an existing directory, else `<variant>` in [`search_dirs`]; a
    /// variant with an embedded blob found nowhere resolves to that blob.
    pub fn resolve(name_or_dir: &str) -> Result<Self, UnknownModel> {
        let given = Path::new(name_or_dir);
        let mut looked = vec![given.to_path_buf()];
        if !given.is_dir() && VARIANTS.contains(&name_or_dir) {
            looked.extend(search_dirs().into_iter().map(|d| d.join(name_or_dir)));
        }
        let Some(dir) = looked.iter().find(|p| p.is_dir()).cloned() else {
            if crate::inference::embedded_blob(name_or_dir).is_some() {
                return Ok(ModelFiles {
                    dir: PathBuf::from("<embedded>"),
                    variant: name_or_dir.into(),
                    network: name_or_dir.into(),
                    embedded: true,
                });
            }
            return Err(UnknownModel {
                given: name_or_dir.to_string(),
                looked,
            });
        };
        let variant = dir.file_name().map_or_else(
            || name_or_dir.to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let network = graph_variant(&dir).unwrap_or_else(|| variant.clone());
        Ok(ModelFiles {
            dir,
            variant,
            network,
            embedded: false,
        })
    }

    /// Where the files are, for messages and summaries: the folder, or `embedded`.
    pub fn describe(&self) -> String {
        if self.embedded {
            format!("embedded in the binary ({} int8 blob only)", self.variant)
        } else {
            self.dir.display().to_string()
        }
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

    /// The learned zone gate (`depthor_core::zone_gate`), shipped with some models only.
    pub fn zone_gate(&self) -> PathBuf {
        self.dir.join("zone_gate.bin")
    }

    /// Simulator preset for this model's inputs: that of the shipped network the folder holds
    /// ([`Self::network`], [`PRESETS`]), else `mcu`.
    pub fn preset(&self) -> &str {
        PRESETS
            .iter()
            .find(|(v, _)| *v == self.network)
            .map_or("mcu", |(_, p)| p)
    }
}

/// The shipped variant named by `<dir>/graph.json`'s `variant` field; `None` when the file is
/// missing, unreadable, not JSON or names no shipped variant (the folder name decides then).
fn graph_variant(dir: &Path) -> Option<String> {
    let text = std::fs::read_to_string(dir.join("graph.json")).ok()?;
    let graph: serde_json::Value = serde_json::from_str(&text).ok()?;
    let v = graph.get("variant")?.as_str()?;
    VARIANTS.contains(&v).then(|| v.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolves_variants_and_rejects_unknown_names() {
        let m = ModelFiles::resolve("mcu").unwrap();
        assert_eq!(m.variant, "mcu");
        assert!(!m.embedded, "the source tree's models/mcu is found");
        assert!(m.blob().is_file());
        assert_eq!(m.preset(), "mcu");
        let lite = ModelFiles::resolve("mcu_lite").unwrap();
        assert_eq!((lite.variant.as_str(), lite.preset()), ("mcu_lite", "mcu"));
        assert!(lite.blob().is_file());
        let phone_lite = ModelFiles::resolve("phone_lite").unwrap();
        assert_eq!(phone_lite.preset(), "phone");
        assert!(phone_lite.blob().is_file());
        // A candidate folder of another name takes its network's preset from graph.json.
        let tmp = tempfile::tempdir().unwrap();
        let cand = tmp.path().join("cand1");
        std::fs::create_dir(&cand).unwrap();
        let cand_s = cand.to_str().unwrap();
        assert_eq!(ModelFiles::resolve(cand_s).unwrap().preset(), "mcu");
        std::fs::write(cand.join("graph.json"), r#"{"variant": "phone_lite"}"#).unwrap();
        let c = ModelFiles::resolve(cand_s).unwrap();
        assert_eq!((c.variant.as_str(), c.preset()), ("cand1", "phone"));
        std::fs::write(cand.join("graph.json"), r#"{"variant": "nano"}"#).unwrap();
        assert_eq!(ModelFiles::resolve(cand_s).unwrap().preset(), "mcu");
        let e = ModelFiles::resolve("nano").unwrap_err().to_string();
        assert!(
            e.contains("\"nano\"") && e.contains("mcu_lite, mcu, phone_lite, phone"),
            "{e}"
        );
    }

    #[test]
    fn embedded_blobs_are_the_shipped_ones() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
        for v in ["mcu_lite", "mcu"] {
            let on_disk = std::fs::read(root.join(v).join("depthor.dblob")).unwrap();
            assert_eq!(
                crate::inference::embedded_blob(v),
                Some(on_disk.as_slice()),
                "{v}"
            );
        }
        assert_eq!(crate::inference::embedded_blob("phone"), None);
    }
}
