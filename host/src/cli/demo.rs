//! `depthor demo`: the main job on the embedded default model. With no arguments it renders a
//! scene, simulates the `mcu` sensor (8×8 zones), projects the zones, runs the int8 model in the
//! core, and compares it with the classical baselines; with `--recording DIR` it runs on the
//! user's recording (its own dToF if it has some, else the simulated `mcu` sensor on its
//! reference depth). Writes `<out>/depth_<id>.png` (16-bit mm) and `<out>/mosaic_<id>.png`
//! (RGB with the points | reference | int8 model | |error| | joint bilateral baseline).

use anyhow::{Context, Result};
use depthor_core::metrics::MetricsAccumulator;
use depthor_host::atomic::{AtomicDir, Existing};
use depthor_host::evaluation::{
    comparison_mosaic, metrics_table, rendered_frame, EvalFrame, Evaluator, Method, RecordingFrames,
};
use depthor_host::inference::Int8Model;
use depthor_host::recording::depth_m_to_mm;
use image::{ImageBuffer, Luma};
use std::path::{Path, PathBuf};

/// Arguments of `depthor demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Run on this recording instead of a rendered scene.
    #[arg(long)]
    recording: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "demo")]
    out: PathBuf,
    /// Frames to run (rendered scenes, or the first frames of the recording).
    #[arg(long, default_value_t = 1)]
    frames: usize,
    /// Scene seed.
    #[arg(long, default_value_t = 2025)]
    seed: u64,
    /// Largest depth counted by the metrics, metres.
    #[arg(long, default_value_t = 10.0)]
    max_depth: f32,
}

/// The simulator preset of the embedded model.
const PRESET: &str = "mcu";

/// Runs the demo and prints metrics and time per frame.
pub fn handle(args: Args) -> Result<()> {
    let mut eval = Evaluator::new(Int8Model::embedded_mcu()?, None, (0.1, args.max_depth));
    let (h, w) = eval.int8().input_shape();
    let frames: Vec<EvalFrame> = match &args.recording {
        None => (0..args.frames.max(1) as u64)
            .map(|i| rendered_frame(PRESET, args.seed, i, w as u32, h as u32))
            .collect::<Result<_>>()?,
        Some(dir) => {
            let rec = RecordingFrames::open(dir, PRESET)?;
            (0..rec.len().min(args.frames.max(1)))
                .map(|i| rec.frame(i, w as u32, h as u32))
                .collect::<Result<_>>()?
        }
    };
    // Everything goes into `<out>.partial-<pid>`; an error anywhere leaves `<out>` untouched.
    let staging = AtomicDir::create(&args.out, Existing::Merge)?;
    let methods = eval.methods();
    let mut acc: Vec<MetricsAccumulator> = methods
        .iter()
        .map(|_| MetricsAccumulator::new(args.max_depth))
        .collect();
    let mut model_time = 0.0f64;
    for f in &frames {
        let preds = eval.predict(f)?;
        for (a, p) in acc.iter_mut().zip(&preds) {
            a.add_map(&p.depth_m, &f.reference_m, w, h)?;
        }
        let pick = |m: Method| preds.iter().find(|p| p.method == m).map(|p| &p.depth_m[..]);
        let pred = pick(Method::Int8).context("no int8 prediction")?;
        model_time += preds[0].seconds;
        write_outputs(staging.path(), f, pred, pick(Method::JointBilateral))?;
    }
    let out = staging.commit()?;
    println!(
        "depthor demo: {} frame(s) at {h}×{w}, embedded mcu model ({} KiB blob, {} KiB arena)",
        frames.len(),
        eval.int8().blob_bytes() / 1024,
        eval.int8().arena_bytes() / 1024
    );
    let rows: Vec<_> = methods
        .iter()
        .zip(&acc)
        .map(|(m, a)| (m.label(), a.finish()))
        .collect();
    print!("{}", metrics_table(&rows));
    println!(
        "int8 model time per frame (this machine, one thread): {:.1} ms",
        1e3 * model_time / frames.len().max(1) as f64
    );
    println!("wrote {}", out.display());
    Ok(())
}

/// depth_<id>.png (16-bit mm) and mosaic_<id>.png.
fn write_outputs(out: &Path, f: &EvalFrame, pred: &[f32], jbu: Option<&[f32]>) -> Result<()> {
    let (w, h) = (f.width(), f.height());
    let mm: Vec<u16> = pred.iter().map(|&d| depth_m_to_mm(d)).collect();
    let depth_png: ImageBuffer<Luma<u16>, Vec<u16>> =
        ImageBuffer::from_raw(w, h, mm).context("depth size")?;
    let path = out.join(format!("depth_{}.png", f.id));
    depth_png
        .save(&path)
        .with_context(|| format!("{}: cannot write", path.display()))?;
    let path = out.join(format!("mosaic_{}.png", f.id));
    comparison_mosaic(f, pred, jbu)
        .save(&path)
        .with_context(|| format!("{}: cannot write", path.display()))
}
