//! `depthor project <recording> --frame ID --out x.png`: a frame's zones projected onto its RGB.

use anyhow::{bail, Context, Result};
use depthor_core::projection::{for_each_point, ProjectionStats};
use depthor_host::recording::Recording;
use depthor_host::viz::{render_projection, Overlay};
use std::path::{Path, PathBuf};

/// Arguments of `depthor project`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recording directory (holds recording.json).
    recording: PathBuf,
    /// Frame id (its directory name under frames/).
    #[arg(long)]
    frame: String,
    /// Output PNG.
    #[arg(long)]
    out: PathBuf,
    /// Disc radius in pixels (default: about 1/100 of the larger image side).
    #[arg(long)]
    radius: Option<f32>,
}

/// Projects, draws, writes the PNG, prints the projection statistics.
pub fn handle(args: Args) -> Result<()> {
    let rec = Recording::open(&args.recording)?;
    let Some(i) = rec.index_of(&args.frame) else {
        bail!(
            "{}: frames: no frame with id {:?} ({} frames)",
            rec.dir().join("recording.json").display(),
            args.frame,
            rec.len()
        );
    };
    let Some(cal) = rec.calibration(i) else {
        bail!(
            "{}: dtof: the recording has no dToF sensor to project",
            rec.dir().join("recording.json").display()
        );
    };
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
        if !(r.is_finite() && r >= 0.0) {
            bail!("--radius: must be a finite number >= 0, found {r}");
        }
        overlay.radius = r;
    }
    let img = render_projection(&frame.rgb, &points, &overlay);
    save_atomically(&img, &args.out)?;
    print_stats(&stats);
    println!(
        "colour range {:.3}..{:.3} m, wrote {}",
        overlay.lo_m,
        overlay.hi_m,
        args.out.display()
    );
    Ok(())
}

fn print_stats(s: &ProjectionStats) {
    println!(
        "zones {}  projected {}  invalid_status {}  bad_distance {}  behind_camera {}  out_of_image {}  collisions {}",
        s.zones, s.projected, s.invalid_status, s.bad_distance, s.behind_camera, s.out_of_image, s.collisions
    );
}

/// Encodes the PNG in memory and writes it with [`depthor_host::atomic::write_file`], so a
/// failure leaves nothing.
fn save_atomically(img: &image::RgbImage, out: &Path) -> Result<()> {
    let mut png = std::io::Cursor::new(Vec::new());
    img.write_to(&mut png, image::ImageFormat::Png)
        .with_context(|| format!("{}: encode", out.display()))?;
    depthor_host::atomic::write_file(out, png.get_ref())?;
    Ok(())
}
