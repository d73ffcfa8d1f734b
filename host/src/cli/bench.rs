//! `depthor bench <what>`: throughput figures printed for the README (never asserted in tests).
//!
//! - `depthor bench sim [--frames N] [--preset P]`: frames per second of scene rendering plus
//!   dToF simulation at 240×320 and 480×640 (H×W), on all cores (rayon), and the split between
//!   the renderer and the simulator on one core.
//! - `depthor bench engine [--model M] [--height H --width W] [--runs N] [--per-op]
//!   [--kernels best|all|SET] [--runtime both|core|tract]`: one thread, median time per frame
//!   of the core's int8 engine (prepared once, as on a device) and of tract's f32 run of the
//!   exported NNEF on the same model, size and simulated input; their ratio, MACs per frame,
//!   int8 weight bytes, blob bytes, arena bytes, and the depth SQNR of int8 against float on
//!   that input; with `--per-op`, ms, MACs and GMAC/s per op and per op kind, and the convs'
//!   share of the assumed int8 peak. Without `--model` it measures every shipped variant at its
//!   native size. `--runtime core` or `--runtime tract` runs one runtime alone (no ratio, no
//!   SQNR), so that instruction counters see only that runtime: each runs its frame
//!   `1 + --runs` times (one warm-up), so the difference between two `--runs` values is exact
//!   whole frames.

use anyhow::{Context, Result};
use depthor_core::blob::format::op_name;
use depthor_core::engine::Engine;
use depthor_core::kernels::isa::Isa;
use depthor_host::dataset::{frame_seed, scene_config_for};
use depthor_host::inference::Int8Model;
use depthor_host::models::{ModelFiles, VARIANTS};
use depthor_host::quantize::calibrate::simulated_frames;
use depthor_host::quantize::check::sqnr_db;
use depthor_host::reference::FloatReference;
use depthor_host::scene::{camera_for, render_scene};
use depthor_host::sim::{preset, simulate};
use rayon::prelude::*;
use std::time::Instant;

/// Arguments of `depthor bench`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:
  depthor bench sim --frames 64                      # scene + simulator throughput
  depthor bench engine --model mcu --per-op          # core int8 vs tract f32, per op
  depthor bench engine --kernels all                 # every kernel set this CPU runs
  depthor bench engine --model mcu_lite --runtime tract --runs 1   # tract alone")]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

/// What to measure.
#[derive(Debug, clap::Subcommand)]
enum What {
    /// Scene generator + dToF simulator throughput.
    Sim {
        /// Frames per resolution.
        #[arg(long, default_value_t = 64)]
        frames: u64,
        /// Simulator preset.
        #[arg(long, default_value = "l5")]
        preset: String,
    },
    /// Core int8 engine vs tract f32 on the same model, one thread.
    Engine {
        /// `mcu`, `phone` or a model directory (default: every shipped variant).
        #[arg(long)]
        model: Option<String>,
        /// Input rows (default: the model's native size).
        #[arg(long, requires = "width")]
        height: Option<usize>,
        /// Input columns.
        #[arg(long, requires = "height")]
        width: Option<usize>,
        /// Timed runs per runtime (after one warm-up run); the median is printed.
        #[arg(long, default_value_t = 10)]
        runs: usize,
        /// Also print time, MACs and GMAC/s per op (median over the runs).
        #[arg(long)]
        per_op: bool,
        /// Kernel set of the core: `best` (default), `all` (every set this CPU runs, side by
        /// side), or one of `portable`, `avx2`, `avx512-vnni` (x86-64), `neon`, `neon-dot`
        /// (aarch64).
        #[arg(long, default_value = "best")]
        kernels: String,
        /// Which runtime runs: both (default, side by side, with their ratio and the int8
        /// depth's SQNR against f32), or the core or tract alone.
        #[arg(long, value_enum, default_value_t = Runtime::Both)]
        runtime: Runtime,
    },
}

/// The runtimes `depthor bench engine --runtime` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Runtime {
    /// The core's int8 engine and tract's f32 run, side by side.
    Both,
    /// The core's int8 engine alone.
    Core,
    /// tract's f32 run alone.
    Tract,
}

impl Runtime {
    fn core(self) -> bool {
        self != Runtime::Tract
    }
    fn tract(self) -> bool {
        self != Runtime::Core
    }
}

