//! Atomic outputs: every command that writes a folder or a file writes it into a temporary
//! sibling `<out>.partial-<pid>`, renames it onto `<out>` only once everything is written, and
//! removes it on any error (a dropped [`AtomicDir`] deletes its folder). A run killed before
//! that (SIGKILL, power loss) leaves only the sibling; the next run for the same `<out>`
//! removes such siblings whose process is gone and names them on stderr, and leaves those of a
//! process still running. So `<out>` is either absent, as it was, or complete.

use std::fmt;
use std::path::{Path, PathBuf};

/// What [`AtomicDir::commit`] does with a destination that already holds something.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Existing {
    /// Refuse a non-empty destination (checked at creation too, before any work).
    Refuse,
    /// Replace it whole (moved aside, the new folder renamed in, the old one deleted).
    Replace,
    /// Keep it and move each new entry into it, replacing entries of the same name (for
    /// result folders such as `eval/mcu` that a user may keep other files in).
    Merge,
}

/// An output could not be prepared, written or moved into place.
#[derive(Debug, thiserror::Error)]
#[error("{}: {what}: {message}", path.display())]
pub struct OutputError {
    /// The file or folder concerned.
    pub path: PathBuf,
    /// The step (`create`, `rename onto`, `output`…).
    pub what: String,
    /// What went wrong, one line.
    pub message: String,
}

impl OutputError {
    fn new(path: &Path, what: &str, message: impl fmt::Display) -> Self {
        OutputError {
            path: path.to_path_buf(),
            what: what.into(),
            message: message.to_string(),
        }
    }
}

/// `(parent, file name)` of `out`; `out` must name something (not `/`, `.` or `..`).
fn split(out: &Path) -> Result<(PathBuf, String), OutputError> {
    let name = match out.file_name() {
        Some(n)
            if out
                .components()
                .next_back()
                .is_some_and(|c| matches!(c, std::path::Component::Normal(_))) =>
        {
            n.to_string_lossy().into_owned()
        }
        _ => {
            return Err(OutputError::new(
                out,
                "output",
                "must name a file or folder (not `/`, `.` or `..`)",
            ))
        }
    };
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Ok((parent, name))
}

/// The temporary sibling of `out` for this process: `<out>.partial-<pid>`.
pub fn partial_path(out: &Path) -> Result<PathBuf, OutputError> {
    let (parent, name) = split(out)?;
    Ok(parent.join(format!("{name}.{}", tag("partial"))))
}

fn tag(kind: &str) -> String {
    format!("{kind}-{}", std::process::id())
}

/// Whether process `pid` is running (Linux `/proc`; elsewhere every other process counts as
/// running, so its siblings are named but kept).
fn alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return false;
    }
    let proc_fs = Path::new("/proc/self");
    !proc_fs.exists() || Path::new("/proc").join(pid.to_string()).exists()
}

/// Removes the temporary siblings of `out` (`<out>.partial-<pid>`, `<out>.old-<pid>` and the
/// older hidden `.<out>.partial-<pid>`) left by runs that are gone, saying so on stderr;
/// siblings of running processes are named and kept. Returns the removed paths.
pub fn clean_stale(out: &Path) -> Vec<PathBuf> {
    let Ok((parent, name)) = split(out) else {
        return Vec::new();
    };
    let Ok(entries) = std::fs::read_dir(&parent) else {
        return Vec::new();
    };
    let prefixes = [
        format!("{name}.partial-"),
        format!("{name}.old-"),
        format!(".{name}.partial-"),
        format!(".{name}.old-"),
    ];
    let mut removed = Vec::new();
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = prefixes
            .iter()
            .find_map(|p| file.strip_prefix(p.as_str()))
            .and_then(|rest| rest.parse::<u32>().ok())
        else {
            continue;
        };
        let path = e.path();
        if alive(pid) {
            eprintln!(
                "note: {} is being written by process {pid}; left alone",
                path.display()
            );
            continue;
        }
        let gone = if path.is_dir() {
            std::fs::remove_dir_all(&path)
        } else {
            std::fs::remove_file(&path)
        };
        match gone {
            Ok(()) => {
                if pid != std::process::id() {
                    eprintln!(
                        "note: removed {}, left by an interrupted run (process {pid})",
                        path.display()
                    );
                }
                removed.push(path);
            }
            Err(err) => eprintln!(
                "note: {}: cannot remove stale output: {err}",
                path.display()
            ),
        }
    }
    removed
}

