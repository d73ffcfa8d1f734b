//! `depthor gap`: where does the simulator differ from a real recording, which physics is missing,
//! and does the fit improve held-out frames.

use std::path::PathBuf;
use std::sync::Mutex;

use anyhow::Context;

use depthor_host::gap::{analyze, load_recording, report, GapOptions};
use depthor_host::sim::{preset, SimConfig};

/// Arguments of `depthor gap`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor gap --recording rec/real-l5 --out gap/l5
  depthor gap --recording rec/real-l5 --sim-config my_sim.json --draws 64 --out gap/l5 --overwrite
Outputs and method: docs/gap.md.")]
pub struct Args {
    /// The real recording (needs reference depth and dToF zones; `--real` is the older spelling).
    #[arg(long = "recording", short = 'r', value_name = "DIR", alias = "real")]
    real: PathBuf,
    /// Simulator configuration JSON to compare with (default: the preset matching the
    /// recording's zone grid, `l5` for 8×8, `phone` for 40×30).
    #[arg(long)]
    sim_config: Option<PathBuf>,
    /// Output folder for report.md, report.json, sim_config.json and plots.
    #[arg(long)]
    out: PathBuf,
    /// Write into an existing non-empty --out (files of the same name are replaced).
    #[arg(long)]
    overwrite: bool,
    /// Print the findings and fit as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Monte-Carlo draws of the simulator per frame.
    #[arg(long, default_value_t = GapOptions::default().draws)]
    draws: usize,
    /// Seed of the draws.
    #[arg(long, default_value_t = super::common::DEFAULT_SEED)]
    seed: u64,
}

/// Runs `depthor gap`.
pub fn handle(args: Args) -> anyhow::Result<()> {
    // The recording's errors name the file and field already.
    let header = depthor_host::recording::Recording::open(&args.real)?;
    let bar = super::progress(header.len() as u64, "reading");
    let data = load_recording(&args.real, || bar.inc(1))?;
    bar.finish_and_clear();
    let base: SimConfig = match &args.sim_config {
        Some(p) => SimConfig::from_json(
            &std::fs::read_to_string(p).with_context(|| format!("{}: cannot read", p.display()))?,
        )
        .with_context(|| p.display().to_string())?,
        None => match data.grid {
            (8, 8) => preset("l5")?,
            (40, 30) => preset("phone")?,
            (r, c) => anyhow::bail!(
                "no preset has a {r}×{c} zone grid: pass --sim-config with the recording's grid"
            ),
        },
    };
    let bar = super::progress(data.frames.len() as u64, "simulating");
    let msg = Mutex::new(());
    let opts = GapOptions {
        draws: args.draws,
        seed: args.seed,
        ..GapOptions::default()
    };
    let a = analyze(&data, &base, &opts, &|m| {
        let _g = msg.lock();
        match m {
            None => bar.inc(1),
            Some(m) => bar.set_message(m.to_string()),
        }
    })?;
    bar.finish_and_clear();
    // The report goes into `<out>.partial-<pid>` and moves into place only when complete.
    let staging = super::common::out_dir(&args.out, args.overwrite)?;
    report::write(&a, staging.path())?;
    staging.commit()?;
    if args.json {
        let report = staging_report(&args.out)?;
        return super::common::print_json(&report);
    }
    if !a.power.conclusive {
        println!(
            "inconclusive: {} held-out frames cannot reach p ≤ {} (smallest achievable p {:.4}); \
             record at least {} frames",
            a.power.heldout_frames, a.power.level, a.power.min_achievable_p, a.power.frames_needed
        );
    }
    println!(
        "{} finding(s); held-out NLL/zone {:.4} → {:.4}; report in {}",
        a.selection.findings.len(),
        a.fit_before.heldout_nll_per_zone,
        a.fit_after.heldout_nll_per_zone,
        args.out.join("report.md").display()
    );
    for f in &a.selection.findings {
        println!(
            "  {:<18} gain {:.4} nats/zone  {:?}",
            f.effect, f.heldout_gain, f.params
        );
    }
    Ok(())
}

/// report.json as written (the same findings and fit, for `--json`).
fn staging_report(out: &std::path::Path) -> anyhow::Result<serde_json::Value> {
    let path = out.join("report.json");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))
}
