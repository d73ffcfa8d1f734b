//! `depthor eval-grid --model VARIANT --set DIR [--set DIR …] [--conditions manifest.json]`: the
//! evaluation grid, measurement conditions × sets (docs/eval.md "Evaluation grid"). Every frame
//! of every set gets zones simulated under every condition, then the int8 model, the float model
//! and every baseline run on them as in `depthor eval`. Writes `grid.csv` (one row per cell),
//! `methods.csv` (every method per cell), `frames.csv` (every method per frame and condition),
//! `summary.json`, `heatmap.png` (+ `heatmap.csv`) and `conditions/<name>.json` (each condition's
//! full simulator configuration, for `depthor sim --config`).

use anyhow::{bail, Result};
use depthor_host::evaluation::grid::{
    cell_table, frames_csv_header, frames_of, grid_csv, grid_json, heat_map, load_conditions,
    with_means, CellSummary, Condition, GridOptions, GridSet, BUILT_IN,
};
use depthor_host::evaluation::output::{csv_row, relative, summary_json, SummaryInfo, CSV_HEADER};
use depthor_host::evaluation::{Aggregate, Evaluator, Method, RecordingFrames};
use depthor_host::models::ModelFiles;
use depthor_host::sim::preset;
use std::path::{Path, PathBuf};

/// Arguments of `depthor eval-grid`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor import middlebury ../shared/data/real/middlebury2014-Q --out rec/middlebury
  depthor sim --preset mcu --scenes 16 --seed 900000 --out rec/heldout-mcu16
  depthor eval-grid --model mcu_lite --set rec/middlebury --set rec/heldout-mcu16 --out eval/grid-mcu_lite
  depthor eval-grid --model phone_lite --set rec/nyu --frames 2 --condition clean --condition misreg_1zone
  depthor eval-grid --model mcu --set rec/redwood --conditions my_grid/manifest.json --no-float
Default conditions: host/eval_grid/ (built in). Outputs and the manifest format: docs/eval.md.")]
pub struct Args {
    /// `mcu_lite`, `mcu`, `phone_lite`, `phone` or a model folder; its sensor preset is what the
    /// conditions change.
    #[arg(long, default_value = "mcu")]
    model: String,
    /// A set: a recording with RGB and reference depth (its own zones, if any, are not used).
    /// Repeat for several; each is a column of the grid.
    #[arg(
        long,
        short = 'r',
        value_name = "DIR",
        alias = "recording",
        required = true
    )]
    set: Vec<PathBuf>,
    /// Manifest of the conditions (default: the built-in host/eval_grid/manifest.json).
    #[arg(long, value_name = "FILE")]
    conditions: Option<PathBuf>,
    /// Only these conditions of the manifest (by name; repeat), in the manifest's order.
    #[arg(long, value_name = "NAME")]
    condition: Vec<String>,
    /// Evaluate only the first N frames of each set (0 = all).
    #[arg(long, default_value_t = 0)]
    frames: usize,
    /// Frame i of every set is simulated with seed SEED + i under every condition.
    #[arg(long, default_value_t = super::common::DEFAULT_SEED)]
    seed: u64,
    /// Output folder (default: eval/grid_<variant>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write into an existing non-empty --out (files of the same name are replaced).
    #[arg(long)]
    overwrite: bool,
    /// Skip the tract float model and the prior baseline (int8 and zone baselines only).
    #[arg(long)]
    no_float: bool,
    /// Pixels with reference depth beyond this are not counted, metres.
    #[arg(long, default_value_t = 10.0)]
    max_depth: f32,
    /// How frames are combined in a cell: `image` (per-frame mean) or `pixel` (pooled).
    #[arg(long, value_enum, default_value_t = Aggregate::Image)]
    aggregate: Aggregate,
    /// Print summary.json on stdout instead of the tables.
    #[arg(long)]
    json: bool,
}

/// A set's name for columns and file names (its directory name).
fn name_of(dir: &Path) -> String {
    dir.file_name()
        .map_or_else(|| "set".into(), |s| s.to_string_lossy().into_owned())
}

