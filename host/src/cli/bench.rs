//! `depthor bench <what>`: throughput figures printed for the README (never asserted in tests).
//!
//! - `depthor bench sim [--frames N] [--preset P]`: frames per second of scene rendering plus
//!   dToF simulation at 240×320 and 480×640 (H×W), on all cores (rayon), and the split between
//!   the renderer and the simulator on one core.

use anyhow::Result;
use depthor_host::dataset::{frame_seed, scene_config_for};
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
}

/// Runs the chosen benchmark and prints its figures.
pub fn handle(args: Args) -> Result<()> {
    match args.what {
        What::Sim { frames, preset } => bench_sim(frames, &preset),
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
