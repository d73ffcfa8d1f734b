//! `depthor demo`: the main job on the embedded default model. With no arguments it renders a
//! scene, simulates the `mcu` sensor (8×8 zones), projects the zones, runs the int8 model in the
//! core, and compares it with the classical baselines; with `--recording DIR` it runs on the
//! user's recording (its own dToF if it has some, else the simulated `mcu` sensor on its
//! reference depth). Writes `<out>/depth_<id>.png` (16-bit mm) and `<out>/mosaic_<id>.png`.

use anyhow::{Context, Result};
use depthor_core::metrics::{Metrics, MetricsAccumulator};
use depthor_core::projection::{for_each_point, ProjectedPoint};
use depthor_host::baselines::{self, SparseFrame};
use depthor_host::dataset::{resample_frame, scene_config_for, synth_frame};
use depthor_host::inference::Int8Model;
use depthor_host::recording::{depth_m_to_mm, CalibrationData, Recording};
use depthor_host::sim::{preset, simulate, SimInput, SimOutput};
use depthor_host::viz::{depth_image, mosaic, render_projection, Overlay};
use image::{ImageBuffer, Luma, RgbImage};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `depthor demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Run on this recording instead of a rendered scene.
    #[arg(long)]
    recording: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "demo")]
    out: PathBuf,
    /// Frames to run (rendered scenes, or the first frames of the recording).
    #[arg(long, default_value_t = 1)]
    frames: usize,
    /// Scene seed.
    #[arg(long, default_value_t = 2025)]
    seed: u64,
    /// Largest depth counted by the metrics, metres.
    #[arg(long, default_value_t = 10.0)]
    max_depth: f32,
}

/// One input frame at the model's size.
struct DemoFrame {
    id: String,
    rgb: RgbImage,
    reference_m: Vec<f32>,
    points: Vec<ProjectedPoint>,
}

/// Runs the demo and prints metrics and time per frame.
pub fn handle(args: Args) -> Result<()> {
    let mut model = Int8Model::embedded_mcu()?;
    let (h, w) = model.input_shape();
    let frames = match &args.recording {
        None => rendered(&args, w as u32, h as u32)?,
        Some(dir) => from_recording(dir, args.frames, w as u32, h as u32)?,
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let names = [
        "int8 model (core)",
        "nearest zone",
        "bilinear zones",
        "joint bilateral",
    ];
    let mut acc: Vec<MetricsAccumulator> = names
        .iter()
        .map(|_| MetricsAccumulator::new(args.max_depth))
        .collect();
    let mut model_time = 0.0f64;
    for f in &frames {
        let mut sparse = vec![0.0f32; w * h];
        for p in &f.points {
            let i = p.y as usize * w + p.x as usize;
            if sparse[i] == 0.0 || p.depth_m < sparse[i] {
                sparse[i] = p.depth_m;
            }
        }
        let t = Instant::now();
        let (pred, _) = model.run(f.rgb.as_raw(), &sparse)?;
        model_time += t.elapsed().as_secs_f64();
        let s = SparseFrame {
            width: w as u32,
            height: h as u32,
            rows: 8,
            cols: 8,
            points: &f.points,
        };
        let [near, bil, jbu] = baselines::run_all(&s, f.rgb.as_raw());
        for (a, p) in acc.iter_mut().zip([&pred, &near, &bil, &jbu]) {
            a.add_map(p, &f.reference_m, w, h)?;
        }
        write_outputs(&args, f, &pred, &jbu, w as u32, h as u32)?;
    }
    println!(
        "depthor demo: {} frame(s) at {h}×{w}, embedded mcu model ({} KiB blob, {} KiB arena)",
        frames.len(),
        model.blob_bytes() / 1024,
        model.arena_bytes() / 1024
    );
    println!(
        "{:<20} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}",
        "method", "δ1", "δ2", "δ3", "Rel", "RMSE", "log10", "EWMAE"
    );
    for (name, a) in names.iter().zip(&acc) {
        print_row(name, &a.finish());
    }
    println!(
        "int8 model time per frame (this machine, one thread): {:.1} ms",
        1e3 * model_time / frames.len().max(1) as f64
    );
    println!("wrote {}", args.out.display());
    Ok(())
}

fn print_row(name: &str, m: &Metrics) {
    println!(
        "{:<20} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3}",
        name, m.delta1, m.delta2, m.delta3, m.abs_rel, m.rmse, m.log10, m.ewmae
    );
}

/// Rendered scenes with the `mcu` sensor simulated on them.
fn rendered(args: &Args, w: u32, h: u32) -> Result<Vec<DemoFrame>> {
    let cfg = preset("mcu")?;
    let scene_cfg = scene_config_for("mcu");
    (0..args.frames as u64)
        .map(|i| {
            let f = synth_frame(&scene_cfg, &cfg, args.seed, i, w, h)?;
            let rgb = RgbImage::from_raw(w, h, f.scene.rgb.clone()).context("scene size")?;
            let points = sim_points(&f.sim, &f.scene.camera)?;
            Ok(DemoFrame {
                id: format!("{i:06}"),
                rgb,
                reference_m: f
                    .scene
                    .depth_m
                    .iter()
                    .map(|d| d * f.sim.depth_scale)
                    .collect(),
                points,
            })
        })
        .collect()
}

/// The projected points of a simulator output (zone rectangles in camera pixels).
fn sim_points(
    sim: &SimOutput,
    camera: &depthor_core::calibration::CameraIntrinsics,
) -> Result<Vec<ProjectedPoint>> {
    let cfg = preset("mcu")?;
    let meta = depthor_host::dataset::dtof_meta(&cfg, camera);
    let cal = CalibrationData::new(&(*camera).into(), &meta, None);
    let frame = depthor_host::dataset::dtof_frame(sim);
    let mut points = Vec::new();
    for_each_point(&cal.as_core(), &frame.view(&meta), |p| points.push(p))?;
    Ok(points)
}

/// The first `n` frames of a recording, resampled to the model's size; zones projected at the
/// recording's own resolution and mapped onto the resampled image, or simulated (`mcu` preset)
/// when the recording has no dToF.
fn from_recording(dir: &PathBuf, n: usize, w: u32, h: u32) -> Result<Vec<DemoFrame>> {
    let rec = Recording::open(dir)?;
    let cfg = preset("mcu")?;
    (0..rec.len().min(n.max(1)))
        .map(|i| {
            let frame = rec.read_frame(i)?;
            let cam = rec.camera(i);
            let depth = frame
                .depth_m
                .clone()
                .unwrap_or_else(|| vec![0.0; (cam.width * cam.height) as usize]);
            let r = resample_frame(&cam, &frame.rgb, &depth, frame.labels.as_deref(), w, h);
            let points = match (&frame.dtof, rec.calibration(i), rec.meta().dtof.as_ref()) {
                (Some(d), Some(cal), Some(meta)) => {
                    // Map the recording's pixel coordinates onto the resampled image.
                    let (sx, sy) = (r.camera.fx / cam.fx, r.camera.fy / cam.fy);
                    let mut pts = Vec::new();
                    for_each_point(&cal.as_core(), &d.view(meta), |p| {
                        let u = (p.u - cam.cx) * sx + r.camera.cx;
                        let v = (p.v - cam.cy) * sy + r.camera.cy;
                        let (x, y) = ((u + 0.5).floor(), (v + 0.5).floor());
                        if x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32 {
                            pts.push(ProjectedPoint {
                                u,
                                v,
                                x: x as u32,
                                y: y as u32,
                                ..p
                            });
                        }
                    })?;
                    pts
                }
                _ => {
                    let sim = simulate(
                        &cfg,
                        &SimInput {
                            width: w,
                            height: h,
                            depth_m: &r.depth_m,
                            rgb: r.rgb.as_raw(),
                            labels: r.labels.as_deref(),
                            reflectance: None,
                            second_depth_m: None,
                        },
                        i as u64,
                    )?;
                    sim_points(&sim, &r.camera)?
                }
            };
            Ok(DemoFrame {
                id: frame.id,
                rgb: r.rgb,
                reference_m: r.depth_m,
                points,
            })
        })
        .collect()
}

/// depth_<id>.png (16-bit mm) and mosaic_<id>.png: RGB+points | reference | int8 model |
/// |error| of the model | joint bilateral baseline.
fn write_outputs(
    args: &Args,
    f: &DemoFrame,
    pred: &[f32],
    jbu: &[f32],
    w: u32,
    h: u32,
) -> Result<()> {
    let mm: Vec<u16> = pred.iter().map(|&d| depth_m_to_mm(d)).collect();
    let depth_png: ImageBuffer<Luma<u16>, Vec<u16>> =
        ImageBuffer::from_raw(w, h, mm).context("depth size")?;
    let path = args.out.join(format!("depth_{}.png", f.id));
    depth_png
        .save(&path)
        .with_context(|| format!("{}: cannot write", path.display()))?;
    let hi = f
        .reference_m
        .iter()
        .copied()
        .fold(0.0f32, f32::max)
        .max(1.0);
    let err: Vec<f32> = pred
        .iter()
        .zip(&f.reference_m)
        .map(|(p, r)| if *r > 0.0 { (p - r).abs() + 1e-6 } else { 0.0 })
        .collect();
    let overlay = Overlay {
        lo_m: 0.0,
        hi_m: hi,
        ..Overlay::auto(w, h, &f.points)
    };
    let panels = [
        render_projection(&f.rgb, &f.points, &overlay),
        depth_image(&f.reference_m, w, h, 0.0, hi),
        depth_image(pred, w, h, 0.0, hi),
        depth_image(&err, w, h, 0.0, 1.0),
        depth_image(jbu, w, h, 0.0, hi),
    ];
    let path = args.out.join(format!("mosaic_{}.png", f.id));
    mosaic(&panels, 4)
        .save(&path)
        .with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(())
}
