//! `depthor info --recording DIR`: validates every frame and prints what it holds.

use anyhow::Result;
use depthor_host::recording::{FrameSummary, Recording};
use rayon::prelude::*;
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `depthor info`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor info --recording rec/middlebury
  depthor info --recording rec/l5 --json > l5.json")]
pub struct Args {
    /// Recording folder (holds recording.json).
    #[arg(long = "recording", short = 'r', value_name = "DIR")]
    recording: Option<PathBuf>,
    /// The same as a path (older spelling).
    #[arg(value_name = "RECORDING", hide = true)]
    recording_path: Option<PathBuf>,
    /// Print the summary as JSON on stdout instead of the table.
    #[arg(long)]
    json: bool,
}

/// Reads every frame (in parallel), then prints the summary.
pub fn handle(args: Args) -> Result<()> {
    let dir = super::common::input_recording(args.recording, args.recording_path)?;
    let rec = Recording::open(&dir)?;
    let meta = rec.meta();
    let bar = super::progress(rec.len() as u64, "reading frames");
    let summaries = (0..rec.len())
        .into_par_iter()
        .map(|i| {
            let s = rec.read_frame(i).map(|f| FrameSummary::of(&f));
            bar.inc(1);
            s
        })
        .collect::<Result<Vec<_>, _>>();
    bar.finish_and_clear();
    let summaries = summaries?;
    if args.json {
        return super::common::print_json(&info_json(&rec, &summaries));
    }

    println!("recording  {}", rec.dir().display());
    println!("format     {}", meta.format);
    if !meta.rgb {
        println!("rgb        none (zone-only recording: eval and demo need RGB, gap needs reference depth)");
    }
    println!("frames     {}", rec.len());
    let c = &meta.camera;
    println!(
        "camera     {}×{}  fx {} fy {} cx {} cy {}",
        c.width, c.height, c.fx, c.fy, c.cx, c.cy
    );
    match &meta.dtof {
        Some(d) => println!(
            "dtof       {}×{} zones  fov {}°×{}°  {:?} distance  max {} m{}",
            d.rows,
            d.cols,
            d.fov_deg[0],
            d.fov_deg[1],
            d.distance,
            d.max_range_m,
            if d.zone_rects_px.is_some() {
                "  zone rectangles"
            } else {
                ""
            }
        ),
        None => println!("dtof       none"),
    }
    let (mut valid, mut zones) = (0usize, 0usize);
    for (s, f) in summaries.iter().zip(&meta.frames) {
        let depth = match &s.depth {
            Some(d) => format!(
                "depth valid {:5.1} %  min {:.3} median {:.3} max {:.3} m",
                d.valid_fraction * 100.0,
                d.min_m,
                d.median_m,
                d.max_m
            ),
            None => "no reference depth".to_string(),
        };
        let dtof = match s.dtof_valid {
            Some((v, n)) => {
                valid += v;
                zones += n;
                format!("  zones valid {v}/{n}")
            }
            None => String::new(),
        };
        let labels = if s.has_labels { "  labels" } else { "" };
        println!(
            "  {}  t {:.3} s  {}×{}  {depth}{dtof}{labels}",
            s.id, f.t_s, s.size.0, s.size.1
        );
    }
    if zones > 0 {
        println!(
            "dtof valid zones: {valid}/{zones} ({:.1} %)",
            100.0 * valid as f64 / zones as f64
        );
    }
    Ok(())
}

/// The summary as JSON (`--json`): header fields and one object per frame.
fn info_json(rec: &Recording, summaries: &[FrameSummary]) -> serde_json::Value {
    let meta = rec.meta();
    let c = &meta.camera;
    let frames: Vec<_> = summaries
        .iter()
        .zip(&meta.frames)
        .map(|(s, f)| {
            json!({
                "id": s.id, "t_s": f.t_s, "width": s.size.0, "height": s.size.1,
                "depth": s.depth.as_ref().map(|d| json!({
                    "valid_fraction": d.valid_fraction, "min_m": d.min_m,
                    "median_m": d.median_m, "max_m": d.max_m,
                })),
                "zones_valid": s.dtof_valid.map(|v| v.0),
                "zones": s.dtof_valid.map(|v| v.1),
                "labels": s.has_labels,
            })
        })
        .collect();
    json!({
        "recording": rec.dir().display().to_string(),
        "format": meta.format,
        "rgb": meta.rgb,
        "frames": rec.len(),
        "camera": {"width": c.width, "height": c.height, "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy},
        "dtof": meta.dtof.as_ref().map(|d| json!({
            "rows": d.rows, "cols": d.cols, "fov_deg": d.fov_deg,
            "distance": format!("{:?}", d.distance), "max_range_m": d.max_range_m,
        })),
        "per_frame": frames,
    })
}
