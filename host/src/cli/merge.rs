//! `depthor merge`: joins the shard recordings of one `depthor sim --shard K/N` run.
//!
//! ```text
//! depthor merge --out DIR SHARD_0 SHARD_1 … SHARD_N-1 [--overwrite]
//! ```

use anyhow::Result;
use depthor_host::recording::{merge_shards, Recording, WriteOptions};
use std::path::PathBuf;

/// Arguments of `depthor merge`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor sim --preset l5 --scenes 100 --shard 0/2 --out rec/l5-0     # and --shard 1/2 --out rec/l5-1
  depthor merge --out rec/l5 rec/l5-0 rec/l5-1                        # byte-identical to the unsharded run")]
pub struct Args {
    /// Shard recordings in shard order: the one written with `--shard 0/N` first, then 1/N, …
    #[arg(required = true, num_args = 1..)]
    shards: Vec<PathBuf>,
    /// Output recording directory.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing recording at --out.
    #[arg(long)]
    overwrite: bool,
}

/// Opens the shards and writes their union (frames round-robin) to `--out`.
pub fn handle(args: Args) -> Result<()> {
    let shards = args
        .shards
        .iter()
        .map(Recording::open)
        .collect::<Result<Vec<_>, _>>()?;
    let out = merge_shards(
        &shards,
        &args.out,
        WriteOptions {
            overwrite: args.overwrite,
        },
    )?;
    let frames: usize = shards.iter().map(Recording::len).sum();
    println!(
        "wrote {} ({frames} frames from {} shards)",
        out.display(),
        shards.len()
    );
    Ok(())
}
