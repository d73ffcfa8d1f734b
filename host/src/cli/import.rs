//! `depthor import <kind> <src> <out>`: converts a real RGB-D set into a `depthor-recording/1`
//! with rgb.png, depth.png and the camera intrinsics (no dToF yet: `depthor sim --from` adds it).

use anyhow::{Context, Result};
use depthor_host::import::{self, ImportKind, ImportedSet};
use depthor_host::recording::{
    CameraMeta, Frame, FrameMeta, RecordingMeta, RecordingWriter, WriteOptions,
};
use std::path::{Path, PathBuf};

/// Arguments of `depthor import`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Which dataset layout `src` holds.
    kind: ImportKind,
    /// The dataset folder (e.g. ../shared/data/real/middlebury2014-Q).
    src: PathBuf,
    /// Output recording directory (must not exist or be empty unless --overwrite).
    out: PathBuf,
    /// Replace an existing recording at `out`.
    #[arg(long)]
    overwrite: bool,
}

/// Loads the set and writes it as one recording.
pub fn handle(args: Args) -> Result<()> {
    let set = import::load(args.kind, &args.src)?;
    let out = write_set(&set, &args.out, args.overwrite)?;
    let stats = set.depth_stats();
    println!(
        "imported {} frames of {} into {}  (depth valid {:.1} %, {:.3}–{:.3} m)",
        set.frames.len(),
        set.name,
        out.display(),
        100.0 * stats.valid_fraction(),
        stats.min_m,
        stats.max_m
    );
    for note in &set.notes {
        println!("note: {note}");
    }
    Ok(())
}

/// Writes an imported set as one recording; frames whose camera differs from the first frame's
/// carry their own `camera` object (docs/recording.md).
pub fn write_set(set: &ImportedSet, out: &Path, overwrite: bool) -> Result<PathBuf> {
    let first = set
        .frames
        .first()
        .with_context(|| format!("{}: no frames to import", set.name))?;
    let base = CameraMeta::from(first.camera);
    let meta = RecordingMeta::new(base, None, None);
    let mut writer = RecordingWriter::create_with(out, meta, WriteOptions { overwrite })?;
    let bar = super::progress(set.frames.len() as u64, "writing frames");
    for f in &set.frames {
        let camera = CameraMeta::from(f.camera);
        let frame_meta = FrameMeta {
            id: f.id.clone(),
            t_s: f.t_s,
            camera: (camera != base).then_some(camera),
        };
        let frame = Frame {
            id: f.id.clone(),
            rgb: f.rgb.clone(),
            depth_m: Some(f.depth_m.clone()),
            labels: None,
            dtof: None,
        };
        writer.add_frame(frame_meta, &frame)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(writer.finish()?)
}
