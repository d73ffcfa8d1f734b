//! `depthor gap-bench`: the concealed-effect benchmark table of the gap tool.

use std::path::PathBuf;
use std::time::Instant;

use depthor_host::gap::bench::{
    case_seed, dark_far, real_cases, real_scenes, render_scenes, run_case, standard_cases, table,
    SceneSet,
};
use depthor_host::gap::shapes::{
    self, calibrated_shapes, run_shape_case, shape_cases, shape_table, shape_unit, shape_unit_in,
};
use depthor_host::gap::units::{calibrate, CalibrateOptions, UnitTable};
use depthor_host::gap::{effects, GapOptions};
use depthor_host::gap::{leave_one_out, power};
use depthor_host::sim::preset;

/// Arguments of `depthor gap-bench`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor gap-bench --frames 40 --sizes 1,2,4 --nulls 20 --seed 1000 --out bench   # bench/gap_bench.md
  depthor gap-bench --calibrate-units --frames 40 --trials 4 --out units            # units/gap_units.json
  depthor gap-bench --calibrate-units --shapes --trials 4 --out host/data/gap_shape_units.json
  depthor gap-bench --shapes --frames 40 --repeats 2 --nulls 30 --real-nulls 30 --seed 9300
Method and results: docs/gap.md.")]
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
    /// Null cases (no hidden effect) on rendered scenes.
    #[arg(long, default_value_t = 50)]
    nulls: usize,
    /// The real RGB-D sets (`data/real`, see its README); cases on them are skipped when the
    /// folder is missing.
    #[arg(long, default_value = "../shared/data/real")]
    real_data: PathBuf,
    /// Null cases on the real RGB-D frames.
    #[arg(long, default_value_t = 50)]
    real_nulls: usize,
    /// Leave out the cases on the real RGB-D frames.
    #[arg(long)]
    no_real: bool,
    /// Keep the real RGB-D frames at their native resolutions (per-frame cameras) instead of
    /// resampling them to `--width` × `--height`.
    #[arg(long)]
    native: bool,
    /// Only cases whose label contains this.
    #[arg(long)]
    only: Option<String>,
    /// Seed of the scenes and the "real" measurements (the docs/results/gap tables used 1000).
    #[arg(long, default_value_t = super::common::DEFAULT_SEED)]
    seed: u64,
    /// Monte-Carlo draws of the simulator per frame (the tool's `--draws`).
    #[arg(long, default_value_t = GapOptions::default().draws)]
    draws: usize,
    /// Print each case's selection log.
    #[arg(long)]
    verbose: bool,
    /// Also write the Markdown table into this folder as gap_bench.md (with
    /// `--calibrate-units`: the unit table as gap_units.json); an --out ending in .md / .json
    /// names the file itself.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Replace an existing output file (refused otherwise).
    #[arg(long)]
    overwrite: bool,
    /// Measure each effect's unit ("1×") size instead of running the benchmark: the smallest
    /// size at which the tool names it in ≥ half of `--trials` recordings of `--frames` rendered
    /// frames, scene seeds from `--calibrate-seed` (disjoint from the benchmark's).
    #[arg(long)]
    calibrate_units: bool,
    /// Trials per rung of the calibration ladder (each on its own scenes).
    #[arg(long, default_value_t = 4)]
    trials: usize,
    /// First scene seed of the calibration.
    #[arg(long, default_value_t = 500_000)]
    calibrate_seed: u64,
    /// Geometric ratio between calibration rungs.
    #[arg(long, default_value_t = std::f64::consts::SQRT_2)]
    step: f64,
    /// Log-bisection steps inside the calibration bracket.
    #[arg(long, default_value_t = 1)]
    refine: usize,
    /// Add to the committed unit table (`host/data/gap_units.json`) each unit's reference gain
    /// instead of running the benchmark: the expected held-out gain of the effect at 1× on the
    /// calibration's scenes (`--trials` sets of `--frames` rendered frames from
    /// `--calibrate-seed`), which `depthor gap` scales to a recording's detection limits
    /// (docs/gap.md "Detection limits"). Writes the table to `--out`.
    #[arg(long)]
    reference_gains: bool,
    /// Run the misspecified-shape benchmark instead (docs/gap.md "Shape bench"): every effect
    /// family injected with forward models other than the library's, by the benchmark's own
    /// code, at `--shape-size` × the shape's measured detection limit
    /// (`host/data/gap_shape_units.json`); `--nulls` / `--real-nulls` null cases. With
    /// `--calibrate-units`: measure those detection limits instead.
    #[arg(long)]
    shapes: bool,
    /// Size the shape benchmark by the library form's unit instead of each shape's own
    /// detection limit (the same mean effect as the library's case at that size).
    #[arg(long)]
    library_units: bool,
    /// Size the shape benchmark by the shape units of this table (written by `--calibrate-units
    /// --shapes`) instead of the committed `host/data/gap_shape_units.json`.
    #[arg(long)]
    shape_units: Option<PathBuf>,
    /// Size multiple of the shape benchmark.
    #[arg(long, default_value_t = 2.0)]
    shape_size: f64,
    /// Recordings per shape and scene set in the shape benchmark (each on its own seed), or per
    /// left-out effect.
    #[arg(long, default_value_t = 1)]
    repeats: usize,
    /// Run the leave-one-out benchmark instead (docs/gap.md): each of range_dropout,
    /// dark_dropout, border_dropout, range_bias, radial_distance and range_noise hidden at
    /// `--loo-size` × its unit on rendered scenes and removed from the tool's candidates.
    #[arg(long)]
    leave_one_out: bool,
    /// Size multiple of the leave-one-out benchmark.
    #[arg(long, default_value_t = 4.0)]
    loo_size: f64,
}

