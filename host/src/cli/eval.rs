//! `depthor eval --model VARIANT --recording DIR [--recording DIR2 …] [--out DIR]`: the int8
//! model (core), the float model (tract) and the baselines on the same inputs of every frame of
//! one or more recordings. Writes `<out>/frames.csv` (one row per recording, frame and method),
//! `<out>/summary.json` (metrics over all frames of each recording and over their union, the best
//! baseline, int8 against it and against float; the depthor version, commit, blob SHA-256),
//! `<out>/mosaic_<recording>_<id>.png` for a sample of frames and, with `--save-depth`,
//! `<out>/depth/<recording>/<method>/<id>.png` (16-bit PNG, millimetres). The metrics, their
//! aggregation and every output are documented in docs/eval.md.

use anyhow::{bail, Context, Result};
use depthor_core::metrics::{Metrics, MetricsAccumulator};
use depthor_host::evaluation::{
    metrics_table, resize_bilinear, write_mosaic, Aggregate, EvalFrame, Evaluator, Method,
    MetricsSet, RecordingFrames,
};
use depthor_host::models::ModelFiles;
use depthor_host::recording::depth_m_to_mm;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `depthor eval`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor eval --model mcu --recording rec/mcu-test --out eval/mcu
  depthor eval --model phone --recording rec/a --recording rec/b --aggregate pixel --json
  depthor eval --recording rec/middlebury --native --save-depth --out eval/mb --overwrite
Metrics and outputs: docs/eval.md.")]
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

const CSV_HEADER: &str =
    "recording,frame,method,pixels,delta1,delta2,delta3,abs_rel,rmse,log10,mae,ewmae,invalid_pred,ms";

/// Metrics of every method over a set of frames, and their time.
struct Totals {
    sets: Vec<MetricsSet>,
    seconds: Vec<f64>,
    frames: usize,
}

impl Totals {
    fn new(methods: usize, max_depth: f32) -> Self {
        Totals {
            sets: (0..methods).map(|_| MetricsSet::new(max_depth)).collect(),
            seconds: vec![0.0; methods],
            frames: 0,
        }
    }

    fn merge(&mut self, other: &Totals) {
        for (a, b) in self.sets.iter_mut().zip(&other.sets) {
            a.merge(b);
        }
        for (a, b) in self.seconds.iter_mut().zip(&other.seconds) {
            *a += b;
        }
        self.frames += other.frames;
    }

    fn results(&self, methods: &[Method], how: Aggregate) -> Vec<(Method, Metrics, f64)> {
        methods
            .iter()
            .zip(&self.sets)
            .zip(&self.seconds)
            .map(|((m, a), s)| (*m, a.finish(how), 1e3 * s / self.frames.max(1) as f64))
            .collect()
    }
}

/// A recording's name for file names and tables (its directory name).
fn name_of(dir: &Path) -> String {
    dir.file_name()
        .map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned())
}

/// `p` relative to the current folder when it is inside it, else as given.
fn relative(p: &Path) -> String {
    let rel = std::env::current_dir()
        .ok()
        .and_then(|cwd| p.strip_prefix(&cwd).ok().map(Path::to_path_buf));
    rel.unwrap_or_else(|| p.to_path_buf()).display().to_string()
}

/// The source tree's commit (`git rev-parse HEAD`, `-dirty` with uncommitted changes to tracked
/// files) when the tree this binary was built from is still there; else `None`.
fn git_commit() -> Option<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .arg("-C")
            .arg(dir)
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let head = git(&["rev-parse", "HEAD"])?;
    let dirty =
        git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    Some(if dirty { format!("{head}-dirty") } else { head })
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
            for (k, p) in preds.iter().enumerate() {
                let (pred, reference, sw, sh) = scored(&frame, &p.depth_m, args.native)?;
                native_size.get_or_insert((sh, sw));
                let mut acc = MetricsAccumulator::new(args.max_depth);
                acc.add_map(&pred, reference, sw as usize, sh as usize)?;
                totals.sets[k].add_image(&acc);
                totals.seconds[k] += p.seconds;
                csv.push(format!(
                    "{name},{}",
                    csv_row(&frame.id, p.method, &acc.finish(), p.seconds)
                ));
                if args.save_depth && matches!(p.method, Method::Int8 | Method::Float) {
                    save_depth(&out, &name, p.method, &frame.id, &pred, sw, sh)?;
                }
            }
            if i % mosaic_every == 0 {
                let path = out.join(format!("mosaic_{name}_{}.png", frame.id));
                write_mosaic(&path, &frame, ("int8 model", &preds[0].depth_m), None)?;
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
    let mut summary = comparison_json(&union_results);
    summary["depthor_version"] = json!(env!("CARGO_PKG_VERSION"));
    summary["git_commit"] = json!(git_commit());
    summary["model"] = json!(files.variant);
    summary["model_dir"] = if files.embedded {
        json!(null)
    } else {
        json!(relative(&files.dir))
    };
    summary["model_embedded"] = json!(files.embedded);
    summary["blob_sha256"] = json!(eval.int8().blob_sha256());
    summary["aggregate"] = json!(how.key());
    summary["aggregate_note"] = json!(how.describe());
    summary["scored_at"] = json!(if args.native { "native" } else { "model" });
    summary["frames"] = json!(union.frames);
    summary["height"] = json!(h);
    summary["width"] = json!(w);
    if args.native {
        summary["first_native_crop"] =
            json!(native_size.map(|(h, w)| json!({"height": h, "width": w})));
    }
    summary["max_depth_m"] = json!(args.max_depth);
    summary["recordings"] = per_recording
        .iter()
        .map(|(dir, t)| {
            let mut r = comparison_json(&t.results(&methods, how));
            r["recording"] = json!(relative(dir));
            r["frames"] = json!(t.frames);
            r
        })
        .collect();
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

/// One method's metrics as JSON (the keys of docs/eval.md).
pub fn metrics_json(x: &Metrics) -> serde_json::Value {
    json!({
        "pixels": x.count, "delta1": x.delta1, "delta2": x.delta2, "delta3": x.delta3,
        "abs_rel": x.abs_rel, "rmse": x.rmse, "log10": x.log10, "mae": x.mae, "ewmae": x.ewmae,
        "invalid_pred": x.invalid_pred,
    })
}

/// Per-method metrics and the comparisons the model cards quote (best baseline by RMSE and by
/// δ1, int8 against it and against float).
fn comparison_json(results: &[(Method, Metrics, f64)]) -> serde_json::Value {
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
    let mut s = json!({ "methods": methods });
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