/// Runs the chosen benchmark and prints its figures.
pub fn handle(args: Args) -> Result<()> {
    match args.what {
        What::Sim { frames, preset } => bench_sim(frames, &preset),
        What::Engine {
            model,
            height,
            width,
            runs,
            per_op,
            kernels,
            runtime,
        } => {
            let size = height.zip(width);
            let sets = kernel_sets(&kernels)?;
            anyhow::ensure!(
                runtime.core() || !per_op,
                "--per-op profiles the core's ops: not with --runtime tract"
            );
            let opts = EngineBench {
                size,
                runs,
                per_op,
                sets: &sets,
                runtime,
            };
            match model {
                Some(m) => bench_engine(&ModelFiles::resolve(&m)?, &opts),
                None => VARIANTS.iter().try_for_each(|v| {
                    bench_engine(&ModelFiles::resolve(v)?, &opts)?;
                    println!();
                    Ok(())
                }),
            }
        }
    }
}

/// User + system CPU seconds of this process so far (Linux `/proc/self/stat`), if readable.
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0) // USER_HZ is 100 on Linux
}

fn bench_sim(frames: u64, preset_name: &str) -> Result<()> {
    let cfg = preset(preset_name)?;
    let scene_cfg = scene_config_for(preset_name);
    println!(
        "scene + sim ({preset_name}), {frames} frames per size, {} threads",
        rayon::current_num_threads()
    );
    for (h, w) in [(240u32, 320u32), (480, 640)] {
        let one = |i: u64| -> Result<(f64, f64)> {
            let s = frame_seed(7, i);
            let t0 = Instant::now();
            let scene = render_scene(&scene_cfg, s, camera_for(&scene_cfg, s, w, h));
            let t1 = Instant::now();
            simulate(&cfg, &scene.sim_input(), s)?;
            let t2 = Instant::now();
            Ok(((t1 - t0).as_secs_f64(), (t2 - t1).as_secs_f64()))
        };
        let cpu0 = process_cpu_seconds();
        let start = Instant::now();
        let parts = (0..frames)
            .into_par_iter()
            .map(one)
            .collect::<Result<Vec<_>>>()?;
        let wall = start.elapsed().as_secs_f64();
        let cpu = process_cpu_seconds().zip(cpu0).map(|(b, a)| b - a);
        let n = frames as f64;
        let render_ms = 1e3 * parts.iter().map(|p| p.0).sum::<f64>() / n;
        let sim_ms = 1e3 * parts.iter().map(|p| p.1).sum::<f64>() / n;
        println!(
            "  {h}×{w}: {:.1} frames/s wall  (per frame, wall on one thread: render {render_ms:.1} ms, sim {sim_ms:.2} ms)",
            n / wall
        );
        if let Some(cpu) = cpu {
            // On a shared machine wall time includes other processes' share of the cores; CPU
            // time does not: threads / (CPU s per frame) is the rate with the cores to ourselves.
            let per_frame = cpu / n;
            println!(
                "  {h}×{w}: {:.1} ms CPU per frame → {:.1} frames/s on {} free cores",
                1e3 * per_frame,
                rayon::current_num_threads() as f64 / per_frame,
                rayon::current_num_threads()
            );
        }
    }
    Ok(())
}

/// Median of `runs` timings of `f` (after one untimed warm-up call), in milliseconds.
fn median_ms(runs: usize, mut f: impl FnMut() -> Result<()>) -> Result<f64> {
    f()?;
    let mut t = Vec::with_capacity(runs.max(1));
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        f()?;
        t.push(start.elapsed().as_secs_f64() * 1e3);
    }
    t.sort_by(f64::total_cmp);
    Ok(t[t.len() / 2])
}

/// The kernel sets `--kernels` names.
fn kernel_sets(name: &str) -> Result<Vec<Isa>> {
    Ok(match name {
        "best" => vec![Isa::best()],
        "all" => Isa::ALL.into_iter().filter(|i| i.available()).collect(),
        n => {
            let isa = Isa::from_name(n).with_context(|| {
                format!("--kernels: unknown kernel set {n:?} (allowed: best, all, portable, arm-dsp, avx2, avx512-vnni, neon, neon-dot)")
            })?;
            anyhow::ensure!(isa.available(), "--kernels: {n} does not run on this CPU");
            vec![isa]
        }
    })
}

/// Options of `depthor bench engine`.
struct EngineBench<'a> {
    size: Option<(usize, usize)>,
    runs: usize,
    per_op: bool,
    sets: &'a [Isa],
    runtime: Runtime,
}

/// One timed op of the per-op profile.
struct OpTime {
    name: &'static str,
    shape: String,
    macs: u64,
    ms: Vec<f64>,
}

