//! `depthor gap-bench`: the concealed-effect benchmark table of the gap tool.

use std::path::PathBuf;

use depthor_host::gap::bench::{render_scenes, run_case, standard_cases, table};
use depthor_host::gap::GapOptions;
use depthor_host::sim::preset;

/// Arguments of `depthor gap-bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Frames per "real" recording.
    #[arg(long, default_value_t = 40)]
    frames: usize,
    /// Image width (the `mcu` preset's 160 by default).
    #[arg(long, default_value_t = 160)]
    width: u32,
    /// Image height.
    #[arg(long, default_value_t = 120)]
    height: u32,
    /// Size multiples of each effect's unit size.
    #[arg(long, value_delimiter = ',', default_values_t = vec![1.0, 2.0, 4.0])]
    sizes: Vec<f64>,
    /// Null cases (no hidden effect).
    #[arg(long, default_value_t = 5)]
    nulls: usize,
    /// Only cases whose label contains this.
    #[arg(long)]
    only: Option<String>,
    /// Seed of the scenes and the "real" measurements.
    #[arg(long, default_value_t = 1000)]
    seed: u64,
    /// Print each case's selection log.
    #[arg(long)]
    verbose: bool,
    /// Write the Markdown table here too.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `depthor gap-bench`.
pub fn handle(args: Args) -> anyhow::Result<()> {
    let base = preset("mcu")?;
    let scenes = render_scenes(args.frames, args.width, args.height, args.seed);
    let cases: Vec<_> = standard_cases(&args.sizes, args.nulls)
        .into_iter()
        .filter(|c| {
            args.only
                .as_ref()
                .is_none_or(|o| c.label.contains(o.as_str()))
        })
        .collect();
    let bar = super::progress(cases.len() as u64, "cases");
    let mut results = Vec::new();
    for (i, c) in cases.iter().enumerate() {
        bar.set_message(c.label.clone());
        let (r, a) = run_case(
            &scenes,
            &base,
            c,
            &GapOptions::default(),
            args.seed + 7919 * i as u64,
        )?;
        if args.verbose {
            eprintln!("{}:\n  {}", c.label, a.selection.log.join("\n  "));
        }
        bar.inc(1);
        results.push(r);
    }
    bar.finish_and_clear();
    let t = table(&results);
    println!("{t}");
    if let Some(p) = args.out {
        std::fs::write(p, &t)?;
    }
    Ok(())
}
