//! Conventions every subcommand follows (one home for each):
//!
//! - the input recording is `--recording DIR` (`-r`); older spellings (`--real`, `--from`, a
//!   positional path) are hidden aliases;
//! - `--out` is a folder; `--overwrite` lets a command write into a non-empty one, which it
//!   refuses otherwise;
//! - seeds default to [`DEFAULT_SEED`];
//! - a frame is chosen by its id (`000003`) or its index (`3`) ([`frame_index`]);
//! - human output is rounded; `--json` prints the same results as JSON on stdout.

use anyhow::{bail, Context, Result};
use depthor_host::atomic::{AtomicDir, Existing};
use depthor_host::recording::Recording;
use std::path::{Path, PathBuf};

/// The seed every subcommand starts from unless `--seed` says otherwise.
pub const DEFAULT_SEED: u64 = 0;

/// The input recording: `--recording DIR`, or (older spelling) a positional path.
pub fn input_recording(flag: Option<PathBuf>, positional: Option<PathBuf>) -> Result<PathBuf> {
    match (flag, positional) {
        (Some(p), None) | (None, Some(p)) => Ok(p),
        (Some(_), Some(_)) => bail!("--recording: given twice (as --recording and as a path)"),
        (None, None) => bail!("--recording: required (the recording folder, holds recording.json)"),
    }
}

/// How an output folder treats what is already there: refused unless `--overwrite`, then
/// merged (files of the same name replaced, others kept).
pub fn existing(overwrite: bool) -> Existing {
    if overwrite {
        Existing::Merge
    } else {
        Existing::Refuse
    }
}

/// Stages the output folder `out` (see [`existing`]).
pub fn out_dir(out: &Path, overwrite: bool) -> Result<AtomicDir> {
    Ok(AtomicDir::create(out, existing(overwrite))?)
}

/// Where a one-file command writes: `--out` is a folder and the file gets `name` in it. An
/// `--out` ending in `.<ext>` (the older spelling, a file path) still names the file itself.
pub struct OutFile {
    /// The file to write.
    pub path: PathBuf,
    /// The folder it goes into (created when missing).
    pub dir: PathBuf,
}

impl OutFile {
    /// Resolves `--out` for a file called `name` (older spelling: `--out something.<ext>`).
    pub fn new(out: &Path, name: &str) -> Self {
        let ext = Path::new(name).extension();
        if ext.is_some() && out.extension() == ext && !out.is_dir() {
            let dir = out
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
            return OutFile {
                path: out.to_path_buf(),
                dir,
            };
        }
        OutFile {
            path: out.join(name),
            dir: out.to_path_buf(),
        }
    }

    /// Writes `bytes` atomically, refusing an existing file unless `overwrite`.
    pub fn write(&self, bytes: &[u8], overwrite: bool) -> Result<()> {
        if self.path.exists() && !overwrite {
            bail!(
                "{}: exists (pass --overwrite to replace it)",
                self.path.display()
            );
        }
        std::fs::create_dir_all(&self.dir)
            .with_context(|| format!("{}: cannot create", self.dir.display()))?;
        depthor_host::atomic::write_file(&self.path, bytes)?;
        Ok(())
    }
}

/// The frame `sel` names in `rec`: a frame id, else a 0-based index.
pub fn frame_index(rec: &Recording, sel: &str) -> Result<usize> {
    if let Some(i) = rec.index_of(sel) {
        return Ok(i);
    }
    match sel.parse::<usize>() {
        Ok(i) if i < rec.len() => Ok(i),
        _ => bail!(
            "{}: frames: no frame with id or index {:?} ({} frames: ids {}, indices 0 to {})",
            rec.dir().join("recording.json").display(),
            sel,
            rec.len(),
            match rec.meta().frames.as_slice() {
                [] => "none".to_string(),
                [one] => one.id.clone(),
                [first, .., last] => format!("{} … {}", first.id, last.id),
            },
            rec.len().saturating_sub(1)
        ),
    }
}

/// Prints `v` as pretty JSON on stdout (`--json`).
pub fn print_json(v: &serde_json::Value) -> Result<()> {
    println!("{}", serde_json::to_string_pretty(v)?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_file_is_a_folder_unless_it_ends_in_the_files_extension() {
        let f = OutFile::new(Path::new("x/points"), "project_000003.png");
        assert_eq!(f.path, Path::new("x/points/project_000003.png"));
        let f = OutFile::new(Path::new("x/points.png"), "project_000003.png");
        assert_eq!(f.path, Path::new("x/points.png"));
        assert_eq!(f.dir, Path::new("x"));
        let f = OutFile::new(Path::new("p.png"), "a.png");
        assert_eq!(f.dir, Path::new("."));
    }
}