/// The int8 multiply-accumulate peak of one core this bench assumes, with its derivation.
fn int8_peak(isa: Isa) -> (f64, String) {
    let read = std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|t| {
        t.lines()
            .find(|l| l.starts_with("cpu MHz"))
            .and_then(|l| l.split(':').nth(1))
            .and_then(|v| v.trim().parse::<f64>().ok())
    });
    let (mhz, source) = match read {
        Some(m) => (m, "/proc/cpuinfo"),
        None => (2500.0, "clock not readable: 2500 MHz assumed"),
    };
    let (per_cycle, how) = match isa {
        Isa::Avx512Vnni => (64.0, "one 512-bit vpdpbusd (64 int8 MACs) per cycle"),
        Isa::Avx2 => (32.0, "two 256-bit vpmaddwd (16 MACs each) per cycle"),
        _ => (4.0, "scalar: ~4 MACs per cycle"),
    };
    let peak = per_cycle * mhz * 1e6;
    (
        peak,
        format!(
            "{:.0} GMAC/s = {how} x {mhz:.0} MHz ({source}); an estimate, not measured",
            peak / 1e9
        ),
    )
}

fn bench_engine(files: &ModelFiles, o: &EngineBench) -> Result<()> {
    let runs = o.runs.max(1);
    let mut int8 = Int8Model::from_file(&files.blob(), o.size)?;
    let (h, w) = int8.input_shape();
    let what = match o.runtime {
        Runtime::Both => "core int8 and tract f32",
        Runtime::Core => "core int8 alone",
        Runtime::Tract => "tract f32 alone",
    };
    println!(
        "engine bench: {} ({}) at {h}×{w}, {what}, one thread, median of {runs} runs (after one warm-up) on a simulated {} frame",
        files.variant,
        files.dir.display(),
        files.preset()
    );
    // The MACs of one run, from the plan (the same figure a run reports).
    let macs = int8.with_engine(|e| e.plan().macs())?;
    // The core's input; tract's timed frames use its own synthetic frame, and tract runs this
    // one only when both run, for the SQNR.
    let frame = if o.runtime.core() {
        Some(
            simulated_frames(files.preset(), h, w, 1, 424_242)?
                .pop()
                .context("no simulated frame")?,
        )
    } else {
        None
    };
    let mut float_depth = None;
    let mut tract_ms = None;
    if o.runtime.tract() {
        let float = FloatReference::load(&files.nnef(), h as u32, w as u32)?;
        if let Some(f) = &frame {
            float_depth = Some(float.run(&f.rgb, &f.sparse_m)?);
        }
        tract_ms = Some(float.time_per_frame(runs)?.as_secs_f64() * 1e3);
    }
    let mut rows = Vec::new();
    if let Some(frame) = &frame {
        let mut int8_depth = vec![0f32; h * w];
        for &isa in o.sets {
            let (core_ms, profile) = int8.with_engine(|e| -> Result<(f64, Vec<OpTime>)> {
                e.set_kernels(isa)?;
                let ms = median_ms(runs, || {
                    e.run(&frame.rgb, &frame.sparse_m, &mut int8_depth)?;
                    Ok(())
                })?;
                let profile = if o.per_op {
                    profile_ops(e, &frame.rgb, &frame.sparse_m, runs)?
                } else {
                    Vec::new()
                };
                Ok((ms, profile))
            })??;
            let sqnr = float_depth.as_ref().map(|f| sqnr_db(f, &int8_depth));
            rows.push((isa, core_ms, sqnr, profile));
        }
    }
    println!(
        "  MACs per frame          {:.3} G ({macs})",
        macs as f64 / 1e9
    );
    if o.runtime.core() {
        println!("  int8 weight bytes       {}", int8.int8_weight_bytes());
        println!("  blob bytes              {}", int8.blob_bytes());
        println!("  arena bytes (core)      {}", int8.arena_bytes());
    }
    if let Some(tract_ms) = tract_ms {
        println!(
            "  tract f32               {tract_ms:.1} ms/frame  ({:.2} GMAC/s)",
            macs as f64 / tract_ms / 1e6
        );
    }
    for (isa, core_ms, sqnr, _) in &rows {
        let versus = match (&tract_ms, sqnr) {
            (Some(tract_ms), Some(sqnr)) => format!(
                ", tract / core {:.2} (above 1: the core is faster), depth SQNR vs f32 {sqnr:.1} dB",
                tract_ms / core_ms
            ),
            _ => String::new(),
        };
        println!(
            "  core int8 {:<13} {core_ms:.1} ms/frame  ({:.2} GMAC/s){versus}",
            isa.name(),
            macs as f64 / core_ms / 1e6,
        );
    }
    for (isa, _, _, profile) in rows.iter().filter(|r| !r.3.is_empty()) {
        print_profile(*isa, profile);
    }
    Ok(())
}

