//! `depthor quantize --graph models/mcu/graph.json --out models/mcu/depthor.dblob`: calibrates
//! the exported float graph on simulated frames and writes the int8 blob; `--report` also checks
//! the float graph against the Python golden tensors and the engine against the float graph.

use anyhow::{Context, Result};
use depthor_core::engine::required_arena_bytes;
use depthor_host::evaluation::RecordingFrames;
use depthor_host::quantize::calibrate::{
    simulated_frames, simulated_frames_in, Frame, RangeRule, I16_HEADROOM,
};
use depthor_host::quantize::check::{compare, golden_diff, op_fidelity};
use depthor_host::quantize::fold::fold;
use depthor_host::quantize::golden::read_golden;
use depthor_host::quantize::graph::Graph;
use depthor_host::quantize::upsample_scale::upsample_at_concat_scale;
use depthor_host::quantize::widen::widen;
use depthor_host::quantize::{quantize_with_ranges, QuantizeError};
use std::path::{Path, PathBuf};

/// docs/design.md budgets of the `mcu` variant (bytes).
const MCU_WEIGHTS_BUDGET: usize = 512 * 1024;
const MCU_ARENA_BUDGET: usize = 2 * 1024 * 1024;
const MCU_ARENA_GOAL: usize = 384 * 1024;

/// Arguments of `depthor quantize`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor quantize --graph models/mcu/graph.json --out build/mcu          # build/mcu/depthor.dblob
  depthor quantize --graph models/mcu/graph.json --out models/mcu --overwrite --report \\
      --scene-config models/scenes/close_range.json --scene-config-frames 16
  depthor quantize --graph models/mcu/graph.json --out build/mcu --calibration-recording rec/photo")]
pub struct Args {
    /// graph.json of the Python export.
    #[arg(long)]
    graph: PathBuf,
    /// weights.bin (default: beside graph.json).
    #[arg(long)]
    weights: Option<PathBuf>,
    /// Output folder (receives depthor.dblob; an --out ending in .dblob names the file itself).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing depthor.dblob (refused otherwise).
    #[arg(long)]
    overwrite: bool,
    /// Calibration frames.
    #[arg(long, default_value_t = 16)]
    frames: usize,
    /// Seed of the first calibration scene (scene k uses seed + k).
    #[arg(long, default_value_t = super::common::DEFAULT_SEED)]
    seed: u64,
    /// Activation ranges: `mse` (clip where it lowers the expected int8 error) or `minmax`.
    #[arg(long, default_value = "mse")]
    ranges: RangeRule,
    /// JSON object `{"value name": [lo, hi], …}` whose ranges replace the calibrated ones
    /// (e.g. `qat_ranges.json` from a quantisation-aware run's export; docs/blob.md).
    #[arg(long, value_name = "FILE")]
    ranges_file: Option<PathBuf>,
    /// Store this value as int16 (TFLite's 16×8 scheme; repeatable): a conv or concat output
    /// read only by convs and concats, e.g. one `int8_sensitivity.py` ranks first
    /// (docs/blob.md).
    #[arg(long, value_name = "VALUE")]
    int16: Vec<String>,
    /// Write each int8 upsample read only by an int8 concat at that concat's parameters, so its
    /// interpolated values are rounded once, as quantisation-aware training models them
    /// (docs/blob.md).
    #[arg(long)]
    upsample_at_concat_scale: bool,
    /// A scene configuration (JSON, as for `depthor sim --scene-config`: the preset's scenes
    /// with the named ranges replaced) for
    /// `--scene-config-frames` more calibration frames, e.g. the close-range scenes a model also
    /// serves.
    #[arg(long, requires = "scene_config_frames")]
    scene_config: Option<PathBuf>,
    /// Calibration frames drawn from `--scene-config`, seeds after the default ones.
    #[arg(long, default_value_t = 0)]
    scene_config_frames: usize,
    /// A recording whose frames are added to the calibration set (repeatable): e.g. rendered
    /// frames with photometric changes, or captures from the device the model will serve.
    /// Frames are resampled to the model's input as `depthor eval` does.
    #[arg(long, value_name = "DIR")]
    calibration_recording: Vec<PathBuf>,
    /// At most this many frames from each `--calibration-recording` (its first ones).
    #[arg(long, default_value_t = 64)]
    calibration_recording_frames: usize,
    /// dToF simulator preset (default: the graph's variant).
    #[arg(long)]
    preset: Option<String>,
    /// Also check: float graph vs golden, engine vs float graph on `--eval-frames` new scenes.
    #[arg(long)]
    report: bool,
    /// Evaluation frames for `--report` (scenes after the calibration ones).
    #[arg(long, default_value_t = 20)]
    eval_frames: usize,
    /// `--report` on this recording's frames instead of new scenes (e.g. captures from the
    /// target camera, to see which ops lose the most on them; at most `--eval-frames`).
    #[arg(long, value_name = "DIR", requires = "report")]
    report_recording: Option<PathBuf>,
}

