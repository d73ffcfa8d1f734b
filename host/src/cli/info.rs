//! `depthor info <recording>`: validates every frame and prints what it holds.

use anyhow::Result;
use depthor_host::recording::{FrameSummary, Recording};
use rayon::prelude::*;
use std::path::PathBuf;

/// Arguments of `depthor info`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recording directory (holds recording.json).
    recording: PathBuf,
}

/// Reads every frame (in parallel), then prints the summary.
pub fn handle(args: Args) -> Result<()> {
    let rec = Recording::open(&args.recording)?;
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

    println!("recording  {}", rec.dir().display());
    println!("format     {}", meta.format);
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
