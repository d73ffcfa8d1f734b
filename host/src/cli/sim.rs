//! `depthor sim`: synthetic recordings (scene generator + dToF simulator) or the simulated sensor
//! for an existing recording with reference depth.
//!
//! ```text
//! depthor sim --preset l5 --scenes N --seed S --out DIR [--width W --height H] [--preview]
//!             [--scene-config scenes.json]
//! depthor sim --config cfg.json --from RECORDING --out DIR [--preview]
//! depthor sim --preset mcu --config partial.json …   # the fields it names over the preset's
//! depthor sim --preset mcu [--config partial.json] --print-config   # the effective config
//! depthor sim … --shard K/N      # frames K, K+N, … of the same run (join with `depthor merge`)
//! depthor sim --preset mcu --measurement-mix mix.json …   # a condition drawn per frame
//! ```

use anyhow::{bail, Context, Result};
use depthor_core::calibration::CameraIntrinsics;
use depthor_core::projection::for_each_point;
use depthor_host::atomic::AtomicDir;
use depthor_host::dataset::{
    dtof_frame, preset_size, recording_meta, simulate_recording_frame, synth_frame,
    to_recording_frame, SynthFrame,
};
use depthor_host::plot::{figure, robust_range, ColourMap, Panel};
use depthor_host::recording::{Frame, FrameMeta, Recording, RecordingWriter, Shard, WriteOptions};
use depthor_host::sim::{preset, MeasurementMix, SimConfig, SimError};
use depthor_host::viz::{
    depth_image, draw_points, labels_image, points_csv, Overlay, LABEL_COLOURS,
};
use image::RgbImage;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Arguments of `depthor sim`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor sim --preset l5 --scenes 100 --out rec/l5 --preview
  depthor sim --preset mcu --recording rec/middlebury --out rec/middlebury-mcu
  depthor sim --preset mcu --scenes 100 --scene-config models/scenes/close_range.json --out rec/near
  depthor sim --config my_sim.json --scenes 10 --width 320 --height 240 --out rec/mine --overwrite
  depthor sim --preset mcu --config host/eval_grid/clean.json --recording rec/mb --out rec/mb-clean
  depthor sim --preset mcu --print-config > mcu.json     # every field; feeds back through --config")]
pub struct Args {
    /// Sensor preset: l5, phone or mcu (docs/design.md "Sensor presets").
    #[arg(long)]
    preset: Option<String>,
    /// Simulator configuration JSON. With --preset it may be partial: the fields it names
    /// replace the preset's, objects merged field by field (`{"anomalies": {"enabled": false}}`);
    /// alone it must be complete (as --print-config writes it). See docs/sim.md.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Measurement mix JSON (needs --preset): each frame's configuration is drawn from the
    /// mix's weighted conditions, partial configurations over the preset with `{"uniform":
    /// [lo, hi]}` and `{"choice": […]}` values drawn per frame (docs/sim.md "Measurement
    /// mixes"; models/mixes/ holds the training mixes).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["config", "print_config"], requires = "preset")]
    measurement_mix: Option<PathBuf>,
    /// Print the effective simulator configuration (the preset with --config's fields) as JSON
    /// on stdout and exit; the output fed back through --config reproduces it.
    #[arg(long)]
    print_config: bool,
    /// Number of synthetic scenes to render and simulate.
    #[arg(long, conflicts_with = "from")]
    scenes: Option<u64>,
    /// Scene generator JSON with --scenes: the fields it names replace the preset's scene
    /// ranges (e.g. models/scenes/close_range.json; see `depthor_host::scene::SceneConfig`).
    #[arg(long, conflicts_with = "from")]
    scene_config: Option<PathBuf>,
    /// Simulate the sensor for this recording's reference depth instead of rendering scenes
    /// (`--from` is the older spelling).
    #[arg(long = "recording", short = 'r', value_name = "DIR", alias = "from")]
    from: Option<PathBuf>,
    /// Random seed (frame i uses the sub-stream (seed, i)).
    #[arg(long, default_value_t = super::common::DEFAULT_SEED)]
    seed: u64,
    /// Output recording folder.
    #[arg(long, required_unless_present = "print_config")]
    out: Option<PathBuf>,
    /// Image width (default: the preset's, or the source recording's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (default: the preset's, or the source recording's).
    #[arg(long)]
    height: Option<u32>,
    /// Also write a PNG mosaic per frame (RGB | depth | labels | projected points) to OUT/preview.
    #[arg(long)]
    preview: bool,
    /// Replace an existing recording at --out (refused otherwise).
    #[arg(long)]
    overwrite: bool,
    /// Write only frames K, K+N, K+2N, … of the run (same seeds, ids and times as in the
    /// unsharded run); `depthor merge` joins the N shards into the unsharded recording.
    #[arg(long, value_name = "K/N", value_parser = Shard::parse, default_value = "0/1")]
    shard: Shard,
}

