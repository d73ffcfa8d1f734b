//! The evaluation grid (`depthor eval-grid`, docs/eval.md "Evaluation grid"): measurement
//! conditions × sets. A condition is a simulator configuration made of partial ones (the model's
//! sensor preset, a shared base, the condition's own file; [`SimConfig::with_overrides_value`]),
//! listed in a manifest; the default conditions are `host/eval_grid/`, compiled in. A set is a
//! recording with reference depth. Every frame of every set is simulated under every condition
//! with the same frame seed (each simulator aspect draws from its own stream, so two conditions
//! differ only in what their aspects do), then every method of [`super::Evaluator`] runs on it,
//! as `depthor eval` does.

use depthor_core::metrics::{Metrics, MetricsAccumulator};
use serde::Deserialize;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

use super::output::{comparison_json, csv_row, Totals, CSV_HEADER};
use super::{Aggregate, EvalError, Evaluator, Method, RecordingFrames};
use crate::sim::{SimConfig, SimError};

/// The default condition files (`host/eval_grid/`), compiled in: `(file name, text)`.
pub const DEFAULT_FILES: &[(&str, &str)] = &[
    (
        "manifest.json",
        include_str!("../../eval_grid/manifest.json"),
    ),
    ("clean.json", include_str!("../../eval_grid/clean.json")),
    (
        "noise_2pct.json",
        include_str!("../../eval_grid/noise_2pct.json"),
    ),
    (
        "noise_5pct.json",
        include_str!("../../eval_grid/noise_5pct.json"),
    ),
    (
        "outliers_3pct.json",
        include_str!("../../eval_grid/outliers_3pct.json"),
    ),
    (
        "outliers_10pct.json",
        include_str!("../../eval_grid/outliers_10pct.json"),
    ),
    (
        "blank_10pct.json",
        include_str!("../../eval_grid/blank_10pct.json"),
    ),
    (
        "blank_30pct.json",
        include_str!("../../eval_grid/blank_30pct.json"),
    ),
    (
        "misreg_0.5zone.json",
        include_str!("../../eval_grid/misreg_0.5zone.json"),
    ),
    (
        "misreg_1zone.json",
        include_str!("../../eval_grid/misreg_1zone.json"),
    ),
    (
        "bg_shift_1zone.json",
        include_str!("../../eval_grid/bg_shift_1zone.json"),
    ),
    (
        "bg_shift_2zone.json",
        include_str!("../../eval_grid/bg_shift_2zone.json"),
    ),
    (
        "est_mean.json",
        include_str!("../../eval_grid/est_mean.json"),
    ),
    (
        "est_median.json",
        include_str!("../../eval_grid/est_median.json"),
    ),
    (
        "est_nearest.json",
        include_str!("../../eval_grid/est_nearest.json"),
    ),
    (
        "dark_loss.json",
        include_str!("../../eval_grid/dark_loss.json"),
    ),
    (
        "far_loss.json",
        include_str!("../../eval_grid/far_loss.json"),
    ),
];

/// How the built-in files are named in messages and summaries.
pub const BUILT_IN: &str = "<built-in>/eval_grid";

/// Why the grid's conditions could not be read or a cell not evaluated.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    /// A manifest or condition file could not be read.
    #[error("{}: cannot read", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The manifest is not what [`load_conditions`] expects; `field` names the member.
    #[error("{}: {field}: {message}", path.display())]
    Manifest {
        /// The manifest.
        path: PathBuf,
        /// JSON path of the member (`conditions[2].name`), or `JSON`.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A condition file is refused by the simulator (unknown field, wrong type, out of range).
    #[error("{}: {source}", path.display())]
    Condition {
        /// The condition file.
        path: PathBuf,
        /// The simulator's error, naming the field.
        source: SimError,
    },
    /// Making frames or running a method.
    #[error(transparent)]
    Eval(#[from] EvalError),
}

/// `manifest.json` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestDoc {
    /// What the manifest is (free text).
    #[serde(default)]
    #[allow(dead_code)]
    note: String,
    /// File applied over the preset before every condition's own (unless `on_base` is false).
    #[serde(default)]
    base: Option<String>,
    /// The conditions, in the order of the grid's rows.
    conditions: Vec<EntryDoc>,
}

