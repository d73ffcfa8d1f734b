//! Subcommands of `depthor`, one file each; each file's `handle(args)` calls library code.

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

mod bench;
pub mod common;
mod demo;
mod eval;
mod eval_grid;
mod firmware;
mod gap;
mod gap_bench;
mod import;
mod info;
mod merge;
mod project;
mod quantize;
mod sim;

/// Exit status for every failure (clap also uses 2 for usage errors).
pub const EXIT_FAILURE: u8 = 2;

/// Depth completion from a light-weight dToF sensor and an RGB camera (DEPTHOR).
#[derive(Debug, Parser)]
#[command(
    name = "depthor",
    version,
    about,
    after_help = "Examples:\n  depthor demo                                   # the main job, embedded mcu model\n  depthor info --recording rec/l5\n  depthor eval --model mcu --recording rec/mcu-test --out eval/mcu\n  depthor eval-grid --model mcu_lite --set rec/middlebury --set rec/mcu-test --out eval/grid\n\nEvery command: `depthor <command> --help` shows its options and examples."
)]
pub struct Cli {
    /// Folder holding the model variants (`mcu/`, `phone/`), looked in first (default: beside
    /// the binary, then ./models; the `mcu` int8 blob is embedded in the binary).
    #[arg(long, global = true, env = "DEPTHOR_MODELS", value_name = "DIR")]
    models_dir: Option<std::path::PathBuf>,
    #[command(subcommand)]
    command: Command,
}

/// One variant per subcommand; add new ones here and in [`run`].
#[derive(Debug, Subcommand)]
enum Command {
    /// Print throughput figures (scene + simulator, …).
    Bench(bench::Args),
    /// The main job: scene (or --recording) → dToF → int8 model in the core, vs baselines.
    Demo(demo::Args),
    /// Evaluate a model (int8 core, float tract) and the baselines on a recording.
    Eval(eval::Args),
    /// Evaluation grid: measurement conditions (partial simulator configs) × sets, every method.
    EvalGrid(eval_grid::Args),
    /// Write a firmware-sim replay flash image (RGB 120×160 + zones) from a recording.
    FirmwareImage(firmware::ImageArgs),
    /// Host build of the firmware-sim loop: per-frame depth hashes, as the QEMU firmware prints.
    FirmwareReplay(firmware::ReplayArgs),
    /// Compare a real recording with the simulator: locate the mismatch, name and fit the missing physics.
    Gap(gap::Args),
    /// Concealed-effect benchmark of the gap tool (hidden effects in simulated "real" recordings).
    GapBench(gap_bench::Args),
    /// Import a real RGB-D set (Middlebury, NYU, Redwood, TUM, SUN, raw NYU, ARKit) as a recording.
    Import(import::Args),
    /// Summarise a recording: frames, resolution, reference depth and zone validity.
    Info(info::Args),
    /// Join the shard recordings of a `depthor sim --shard K/N` run into one recording.
    Merge(merge::Args),
    /// Simulate dToF: synthetic scenes (--scenes) or an existing recording (--from).
    Sim(sim::Args),
    /// Draw a frame's dToF zones projected onto its RGB image.
    Project(project::Args),
    /// Quantise an exported float graph (graph.json) to the core's int8 blob.
    Quantize(quantize::Args),
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    if let Some(dir) = cli.models_dir {
        depthor_host::models::set_models_dir(dir);
    }
    match cli.command {
        Command::Bench(args) => bench::handle(args),
        Command::Demo(args) => demo::handle(args),
        Command::Eval(args) => eval::handle(args),
        Command::EvalGrid(args) => eval_grid::handle(args),
        Command::FirmwareImage(args) => firmware::handle_image(args),
        Command::FirmwareReplay(args) => firmware::handle_replay(args),
        Command::Gap(args) => gap::handle(args),
        Command::GapBench(args) => gap_bench::handle(args),
        Command::Import(args) => import::handle(args),
        Command::Info(args) => info::handle(args),
        Command::Merge(args) => merge::handle(args),
        Command::Project(args) => project::handle(args),
        Command::Sim(args) => sim::handle(args),
        Command::Quantize(args) => quantize::handle(args),
    }
}

/// The error chain on one line, `outer: inner: …`, each link said once: a link whose text the
/// previous link already contains (a `thiserror` `"…: {0}"` wrapper with a `#[from]` source)
/// is dropped, and line breaks are folded.
pub fn one_line(e: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    for link in e.chain() {
        let text = link
            .to_string()
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        if text.is_empty() || parts.last().is_some_and(|p| p.contains(&text)) {
            continue;
        }
        parts.push(text);
    }
    parts.join(": ")
}

/// A progress bar on stderr for `len` steps (drawn only on a terminal, so piped output and
/// error messages stay clean).
pub fn progress(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) =
        ProgressStyle::with_template("{msg} {wide_bar} {pos}/{len} [{elapsed}<{eta}]")
    {
        bar.set_style(style);
    }
    bar.set_message(what.to_string());
    bar
}

/// The scene configuration a preset's scenes are drawn from (`dataset::scene_config_for`), with
/// the ranges named in the JSON file `overrides` replaced; errors name the file (and the field).
pub fn scene_config(
    preset: &str,
    overrides: Option<&std::path::Path>,
) -> anyhow::Result<depthor_host::scene::SceneConfig> {
    use anyhow::Context;
    let cfg = depthor_host::dataset::scene_config_for(preset);
    let Some(path) = overrides else {
        return Ok(cfg);
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    cfg.with_overrides(&text)
        .with_context(|| format!("{}", path.display()))
}
