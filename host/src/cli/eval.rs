//! `depthor eval --model VARIANT --recording DIR [--recording DIR2 …] [--out DIR]`: the int8
//! model (core), the float model (tract) and the baselines on the same inputs of every frame of
//! one or more recordings. Writes `<out>/frames.csv` (one row per recording, frame and method),
//! `<out>/summary.json` (metrics over all frames of each recording and over their union, the best
//! baseline, int8 against it and against float; the depthor version, commit, blob SHA-256),
//! `<out>/mosaic_<recording>_<id>.png` for a sample of frames (the int8 model beside the frame's
//! best baseline) and, with `--save-depth`,
//! `<out>/depth/<recording>/<method>/<id>.png` (16-bit PNG, millimetres). The metrics, their
//! aggregation and every output are documented in docs/eval.md.

use anyhow::{bail, Context, Result};
use depthor_core::metrics::{Metrics, MetricsAccumulator};
use depthor_host::evaluation::output::{
    comparison_json, csv_row, relative, summary_json, SummaryInfo, Totals, CSV_HEADER,
};
use depthor_host::evaluation::{
    metrics_table, resize_bilinear, write_mosaic, Aggregate, EvalFrame, Evaluator, Method,
    RecordingFrames,
};
use depthor_host::models::ModelFiles;
use depthor_host::recording::depth_m_to_mm;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `depthor eval`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor eval --model mcu --recording rec/mcu-test --out eval/mcu
  depthor eval --model phone --recording rec/a --recording rec/b --aggregate pixel --json
  depthor eval --recording rec/middlebury --native --save-depth --out eval/mb --overwrite
Metrics and outputs: docs/eval.md. Measurement conditions × sets (clean, noisy, misregistered
zones …): depthor eval-grid --help.")]
pub struct Args {
    /// `mcu`, `phone` or a model folder (depthor.dblob, depthor.nnef.tgz, prior.nnef.tgz).
    #[arg(long, default_value = "mcu")]
    model: String,
    /// Recording(s) to evaluate on (need reference depth; zones are simulated with the
    /// variant's preset where a recording has none). Repeat for several; the summary also
    /// gives their union.
    #[arg(long, short = 'r', value_name = "DIR", required = true)]
    recording: Vec<PathBuf>,
    /// Output folder (default: eval/<variant>_<first recording's name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write into an existing non-empty --out (files of the same name are replaced).
    #[arg(long)]
    overwrite: bool,
    /// Evaluate only the first N frames of each recording (0 = all).
    #[arg(long, default_value_t = 0)]
    frames: usize,
    /// Mosaics to write per recording, spread evenly over its frames.
    #[arg(long, default_value_t = 6)]
    mosaics: usize,
    /// Skip the tract float model and the prior baseline (int8 and zone baselines only).
    #[arg(long)]
    no_float: bool,
    /// Pixels with reference depth beyond this are not counted, metres.
    #[arg(long, default_value_t = 10.0)]
    max_depth: f32,
    /// How frames are combined: `image` (each metric per frame, then the mean over frames: the
    /// published protocol) or `pixel` (all valid pixels pooled).
    #[arg(long, value_enum, default_value_t = Aggregate::Image)]
    aggregate: Aggregate,
    /// Score at the recording's own resolution: predictions upsampled bilinearly to the crop of
    /// the frame the model's input came from, against the full-resolution reference.
    #[arg(long)]
    native: bool,
    /// Also write every int8 and float prediction as a 16-bit PNG in millimetres (at the scoring
    /// resolution) under <out>/depth/<recording>/<method>/<id>.png.
    #[arg(long)]
    save_depth: bool,
    /// Print summary.json on stdout instead of the tables.
    #[arg(long)]
    json: bool,
}

/// A recording's name for file names and tables (its directory name).
fn name_of(dir: &Path) -> String {
    dir.file_name()
        .map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned())
}