fn yes() -> bool {
    true
}

/// One condition of `manifest.json`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EntryDoc {
    /// Row name (letters, digits, `_`, `-`, `.`): also the name of its file in the outputs.
    name: String,
    /// One line for people.
    #[serde(default)]
    description: String,
    /// Its partial configuration (relative to the manifest's folder); none = the base alone.
    #[serde(default)]
    file: Option<String>,
    /// Whether the manifest's `base` applies first.
    #[serde(default = "yes")]
    on_base: bool,
}

/// One measurement condition: a name and the full simulator configuration it makes.
#[derive(Clone, Debug, PartialEq)]
pub struct Condition {
    /// Row name.
    pub name: String,
    /// One line for people.
    pub description: String,
    /// The partial files applied over the preset, in order (as the summary names them).
    pub files: Vec<String>,
    /// The effective configuration.
    pub config: SimConfig,
}

/// Reads the conditions of `manifest` (a `manifest.json`; `None`: the built-in
/// [`DEFAULT_FILES`]) over the sensor preset `preset`. Errors name the file and the field.
pub fn load_conditions(
    manifest: Option<&Path>,
    preset: &SimConfig,
) -> Result<Vec<Condition>, GridError> {
    let dir = manifest.map(|m| m.parent().unwrap_or(Path::new("")).to_path_buf());
    let shown = |name: &str| match &dir {
        Some(d) => d.join(name),
        None => Path::new(BUILT_IN).join(name),
    };
    let read = |name: &str| -> Result<String, GridError> {
        match &dir {
            Some(d) => std::fs::read_to_string(d.join(name)).map_err(|source| GridError::Read {
                path: d.join(name),
                source,
            }),
            None => DEFAULT_FILES
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, t)| t.to_string())
                .ok_or_else(|| GridError::Read {
                    path: shown(name),
                    source: std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        "no such built-in condition file",
                    ),
                }),
        }
    };
    let manifest_path = manifest.map_or_else(|| shown("manifest.json"), Path::to_path_buf);
    let manifest_name = manifest.and_then(|m| m.file_name()).map_or_else(
        || "manifest.json".into(),
        |n| n.to_string_lossy().into_owned(),
    );
    let bad = |field: String, message: String| GridError::Manifest {
        path: manifest_path.clone(),
        field,
        message,
    };
    let doc: ManifestDoc = serde_json::from_str(&read(&manifest_name)?)
        .map_err(|e| bad("JSON".into(), e.to_string()))?;
    if doc.conditions.is_empty() {
        return Err(bad("conditions".into(), "empty (give at least one)".into()));
    }
    // Each file parsed once; a condition's layers are applied in order.
    let parse = |name: &str| -> Result<Value, GridError> {
        serde_json::from_str(&read(name)?).map_err(|e| GridError::Condition {
            path: shown(name),
            source: SimError::Json {
                field: "JSON syntax".into(),
                message: e.to_string(),
            },
        })
    };
    let mut out: Vec<Condition> = Vec::new();
    for (k, c) in doc.conditions.iter().enumerate() {
        let ok_name = !c.name.is_empty()
            && c.name
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || "_-.".contains(ch));
        if !ok_name {
            return Err(bad(
                format!("conditions[{k}].name"),
                format!("{:?}: use letters, digits, `_`, `-` and `.`", c.name),
            ));
        }
        if out.iter().any(|o| o.name == c.name) {
            return Err(bad(
                format!("conditions[{k}].name"),
                format!("{:?} is given twice", c.name),
            ));
        }
        let layers: Vec<&String> = doc
            .base
            .iter()
            .filter(|_| c.on_base)
            .chain(c.file.iter())
            .collect();
        let mut config = preset.clone();
        for name in &layers {
            config = config
                .with_overrides_value(&parse(name)?)
                .map_err(|source| GridError::Condition {
                    path: shown(name),
                    source,
                })?;
        }
        out.push(Condition {
            name: c.name.clone(),
            description: c.description.clone(),
            files: layers
                .iter()
                .map(|n| shown(n).display().to_string())
                .collect(),
            config,
        });
    }
    Ok(out)
}

