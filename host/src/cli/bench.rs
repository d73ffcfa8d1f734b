//! `depthor bench <what>`: throughput figures printed for the README (never asserted in tests).
//!
//! - `depthor bench sim [--frames N] [--preset P]`: frames per second of scene rendering plus
//!   dToF simulation at 240×320 and 480×640 (H×W), on all cores (rayon), and the split between
//!   the renderer and the simulator on one core.
//! - `depthor bench engine [--model M] [--height H --width W] [--runs N]`: one thread, median
//!   time per frame of the core's int8 engine and of tract's f32 run of the exported NNEF on the
//!   same model, size and simulated input; their ratio, MACs per frame, int8 weight bytes, blob
//!   bytes, arena bytes, and the depth SQNR of int8 against float on that input. Without
//!   `--model` it measures every shipped variant at its native size.

use anyhow::{Context, Result};
use depthor_host::dataset::{frame_seed, scene_config_for};
use depthor_host::inference::Int8Model;
use depthor_host::models::{ModelFiles, VARIANTS};
use depthor_host::quantize::calibrate::simulated_frames;
use depthor_host::quantize::check::sqnr_db;
use depthor_host::reference::FloatReference;
use depthor_host::scene::{camera_for, render_scene};
use depthor_host::sim::{preset, simulate, SimInput};
use rayon::prelude::*;
use std::time::Instant;

/// Arguments of `depthor bench`.
#[derive(Debug, clap::Args)]
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
    },
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
        } => {
            let size = height.zip(width);
            match model {
                Some(m) => bench_engine(&ModelFiles::resolve(&m)?, size, runs),
                None => VARIANTS.iter().try_for_each(|v| {
                    bench_engine(&ModelFiles::resolve(v)?, size, runs)?;
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
            let input = SimInput {
                width: w,
                height: h,
                depth_m: &scene.depth_m,
                rgb: &scene.rgb,
                labels: Some(&scene.labels),
                reflectance: Some(&scene.reflectance),
                second_depth_m: Some(&scene.second_depth_m),
            };
            simulate(&cfg, &input, s)?;
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

fn bench_engine(files: &ModelFiles, size: Option<(usize, usize)>, runs: usize) -> Result<()> {
    let mut int8 = Int8Model::from_file(&files.blob(), size)?;
    let (h, w) = int8.input_shape();
    let float = FloatReference::load(&files.nnef(), h as u32, w as u32)?;
    let frame = simulated_frames(files.preset(), h, w, 1, 424_242)?
        .pop()
        .context("no simulated frame")?;
    let mut stats = None;
    let mut int8_depth = Vec::new();
    let core_ms = median_ms(runs, || {
        let (d, s) = int8.run(&frame.rgb, &frame.sparse_m)?;
        int8_depth = d;
        stats = Some(s);
        Ok(())
    })?;
    let float_depth = float.run(&frame.rgb, &frame.sparse_m)?;
    let tract_ms = float.time_per_frame(runs)?.as_secs_f64() * 1e3;
    let macs = stats.map_or(0, |s| s.macs);
    println!(
        "engine bench: {} ({}) at {h}×{w}, one thread, median of {runs} runs on a simulated {} frame",
        files.variant,
        files.dir.display(),
        files.preset()
    );
    println!("  MACs per frame          {:.3} G", macs as f64 / 1e9);
    println!("  int8 weight bytes       {}", int8.int8_weight_bytes());
    println!("  blob bytes              {}", int8.blob_bytes());
    println!("  arena bytes (core)      {}", int8.arena_bytes());
    println!(
        "  core int8               {core_ms:.1} ms/frame  ({:.2} GMAC/s)",
        macs as f64 / core_ms / 1e6
    );
    println!(
        "  tract f32               {tract_ms:.1} ms/frame  ({:.2} GMAC/s)",
        macs as f64 / tract_ms / 1e6
    );
    println!(
        "  ratio tract / core      {:.2} (above 1: the core is faster)",
        tract_ms / core_ms
    );
    println!(
        "  depth SQNR int8 vs f32  {:.1} dB on this frame",
        sqnr_db(&float_depth, &int8_depth)
    );
    Ok(())
}
