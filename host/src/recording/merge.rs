//! Joining shard recordings (`depthor sim --shard K/N`) into one: shard `k` of `N` holds the
//! frames `k, k + N, k + 2N, …` of one run, so the joined recording takes its frames round-robin
//! from the shards in the order given. Frame files are copied byte for byte and the header is
//! written as [`super::RecordingWriter`] writes it, so the union of the shards of a run is
//! byte-identical to the unsharded run.

use super::error::RecordingError;
use super::files;
use super::reader::Recording;
use super::writer::WriteOptions;
use crate::atomic::{AtomicDir, Existing};
use std::path::{Path, PathBuf};

/// Which frames of a run a shard holds: `index` of `count` (frames `index`, `index + count`, …).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// K, in `0..count`.
    pub index: u64,
    /// N ≥ 1.
    pub count: u64,
}

/// Why a `--shard` value is not `K/N` with 0 ≤ K < N.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ShardError {
    /// No `/`.
    #[error("{text:?}: expected K/N, e.g. 0/4")]
    Form {
        /// The value.
        text: String,
    },
    /// K or N is not a whole number.
    #[error("{text:?}: {part} {value:?}: {source}")]
    Number {
        /// The value.
        text: String,
        /// `K` or `N`.
        part: &'static str,
        /// Its text.
        value: String,
        /// Why it does not parse.
        source: std::num::ParseIntError,
    },
    /// K ≥ N or N = 0.
    #[error("{text:?}: need 0 <= K < N and N >= 1")]
    Range {
        /// The value.
        text: String,
    },
}

impl Shard {
    /// The whole run (`0/1`).
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Parses `K/N` (0 ≤ K < N); the error says what is wrong with `text`.
    pub fn parse(text: &str) -> Result<Shard, ShardError> {
        let (k, n) = text.split_once('/').ok_or_else(|| ShardError::Form {
            text: text.to_string(),
        })?;
        let parse = |s: &str, part: &'static str| {
            s.trim()
                .parse::<u64>()
                .map_err(|source| ShardError::Number {
                    text: text.to_string(),
                    part,
                    value: s.to_string(),
                    source,
                })
        };
        let (index, count) = (parse(k, "K")?, parse(n, "N")?);
        if count == 0 || index >= count {
            return Err(ShardError::Range {
                text: text.to_string(),
            });
        }
        Ok(Shard { index, count })
    }

    /// The frame indices of a run of `n` frames that this shard holds, in order.
    pub fn frames(&self, n: u64) -> impl Iterator<Item = u64> {
        (self.index..n).step_by(self.count as usize)
    }

    /// How many of a run's `n` frames this shard holds.
    pub fn len(&self, n: u64) -> u64 {
        n.saturating_sub(self.index).div_ceil(self.count)
    }

    /// True when the shard holds none of a run's `n` frames.
    pub fn is_empty(&self, n: u64) -> bool {
        self.len(n) == 0
    }
}

