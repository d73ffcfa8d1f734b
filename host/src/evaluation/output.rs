//! The files `depthor eval` writes, as `models/card.py` and the tests read them (docs/eval.md,
//! "Outputs"): `frames.csv` (one row per recording, frame and method) and `summary.json` (each
//! method's metrics over each recording and over their union, the best baseline, int8 against it
//! and against float, and where the figures came from).

use depthor_core::metrics::Metrics;
use serde_json::{json, Value};
use std::path::Path;

use super::{Aggregate, Method, MetricsSet};

/// The header line of `frames.csv`.
pub const CSV_HEADER: &str =
    "recording,frame,method,pixels,delta1,delta2,delta3,abs_rel,rmse,log10,mae,ewmae,invalid_pred,ms";

/// One row of `frames.csv` (no line end): frame `id` of `recording` scored `x` by `method`,
/// which took `seconds`.
pub fn csv_row(recording: &str, id: &str, method: Method, x: &Metrics, seconds: f64) -> String {
    format!(
        "{recording},{id},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{},{:.3}",
        method.key(),
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
pub fn metrics_json(x: &Metrics) -> Value {
    json!({
        "pixels": x.count, "delta1": x.delta1, "delta2": x.delta2, "delta3": x.delta3,
        "abs_rel": x.abs_rel, "rmse": x.rmse, "log10": x.log10, "mae": x.mae, "ewmae": x.ewmae,
        "invalid_pred": x.invalid_pred,
    })
}

/// Per-method metrics (with each method's label and milliseconds per frame) and the comparisons
/// the model cards quote: the best baseline by RMSE and by δ1, int8 against it and against float.
pub fn comparison_json(results: &[(Method, Metrics, f64)]) -> Value {
    let methods: serde_json::Map<String, Value> = results
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
    if let (Some(g), Some(br)) = (get(Method::Gate), best_rmse) {
        s["int8_gate_vs_best_baseline"] = json!({ "rmse_ratio": g.rmse / br.1.rmse });
    }
    if let (Some(q), Some(f)) = (get(Method::Int8), get(Method::Float)) {
        s["int8_vs_float"] = json!({
            "rmse_rel_diff": (q.rmse - f.rmse) / f.rmse,
            "delta1_diff": q.delta1 - f.delta1,
        });
    }
    s
}

/// Metrics of every method over a set of frames, and their time.
#[derive(Clone, Debug)]
pub struct Totals {
    /// Per method, in the evaluator's order.
    pub sets: Vec<MetricsSet>,
    /// Seconds per method, summed over the frames.
    pub seconds: Vec<f64>,
    /// Frames scored.
    pub frames: usize,
}

impl Totals {
    /// Empty totals of `methods` methods, counting reference depth up to `max_depth` metres.
    pub fn new(methods: usize, max_depth: f32) -> Self {
        Totals {
            sets: (0..methods).map(|_| MetricsSet::new(max_depth)).collect(),
            seconds: vec![0.0; methods],
            frames: 0,
        }
    }

    /// Adds `other`'s frames.
    pub fn merge(&mut self, other: &Totals) {
        for (a, b) in self.sets.iter_mut().zip(&other.sets) {
            a.merge(b);
        }
        for (a, b) in self.seconds.iter_mut().zip(&other.seconds) {
            *a += b;
        }
        self.frames += other.frames;
    }

    /// Each method's metrics combined `how`, and its milliseconds per frame.
    pub fn results(&self, methods: &[Method], how: Aggregate) -> Vec<(Method, Metrics, f64)> {
        methods
            .iter()
            .zip(&self.sets)
            .zip(&self.seconds)
            .map(|((m, a), s)| (*m, a.finish(how), 1e3 * s / self.frames.max(1) as f64))
            .collect()
    }
}

/// Where the figures of a `summary.json` came from and how they were scored.
#[derive(Clone, Debug)]
pub struct SummaryInfo<'a> {
    /// The model variant (`mcu`, `phone` or the folder's name).
    pub model: &'a str,
    /// The model folder, relative where possible; `None` for the model embedded in the binary.
    pub model_dir: Option<String>,
    /// The blob's SHA-256, hex.
    pub blob_sha256: String,
    /// How frames were combined.
    pub aggregate: Aggregate,
    /// Scored at the recording's resolution (`--native`) rather than the model's.
    pub native: bool,
    /// The size of the first frame scored at the recording's resolution, `(height, width)`.
    pub first_native_crop: Option<(u32, u32)>,
    /// The model's input size, `(height, width)`.
    pub model_size: (usize, usize),
    /// Reference depth beyond this is not counted, metres.
    pub max_depth_m: f32,
}

/// `summary.json`: the comparison over the union of the recordings, the provenance in `info`,
/// and one comparison per recording (`recordings`: its path as given and its totals).
pub fn summary_json(
    info: &SummaryInfo<'_>,
    methods: &[Method],
    union: &Totals,
    recordings: &[(&Path, &Totals)],
) -> Value {
    let how = info.aggregate;
    let mut summary = comparison_json(&union.results(methods, how));
    summary["depthor_version"] = json!(env!("CARGO_PKG_VERSION"));
    summary["git_commit"] = json!(git_commit());
    summary["model"] = json!(info.model);
    summary["model_dir"] = json!(info.model_dir);
    summary["model_embedded"] = json!(info.model_dir.is_none());
    summary["blob_sha256"] = json!(info.blob_sha256);
    summary["aggregate"] = json!(how.key());
    summary["aggregate_note"] = json!(how.describe());
    summary["scored_at"] = json!(if info.native { "native" } else { "model" });
    summary["frames"] = json!(union.frames);
    summary["height"] = json!(info.model_size.0);
    summary["width"] = json!(info.model_size.1);
    if info.native {
        summary["first_native_crop"] = json!(info
            .first_native_crop
            .map(|(h, w)| json!({"height": h, "width": w})));
    }
    summary["max_depth_m"] = json!(info.max_depth_m);
    summary["recordings"] = recordings
        .iter()
        .map(|(dir, t)| {
            let mut r = comparison_json(&t.results(methods, how));
            r["recording"] = json!(relative(dir));
            r["frames"] = json!(t.frames);
            r
        })
        .collect();
    summary
}

/// `p` relative to the current folder when it is inside it, else as given.
pub fn relative(p: &Path) -> String {
    let rel = std::env::current_dir()
        .ok()
        .and_then(|cwd| p.strip_prefix(&cwd).ok().map(Path::to_path_buf));
    rel.unwrap_or_else(|| p.to_path_buf()).display().to_string()
}

/// The source tree's commit (`git rev-parse HEAD`, `-dirty` with uncommitted changes to tracked
/// files) when the tree this binary was built from is still there; else `None`.
pub fn git_commit() -> Option<String> {
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
