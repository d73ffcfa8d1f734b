//! `depthor firmware-image` and `depthor firmware-replay`: the host side of `firmware-sim`.
//!
//! - `firmware-image RECORDING --frames N --out image.dri` writes a replay flash image
//!   (`DPTHRPLY` v1, see `firmware-sim/README.md`) from the first `N` frames of a recording: RGB
//!   resampled to the `mcu` size (120×160, `dataset::resample_frame`) when it differs, the
//!   recording's dToF zones (dtof.json) as they are, and one calibration (the resampled camera,
//!   the recording's zone geometry and extrinsics; per-zone rectangles, which format v1 cannot
//!   hold, are dropped with a note, so the firmware projects with the FoV geometry).
//! - `firmware-replay IMAGE|RECORDING` runs the host build of the firmware loop (same core
//!   calls, same `mcu` blob) and prints the firmware's per-frame lines
//!   (`frame i depth_fnv1a64=… points=… skipped=… collisions=…`).

use anyhow::{bail, Context, Result};
use depthor_core::calibration::{Calibration, CameraIntrinsics};
use depthor_host::dataset::resample_frame;
use depthor_host::recording::Recording;
use depthor_replay::format::Image;
use depthor_replay::host::{replay_image, StdDelay};
use depthor_replay::writer::{image_bytes, FrameData};
use std::path::{Path, PathBuf};

/// Zones the firmware holds (8×8); the host build holds as many so it fails the same way.
const FIRMWARE_ZONES: usize = 64;

/// Arguments of `depthor firmware-image`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor firmware-image --recording rec/mcu --frames 5 --out fw      # fw/replay.dri
  depthor firmware-image --recording rec/mcu --out fw --overwrite")]
pub struct ImageArgs {
    /// Recording folder (holds recording.json and per-frame dtof.json).
    #[arg(long = "recording", short = 'r', value_name = "DIR")]
    recording: Option<PathBuf>,
    /// The same as a path (older spelling).
    #[arg(value_name = "RECORDING", hide = true)]
    recording_path: Option<PathBuf>,
    /// Frames to take from the start of the recording.
    #[arg(long, default_value_t = 5)]
    frames: usize,
    /// Output image height (the `mcu` model's 120).
    #[arg(long, default_value_t = 120)]
    height: u32,
    /// Output image width (the `mcu` model's 160).
    #[arg(long, default_value_t = 160)]
    width: u32,
    /// Output folder (receives replay.dri; an --out ending in .dri names the file itself).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing replay.dri (refused otherwise).
    #[arg(long)]
    overwrite: bool,
}

/// Arguments of `depthor firmware-replay`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor firmware-replay --image fw/replay.dri
  depthor firmware-replay --recording rec/mcu --frames 3")]
pub struct ReplayArgs {
    /// A recording folder (converted as `firmware-image` would).
    #[arg(
        long = "recording",
        short = 'r',
        value_name = "DIR",
        conflicts_with = "image"
    )]
    recording: Option<PathBuf>,
    /// A replay image file (`firmware-image`'s replay.dri).
    #[arg(long, value_name = "FILE")]
    image: Option<PathBuf>,
    /// An image file or a recording folder as a path (older spelling).
    #[arg(value_name = "INPUT", hide = true)]
    input: Option<PathBuf>,
    /// With a recording: frames to take.
    #[arg(long, default_value_t = 5)]
    frames: usize,
}

/// Writes the image and says what it holds.
pub fn handle_image(args: ImageArgs) -> Result<()> {
    let recording = super::common::input_recording(args.recording, args.recording_path)?;
    let target = super::common::OutFile::new(&args.out, "replay.dri");
    if target.path.exists() && !args.overwrite {
        bail!(
            "{}: exists (pass --overwrite to replace it)",
            target.path.display()
        );
    }
    let bytes = image_from_recording(&recording, args.frames, args.height, args.width)?;
    // Parsed before writing, so an image the replay would refuse is never left at --out.
    let image = Image::parse(&bytes).context("the image does not parse")?;
    target.write(&bytes, args.overwrite)?;
    let (h, w) = image.size();
    let (rows, cols) = image.zone_grid();
    println!(
        "{}: {} frames, {h}x{w} RGB, {rows}x{cols} zones, {} bytes",
        target.path.display(),
        image.frame_count(),
        bytes.len()
    );
    Ok(())
}

