//! Subcommands of `depthor`, one file each; each file's `handle(args)` calls library code.

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

mod import;
mod info;
mod project;
mod quantize;

/// Exit status for every failure (clap also uses 2 for usage errors).
pub const EXIT_FAILURE: u8 = 2;

/// Depth completion from a light-weight dToF sensor and an RGB camera (DEPTHOR).
#[derive(Debug, Parser)]
#[command(name = "depthor", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// One variant per subcommand; add new ones here and in [`run`].
#[derive(Debug, Subcommand)]
enum Command {
    /// Import a real RGB-D set (Middlebury, NYU, Redwood, TUM, SUN, raw NYU, ARKit) as a recording.
    Import(import::Args),
    /// Summarise a recording: frames, resolution, reference depth and zone validity.
    Info(info::Args),
    /// Draw a frame's dToF zones projected onto its RGB image.
    Project(project::Args),
    /// Quantise an exported float graph (graph.json) to the core's int8 blob.
    Quantize(quantize::Args),
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Import(args) => import::handle(args),
        Command::Info(args) => info::handle(args),
        Command::Project(args) => project::handle(args),
        Command::Quantize(args) => quantize::handle(args),
    }
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