/// One set of the grid: a recording and the name its column gets.
pub struct GridSet {
    /// Column name (the recording folder's name).
    pub name: String,
    /// The recording folder, as given.
    pub path: PathBuf,
    /// Its frames.
    pub frames: RecordingFrames,
}

/// How the grid is run.
#[derive(Clone, Copy, Debug)]
pub struct GridOptions {
    /// Frame `i` of every set is simulated with seed `seed + i` under every condition.
    pub seed: u64,
    /// The first this many frames of each set (0 = all).
    pub frames: usize,
    /// Reference depth beyond this is not counted, metres.
    pub max_depth_m: f32,
}

/// The grid's figures: one [`Totals`] per condition and set, and `frames.csv`'s rows.
pub struct GridResult {
    /// The methods, in the evaluator's order.
    pub methods: Vec<Method>,
    /// `cells[condition][set]`.
    pub cells: Vec<Vec<Totals>>,
    /// Rows of `frames.csv` (no header): `condition,` then `depthor eval`'s row.
    pub frame_rows: Vec<String>,
}

/// The header of the grid's `frames.csv`: `condition,` then `depthor eval`'s header.
pub fn frames_csv_header() -> String {
    format!("condition,{CSV_HEADER}")
}

/// Runs every method on every frame of every set under every condition. `progress` is called
/// once per frame and condition.
pub fn run_grid(
    eval: &mut Evaluator,
    conditions: &[Condition],
    sets: &[GridSet],
    opts: GridOptions,
    progress: &dyn Fn(),
) -> Result<GridResult, GridError> {
    let methods = eval.methods();
    let (h, w) = eval.int8().input_shape();
    let mut cells: Vec<Vec<Totals>> = conditions
        .iter()
        .map(|_| {
            sets.iter()
                .map(|_| Totals::new(methods.len(), opts.max_depth_m))
                .collect()
        })
        .collect();
    let mut frame_rows = Vec::new();
    for (s, set) in sets.iter().enumerate() {
        for i in 0..frames_of(opts.frames, set.frames.len()) {
            let src = set.frames.source(i, w as u32, h as u32)?;
            let scorable = src
                .resampled
                .depth_m
                .iter()
                .any(|&d| d > 0.0 && d < opts.max_depth_m);
            for (c, cond) in conditions.iter().enumerate() {
                progress();
                if !scorable {
                    continue;
                }
                let frame = src.simulated(&cond.config, opts.seed.wrapping_add(i as u64))?;
                let totals = &mut cells[c][s];
                totals.frames += 1;
                for (k, p) in eval.predict(&frame)?.iter().enumerate() {
                    let mut acc = MetricsAccumulator::new(opts.max_depth_m);
                    acc.add_map(
                        &p.depth_m,
                        &frame.reference_m,
                        frame.width() as usize,
                        frame.height() as usize,
                    )
                    .map_err(EvalError::Metrics)?;
                    totals.sets[k].add_image(&acc);
                    totals.seconds[k] += p.seconds;
                    let row = csv_row(&set.name, &frame.id, p.method, &acc.finish(), p.seconds);
                    frame_rows.push(format!("{},{row}", cond.name));
                }
            }
        }
    }
    Ok(GridResult {
        methods,
        cells,
        frame_rows,
    })
}

/// The first `limit` of `len` frames (0 = all).
pub fn frames_of(limit: usize, len: usize) -> usize {
    match limit {
        0 => len,
        k => k.min(len),
    }
}

/// One cell's comparison: the int8 model, the float model, the best baseline by RMSE.
#[derive(Clone, Copy, Debug)]
pub struct CellSummary {
    /// Frames scored.
    pub frames: usize,
    /// The int8 model.
    pub int8: Metrics,
    /// The float model, when it ran.
    pub float: Option<Metrics>,
    /// The int8 model blended by the model's zone gate, when the model has one.
    pub gate: Option<Metrics>,
    /// The baseline with the lowest RMSE, and its metrics.
    pub best: (Method, Metrics),
}