/// Runs the host build of the firmware loop and prints its lines.
pub fn handle_replay(args: ReplayArgs) -> Result<()> {
    let input = match (args.recording, args.image, args.input) {
        (Some(p), None, None) | (None, Some(p), None) | (None, None, Some(p)) => p,
        (None, None, None) => bail!("firmware-replay: give --recording DIR or --image FILE"),
        _ => bail!("firmware-replay: give one input (--recording DIR or --image FILE)"),
    };
    let bytes = if input.is_dir() {
        image_from_recording(&input, args.frames, 120, 160)?
    } else {
        std::fs::read(&input).with_context(|| format!("{}", input.display()))?
    };
    let image = Image::parse(&bytes)
        .map_err(|e| anyhow::anyhow!("ERROR {}: {e} ({})", e.exit_code(), input.display()))?;
    let n = replay_image::<FIRMWARE_ZONES>(image, StdDelay, |out| println!("{out}"))
        .map_err(|e| anyhow::anyhow!("ERROR {}: {e}", e.exit_code()))?;
    println!("frames {n}");
    Ok(())
}

/// Millimetres as stored in the image: rounded, clamped to the `i16` range (the driver's
/// register width).
fn mm_i16(mm: f32) -> i16 {
    if mm.is_nan() {
        0
    } else {
        mm.round().clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16
    }
}

/// The replay image of the first `frames` frames of `dir` at `height × width`.
pub fn image_from_recording(dir: &Path, frames: usize, height: u32, width: u32) -> Result<Vec<u8>> {
    let rec = Recording::open(dir)?;
    let n = rec.len().min(frames);
    if n == 0 {
        bail!("{}: no frames to take", dir.display());
    }
    let mut camera: Option<CameraIntrinsics> = None;
    let mut cal_data = None;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let frame = rec.read_frame(i)?;
        let cal = rec
            .calibration(i)
            .with_context(|| format!("{}: the recording has no dToF", dir.display()))?;
        if cal.zone_rects_px.is_some() && i == 0 {
            eprintln!(
                "note: {}: the recording's zone rectangles are not stored (image format v1); \
                 the firmware projects with the FoV geometry",
                dir.display()
            );
        }
        let dtof = frame
            .dtof
            .with_context(|| format!("{}: frame {i} has no dtof.json", dir.display()))?;
        let cam = rec.camera(i);
        let (rgb, cam_out) = if (cam.width, cam.height) == (width, height) {
            (frame.rgb.into_raw(), cam)
        } else {
            let depth = vec![0.0; (cam.width * cam.height) as usize];
            let r = resample_frame(&cam, &frame.rgb, &depth, None, width, height);
            (r.rgb.into_raw(), r.camera)
        };
        match camera {
            None => camera = Some(cam_out),
            Some(c) if c == cam_out => {}
            Some(_) => bail!(
                "{}: frame {i} has other intrinsics than frame 0; a replay image holds one camera",
                dir.display()
            ),
        }
        out.push(FrameData {
            rgb,
            distance_mm: dtof.distance_mm.iter().map(|&d| mm_i16(d)).collect(),
            status: dtof.status.clone(),
        });
        cal_data.get_or_insert(cal);
    }
    let (Some(camera), Some(cal)) = (camera, cal_data) else {
        bail!("{}: no frames", dir.display());
    };
    let calibration = Calibration {
        camera,
        dtof: cal.dtof,
        dtof_to_camera: cal.dtof_to_camera,
        zone_rects_px: None,
    };
    Ok(image_bytes(&calibration, &out)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn millimetres_round_and_clamp() {
        assert_eq!(mm_i16(1234.4), 1234);
        assert_eq!(mm_i16(1234.5), 1235);
        assert_eq!(mm_i16(0.0), 0);
        assert_eq!(mm_i16(40_000.0), i16::MAX);
        assert_eq!(mm_i16(-40_000.0), i16::MIN);
        assert_eq!(mm_i16(f32::NAN), 0);
    }
}