/// Runs `depthor gap-bench`.
pub fn handle(args: Args) -> anyhow::Result<()> {
    // Refused before the (long) run, not after it.
    if let Some(p) = &args.out {
        let name = if args.reference_gains {
            "gap_units.json"
        } else if args.calibrate_units && args.shapes {
            "gap_shape_units.json"
        } else if args.calibrate_units {
            "gap_units.json"
        } else {
            "gap_bench.md"
        };
        let f = super::common::OutFile::new(p, name);
        if f.path.exists() && !args.overwrite {
            anyhow::bail!(
                "{}: exists (pass --overwrite to replace it)",
                f.path.display()
            );
        }
    }
    if args.reference_gains {
        return reference_gains(&args);
    }
    if args.calibrate_units {
        return calibrate_units(&args);
    }
    if args.shapes {
        return shape_bench(&args);
    }
    if args.leave_one_out {
        return leave_one_out_bench(&args);
    }
    let t0 = Instant::now();
    let base = preset("mcu")?;
    let scenes = render_scenes(args.frames, args.width, args.height, args.seed);
    let mut cases = standard_cases(&args.sizes, args.nulls);
    let real = load_real(&args);
    if real.len() >= 8 {
        cases.extend(real_cases(&args.sizes, args.real_nulls));
    }
    let cases: Vec<_> = cases
        .into_iter()
        .filter(|c| {
            args.only
                .as_ref()
                .is_none_or(|o| c.label.contains(o.as_str()))
        })
        .collect();
    let dark = if cases.iter().any(|c| c.scenes == SceneSet::DarkFar) {
        dark_far(&scenes)
    } else {
        Vec::new()
    };
    let bar = super::progress(cases.len() as u64, "cases");
    let mut results = Vec::new();
    for c in &cases {
        bar.set_message(c.label.clone());
        let set = match c.scenes {
            SceneSet::Sim => &scenes,
            SceneSet::Real => &real,
            SceneSet::DarkFar => &dark,
        };
        let t = Instant::now();
        let (r, a) = run_case(
            set,
            &base,
            c,
            &GapOptions {
                draws: args.draws,
                ..GapOptions::default()
            },
            case_seed(args.seed, &c.label),
        )?;
        if args.verbose {
            bar.suspend(|| {
                eprintln!(
                    "{} ({:.1} s): named {:?}, fitted {:?}\n  {}",
                    c.label,
                    t.elapsed().as_secs_f64(),
                    r.named,
                    r.fitted,
                    a.selection.log.join("\n  ")
                )
            });
        }
        bar.inc(1);
        results.push(r);
    }
    bar.finish_and_clear();
    let mut t = table(&results);
    t.push_str(&format!(
        "\n{} cases; {} rendered frames of {}×{} and {} real-set frames ({}) per recording; wall time {:.0} s.\n",
        results.len(),
        scenes.len(),
        args.width,
        args.height,
        real.len(),
        real_sizes(&real),
        t0.elapsed().as_secs_f64()
    ));
    println!("{t}");
    if let Some(p) = args.out {
        super::common::OutFile::new(&p, "gap_bench.md").write(t.as_bytes(), args.overwrite)?;
    }
    Ok(())
}