/// Times every op of `runs` frames through the observer (called right after each op).
fn profile_ops(
    e: &mut Engine<'_>,
    rgb: &[u8],
    sparse_m: &[f32],
    runs: usize,
) -> Result<Vec<OpTime>> {
    let plan = e.plan();
    let graph = e.graph();
    let mut ops: Vec<OpTime> = graph
        .ops
        .iter()
        .enumerate()
        .map(|(i, op)| OpTime {
            name: op_name(op.code).unwrap_or("?"),
            shape: plan
                .shape(op.output)
                .map_or(String::new(), |s| format!("{}x{}x{}", s.c, s.h, s.w)),
            macs: plan.op_macs(graph, i),
            ms: Vec::with_capacity(runs),
        })
        .collect();
    // Ops fused into another (affinity heads into the refinement, a concat into its conv) run
    // inside it: their MACs and time belong to that op's row.
    for i in 0..ops.len() {
        if let Some(j) = plan.fused_into(i) {
            let macs = std::mem::take(&mut ops[i].macs);
            ops[i].name = "(fused)";
            if let Some(t) = ops.get_mut(j) {
                t.macs += macs;
            }
        }
    }
    let mut out = vec![0f32; rgb.len() / 3];
    for _ in 0..runs {
        let mut last = Instant::now();
        let mut times = vec![0f64; ops.len()];
        e.run_observed(rgb, sparse_m, &mut out, &mut |i, _| {
            let now = Instant::now();
            if let Some(t) = times.get_mut(i) {
                *t = (now - last).as_secs_f64() * 1e3;
            }
            last = Instant::now();
        })?;
        for (op, t) in ops.iter_mut().zip(times) {
            op.ms.push(t);
        }
    }
    Ok(ops)
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

fn print_profile(isa: Isa, ops: &[OpTime]) {
    let total: f64 = ops.iter().map(|o| median(&o.ms)).sum();
    println!(
        "\n  per-op profile, kernel set {} (sum of medians {total:.2} ms)",
        isa.name()
    );
    println!(
        "  {:>3}  {:<18} {:>14} {:>10} {:>8} {:>8} {:>6}",
        "op", "kind", "output CxHxW", "MMAC", "ms", "GMAC/s", "%"
    );
    for (i, o) in ops.iter().enumerate() {
        let ms = median(&o.ms);
        let gmacs = if o.macs > 0 && ms > 0.0 {
            format!("{:.1}", o.macs as f64 / ms / 1e6)
        } else {
            "-".into()
        };
        println!(
            "  {i:>3}  {:<18} {:>14} {:>10.2} {ms:>8.3} {gmacs:>8} {:>6.1}",
            o.name,
            o.shape,
            o.macs as f64 / 1e6,
            100.0 * ms / total.max(1e-9)
        );
    }
    let mut kinds: Vec<(&str, f64, u64)> = Vec::new();
    for o in ops {
        match kinds.iter_mut().find(|k| k.0 == o.name) {
            Some(k) => {
                k.1 += median(&o.ms);
                k.2 += o.macs;
            }
            None => kinds.push((o.name, median(&o.ms), o.macs)),
        }
    }
    kinds.sort_by(|a, b| b.1.total_cmp(&a.1));
    println!("  by kind:");
    for (name, ms, macs) in &kinds {
        println!(
            "    {name:<18} {ms:>8.2} ms {:>6.1} %  {:>8.1} MMAC",
            100.0 * ms / total.max(1e-9),
            *macs as f64 / 1e6
        );
    }
    let (conv_ms, conv_macs) = ops
        .iter()
        .filter(|o| o.name == "conv2d" || o.name == "linear")
        .fold((0.0, 0u64), |(t, m), o| (t + median(&o.ms), m + o.macs));
    let (peak, how) = int8_peak(isa);
    let rate = conv_macs as f64 / (conv_ms / 1e3).max(1e-12);
    println!(
        "  convs: {:.2} GMAC/s = {:.1} % of the assumed int8 peak of one core, {how}",
        rate / 1e9,
        100.0 * rate / peak
    );
}
