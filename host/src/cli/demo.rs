//! `depthor demo`: the main job. With no arguments it renders a scene, simulates the `mcu`
//! sensor (8×8 zones), projects the zones, runs the int8 model embedded in the binary in the
//! core, and compares it with the classical baselines; `--model phone` (or a model folder) runs
//! another variant on its own preset; `--recording DIR` runs on the user's recording (its own dToF
//! if it has some, else the simulated sensor on its reference depth). Writes
//! `<out>/depth_<id>.png` (16-bit mm) and `<out>/mosaic_<id>.png` (RGB with the points |
//! reference | int8 model | |error| | joint bilateral baseline); for a model with a zone gate
//! (`zone_gate.bin`, phone_lite) the depth and the mosaic are the gated output.

use anyhow::{Context, Result};
use depthor_core::metrics::MetricsAccumulator;
use depthor_host::evaluation::{
    metrics_table, rendered_frame, write_mosaic, Aggregate, EvalFrame, Evaluator, Method,
    MetricsSet, RecordingFrames,
};
use depthor_host::models::ModelFiles;
use depthor_host::recording::depth_m_to_mm;
use image::{ImageBuffer, Luma};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Arguments of `depthor demo`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor demo                                    # rendered scene, embedded mcu_lite model, ./demo/
  depthor demo --model mcu --out demo-mcu         # the larger mcu network (also embedded)
  depthor demo --model phone --out demo-phone     # the phone variant on its 40×30 sensor
  depthor demo --recording rec/middlebury --frames 3 --out demo-mb --overwrite
  depthor demo --json | jq .methods.int8.rmse")]
pub struct Args {
    /// `mcu_lite` or `mcu` (both embedded in the binary), `phone`, or a model folder
    /// (depthor.dblob).
    #[arg(long, default_value = "mcu_lite")]
    model: String,
    /// Run on this recording instead of rendered scenes.
    #[arg(long, short = 'r', value_name = "DIR")]
    recording: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "demo")]
    out: PathBuf,
    /// Write into an existing non-empty --out (files of the same name are replaced).
    #[arg(long)]
    overwrite: bool,
    /// Frames: rendered scenes, or the first N frames of --recording (0 = all of them).
    #[arg(long, default_value_t = 1)]
    frames: usize,
    /// Scene seed (rendered scenes).
    #[arg(long, default_value_t = super::common::DEFAULT_SEED)]
    seed: u64,
    /// Largest depth counted by the metrics, metres.
    #[arg(long, default_value_t = 10.0)]
    max_depth: f32,
    /// Print the results as JSON on stdout instead of the table.
    #[arg(long)]
    json: bool,
}

/// Runs the demo and prints metrics and time per frame.
pub fn handle(args: Args) -> Result<()> {
    let files = ModelFiles::resolve(&args.model)?;
    let preset = files.preset().to_string();
    let mut eval = Evaluator::load(&files, false, (0.1, args.max_depth))?;
    let (h, w) = eval.int8().input_shape();
    let frames: Vec<EvalFrame> = match &args.recording {
        None => (0..args.frames.max(1) as u64)
            .map(|i| rendered_frame(&preset, args.seed, i, w as u32, h as u32))
            .collect::<Result<_, _>>()?,
        Some(dir) => {
            let rec = RecordingFrames::open(dir, &preset)?;
            if !rec.has_rgb() {
                anyhow::bail!(
                    "{}: recording.json: rgb: false (zone-only recording); the models need colour images",
                    dir.display()
                );
            }
            let n = match args.frames {
                0 => rec.len(),
                n => n.min(rec.len()),
            };
            (0..n)
                .map(|i| rec.frame(i, w as u32, h as u32))
                .collect::<Result<_, _>>()?
        }
    };
    // Everything goes into `<out>.partial-<pid>`; an error anywhere leaves `<out>` untouched.
    let staging = super::common::out_dir(&args.out, args.overwrite)?;
    let methods = eval.methods();
    let mut acc: Vec<MetricsSet> = methods
        .iter()
        .map(|_| MetricsSet::new(args.max_depth))
        .collect();
    let mut model_time = 0.0f64;
    for f in &frames {
        let preds = eval.predict(f)?;
        for (a, p) in acc.iter_mut().zip(&preds) {
            let mut frame = MetricsAccumulator::new(args.max_depth);
            frame.add_map(&p.depth_m, &f.reference_m, w, h)?;
            a.add_image(&frame);
        }
        let pick = |m: Method| preds.iter().find(|p| p.method == m).map(|p| &p.depth_m[..]);
        // The product's output: the gated depth when the model ships a zone gate.
        let pred = match pick(Method::Gate) {
            Some(g) => ("int8 model + zone gate", g),
            None => (
                "int8 model",
                pick(Method::Int8).context("no int8 prediction")?,
            ),
        };
        model_time += preds[0].seconds;
        write_outputs(staging.path(), f, pred, pick(Method::JointBilateral))?;
    }
    let out = staging.commit()?;
    let ms = 1e3 * model_time / frames.len().max(1) as f64;
    let rows: Vec<_> = methods
        .iter()
        .zip(&acc)
        .map(|(m, a)| (*m, a.finish(Aggregate::Image)))
        .collect();
    if args.json {
        let methods: serde_json::Map<_, _> = rows
            .iter()
            .map(|(m, x)| {
                (
                    m.key().to_string(),
                    depthor_host::evaluation::output::metrics_json(x),
                )
            })
            .collect();
        return super::common::print_json(&json!({
            "model": files.variant, "model_files": files.describe(),
            "blob_sha256": eval.int8().blob_sha256(),
            "frames": frames.len(), "height": h, "width": w, "seed": args.seed,
            "aggregate": Aggregate::Image.key(),
            "max_depth_m": args.max_depth, "methods": methods,
            "int8_ms_per_frame": ms, "out": out.display().to_string(),
        }));
    }
    println!(
        "depthor demo: {} frame(s) at {h}×{w}, {} model ({}; {} KiB blob, {} KiB arena)",
        frames.len(),
        files.variant,
        files.describe(),
        eval.int8().blob_bytes() / 1024,
        eval.int8().arena_bytes() / 1024
    );
    let table: Vec<_> = rows.iter().map(|(m, x)| (m.label(), *x)).collect();
    print!("{}", metrics_table(&table));
    println!(
        "aggregate: {} (see docs/eval.md); RMSE and EWMAE in m, δ fractions",
        Aggregate::Image.describe()
    );
    println!("int8 model time per frame (this machine, one thread): {ms:.1} ms");
    println!("wrote {}", out.display());
    Ok(())
}

/// depth_<id>.png (16-bit mm) and mosaic_<id>.png of the labelled prediction.
fn write_outputs(
    out: &Path,
    f: &EvalFrame,
    (label, pred): (&str, &[f32]),
    jbu: Option<&[f32]>,
) -> Result<()> {
    let (w, h) = (f.width(), f.height());
    let mm: Vec<u16> = pred.iter().map(|&d| depth_m_to_mm(d)).collect();
    let depth_png: ImageBuffer<Luma<u16>, Vec<u16>> =
        ImageBuffer::from_raw(w, h, mm).context("depth size")?;
    let path = out.join(format!("depth_{}.png", f.id));
    depth_png
        .save(&path)
        .with_context(|| format!("{}: cannot write", path.display()))?;
    write_mosaic(
        &out.join(format!("mosaic_{}.png", f.id)),
        f,
        (label, pred),
        jbu.map(|d| ("joint bilateral", d)),
    )?;
    Ok(())
}