/// `depthor gap-bench --calibrate-units`: measures every effect's unit size (only the effects
/// whose name contains `--only`) and writes the unit table.
fn calibrate_units(args: &Args) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let base = preset("mcu")?;
    let sets = calibration_sets(args)?;
    let k = sets.len() as u64;
    let keep = |n: &str| args.only.as_ref().is_none_or(|o| n.contains(o.as_str()));
    let names: Vec<String> = if args.shapes {
        calibrated_shapes()
            .map(|s| shapes::key(&s))
            .filter(|n| keep(n))
            .collect()
    } else {
        effects::ALL
            .iter()
            .map(|c| c.name.to_string())
            .filter(|n| keep(n))
            .collect()
    };
    let bar = super::progress(names.len() as u64, "effects");
    let opts = CalibrateOptions {
        threshold: 0.5,
        step: args.step,
        refine: args.refine,
        gap: GapOptions {
            draws: args.draws,
            ..GapOptions::default()
        },
        seed: args.seed,
    };
    let mut units = std::collections::BTreeMap::new();
    for name in names {
        bar.set_message(name.clone());
        let log = |m: &str| bar.suspend(|| eprintln!("{m}"));
        if let Some(sh) = calibrated_shapes().find(|s| args.shapes && shapes::key(s) == name) {
            units.extend(shapes::calibrate(&base, &sets, &[sh], &opts, log)?);
        } else if let Some(c) = effects::ALL.iter().find(|c| c.name == name) {
            units.extend(calibrate(&base, &sets, &[c.name], &opts, log)?);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let mut table = UnitTable {
        command: command_line(),
        frames: args.frames,
        trials: k as usize,
        seed: args.calibrate_seed,
        width: args.width,
        height: args.height,
        draws: args.draws,
        threshold: opts.threshold,
        step: opts.step,
        refine: opts.refine,
        wall_s: t0.elapsed().as_secs_f64(),
        units,
        reference_command: String::new(),
    };
    if !args.shapes {
        // The detection limits of `depthor gap` scale each unit by its reference gain.
        let command = table.command.clone();
        power::add_reference_gains(&mut table, &base, &sets, &opts.gap, &command)?;
    }
    let json = serde_json::to_string_pretty(&table)?;
    println!("{json}");
    if let Some(p) = &args.out {
        let name = if args.shapes {
            "gap_shape_units.json"
        } else {
            "gap_units.json"
        };
        super::common::OutFile::new(p, name).write((json + "\n").as_bytes(), args.overwrite)?;
    }
    Ok(())
}

/// The command line as run, `depthor …`.
fn command_line() -> String {
    std::iter::once("depthor".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The calibration's scene sets: `--trials` sets of `--frames` rendered frames from
/// `--calibrate-seed`, refused when they overlap the benchmark's seeds.
fn calibration_sets(args: &Args) -> anyhow::Result<Vec<Vec<depthor_host::scene::SceneFrame>>> {
    let (n, k) = (args.frames as u64, args.trials.max(1) as u64);
    let (bench0, bench1) = (args.seed, args.seed + n);
    let (cal0, cal1) = (args.calibrate_seed, args.calibrate_seed + k * n);
    anyhow::ensure!(
        cal1 <= bench0 || cal0 >= bench1,
        "calibration scene seeds {cal0}..{cal1} overlap the benchmark's {bench0}..{bench1}"
    );
    Ok((0..k)
        .map(|t| render_scenes(args.frames, args.width, args.height, cal0 + t * n))
        .collect())
}

/// `depthor gap-bench --reference-gains`: the committed unit table with each unit's reference
/// gain ([`power::add_reference_gains`]) on the calibration's scenes.
fn reference_gains(args: &Args) -> anyhow::Result<()> {
    let base = preset("mcu")?;
    let sets = calibration_sets(args)?;
    let mut table = depthor_host::gap::units::calibrated().clone();
    anyhow::ensure!(
        !table.units.is_empty(),
        "the committed unit table host/data/gap_units.json is empty"
    );
    let opts = GapOptions {
        draws: args.draws,
        ..GapOptions::default()
    };
    power::add_reference_gains(&mut table, &base, &sets, &opts, &command_line())?;
    let json = serde_json::to_string_pretty(&table)?;
    println!("{json}");
    if let Some(p) = &args.out {
        super::common::OutFile::new(p, "gap_units.json")
            .write((json + "\n").as_bytes(), args.overwrite)?;
    }
    Ok(())
}

/// The image sizes of `frames` in words (`160×120`, or `native, 346×243 to 1920×1440`).
fn real_sizes(frames: &[depthor_host::scene::SceneFrame]) -> String {
    let px = |f: &&depthor_host::scene::SceneFrame| u64::from(f.width) * u64::from(f.height);
    match (frames.iter().min_by_key(px), frames.iter().max_by_key(px)) {
        (Some(a), Some(b)) if (a.width, a.height) == (b.width, b.height) => {
            format!("{}×{}", a.width, a.height)
        }
        (Some(a), Some(b)) => format!(
            "native, {}×{} to {}×{}",
            a.width, a.height, b.width, b.height
        ),
        _ => "none".into(),
    }
}

/// The real-set frames of `args` (empty with `--no-real` or without the folder, with a note).
fn load_real(args: &Args) -> Vec<depthor_host::scene::SceneFrame> {
    if args.no_real {
        Vec::new()
    } else if args.real_data.is_dir() {
        let size = (!args.native).then_some((args.width, args.height));
        let (r, notes) = real_scenes(&args.real_data, size);
        for n in notes {
            eprintln!("note: {n}");
        }
        r
    } else {
        eprintln!(
            "note: {} not found: no cases on real RGB-D frames (pass --real-data)",
            args.real_data.display()
        );
        Vec::new()
    }
}

/// `depthor gap-bench --shapes`: the misspecified-shape benchmark on rendered and real-set
/// recordings.
fn shape_bench(args: &Args) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let base = preset("mcu")?;
    let scenes = render_scenes(args.frames, args.width, args.height, args.seed);
    let real = load_real(args);
    let table: Option<UnitTable> = match &args.shape_units {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .map_err(|e| anyhow::anyhow!("--shape-units {}: {e}", p.display()))?;
            Some(
                serde_json::from_str(&text)
                    .map_err(|e| anyhow::anyhow!("--shape-units {}: {e}", p.display()))?,
            )
        }
        None => None,
    };
    let unit = |s: &shapes::Shape| {
        if args.library_units {
            1.0
        } else {
            table
                .as_ref()
                .map_or_else(|| shape_unit(s), |t| shape_unit_in(t, s))
        }
    };
    let mut cases = shape_cases(&["sim"], args.shape_size, args.repeats, args.nulls, unit);
    if real.len() >= 8 {
        cases.extend(shape_cases(
            &["real"],
            args.shape_size,
            args.repeats,
            args.real_nulls,
            unit,
        ));
    }
    cases.retain(|c| {
        args.only
            .as_ref()
            .is_none_or(|o| c.label.contains(o.as_str()))
    });
    let bar = super::progress(cases.len() as u64, "cases");
    let opts = GapOptions {
        draws: args.draws,
        ..GapOptions::default()
    };
    let mut results = Vec::new();
    for c in &cases {
        bar.set_message(c.label.clone());
        let set = if c.scenes == "real" { &real } else { &scenes };
        let (r, a) = run_shape_case(set, &base, c, &opts, case_seed(args.seed, &c.label))?;
        if args.verbose {
            bar.suspend(|| {
                eprintln!(
                    "{}: a {:.4}, named {:?}\n  {}\n  {}",
                    c.label,
                    r.amplitude,
                    r.named,
                    a.selection.log.join("\n  "),
                    a.limits
                        .iter()
                        .map(|l| l.statement.as_str())
                        .collect::<Vec<_>>()
                        .join("\n  ")
                )
            });
        }
        bar.inc(1);
        results.push(r);
    }
    bar.finish_and_clear();
    let mut t = shape_table(&results);
    t.push_str(&format!(
        "\n{} cases at {}× the {}; {} rendered frames of {}×{} and {} real-set frames ({}) per recording; seed {}; wall time {:.0} s.\n",
        results.len(),
        args.shape_size,
        if args.library_units {
            "library form's unit".to_string()
        } else {
            format!(
                "shape's measured detection limit ({})",
                args.shape_units.as_ref().map_or_else(
                    || "host/data/gap_shape_units.json".to_string(),
                    |p| p.display().to_string()
                )
            )
        },
        scenes.len(),
        args.width,
        args.height,
        real.len(),
        real_sizes(&real),
        args.seed,
        t0.elapsed().as_secs_f64()
    ));
    println!("{t}");
    if let Some(p) = &args.out {
        super::common::OutFile::new(p, "gap_bench.md").write(t.as_bytes(), args.overwrite)?;
    }
    Ok(())
}

/// `depthor gap-bench --leave-one-out`: physics outside the library, each effect in turn.
fn leave_one_out_bench(args: &Args) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let base = preset("mcu")?;
    let scenes = render_scenes(args.frames, args.width, args.height, args.seed);
    let opts = GapOptions {
        draws: args.draws,
        ..GapOptions::default()
    };
    let verbose = args.verbose;
    let mut log = |label: &str, lines: &[String]| {
        if verbose {
            eprintln!("{label}\n  {}", lines.join("\n  "));
        }
    };
    let sizes = (args.loo_size, args.repeats, args.seed);
    let results = leave_one_out::run(&scenes, &base, &opts, sizes, &mut log)?;
    let mut t = leave_one_out::table(&results);
    t.push_str(&format!(
        "\n{} cases at {}× the unit; {} rendered frames of {}×{} per recording; seed {}; wall time {:.0} s.\n",
        results.len(),
        args.loo_size,
        scenes.len(),
        args.width,
        args.height,
        args.seed,
        t0.elapsed().as_secs_f64()
    ));
    println!("{t}");
    if let Some(p) = &args.out {
        super::common::OutFile::new(p, "gap_bench.md").write(t.as_bytes(), args.overwrite)?;
    }
    Ok(())
}