/// Writes the recording made of `shards` (shard k at position k, as written by
/// `--shard k/N` with N = `shards.len()`) to `out`, atomically. Refuses shards whose headers
/// (camera, dToF, extrinsics) differ from the first's, frame counts that are not those of one
/// run split N ways, and duplicate frame ids. Returns the written path.
pub fn merge_shards(
    shards: &[Recording],
    out: impl AsRef<Path>,
    options: WriteOptions,
) -> Result<PathBuf, RecordingError> {
    let out = out.as_ref();
    let header = out.join(files::RECORDING_JSON);
    let Some(first) = shards.first() else {
        return Err(RecordingError::new(
            out,
            "shards",
            "no shard recording given",
        ));
    };
    let m0 = first.meta();
    for s in &shards[1..] {
        let m = s.meta();
        let path = s.dir().join(files::RECORDING_JSON);
        for (field, same) in [
            ("format", m.format == m0.format),
            ("camera", m.camera == m0.camera),
            ("dtof", m.dtof == m0.dtof),
            ("dtof_to_camera", m.dtof_to_camera == m0.dtof_to_camera),
        ] {
            if !same {
                return Err(RecordingError::new(
                    path,
                    field,
                    format_args!(
                        "differs from {} (shards of one run share the header)",
                        first.dir().join(files::RECORDING_JSON).display()
                    ),
                ));
            }
        }
    }
    let n = shards.len() as u64;
    let total: u64 = shards.iter().map(|s| s.len() as u64).sum();
    for (k, s) in shards.iter().enumerate() {
        let want = Shard {
            index: k as u64,
            count: n,
        }
        .len(total);
        if s.len() as u64 != want {
            return Err(RecordingError::new(
                s.dir().join(files::RECORDING_JSON),
                "frames",
                format_args!(
                    "{} frames, but shard {k}/{n} of a {total}-frame run holds {want} \
                     (give the shards in order 0/{n} … {}/{n}, all of them)",
                    s.len(),
                    n - 1
                ),
            ));
        }
    }
    let existing = if options.overwrite {
        Existing::Replace
    } else {
        Existing::Refuse
    };
    let dir = AtomicDir::create(out, existing)?;
    let frames_dir = dir.path().join(files::FRAMES);
    std::fs::create_dir_all(&frames_dir)
        .map_err(|e| RecordingError::io(&frames_dir, "create", e))?;
    let mut meta = m0.clone();
    meta.frames.clear();
    let mut seen = std::collections::HashSet::new();
    for g in 0..total as usize {
        let (s, j) = (&shards[g % shards.len()], g / shards.len());
        let fm = &s.meta().frames[j];
        if !seen.insert(fm.id.clone()) {
            return Err(RecordingError::new(
                s.dir().join(files::RECORDING_JSON),
                format!("frames[{j}].id"),
                format_args!("duplicate frame id {:?} across the shards", fm.id),
            ));
        }
        copy_dir(
            &s.dir().join(files::FRAMES).join(&fm.id),
            &frames_dir.join(&fm.id),
        )?;
        let preview = s.dir().join("preview").join(format!("{}.png", fm.id));
        if preview.is_file() {
            let to = dir.path().join("preview");
            std::fs::create_dir_all(&to).map_err(|e| RecordingError::io(&to, "create", e))?;
            let to = to.join(format!("{}.png", fm.id));
            std::fs::copy(&preview, &to).map_err(|e| RecordingError::io(&to, "copy", e))?;
        }
        meta.frames.push(fm.clone());
    }
    meta.validate()
        .map_err(|e| RecordingError::at(&header, e))?;
    let path = dir.path().join(files::RECORDING_JSON);
    let text =
        serde_json::to_vec_pretty(&meta).map_err(|e| RecordingError::new(&path, "encode", e))?;
    std::fs::write(&path, text).map_err(|e| RecordingError::io(&path, "write", e))?;
    Ok(dir.commit()?)
}

/// Copies the files of frame directory `from` (flat) into a new directory `to`.
fn copy_dir(from: &Path, to: &Path) -> Result<(), RecordingError> {
    std::fs::create_dir_all(to).map_err(|e| RecordingError::io(to, "create", e))?;
    let entries = std::fs::read_dir(from).map_err(|e| RecordingError::io(from, "read", e))?;
    for e in entries {
        let e = e.map_err(|e| RecordingError::io(from, "read", e))?;
        let src = e.path();
        if src.is_file() {
            let dst = to.join(e.file_name());
            std::fs::copy(&src, &dst).map_err(|e| RecordingError::io(&dst, "copy", e))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Shard;

    #[test]
    fn shard_parse_and_frames() {
        let s = Shard::parse("1/3").unwrap();
        assert_eq!(s.frames(8).collect::<Vec<_>>(), vec![1, 4, 7]);
        assert_eq!((s.len(8), s.len(1), s.len(0)), (3, 0, 0));
        assert_eq!(Shard::parse("2/3").unwrap().len(8), 2);
        assert_eq!(Shard::ALL.frames(3).collect::<Vec<_>>(), vec![0, 1, 2]);
        for bad in ["3/3", "0/0", "1", "a/2", "-1/2", "1/"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }
}