/// Frames generated in parallel before they are written in order.
const CHUNK: u64 = 32;

/// Validates the arguments, generates and writes the recording, then the previews.
pub fn handle(args: Args) -> Result<()> {
    let cfg = sim_config(args.preset.as_deref(), args.config.as_deref())?;
    let measurement = match &args.measurement_mix {
        None => Measurement::Fixed(cfg.clone()),
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read", path.display()))?;
            let mix = MeasurementMix::from_json(&cfg, &text)
                .with_context(|| path.display().to_string())?;
            Measurement::Mix(mix)
        }
    };
    if args.print_config {
        println!("{}", cfg.to_json());
        return Ok(());
    }
    let Some(out_dir) = args.out.as_deref() else {
        bail!("sim: --out: required (the output recording folder)");
    };
    let preset_name = args.preset.as_deref().unwrap_or("");
    // Where the configuration came from, in front of its errors.
    let source = match (&args.config, &args.preset) {
        (Some(path), _) => path.display().to_string(),
        (None, name) => format!("--preset {}", name.as_deref().unwrap_or("")),
    };
    let out = match (&args.scenes, &args.from) {
        (Some(n), None) => {
            let (h, w) = size(&args, preset_name, None)?;
            check_memory(&cfg, w, h, CHUNK.min(args.shard.len(*n)), &source)?;
            synthetic(&args, out_dir, &cfg, &measurement, preset_name, *n, w, h)?
        }
        (None, Some(src)) => {
            let rec = Recording::open(src)?;
            let (h, w) = size(&args, preset_name, Some(&rec))?;
            check_memory(&cfg, w, h, args.shard.len(rec.len() as u64), &source)?;
            from_recording(&args, out_dir, &cfg, &measurement, &rec, w, h)?
        }
        _ => bail!("sim: give either --scenes N or --recording DIR"),
    };
    // The recording is complete in its temporary folder; previews join it before it moves.
    if args.preview {
        write_previews(out.path())?;
    }
    let out = out.commit()?;
    println!("wrote {}", out.display());
    Ok(())
}

/// How each frame's simulator configuration is chosen.
enum Measurement {
    /// One configuration for every frame.
    Fixed(SimConfig),
    /// A condition of the mix drawn per frame.
    Mix(MeasurementMix),
}

impl Measurement {
    /// The configuration of frame `i` of a run seeded `seed`, with the mix condition's index.
    fn for_frame(&self, seed: u64, i: u64) -> Result<(Option<usize>, SimConfig), SimError> {
        match self {
            Measurement::Fixed(cfg) => Ok((None, cfg.clone())),
            Measurement::Mix(mix) => mix.draw(seed, i).map(|(k, cfg)| (Some(k), cfg)),
        }
    }

    /// Prints how many frames each mix condition got (nothing for a fixed configuration).
    fn report(&self, drawn: &[Option<usize>]) {
        if let Measurement::Mix(mix) = self {
            let counts: Vec<String> = mix
                .names()
                .enumerate()
                .map(|(k, name)| {
                    let n = drawn.iter().filter(|d| **d == Some(k)).count();
                    format!("{name} {n}")
                })
                .collect();
            println!(
                "measurement mix, frames per condition: {}",
                counts.join(", ")
            );
        }
    }
}

