//! `depthor eval --model VARIANT --recording DIR [--out DIR]`: the int8 model (core), the float
//! model (tract) and the baselines on the same inputs of every frame of a recording. Writes
//! `<out>/frames.csv` (one row per frame and method), `<out>/summary.json` (metrics over all
//! frames, the best baseline, int8 against it and against float) and `<out>/mosaic_<id>.png` for
//! a sample of frames (RGB with the dToF points | reference | int8 prediction | |error|).

use anyhow::{bail, Context, Result};
use depthor_core::metrics::{Metrics, MetricsAccumulator};
use depthor_host::evaluation::{
    comparison_mosaic, metrics_table, EvalFrame, Evaluator, Method, RecordingFrames,
};
use depthor_host::models::ModelFiles;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `depthor eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// `mcu`, `phone` or a model directory (depthor.dblob, depthor.nnef.tgz, prior.nnef.tgz).
    #[arg(long, default_value = "mcu")]
    model: String,
    /// The recording to evaluate on (needs reference depth; zones are simulated with the
    /// variant's preset where it has none).
    #[arg(long)]
    recording: PathBuf,
    /// Output directory (default: eval/<variant>_<recording name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Evaluate only the first N frames (0 = all).
    #[arg(long, default_value_t = 0)]
    frames: usize,
    /// Mosaics to write, spread evenly over the frames.
    #[arg(long, default_value_t = 6)]
    mosaics: usize,
    /// Skip the tract float model and the prior baseline (int8 and zone baselines only).
    #[arg(long)]
    no_float: bool,
    /// Pixels with reference depth beyond this are not counted, metres.
    #[arg(long, default_value_t = 10.0)]
    max_depth: f32,
}

const CSV_HEADER: &str =
    "frame,method,pixels,delta1,delta2,delta3,abs_rel,rmse,log10,mae,ewmae,invalid_pred,ms";

/// Runs the evaluation and prints the summary table.
pub fn handle(args: Args) -> Result<()> {
    let files = ModelFiles::resolve(&args.model)?;
    let frames = RecordingFrames::open(&args.recording, files.preset())?;
    if frames.is_empty() {
        bail!("{}: the recording has no frames", args.recording.display());
    }
    let n = match args.frames {
        0 => frames.len(),
        k => k.min(frames.len()),
    };
    let mut eval = Evaluator::load(&files, !args.no_float, (0.1, args.max_depth))?;
    let (h, w) = eval.int8().input_shape();
    let out = args.out.clone().unwrap_or_else(|| {
        let rec = args
            .recording
            .file_name()
            .map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("eval").join(format!("{}_{rec}", files.variant))
    });
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    let methods = eval.methods();
    let mut totals: Vec<MetricsAccumulator> = methods
        .iter()
        .map(|_| MetricsAccumulator::new(args.max_depth))
        .collect();
    let mut seconds = vec![0.0f64; methods.len()];
    let mut csv = vec![CSV_HEADER.to_string()];
    let mosaic_every = if args.mosaics == 0 {
        usize::MAX
    } else {
        n.div_ceil(args.mosaics)
    };
    let bar = super::progress(n as u64, "eval");
    let mut counted = 0usize;
    for i in 0..n {
        let frame = frames.frame(i, w as u32, h as u32)?;
        bar.inc(1);
        if !frame
            .reference_m
            .iter()
            .any(|&d| d > 0.0 && d < args.max_depth)
        {
            continue; // nothing to score on this frame
        }
        counted += 1;
        let preds = eval.predict(&frame)?;
        for (k, p) in preds.iter().enumerate() {
            let mut acc = MetricsAccumulator::new(args.max_depth);
            acc.add_map(&p.depth_m, &frame.reference_m, w, h)?;
            totals[k].merge(&acc);
            seconds[k] += p.seconds;
            csv.push(csv_row(&frame.id, p.method, &acc.finish(), p.seconds));
        }
        if i % mosaic_every == 0 {
            write_mosaic(&out, &frame, &preds[0].depth_m)?;
        }
    }
    bar.finish_and_clear();
    if counted == 0 {
        bail!(
            "{}: no frame has reference depth within {} m",
            args.recording.display(),
            args.max_depth
        );
    }
    let results: Vec<(Method, Metrics, f64)> = methods
        .iter()
        .zip(&totals)
        .zip(&seconds)
        .map(|((m, a), s)| (*m, a.finish(), 1e3 * s / counted as f64))
        .collect();
    write_text(&out.join("frames.csv"), &(csv.join("\n") + "\n"))?;
    let summary = summary_json(&files, &args, counted, (h, w), &results);
    write_text(
        &out.join("summary.json"),
        &(serde_json::to_string_pretty(&summary)? + "\n"),
    )?;
    let rows: Vec<(&str, Metrics)> = results.iter().map(|(m, x, _)| (m.label(), *x)).collect();
    println!(
        "depthor eval: {} on {} ({counted} frames at {h}×{w}, reference ≤ {} m)",
        files.variant,
        args.recording.display(),
        args.max_depth
    );
    print!("{}", metrics_table(&rows));
    for (m, _, ms) in &results {
        println!("{:<20} {ms:8.1} ms/frame", m.label());
    }
    if let Some(c) = summary.get("int8_vs_best_baseline") {
        println!("int8 vs best baseline: {c}");
    }
    if let Some(c) = summary.get("int8_vs_float") {
        println!("int8 vs float: {c}");
    }
    println!("wrote {}", out.display());
    Ok(())
}

fn csv_row(id: &str, m: Method, x: &Metrics, seconds: f64) -> String {
    format!(
        "{id},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{},{:.3}",
        m.key(),
        x.count,
        x.delta1,
        x.delta2,
        x.delta3,
        x.abs_rel,
        x.rmse,
        x.log10,
        x.mae,
        x.ewmae,
        x.invalid_pred,
        seconds * 1e3
    )
}

fn metrics_json(x: &Metrics) -> serde_json::Value {
    json!({
        "pixels": x.count, "delta1": x.delta1, "delta2": x.delta2, "delta3": x.delta3,
        "abs_rel": x.abs_rel, "rmse": x.rmse, "log10": x.log10, "mae": x.mae, "ewmae": x.ewmae,
        "invalid_pred": x.invalid_pred,
    })
}

/// The summary: per-method metrics and the comparisons the model cards quote.
fn summary_json(
    files: &ModelFiles,
    args: &Args,
    frames: usize,
    (h, w): (usize, usize),
    results: &[(Method, Metrics, f64)],
) -> serde_json::Value {
    let methods: serde_json::Map<String, serde_json::Value> = results
        .iter()
        .map(|(m, x, ms)| {
            let mut v = metrics_json(x);
            v["label"] = json!(m.label());
            v["ms_per_frame"] = json!(ms);
            (m.key().to_string(), v)
        })
        .collect();
    let get = |k: Method| results.iter().find(|r| r.0 == k).map(|r| r.1);
    let baselines = results.iter().filter(|r| r.0.is_baseline());
    let best_rmse = baselines
        .clone()
        .min_by(|a, b| a.1.rmse.total_cmp(&b.1.rmse));
    let best_d1 = baselines.max_by(|a, b| a.1.delta1.total_cmp(&b.1.delta1));
    let mut s = json!({
        "model": files.variant,
        "model_dir": files.dir.display().to_string(),
        "recording": args.recording.display().to_string(),
        "frames": frames,
        "height": h,
        "width": w,
        "max_depth_m": args.max_depth,
        "methods": methods,
    });
    if let (Some(i8m), Some(br), Some(bd)) = (get(Method::Int8), best_rmse, best_d1) {
        s["best_baseline"] = json!({
            "rmse": {"method": br.0.key(), "value": br.1.rmse},
            "delta1": {"method": bd.0.key(), "value": bd.1.delta1},
        });
        s["int8_vs_best_baseline"] = json!({
            "rmse_ratio": i8m.rmse / br.1.rmse,
            "delta1_gain": i8m.delta1 - bd.1.delta1,
        });
    }
    if let (Some(q), Some(f)) = (get(Method::Int8), get(Method::Float)) {
        s["int8_vs_float"] = json!({
            "rmse_rel_diff": (q.rmse - f.rmse) / f.rmse,
            "delta1_diff": q.delta1 - f.delta1,
        });
    }
    s
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(text.as_bytes()))
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// mosaic_<id>.png: RGB with the points | reference | int8 prediction | |error| (0–1 m).
fn write_mosaic(out: &Path, f: &EvalFrame, pred: &[f32]) -> Result<()> {
    let path = out.join(format!("mosaic_{}.png", f.id));
    comparison_mosaic(f, pred, None)
        .save(&path)
        .with_context(|| format!("{}: cannot write", path.display()))
}