/// Runs the grid, writes its files and prints its tables.
pub fn handle(args: Args) -> Result<()> {
    let files = ModelFiles::resolve(&args.model)?;
    let base = preset(files.preset())?;
    let mut conditions = load_conditions(args.conditions.as_deref(), &base)?;
    if !args.condition.is_empty() {
        for name in &args.condition {
            if !conditions.iter().any(|c| &c.name == name) {
                bail!(
                    "--condition {name}: not in {} (conditions: {})",
                    args.conditions
                        .as_deref()
                        .map_or_else(|| format!("{BUILT_IN}/manifest.json"), relative),
                    conditions
                        .iter()
                        .map(|c| c.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
        conditions.retain(|c| args.condition.contains(&c.name));
    }
    let mut sets: Vec<GridSet> = Vec::new();
    for dir in &args.set {
        let frames = RecordingFrames::open(dir, files.preset())?;
        if frames.is_empty() {
            bail!("{}: the recording has no frames", dir.display());
        }
        if !frames.has_rgb() {
            bail!(
                "{}: recording.json: rgb: false (zone-only recording); the grid needs colour \
                 images and reference depth",
                dir.display()
            );
        }
        let name = name_of(dir);
        if sets.iter().any(|s| s.name == name) {
            bail!(
                "{}: --set: a set named {name:?} is given twice (sets are named by their folder)",
                dir.display()
            );
        }
        sets.push(GridSet {
            name,
            path: dir.clone(),
            frames,
        });
    }
    let mut eval = Evaluator::load(&files, !args.no_float, (0.1, args.max_depth))?;
    let (h, w) = eval.int8().input_shape();
    let out_dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("eval").join(format!("grid_{}", files.variant)));
    let staging = super::common::out_dir(&out_dir, args.overwrite)?;
    let out = staging.path().to_path_buf();

    let steps: usize = sets
        .iter()
        .map(|s| frames_of(args.frames, s.frames.len()))
        .sum::<usize>()
        * conditions.len();
    let bar = super::progress(steps as u64, "eval-grid");
    let opts = GridOptions {
        seed: args.seed,
        frames: args.frames,
        max_depth_m: args.max_depth,
    };
    let result =
        depthor_host::evaluation::grid::run_grid(&mut eval, &conditions, &sets, opts, &|| {
            bar.inc(1)
        })?;
    bar.finish_and_clear();
    for row in &result.cells {
        for (t, set) in row.iter().zip(&sets) {
            if t.frames == 0 {
                bail!(
                    "{}: no frame has reference depth within {} m",
                    set.path.display(),
                    args.max_depth
                );
            }
        }
    }

    let how = args.aggregate;
    write(
        &out.join("frames.csv"),
        &(std::iter::once(frames_csv_header())
            .chain(result.frame_rows.iter().cloned())
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"),
    )?;
    write(
        &out.join("grid.csv"),
        &grid_csv(&conditions, &sets, &result, how),
    )?;
    write(
        &out.join("methods.csv"),
        &methods_csv(&conditions, &sets, &result, how),
    )?;
    let conditions_dir = out.join("conditions");
    std::fs::create_dir_all(&conditions_dir)
        .map_err(|e| anyhow::anyhow!("{}: cannot create: {e}", conditions_dir.display()))?;
    for c in &conditions {
        write(
            &conditions_dir.join(format!("{}.json", c.name)),
            &(c.config.to_json() + "\n"),
        )?;
    }
    heat_map(
        &out.join("heatmap.png"),
        (&files.variant, Method::Int8),
        &conditions,
        &sets,
        &result,
        how,
    )?;
    let gated = result.methods.contains(&Method::Gate);
    if gated {
        heat_map(
            &out.join("heatmap_gate.png"),
            (&files.variant, Method::Gate),
            &conditions,
            &sets,
            &result,
            how,
        )?;
    }
    // The eval contract's provenance and union over every cell, then the grid.
    let mut union =
        depthor_host::evaluation::output::Totals::new(result.methods.len(), args.max_depth);
    for row in &result.cells {
        for t in row {
            union.merge(t);
        }
    }
    let info = SummaryInfo {
        model: &files.variant,
        model_dir: (!files.embedded).then(|| relative(&files.dir)),
        blob_sha256: eval.int8().blob_sha256(),
        aggregate: how,
        native: false,
        first_native_crop: None,
        model_size: (h, w),
        max_depth_m: args.max_depth,
    };
    let mut summary = summary_json(&info, &result.methods, &union, &[]);
    if let Some(m) = summary.as_object_mut() {
        m.remove("recordings");
    }
    summary["union_note"] = serde_json::json!(
        "methods, best_baseline, int8_vs_best_baseline and int8_vs_float here are over every \
         frame of every cell; the grid's figures are in cells and means"
    );
    summary["seed"] = serde_json::json!(args.seed);
    summary["frames_per_set"] = serde_json::json!(args.frames);
    summary["preset"] = serde_json::json!(files.preset());
    summary["conditions_manifest"] = serde_json::json!(args
        .conditions
        .as_deref()
        .map_or_else(|| format!("{BUILT_IN}/manifest.json"), relative));
    let grid = grid_json(&conditions, &sets, &result, how);
    for (k, v) in grid.as_object().into_iter().flatten() {
        summary[k] = v.clone();
    }
    write(
        &out.join("summary.json"),
        &(serde_json::to_string_pretty(&summary)? + "\n"),
    )?;
    let out = staging.commit()?;
    if args.json {
        return super::common::print_json(&summary);
    }
    println!(
        "depthor eval-grid: {} at {h}×{w} ({} preset), {} conditions × {} sets, seed {}, {}",
        files.variant,
        files.preset(),
        conditions.len(),
        sets.len(),
        args.seed,
        how.describe()
    );
    print_table(
        "int8 RMSE / best baseline RMSE",
        &conditions,
        &sets,
        &with_means(&cell_table(&result, how, CellSummary::rmse_ratio)),
    );
    print_table(
        "int8 Rel / Rel of that baseline",
        &conditions,
        &sets,
        &with_means(&cell_table(&result, how, CellSummary::abs_rel_ratio)),
    );
    if gated {
        print_table(
            "int8 + zone gate RMSE / best baseline RMSE",
            &conditions,
            &sets,
            &with_means(&cell_table(&result, how, CellSummary::gate_rmse_ratio)),
        );
        print_table(
            "int8 + zone gate Rel / Rel of that baseline",
            &conditions,
            &sets,
            &with_means(&cell_table(&result, how, CellSummary::gate_abs_rel_ratio)),
        );
    }
    if !args.no_float {
        print_table(
            "int8 vs float RMSE, (int8 − float) / float",
            &conditions,
            &sets,
            &with_means(&cell_table(&result, how, CellSummary::int8_vs_float)),
        );
    }
    println!("wrote {}", out.display());
    Ok(())
}

/// `methods.csv`: every method's metrics per cell, `depthor eval`'s columns with `condition` and
/// `set` in front and `ms` per frame.
fn methods_csv(
    conditions: &[Condition],
    sets: &[GridSet],
    result: &depthor_host::evaluation::grid::GridResult,
    how: Aggregate,
) -> String {
    let header = CSV_HEADER.replacen("recording,frame", "condition,set", 1);
    let mut out = vec![header];
    for (c, cond) in conditions.iter().enumerate() {
        for (s, set) in sets.iter().enumerate() {
            for (m, x, ms) in result.cells[c][s].results(&result.methods, how) {
                out.push(csv_row(&cond.name, &set.name, m, &x, ms / 1e3));
            }
        }
    }
    out.join("\n") + "\n"
}

/// A conditions × sets table with its grid means, one line per condition.
fn print_table(title: &str, conditions: &[Condition], sets: &[GridSet], t: &[Vec<f64>]) {
    println!("\n{title}");
    let width = conditions
        .iter()
        .map(|c| c.name.len())
        .max()
        .unwrap_or(0)
        .max(9);
    let cols: Vec<String> = sets
        .iter()
        .map(|s| s.name.clone())
        .chain(["mean".to_string()])
        .collect();
    let cw = cols.iter().map(String::len).max().unwrap_or(0).max(7);
    print!("{:<width$}", "");
    for c in &cols {
        print!(" {c:>cw$}");
    }
    println!();
    let names = conditions
        .iter()
        .map(|c| c.name.as_str())
        .chain(["grid mean"]);
    for (name, row) in names.zip(t) {
        print!("{name:<width$}");
        for v in row {
            print!(" {:>cw$}", format!("{v:.3}"));
        }
        println!();
    }
}

fn write(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", path.display()))
}