fn is_empty_dir(p: &Path) -> bool {
    std::fs::read_dir(p)
        .map(|mut it| it.next().is_none())
        .unwrap_or(false)
}

/// Fails when `out` holds something that `existing` does not allow replacing.
fn check_destination(out: &Path, existing: Existing) -> Result<(), OutputError> {
    if existing != Existing::Refuse || !out.exists() || is_empty_dir(out) {
        return Ok(());
    }
    Err(OutputError::new(
        out,
        "output",
        "exists and is not empty (allowed: an absent or empty folder, or --overwrite)",
    ))
}

/// A folder being written: files go into [`AtomicDir::path`]; [`AtomicDir::commit`] moves it
/// onto the destination; dropping it uncommitted deletes it.
#[derive(Debug)]
pub struct AtomicDir {
    out: PathBuf,
    tmp: PathBuf,
    existing: Existing,
    committed: bool,
}

impl AtomicDir {
    /// Cleans stale siblings of `out`, checks the destination (a non-empty one is refused
    /// under [`Existing::Refuse`]) and creates the empty `<out>.partial-<pid>`.
    pub fn create(out: impl AsRef<Path>, existing: Existing) -> Result<Self, OutputError> {
        let out = out.as_ref().to_path_buf();
        let tmp = partial_path(&out)?;
        clean_stale(&out);
        check_destination(&out, existing)?;
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| OutputError::new(&tmp, "remove stale", e))?;
        }
        std::fs::create_dir_all(&tmp).map_err(|e| OutputError::new(&tmp, "create", e))?;
        Ok(AtomicDir {
            out,
            tmp,
            existing,
            committed: false,
        })
    }

    /// The temporary folder to write into.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// The destination.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// Moves the written folder onto the destination (see [`Existing`]); returns its path.
    pub fn commit(mut self) -> Result<PathBuf, OutputError> {
        let out = self.out.clone();
        check_destination(&out, self.existing)?;
        let rename = |from: &Path, to: &Path| {
            std::fs::rename(from, to).map_err(|e| OutputError::new(to, "rename onto", e))
        };
        if out.is_dir() && !is_empty_dir(&out) {
            match self.existing {
                Existing::Refuse => unreachable!("checked above"),
                Existing::Replace => {
                    let (parent, name) = split(&out)?;
                    let old = parent.join(format!("{name}.{}", tag("old")));
                    rename(&out, &old)?;
                    rename(&self.tmp, &out)?;
                    // The new folder is in place; failing to delete the old one loses nothing.
                    let _ = std::fs::remove_dir_all(&old);
                }
                Existing::Merge => {
                    let entries = std::fs::read_dir(&self.tmp)
                        .map_err(|e| OutputError::new(&self.tmp, "read", e))?;
                    for e in entries {
                        let e = e.map_err(|e| OutputError::new(&self.tmp, "read", e))?;
                        let dest = out.join(e.file_name());
                        if dest.is_dir() {
                            std::fs::remove_dir_all(&dest)
                                .map_err(|e| OutputError::new(&dest, "replace", e))?;
                        }
                        rename(&e.path(), &dest)?;
                    }
                    std::fs::remove_dir(&self.tmp)
                        .map_err(|e| OutputError::new(&self.tmp, "remove", e))?;
                }
            }
        } else {
            if out.is_dir() {
                std::fs::remove_dir(&out)
                    .map_err(|e| OutputError::new(&out, "replace empty", e))?;
            } else if out.exists() || out.is_symlink() {
                std::fs::remove_file(&out).map_err(|e| OutputError::new(&out, "replace", e))?;
            }
            rename(&self.tmp, &out)?;
        }
        self.committed = true;
        Ok(out)
    }
}