/// The prediction and reference a frame is scored on: the model's size, or with `native` the
/// recording's (prediction upsampled bilinearly).
fn scored<'a>(
    frame: &'a EvalFrame,
    pred: &[f32],
    native: bool,
) -> Result<(Vec<f32>, &'a [f32], u32, u32)> {
    if !native {
        return Ok((
            pred.to_vec(),
            &frame.reference_m,
            frame.width(),
            frame.height(),
        ));
    }
    let n = frame.native.as_ref().with_context(|| {
        format!(
            "frame {}: no reference at the recording's resolution",
            frame.id
        )
    })?;
    let up = resize_bilinear(pred, frame.width(), frame.height(), n.width, n.height);
    Ok((up, &n.depth_m, n.width, n.height))
}

/// Runs the evaluation and prints the summary tables.
pub fn handle(args: Args) -> Result<()> {
    let files = ModelFiles::resolve(&args.model)?;
    let recordings = args
        .recording
        .iter()
        .map(|dir| {
            let frames = RecordingFrames::open(dir, files.preset())?;
            if frames.is_empty() {
                bail!("{}: the recording has no frames", dir.display());
            }
            if !frames.has_rgb() {
                bail!(
                    "{}: recording.json: rgb: false (zone-only recording); eval needs colour \
                     images and reference depth",
                    dir.display()
                );
            }
            Ok((dir.clone(), frames))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut eval = Evaluator::load(&files, !args.no_float, (0.1, args.max_depth))?;
    let (h, w) = eval.int8().input_shape();
    let out_dir = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("eval").join(format!("{}_{}", files.variant, name_of(&args.recording[0])))
    });
    // Everything goes into `<out>.partial-<pid>`; an error anywhere leaves `<out>` untouched.
    let staging = super::common::out_dir(&out_dir, args.overwrite)?;
    let out = staging.path().to_path_buf();
    let methods = eval.methods();
    let mut csv = vec![CSV_HEADER.to_string()];
    let mut union = Totals::new(methods.len(), args.max_depth);
    let mut per_recording = Vec::new();
    let mut native_size = None;
    let total: usize = recordings
        .iter()
        .map(|(_, f)| limit(args.frames, f.len()))
        .sum();
    let bar = super::progress(total as u64, "eval");
    for (dir, frames) in &recordings {
        let name = name_of(dir);
        let n = limit(args.frames, frames.len());
        let mosaic_every = if args.mosaics == 0 {
            usize::MAX
        } else {
            n.div_ceil(args.mosaics)
        };
        let mut totals = Totals::new(methods.len(), args.max_depth);
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
            totals.frames += 1;
            let preds = eval.predict(&frame)?;
            // This frame's RMSE per method, for the mosaic's best baseline.
            let mut frame_rmse = Vec::with_capacity(preds.len());
            for (k, p) in preds.iter().enumerate() {
                let (pred, reference, sw, sh) = scored(&frame, &p.depth_m, args.native)?;
                native_size.get_or_insert((sh, sw));
                let mut acc = MetricsAccumulator::new(args.max_depth);
                acc.add_map(&pred, reference, sw as usize, sh as usize)?;
                totals.sets[k].add_image(&acc);
                frame_rmse.push(acc.finish().rmse);
                totals.seconds[k] += p.seconds;
                csv.push(csv_row(
                    &name,
                    &frame.id,
                    p.method,
                    &acc.finish(),
                    p.seconds,
                ));
                if args.save_depth
                    && matches!(p.method, Method::Int8 | Method::Float | Method::Gate)
                {
                    save_depth(&out, &name, p.method, &frame.id, &pred, sw, sh)?;
                }
            }
            if i % mosaic_every == 0 {
                let path = out.join(format!("mosaic_{name}_{}.png", frame.id));
                let best = preds
                    .iter()
                    .zip(&frame_rmse)
                    .filter(|(p, _)| p.method.is_baseline())
                    .min_by(|a, b| a.1.total_cmp(b.1));
                let int8_label = format!("int8 model (RMSE {:.3} m)", frame_rmse[0]);
                let best_label = best
                    .map(|(p, r)| format!("best baseline: {} (RMSE {r:.3} m)", p.method.label()));
                write_mosaic(
                    &path,
                    &frame,
                    (&int8_label, &preds[0].depth_m),
                    best.zip(best_label.as_deref())
                        .map(|((p, _), l)| (l, p.depth_m.as_slice())),
                )?;
            }
        }
        if totals.frames == 0 {
            bail!(
                "{}: no frame has reference depth within {} m",
                dir.display(),
                args.max_depth
            );
        }
        union.merge(&totals);
        per_recording.push((dir.clone(), totals));
    }
    bar.finish_and_clear();
    write_text(&out.join("frames.csv"), &(csv.join("\n") + "\n"))?;

    let how = args.aggregate;
    let union_results = union.results(&methods, how);
    let info = SummaryInfo {
        model: &files.variant,
        model_dir: (!files.embedded).then(|| relative(&files.dir)),
        blob_sha256: eval.int8().blob_sha256(),
        aggregate: how,
        native: args.native,
        first_native_crop: native_size,
        model_size: (h, w),
        max_depth_m: args.max_depth,
    };
    let recordings: Vec<(&Path, &Totals)> = per_recording
        .iter()
        .map(|(dir, t)| (dir.as_path(), t))
        .collect();
    let summary = summary_json(&info, &methods, &union, &recordings);
    write_text(
        &out.join("summary.json"),
        &(serde_json::to_string_pretty(&summary)? + "\n"),
    )?;
    let out = staging.commit()?;
    if args.json {
        return super::common::print_json(&summary);
    }

    println!(
        "depthor eval: {} at {h}×{w}, scored at {}, reference ≤ {} m, {}",
        files.variant,
        if args.native {
            "the recording's resolution (--native)"
        } else {
            "the model's resolution"
        },
        args.max_depth,
        how.describe()
    );
    for (dir, t) in &per_recording {
        println!("\n{} ({} frames)", dir.display(), t.frames);
        print_results(&t.results(&methods, how));
    }
    if per_recording.len() > 1 {
        println!(
            "\nunion of {} recordings ({} frames)",
            per_recording.len(),
            union.frames
        );
        print_results(&union_results);
    }
    for (m, _, ms) in &union_results {
        println!("{:<20} {ms:8.1} ms/frame", m.label());
    }
    println!("aggregate: {} ({})", how.key(), how.describe());
    println!("wrote {}", out.display());
    Ok(())
}