impl CellSummary {
    /// The cell's figures combined `how`; `None` when no frame was scored.
    pub fn of(totals: &Totals, methods: &[Method], how: Aggregate) -> Option<Self> {
        if totals.frames == 0 {
            return None;
        }
        let results = totals.results(methods, how);
        let get = |m: Method| results.iter().find(|r| r.0 == m).map(|r| r.1);
        let best = results
            .iter()
            .filter(|r| r.0.is_baseline())
            .min_by(|a, b| a.1.rmse.total_cmp(&b.1.rmse))
            .map(|r| (r.0, r.1))?;
        Some(CellSummary {
            frames: totals.frames,
            int8: get(Method::Int8)?,
            float: get(Method::Float),
            gate: get(Method::Gate),
            best,
        })
    }

    /// int8 RMSE / best baseline RMSE.
    pub fn rmse_ratio(&self) -> f64 {
        self.int8.rmse / self.best.1.rmse
    }

    /// int8 + zone gate RMSE / best baseline RMSE; NaN without a gate.
    pub fn gate_rmse_ratio(&self) -> f64 {
        self.gate.map_or(f64::NAN, |g| g.rmse / self.best.1.rmse)
    }

    /// int8 + zone gate Rel / the best (by RMSE) baseline's Rel; NaN without a gate.
    pub fn gate_abs_rel_ratio(&self) -> f64 {
        self.gate
            .map_or(f64::NAN, |g| g.abs_rel / self.best.1.abs_rel)
    }

    /// int8 Rel / the best (by RMSE) baseline's Rel.
    pub fn abs_rel_ratio(&self) -> f64 {
        self.int8.abs_rel / self.best.1.abs_rel
    }

    /// (int8 − float) / float RMSE; NaN without the float model.
    pub fn int8_vs_float(&self) -> f64 {
        self.float
            .map_or(f64::NAN, |f| (self.int8.rmse - f.rmse) / f.rmse)
    }
}

/// The header of `grid.csv`.
pub const GRID_CSV_HEADER: &str = "condition,set,frames,int8_rmse,int8_abs_rel,int8_delta1,\
float_rmse,float_abs_rel,float_delta1,best_baseline,best_baseline_rmse,best_baseline_abs_rel,\
best_baseline_delta1,rmse_ratio,abs_rel_ratio,int8_vs_float_rmse";

/// `grid.csv`: one row per condition and set (in the grid's order), header included; a cell
/// without scored frames has empty figures.
pub fn grid_csv(
    conditions: &[Condition],
    sets: &[GridSet],
    result: &GridResult,
    how: Aggregate,
) -> String {
    let mut out = format!("{GRID_CSV_HEADER}\n");
    let f = |x: f64| {
        if x.is_finite() {
            format!("{x:.6}")
        } else {
            String::new()
        }
    };
    for (c, cond) in conditions.iter().enumerate() {
        for (s, set) in sets.iter().enumerate() {
            let t = &result.cells[c][s];
            let Some(x) = CellSummary::of(t, &result.methods, how) else {
                out += &format!("{},{},0{}\n", cond.name, set.name, ",".repeat(13));
                continue;
            };
            let fl = x.float;
            out += &format!(
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                cond.name,
                set.name,
                x.frames,
                f(x.int8.rmse),
                f(x.int8.abs_rel),
                f(x.int8.delta1),
                f(fl.map_or(f64::NAN, |m| m.rmse)),
                f(fl.map_or(f64::NAN, |m| m.abs_rel)),
                f(fl.map_or(f64::NAN, |m| m.delta1)),
                x.best.0.key(),
                f(x.best.1.rmse),
                f(x.best.1.abs_rel),
                f(x.best.1.delta1),
                f(x.rmse_ratio()),
                f(x.abs_rel_ratio()),
                f(x.int8_vs_float()),
            );
        }
    }
    out
}

