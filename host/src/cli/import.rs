//! `depthor import <kind> <src> --out DIR`: converts a real set into a `depthor-recording/1`
//! with rgb.png, depth.png and the camera intrinsics; sets with their own zones (`zjul5`,
//! `vl53l5cx-log`, `uld-dump`) keep them as dtof.json, the others get simulated ones from
//! `depthor sim --recording`.

use anyhow::{Context, Result};
use depthor_host::import::{self, ImportKind, ImportedSet};
use depthor_host::recording::{Frame, FrameMeta, RecordingMeta, RecordingWriter, WriteOptions};
use std::path::{Path, PathBuf};

/// Arguments of `depthor import`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor import middlebury ../shared/data/real/middlebury2014-Q --out rec/middlebury
  depthor import nyu ../shared/data/real/metric3d-nyu-demo --out rec/nyu --overwrite
  depthor import zjul5 ZJUL5/ --out rec/zjul5                    # .h5 files: rgb, depth, zones
  depthor import vl53l5cx-log ../shared/data/real/vecihi-vl53l5cx-flights --out rec/flights
  depthor import uld-dump uld_results.txt --out rec/uld         # ST ULD VL53L5CX_ResultsData dumps
Then: depthor info --recording rec/middlebury")]
pub struct Args {
    /// Which dataset layout `src` holds.
    kind: ImportKind,
    /// The dataset folder (e.g. ../shared/data/real/middlebury2014-Q).
    src: PathBuf,
    /// Output recording folder (must not exist or be empty unless --overwrite).
    #[arg(long = "out", value_name = "DIR")]
    out_flag: Option<PathBuf>,
    /// The same as a path (older spelling).
    #[arg(value_name = "OUT", hide = true)]
    out: Option<PathBuf>,
    /// Replace an existing recording at `out`.
    #[arg(long)]
    overwrite: bool,
}

/// Loads the set and writes it as one recording.
pub fn handle(args: Args) -> Result<()> {
    let out = match (args.out_flag, args.out) {
        (Some(p), None) | (None, Some(p)) => p,
        (None, None) => anyhow::bail!("import: --out DIR is required (the recording to write)"),
        (Some(_), Some(_)) => anyhow::bail!("import: --out given twice (as --out and as a path)"),
    };
    let set = import::load(args.kind, &args.src)?;
    let out = write_set(&set, &out, args.overwrite)?;
    let stats = set.depth_stats();
    let depth = if stats.total == 0 {
        "no reference depth".to_string()
    } else {
        format!(
            "depth valid {:.1} %, {:.3}–{:.3} m",
            100.0 * stats.valid_fraction(),
            stats.min_m,
            stats.max_m
        )
    };
    let zones = set.dtof.as_ref().map_or(String::new(), |d| {
        let (valid, all) = d.frames.iter().fold((0, 0), |(v, n), z| {
            (
                v + z.status.iter().filter(|s| matches!(s, 5 | 9)).count(),
                n + z.status.len(),
            )
        });
        format!(", zones valid {valid}/{all}")
    });
    let rgb = if set.has_rgb { "" } else { ", no RGB" };
    println!(
        "imported {} frames of {} into {}  ({depth}{zones}{rgb})",
        set.frames.len(),
        set.name,
        out.display(),
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
    let base = first.camera;
    let mut meta = RecordingMeta::new(base, set.dtof.as_ref().map(|d| d.meta.clone()), None);
    meta.rgb = set.has_rgb;
    let mut writer = RecordingWriter::create_with(out, meta, WriteOptions { overwrite })?;
    let bar = super::progress(set.frames.len() as u64, "writing frames");
    for (i, f) in set.frames.iter().enumerate() {
        let camera = f.camera;
        let frame_meta = FrameMeta {
            id: f.id.clone(),
            t_s: f.t_s,
            camera: (camera != base).then_some(camera),
        };
        let frame = Frame {
            id: f.id.clone(),
            rgb: f.rgb.clone(),
            depth_m: (!f.depth_m.is_empty()).then(|| f.depth_m.clone()),
            labels: None,
            dtof: set.dtof.as_ref().and_then(|d| d.frames.get(i).cloned()),
        };
        writer.add_frame(frame_meta, &frame)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(writer.finish()?)
}