fn limit(frames: usize, len: usize) -> usize {
    match frames {
        0 => len,
        k => k.min(len),
    }
}

/// `<out>/depth/<recording>/<method>/<id>.png`, 16-bit millimetres.
fn save_depth(out: &Path, rec: &str, m: Method, id: &str, d: &[f32], w: u32, h: u32) -> Result<()> {
    let dir = out.join("depth").join(rec).join(m.key());
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let mm: Vec<u16> = d.iter().map(|&x| depth_m_to_mm(x)).collect();
    let img: image::ImageBuffer<image::Luma<u16>, Vec<u16>> =
        image::ImageBuffer::from_raw(w, h, mm).context("depth size")?;
    let path = dir.join(format!("{id}.png"));
    img.save(&path)
        .with_context(|| format!("{}: cannot write", path.display()))
}

fn print_results(results: &[(Method, Metrics, f64)]) {
    let rows: Vec<(&str, Metrics)> = results.iter().map(|(m, x, _)| (m.label(), *x)).collect();
    print!("{}", metrics_table(&rows));
    let c = comparison_json(results);
    if let Some(c) = c.get("int8_vs_best_baseline") {
        println!(
            "int8 vs best baseline: RMSE ratio {:.3}, δ1 gain {:+.3}",
            c["rmse_ratio"].as_f64().unwrap_or(f64::NAN),
            c["delta1_gain"].as_f64().unwrap_or(f64::NAN)
        );
    }
    if let Some(c) = c.get("int8_vs_float") {
        println!(
            "int8 vs float: RMSE {:+.1} %, δ1 {:+.3}",
            100.0 * c["rmse_rel_diff"].as_f64().unwrap_or(f64::NAN),
            c["delta1_diff"].as_f64().unwrap_or(f64::NAN)
        );
    }
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(text.as_bytes()))
        .with_context(|| format!("{}: cannot write", path.display()))
}