/// Quantises, writes the blob, prints sizes (and the report).
pub fn handle(args: Args) -> Result<()> {
    let graph = Graph::load(&args.graph, args.weights.as_deref())?;
    let mut net = fold(&graph).with_context(|| format!("{}", args.graph.display()))?;
    widen(&mut net, &args.int16)?;
    let rescaled = if args.upsample_at_concat_scale {
        upsample_at_concat_scale(&mut net)
    } else {
        Vec::new()
    };
    let preset = args.preset.clone().unwrap_or_else(|| graph.variant.clone());
    let mut frames = simulated_frames(&preset, net.height, net.width, args.frames, args.seed)?;
    if let Some(path) = &args.scene_config {
        let cfg = super::scene_config(&preset, Some(path))?;
        let seed = args.seed + args.frames as u64;
        frames.extend(simulated_frames_in(
            &cfg,
            &preset,
            net.height,
            net.width,
            args.scene_config_frames,
            seed,
        )?);
    }
    // frames taken from each --calibration-recording, for the summary line
    let mut from_recordings = Vec::with_capacity(args.calibration_recording.len());
    for dir in &args.calibration_recording {
        let taken = recording_frames(
            dir,
            &preset,
            net.height,
            net.width,
            args.calibration_recording_frames,
        )?;
        from_recordings.push(taken.len());
        frames.extend(taken);
    }
    let target = super::common::OutFile::new(&args.out, "depthor.dblob");
    if target.path.exists() && !args.overwrite {
        anyhow::bail!(
            "{}: exists (pass --overwrite to replace it)",
            target.path.display()
        );
    }
    let given = match &args.ranges_file {
        Some(p) => read_ranges_file(p)?,
        None => Vec::new(),
    };
    let q = quantize_with_ranges(&net, &frames, args.ranges, &given).map_err(|e| {
        match (&e, &args.ranges_file) {
            (QuantizeError::Ranges(_), Some(p)) => anyhow::anyhow!("{}: {e}", p.display()),
            _ => e.into(),
        }
    })?;
    // Checked before writing, so a blob the engine refuses is never left at --out.
    let arena = required_arena_bytes(&q.blob, net.height, net.width).map_err(|e| {
        anyhow::anyhow!(
            "{}: {}",
            target.path.display(),
            depthor_host::inference::engine_detail(&e)
        )
    })?;
    target.write(&q.blob, args.overwrite)?;
    println!(
        "{}: variant {} at {}×{} (H×W), {} ops, {} tensors, {} blob bytes",
        target.path.display(),
        net.variant,
        net.height,
        net.width,
        net.ops.len(),
        net.values.len(),
        q.blob.len()
    );
    let mut sources: Vec<String> = Vec::new();
    if let Some(p) = &args.scene_config {
        sources.push(format!("{} from {}", args.scene_config_frames, p.display()));
    }
    for (dir, n) in args.calibration_recording.iter().zip(&from_recordings) {
        sources.push(format!("{n} from recording {}", dir.display()));
    }
    let extra = if sources.is_empty() {
        String::new()
    } else {
        format!(
            " ({})",
            sources.join(", ").replacen(" from ", " of them from ", 1)
        )
    };
    let scenes = args.frames
        + args
            .scene_config
            .as_ref()
            .map_or(0, |_| args.scene_config_frames);
    println!(
        "calibration: {} frames{extra} (preset {preset}, scene seeds {}..{}), activation ranges = {}",
        frames.len(),
        args.seed,
        args.seed + scenes as u64,
        match args.ranges {
            RangeRule::MinMax => "min/max",
            RangeRule::Mse => "MSE-clipped",
        }
    );
    if let Some(p) = &args.ranges_file {
        println!("ranges of {} values from {}", given.len(), p.display());
    }
    if args.upsample_at_concat_scale {
        println!(
            "upsamples at their concat's parameters: {}",
            if rescaled.is_empty() {
                "none".to_string()
            } else {
                rescaled.join(", ")
            }
        );
    }
    if !args.int16.is_empty() {
        println!(
            "int16 values (symmetric, min/max × {I16_HEADROOM}): {}",
            args.int16.join(", ")
        );
    }
    let wb = net.weight_count();
    println!("int8 weight bytes {wb} ({:.1} KiB)", wb as f64 / 1024.0);
    println!(
        "arena bytes at {}×{}: {arena} ({:.1} KiB)",
        net.height,
        net.width,
        arena as f64 / 1024.0
    );
    if net.variant == "mcu" {
        let verdict = |ok: bool| if ok { "within" } else { "OVER" };
        println!(
            "mcu budgets: weights {} 512 KiB; arena {} 2 MiB, {} the 384 KiB goal",
            verdict(wb <= MCU_WEIGHTS_BUDGET),
            verdict(arena <= MCU_ARENA_BUDGET),
            verdict(arena <= MCU_ARENA_GOAL)
        );
    }
    if !args.report {
        return Ok(());
    }
    let index = args.graph.with_file_name("golden").join("index.json");
    if index.exists() {
        let golden = read_golden(&index)?;
        for (name, d) in golden_diff(&net, &golden)? {
            println!("golden: f32 graph vs Python {name}: max |diff| {d:.3e}");
        }
    }
    let eval_seed = args.seed + scenes as u64;
    let (eval, source) = match &args.report_recording {
        Some(dir) => (
            recording_frames(dir, &preset, net.height, net.width, args.eval_frames)?,
            format!("recording {}", dir.display()),
        ),
        None => (
            simulated_frames(&preset, net.height, net.width, args.eval_frames, eval_seed)?,
            format!("seeds {eval_seed}.."),
        ),
    };
    let c = compare(&q.blob, &net, &eval)?;
    let (m, lo) = c.depth_mean_min();
    let (cm, clo) = c.centred_mean_min();
    let worst = c.depth_max_abs_m.iter().copied().fold(0f32, f32::max);
    println!(
        "int8 vs f32 on {} frames ({source}): depth SQNR pooled {:.1} dB, per frame mean {m:.1} dB, min {lo:.1} dB; \
         depth − mean: mean {cm:.1} dB, min {clo:.1} dB; max |err| {worst:.3} m",
        eval.len(),
        c.depth_pooled_db()
    );
    println!("per-op SQNR (dequantised int8 vs f32, all frames):");
    for l in &c.layers {
        println!(
            "  {:3} {:40} {:7.1} dB  max|err| {:.4}",
            l.op, l.name, l.sqnr_db, l.max_abs_err
        );
    }
    println!("worst ops:");
    for l in c.worst_layers(8) {
        println!("  {:3} {:40} {:7.1} dB", l.op, l.name, l.sqnr_db);
    }
    let mut fidelity = op_fidelity(&q.blob, &net, &eval[..eval.len().min(2)])?;
    fidelity.sort_by(|a, b| b.mean_abs_codes.total_cmp(&a.mean_abs_codes));
    println!(
        "ops furthest from their int8 model (f32 op on the engine's inputs, rounded), 2 frames:"
    );
    for f in fidelity.iter().take(5) {
        println!(
            "  {:3} {:40} mean {:.3} codes, max {}",
            f.op, f.name, f.mean_abs_codes, f.max_abs_codes
        );
    }
    Ok(())
}