/// The simulator configuration of `--preset` and `--config`: the preset, with the fields the
/// file names replaced; the file alone when no preset is given (then it must be complete).
/// Errors name the file and the field.
pub fn sim_config(preset_name: Option<&str>, config: Option<&Path>) -> Result<SimConfig> {
    let Some(path) = config else {
        let Some(name) = preset_name else {
            bail!("sim: give --preset l5|phone|mcu or --config cfg.json");
        };
        return Ok(preset(name)?);
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let cfg = match preset_name {
        Some(name) => preset(name)?.with_overrides(&text),
        None => SimConfig::from_json(&text),
    };
    cfg.map_err(|e| {
        let missing = matches!(&e, SimError::Json { message, .. }
            if message.starts_with("missing field"));
        let hint = if missing && preset_name.is_none() {
            " (a partial configuration needs --preset to take the other fields from)"
        } else {
            ""
        };
        anyhow::Error::new(e).context(format!("{}{hint}", path.display()))
    })
}

/// Refuses a run whose memory estimate (rayon's workers simulating, `held` frames kept) is over
/// [`depthor_host::sim::memory_limit_bytes`], before anything is allocated or written.
fn check_memory(cfg: &SimConfig, w: u32, h: u32, held: u64, source: &str) -> Result<()> {
    let workers = rayon::current_num_threads() as u64;
    cfg.check_memory(w, h, workers, held, depthor_host::sim::memory_limit_bytes())
        .with_context(|| source.to_string())?;
    Ok(())
}

/// (height, width): explicit arguments, else the preset's size, else the source's first frame.
fn size(args: &Args, preset_name: &str, src: Option<&Recording>) -> Result<(u32, u32)> {
    let default = preset_size(preset_name).or_else(|| {
        src.filter(|r| !r.is_empty()).map(|r| {
            let c = r.camera(0);
            (c.height, c.width)
        })
    });
    match (args.height, args.width, default) {
        (Some(h), Some(w), _) => Ok((h, w)),
        (h, w, Some((dh, dw))) => Ok((h.unwrap_or(dh), w.unwrap_or(dw))),
        _ => bail!("sim: --width and --height are needed with --config and --scenes"),
    }
    .and_then(|(h, w)| {
        if h == 0 || w == 0 || h > 8192 || w > 8192 {
            bail!("--width/--height: {w}×{h} is out of range (allowed 1 to 8192 pixels each)")
        }
        Ok((h, w))
    })
}

/// Renders and simulates this shard's frames of `n` scenes, writing them in order.
#[allow(clippy::too_many_arguments)]
fn synthetic(
    args: &Args,
    out: &Path,
    cfg: &SimConfig,
    measurement: &Measurement,
    preset_name: &str,
    n: u64,
    w: u32,
    h: u32,
) -> Result<AtomicDir> {
    let scene_cfg = super::scene_config(preset_name, args.scene_config.as_deref())?;
    // The header carries the nominal camera; every frame carries its own intrinsics.
    let nominal = depthor_host::scene::camera_for(&scene_cfg, args.seed, w, h);
    let meta = recording_meta(cfg, &nominal);
    let mut writer = RecordingWriter::create_with(
        out,
        meta,
        WriteOptions {
            overwrite: args.overwrite,
        },
    )?;
    let mine: Vec<u64> = args.shard.frames(n).collect();
    let bar = super::progress(mine.len() as u64, "simulating scenes");
    let mut drawn = Vec::with_capacity(mine.len());
    for chunk in mine.chunks(CHUNK as usize) {
        let frames: Vec<(Option<usize>, SynthFrame)> = chunk
            .par_iter()
            .map(|&i| {
                let (k, cfg) = measurement.for_frame(args.seed, i)?;
                synth_frame(&scene_cfg, &cfg, args.seed, i, w, h).map(|f| (k, f))
            })
            .collect::<Result<_, SimError>>()?;
        for (&i, (k, f)) in chunk.iter().zip(&frames) {
            drawn.push(*k);
            let (mut fm, frame) = to_recording_frame(&format!("{i:06}"), f);
            fm.t_s = i as f64;
            writer.add_frame(fm, &frame)?;
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    measurement.report(&drawn);
    Ok(writer.seal()?)
}

/// Simulates the sensor for this shard's frames of `rec` at `w × h`.
fn from_recording(
    args: &Args,
    out: &Path,
    cfg: &SimConfig,
    measurement: &Measurement,
    rec: &Recording,
    w: u32,
    h: u32,
) -> Result<AtomicDir> {
    if rec.is_empty() {
        bail!(
            "{}: frames: the recording has no frames",
            rec.dir().display()
        );
    }
    let mine: Vec<usize> = args
        .shard
        .frames(rec.len() as u64)
        .map(|i| i as usize)
        .collect();
    let bar = super::progress(mine.len() as u64, "simulating frames");
    let frames = mine
        .par_iter()
        .map(|&i| -> Result<_> {
            let (k, cfg) = measurement.for_frame(args.seed, i as u64)?;
            let r = simulate_recording_frame(rec, i, &cfg, args.seed, w, h)?;
            bar.inc(1);
            Ok((k, r))
        })
        .collect::<Result<Vec<_>>>()?;
    bar.finish_and_clear();
    let (drawn, frames): (Vec<Option<usize>>, Vec<_>) = frames.into_iter().unzip();
    measurement.report(&drawn);
    // The header's camera is the source's first frame's in every shard, as unsharded.
    let first = &match mine.first() {
        Some(0) => frames[0].0.camera,
        _ => {
            simulate_recording_frame(rec, 0, cfg, args.seed, w, h)?
                .0
                .camera
        }
    };
    let mut writer = RecordingWriter::create_with(
        out,
        recording_meta(cfg, first),
        WriteOptions {
            overwrite: args.overwrite,
        },
    )?;
    for (&i, (r, sim)) in mine.iter().zip(&frames) {
        let src = &rec.meta().frames[i];
        let camera = r.camera;
        let fm = FrameMeta {
            id: src.id.clone(),
            t_s: src.t_s,
            camera: (camera != *first).then_some(camera),
        };
        let frame = Frame {
            id: src.id.clone(),
            rgb: r.rgb.clone(),
            depth_m: Some(r.depth_m.iter().map(|d| d * sim.depth_scale).collect()),
            labels: r.labels.clone(),
            dtof: Some(dtof_frame(sim)),
        };
        writer.add_frame(fm, &frame)?;
    }
    Ok(writer.seal()?)
}

/// Writes `<out>/preview/<id>.png` for every frame of the recording at `out`: RGB | depth | labels | projected points.
pub fn write_previews(out: &Path) -> Result<()> {
    let rec = Recording::open(out)?;
    let dir = out.join("preview");
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let bar = super::progress(rec.len() as u64, "previews");
    (0..rec.len())
        .into_par_iter()
        .try_for_each(|i| -> Result<()> {
            let frame = rec.read_frame(i)?;
            let (img, csv) = preview(&rec, i, &frame)?;
            let path = dir.join(format!("{}.png", frame.id));
            img.save(&path)
                .with_context(|| format!("{}: cannot write", path.display()))?;
            let path = path.with_extension("csv");
            std::fs::write(&path, csv)
                .with_context(|| format!("{}: cannot write", path.display()))?;
            bar.inc(1);
            Ok(())
        })?;
    bar.finish_and_clear();
    Ok(())
}

/// One preview figure (RGB | reference depth | material labels | projected zones) and the
/// projected zones as CSV.
fn preview(rec: &Recording, i: usize, frame: &Frame) -> Result<(RgbImage, String)> {
    let cam: CameraIntrinsics = rec.camera(i);
    let (w, h) = (cam.width, cam.height);
    let depth = frame.depth_m.as_deref().unwrap_or(&[]);
    let (lo, hi) = robust_range(depth, 0.02, 0.98).unwrap_or((0.0, 1.0));
    let mut csv = points_csv(&[]);
    let mut panels = vec![
        Panel::new("RGB", frame.rgb.clone()),
        Panel::new("reference depth", depth_image(depth, w, h, lo, hi)).with_bar(
            ColourMap::Turbo,
            lo,
            hi,
            "depth (m), black = none",
        ),
    ];
    if let Some(l) = &frame.labels {
        let names = ["diffuse", "transparent", "specular", "dark"];
        let legend = LABEL_COLOURS
            .iter()
            .zip(names)
            .map(|(c, n)| (image::Rgb(*c), n.to_string()))
            .collect();
        panels.push(Panel::new("material labels", labels_image(l, w, h)).with_legend(legend));
    }
    if let (Some(cal), Some(d), Some(meta)) =
        (rec.calibration(i), &frame.dtof, rec.meta().dtof.as_ref())
    {
        let mut points = Vec::new();
        for_each_point(&cal.as_core(), &d.view(meta), |p| points.push(p))?;
        let overlay = Overlay {
            lo_m: lo,
            hi_m: hi,
            ..Overlay::auto(w, h, &points)
        };
        csv = points_csv(&points);
        panels.push(
            Panel::new(
                format!("{}×{} zones projected", meta.rows, meta.cols),
                draw_points(&frame.rgb, &points, &overlay),
            )
            .with_bar(ColourMap::Turbo, lo, hi, "zone depth (m)"),
        );
    }
    let img = figure(&format!("frame {} ({w}×{h})", frame.id), &panels, 240)?;
    Ok((img, csv))
}
