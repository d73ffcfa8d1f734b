//! `depthor project --recording DIR --frame 3 --out DIR`: a frame's zones projected onto its RGB.
//! Writes `<out>/project_<id>.png` and `<out>/project_<id>.csv` (one row per projected zone).

use anyhow::{bail, Context, Result};
use depthor_core::projection::{for_each_point, ProjectionStats};
use depthor_host::plot::{figure, ColourMap, Panel};
use depthor_host::recording::Recording;
use depthor_host::viz::{draw_points, points_csv, Overlay};
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `depthor project`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor project --recording rec/l5 --frame 3 --out proj        # proj/project_000003.png + .csv
  depthor project --recording rec/l5 --frame 000003 --out proj --overwrite --json")]
pub struct Args {
    /// Recording folder (holds recording.json).
    #[arg(long = "recording", short = 'r', value_name = "DIR")]
    recording: Option<PathBuf>,
    /// The same as a path (older spelling).
    #[arg(value_name = "RECORDING", hide = true)]
    recording_path: Option<PathBuf>,
    /// Frame: its id (`000003`) or its 0-based index (`3`).
    #[arg(long, default_value = "0")]
    frame: String,
    /// Output folder (receives project_<id>.png and project_<id>.csv).
    #[arg(long, default_value = "project")]
    out: PathBuf,
    /// Write into an existing non-empty --out (files of the same name are replaced).
    #[arg(long)]
    overwrite: bool,
    /// Disc radius in pixels (default: about 1/100 of the larger image side).
    #[arg(long)]
    radius: Option<f32>,
    /// Print the projection statistics as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// Projects, draws, writes the PNG and CSV, prints the projection statistics.
pub fn handle(args: Args) -> Result<()> {
    let dir = super::common::input_recording(args.recording, args.recording_path)?;
    let rec = Recording::open(&dir)?;
    let i = super::common::frame_index(&rec, &args.frame)?;
    let Some(cal) = rec.calibration(i) else {
        bail!(
            "{}: dtof: the recording has no dToF sensor to project",
            rec.dir().join("recording.json").display()
        );
    };
    if let Some(r) = args.radius {
        if !(r.is_finite() && r >= 0.0) {
            bail!("--radius: must be a finite number >= 0, found {r}");
        }
    }
    let frame = rec.read_frame(i)?;
    let zones = frame
        .dtof
        .as_ref()
        .context("frame has no zones although the recording has a dToF")?;
    let geometry = rec.meta().dtof.as_ref().context("recording has no dToF")?;
    let mut points = Vec::new();
    let stats = for_each_point(&cal.as_core(), &zones.view(geometry), |p| points.push(p))
        .map_err(|e| anyhow::anyhow!("projection of frame {}: {e:?}", frame.id))?;
    let (w, h) = frame.rgb.dimensions();
    let mut overlay = Overlay::auto(w, h, &points);
    if let Some(r) = args.radius {
        overlay.radius = r;
    }
    let panel = Panel::new(
        format!("{} of {} zones projected", stats.projected, stats.zones),
        draw_points(&frame.rgb, &points, &overlay),
    )
    .with_bar(
        ColourMap::Turbo,
        overlay.lo_m,
        overlay.hi_m,
        "zone depth (m), clamped",
    );
    let title = format!(
        "{} frame {} ({w}×{h}): dToF zones on the RGB",
        dir.file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        frame.id
    );
    let img = figure(&title, &[panel], 480)?;
    // `--out proj.png` (older spelling) still names the picture itself.
    let png = super::common::OutFile::new(&args.out, &format!("project_{}.png", frame.id));
    let csv = super::common::OutFile {
        path: png.path.with_extension("csv"),
        dir: png.dir.clone(),
    };
    for f in [&png, &csv] {
        if f.path.exists() && !args.overwrite {
            bail!(
                "{}: exists (pass --overwrite to replace it)",
                f.path.display()
            );
        }
    }
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)
        .with_context(|| format!("{}: encode", png.path.display()))?;
    png.write(bytes.get_ref(), args.overwrite)?;
    csv.write(points_csv(&points).as_bytes(), args.overwrite)?;
    if args.json {
        return super::common::print_json(&json!({
            "recording": rec.dir().display().to_string(),
            "frame": frame.id,
            "stats": stats_json(&stats),
            "colour_range_m": [overlay.lo_m, overlay.hi_m],
            "png": png.path.display().to_string(),
            "csv": csv.path.display().to_string(),
        }));
    }
    print_stats(&stats);
    println!(
        "colour range {:.3}..{:.3} m, wrote {}",
        overlay.lo_m,
        overlay.hi_m,
        png.path.display()
    );
    Ok(())
}

fn stats_json(s: &ProjectionStats) -> serde_json::Value {
    json!({
        "zones": s.zones, "projected": s.projected, "invalid_status": s.invalid_status,
        "bad_distance": s.bad_distance, "behind_camera": s.behind_camera,
        "out_of_image": s.out_of_image, "collisions": s.collisions,
    })
}

fn print_stats(s: &ProjectionStats) {
    println!(
        "zones {}  projected {}  invalid_status {}  bad_distance {}  behind_camera {}  out_of_image {}  collisions {}",
        s.zones, s.projected, s.invalid_status, s.bad_distance, s.behind_camera, s.out_of_image, s.collisions
    );
}