/// The first `max` frames of the recording `dir` as calibration inputs at `height × width`.
fn recording_frames(
    dir: &Path,
    preset: &str,
    height: usize,
    width: usize,
    max: usize,
) -> Result<Vec<Frame>> {
    let rec = RecordingFrames::open(dir, preset)
        .with_context(|| format!("--calibration-recording {}", dir.display()))?;
    if !rec.has_rgb() {
        anyhow::bail!(
            "--calibration-recording {}: the recording has no colour images",
            dir.display()
        );
    }
    (0..rec.len().min(max))
        .map(|i| {
            let f = rec
                .frame(i, width as u32, height as u32)
                .with_context(|| format!("{}: frame {i}", dir.display()))?;
            Ok(Frame {
                height,
                width,
                sparse_m: f.sparse_m(),
                rgb: f.rgb.into_raw(),
            })
        })
        .collect()
}

/// `--ranges-file`: a JSON object of value name → `[lo, hi]`.
fn read_ranges_file(path: &Path) -> Result<Vec<(String, [f32; 2])>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let map: std::collections::BTreeMap<String, [f32; 2]> = serde_json::from_str(&text)
        .with_context(|| {
            format!(
                "{}: expected {{\"value name\": [lo, hi], …}}",
                path.display()
            )
        })?;
    Ok(map.into_iter().collect())
}