impl Drop for AtomicDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
    }
}

/// Writes `bytes` to `out` atomically: into `<out>.partial-<pid>` (synced), then renamed onto
/// `out`; on error the partial file is removed and `out` is as it was.
pub fn write_file(out: impl AsRef<Path>, bytes: &[u8]) -> Result<(), OutputError> {
    use std::io::Write;
    let out = out.as_ref();
    let tmp = partial_path(out)?;
    clean_stale(out);
    if out.is_dir() {
        return Err(OutputError::new(
            out,
            "output",
            "is a folder (allowed: a file path)",
        ));
    }
    let result = std::fs::File::create(&tmp)
        .and_then(|mut f| {
            f.write_all(bytes)?;
            f.sync_all()
        })
        .map_err(|e| OutputError::new(&tmp, "write", e))
        .and_then(|()| {
            std::fs::rename(&tmp, out).map_err(|e| OutputError::new(out, "rename onto", e))
        });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dir_is_absent_until_commit_and_removed_on_drop() {
        let t = tempfile::tempdir().unwrap();
        let out = t.path().join("res");
        {
            let d = AtomicDir::create(&out, Existing::Refuse).unwrap();
            std::fs::write(d.path().join("a.txt"), "x").unwrap();
            assert!(!out.exists());
        }
        assert!(std::fs::read_dir(t.path()).unwrap().next().is_none());
        let d = AtomicDir::create(&out, Existing::Refuse).unwrap();
        std::fs::write(d.path().join("a.txt"), "x").unwrap();
        d.commit().unwrap();
        assert_eq!(std::fs::read_to_string(out.join("a.txt")).unwrap(), "x");
        assert!(AtomicDir::create(&out, Existing::Refuse).is_err());
        // Merge keeps other files and replaces same-named ones.
        std::fs::write(out.join("keep.txt"), "k").unwrap();
        let d = AtomicDir::create(&out, Existing::Merge).unwrap();
        std::fs::write(d.path().join("a.txt"), "y").unwrap();
        d.commit().unwrap();
        assert_eq!(std::fs::read_to_string(out.join("a.txt")).unwrap(), "y");
        assert!(out.join("keep.txt").exists());
        // Replace drops them.
        let d = AtomicDir::create(&out, Existing::Replace).unwrap();
        std::fs::write(d.path().join("b.txt"), "z").unwrap();
        d.commit().unwrap();
        assert!(!out.join("keep.txt").exists() && out.join("b.txt").exists());
        assert_eq!(std::fs::read_dir(t.path()).unwrap().count(), 1);
    }

    #[test]
    fn stale_siblings_of_dead_processes_are_removed() {
        let t = tempfile::tempdir().unwrap();
        let out = t.path().join("res");
        // No process has a pid this large (Linux caps pids at 2^22).
        let stale = t.path().join("res.partial-4294967");
        std::fs::create_dir_all(stale.join("frames")).unwrap();
        let hidden = t.path().join(".res.partial-4294966");
        std::fs::create_dir_all(&hidden).unwrap();
        let unrelated = t.path().join("res.partial-notapid");
        std::fs::create_dir_all(&unrelated).unwrap();
        let removed = clean_stale(&out);
        assert_eq!(removed.len(), 2, "{removed:?}");
        assert!(!stale.exists() && !hidden.exists() && unrelated.exists());
    }

    #[test]
    fn files_are_written_whole_or_not_at_all() {
        let t = tempfile::tempdir().unwrap();
        let out = t.path().join("m.dblob");
        write_file(&out, b"abc").unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"abc");
        assert!(write_file(t.path(), b"x").is_err());
        let missing = t.path().join("no/such/dir/m.dblob");
        assert!(write_file(&missing, b"x").is_err());
        assert_eq!(std::fs::read_dir(t.path()).unwrap().count(), 1);
    }
}