/// A `conditions × sets` table of `value` per cell (NaN where nothing was scored), with the
/// mean over each row appended as a last column and the mean over each column (and over every
/// cell) as a last row: the grid means. Means skip NaN cells.
pub fn with_means(table: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mean = |v: &mut dyn Iterator<Item = f64>| {
        let x: Vec<f64> = v.filter(|x| x.is_finite()).collect();
        if x.is_empty() {
            f64::NAN
        } else {
            x.iter().sum::<f64>() / x.len() as f64
        }
    };
    let cols = table.first().map_or(0, Vec::len);
    let mut out: Vec<Vec<f64>> = table
        .iter()
        .map(|row| {
            let mut r = row.clone();
            r.push(mean(&mut row.iter().copied()));
            r
        })
        .collect();
    let mut last: Vec<f64> = (0..cols)
        .map(|c| mean(&mut table.iter().map(|r| r[c])))
        .collect();
    last.push(mean(&mut table.iter().flatten().copied()));
    out.push(last);
    out
}

/// `f` of every cell's [`CellSummary`] (NaN where nothing was scored), `conditions × sets`.
pub fn cell_table(
    result: &GridResult,
    how: Aggregate,
    f: impl Fn(&CellSummary) -> f64,
) -> Vec<Vec<f64>> {
    result
        .cells
        .iter()
        .map(|row| {
            row.iter()
                .map(|t| CellSummary::of(t, &result.methods, how).map_or(f64::NAN, |x| f(&x)))
                .collect()
        })
        .collect()
}

/// The grid part of `summary.json`: the conditions (with their effective configurations), the
/// sets, every cell's comparison (as `depthor eval`'s summary has it, plus `abs_rel_ratio`) and
/// the grid means of the RMSE and Rel ratios and of int8 vs float (and of the zone gate's
/// ratios when the model has one).
pub fn grid_json(
    conditions: &[Condition],
    sets: &[GridSet],
    result: &GridResult,
    how: Aggregate,
) -> Value {
    let mut cells = Vec::new();
    for (c, cond) in conditions.iter().enumerate() {
        for (s, set) in sets.iter().enumerate() {
            let t = &result.cells[c][s];
            let mut v = comparison_json(&t.results(&result.methods, how));
            v["condition"] = json!(cond.name);
            v["set"] = json!(set.name);
            v["frames"] = json!(t.frames);
            if let Some(x) = CellSummary::of(t, &result.methods, how) {
                v["int8_vs_best_baseline"]["abs_rel_ratio"] = json!(x.abs_rel_ratio());
                if x.gate.is_some() {
                    v["int8_gate_vs_best_baseline"] = json!({
                        "rmse_ratio": finite(x.gate_rmse_ratio()),
                        "abs_rel_ratio": finite(x.gate_abs_rel_ratio()),
                    });
                }
            }
            cells.push(v);
        }
    }
    let means = |f: &dyn Fn(&CellSummary) -> f64| {
        let t = with_means(&cell_table(result, how, f));
        let last = t.last().cloned().unwrap_or_default();
        json!({
            "by_condition": conditions.iter().zip(&t)
                .map(|(c, row)| (c.name.clone(), json!(finite(*row.last().unwrap_or(&f64::NAN)))))
                .collect::<serde_json::Map<_, _>>(),
            "by_set": sets.iter().zip(&last)
                .map(|(s, v)| (s.name.clone(), json!(finite(*v))))
                .collect::<serde_json::Map<_, _>>(),
            "grid": finite(*last.last().unwrap_or(&f64::NAN)),
        })
    };
    let mut mean_ratios = json!({
        "rmse_ratio": means(&|x| x.rmse_ratio()),
        "abs_rel_ratio": means(&|x| x.abs_rel_ratio()),
        "int8_vs_float_rmse": means(&|x| x.int8_vs_float()),
    });
    if result.methods.contains(&Method::Gate) {
        mean_ratios["gate_rmse_ratio"] = means(&|x| x.gate_rmse_ratio());
        mean_ratios["gate_abs_rel_ratio"] = means(&|x| x.gate_abs_rel_ratio());
    }
    json!({
        "conditions": conditions.iter().map(|c| json!({
            "name": c.name, "description": c.description, "files": c.files,
            "config": serde_json::to_value(&c.config).unwrap_or(Value::Null),
        })).collect::<Vec<_>>(),
        "sets": sets.iter().zip(0..).map(|(s, k)| json!({
            "name": s.name,
            "recording": super::output::relative(&s.path),
            "frames": result.cells.first().map_or(0, |row| row[k].frames),
        })).collect::<Vec<_>>(),
        "cells": cells,
        "means": mean_ratios,
    })
}

/// `x`, or `None` (JSON `null`) when not finite.
fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// The grid's heat map at `path` (and its numbers as `<path>.csv`): rows conditions, columns
/// sets, colour and number the RMSE of `method` (int8, or int8 + zone gate) over the best
/// baseline's, with the grid means.
pub fn heat_map(
    path: &Path,
    (model, method): (&str, Method),
    conditions: &[Condition],
    sets: &[GridSet],
    result: &GridResult,
    how: Aggregate,
) -> Result<(), GridError> {
    let ratio = if method == Method::Gate {
        CellSummary::gate_rmse_ratio
    } else {
        CellSummary::rmse_ratio
    };
    let table = with_means(&cell_table(result, how, ratio));
    let mut rows: Vec<String> = conditions.iter().map(|c| c.name.clone()).collect();
    rows.push("grid mean".into());
    let mut cols: Vec<String> = sets.iter().map(|s| s.name.clone()).collect();
    cols.push("mean".into());
    crate::plot::ratio_heat_map(
        path,
        &format!(
            "{model}: {} RMSE / best baseline RMSE per condition and set ({})",
            if method == Method::Gate {
                "int8 + zone gate"
            } else {
                "int8"
            },
            how.key()
        ),
        "RMSE ratio (< 1: model better)",
        &rows,
        &cols,
        &table,
        true,
    )
    .map_err(|e| GridError::Eval(EvalError::Plot(e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_conditions_load_and_differ_from_the_base_only_where_named() {
        let preset = crate::sim::preset("mcu").unwrap();
        let c = load_conditions(None, &preset).unwrap();
        let names: Vec<&str> = c.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names[..2], ["preset", "clean"]);
        assert_eq!(c[0].config, preset);
        let clean = &c[1].config;
        assert!(!clean.anomalies.enabled && !clean.calibration_shift.enabled);
        assert_eq!(clean.overall_distribution.max_translation, 0.0);
        // The sensor's own range limit stays: a sensor never reports beyond it.
        assert_eq!(clean.range, preset.range);
        let noise = c.iter().find(|c| c.name == "noise_5pct").unwrap();
        let mut back = noise.config.clone();
        back.range_noise = clean.range_noise.clone();
        assert_eq!(&back, clean);
        // Every built-in file is used, and the manifest names only built-in files.
        for (name, _) in DEFAULT_FILES.iter().skip(1) {
            assert!(
                c.iter().any(|x| x.files.iter().any(|f| f.ends_with(name))),
                "{name}"
            );
        }
    }

    #[test]
    fn a_bad_condition_file_is_named_with_its_field() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("m.json"),
            r#"{"conditions": [{"name": "x", "file": "x.json"}]}"#,
        )
        .unwrap();
        std::fs::write(
            dir.path().join("x.json"),
            r#"{"anomalies": {"noise_fractio": 0.1}}"#,
        )
        .unwrap();
        let e = load_conditions(
            Some(&dir.path().join("m.json")),
            &crate::sim::preset("mcu").unwrap(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("x.json: anomalies.noise_fractio: unknown field"),
            "{e}"
        );
    }

    #[test]
    fn means_skip_missing_cells() {
        let t = with_means(&[vec![1.0, 3.0], vec![f64::NAN, 2.0]]);
        assert_eq!(t[0], vec![1.0, 3.0, 2.0]);
        assert_eq!(t[1][2], 2.0);
        assert_eq!(t[2][0], 1.0);
        assert_eq!(t[2][1], 2.5);
        assert_eq!(t[2][2], 2.0);
    }
}
