//! Renders scenes and writes one PNG per scene: RGB | depth (colour map, 0–12 m) | labels over
//! the dimmed image (cyan glass, magenta mirror, yellow dark) | 940 nm reflectance. Prints the
//! render time per frame.
//!
//! `cargo run --release -p depthor-host --example scene_preview -- <out_dir> [count] [width]
//! [height] [first_seed] [hfov_deg]`
use depthor_host::scene::{camera_near, render_scene, SceneConfig};
use std::time::Instant;

fn colormap(t: f32) -> [u8; 3] {
    // Piecewise-linear "turbo"-like ramp: dark blue → cyan → green → yellow → red.
    let stops = [
        [48.0, 18.0, 59.0],
        [40.0, 160.0, 250.0],
        [60.0, 230.0, 110.0],
        [250.0, 220.0, 40.0],
        [200.0, 30.0, 20.0],
    ];
    let t = t.clamp(0.0, 1.0) * 4.0;
    let i = (t as usize).min(3);
    let f = t - i as f32;
    let c = |k: usize| (stops[i][k] + (stops[i + 1][k] - stops[i][k]) * f) as u8;
    [c(0), c(1), c(2)]
}

/// CPU seconds used by this process so far (all threads; Linux `/proc/self/stat`, 100 Hz ticks),
/// so timings stay meaningful on a loaded machine.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let out = a.first().cloned().unwrap_or_else(|| "scene_preview".into());
    let arg = |i: usize, d: f64| a.get(i).and_then(|s| s.parse::<f64>().ok()).unwrap_or(d);
    let (count, w, h, first, hfov) = (
        arg(1, 6.0) as u64,
        arg(2, 320.0) as u32,
        arg(3, 240.0) as u32,
        arg(4, 0.0) as u64,
        arg(5, 63.0) as f32,
    );
    std::fs::create_dir_all(&out)?;
    // Optional JSON config (any subset of SceneConfig's fields) in $SCENE_CONFIG.
    let cfg: SceneConfig = match std::env::var("SCENE_CONFIG") {
        Ok(path) => serde_json::from_str(&std::fs::read_to_string(path)?)?,
        Err(_) => SceneConfig::default(),
    };
    let mut total = 0.0;
    let mut cpu_total = 0.0;
    for seed in first..first + count {
        let cam = camera_near(seed, w, h, hfov);
        let (t0, c0) = (Instant::now(), cpu_seconds());
        let f = render_scene(&cfg, seed, cam);
        let dt = t0.elapsed().as_secs_f64();
        if let (Some(a), Some(b)) = (c0, cpu_seconds()) {
            cpu_total += b - a;
        }
        total += dt;
        let (wu, hu) = (w as usize, h as usize);
        let mut img = image::RgbImage::new(w * 4, h);
        for y in 0..hu {
            for x in 0..wu {
                let i = y * wu + x;
                let rgb = [f.rgb[3 * i], f.rgb[3 * i + 1], f.rgb[3 * i + 2]];
                let dim = rgb.map(|c| c / 3);
                let lab = match f.labels[i] {
                    1 => [0, 230, 230],
                    2 => [230, 0, 230],
                    3 => [240, 220, 0],
                    _ => dim,
                };
                let r = (f.reflectance[i] * 255.0) as u8;
                img.put_pixel(x as u32, y as u32, image::Rgb(rgb));
                img.put_pixel(
                    (x + wu) as u32,
                    y as u32,
                    image::Rgb(colormap(f.depth_m[i] / 12.0)),
                );
                img.put_pixel((x + 2 * wu) as u32, y as u32, image::Rgb(lab));
                img.put_pixel((x + 3 * wu) as u32, y as u32, image::Rgb([r, r, r]));
            }
        }
        img.save(format!("{out}/scene_{seed:04}.png"))?;
        let max_d = f.depth_m.iter().copied().fold(0.0f32, f32::max);
        let frac =
            |l: u8| f.labels.iter().filter(|&&v| v == l).count() as f32 / f.labels.len() as f32;
        println!(
            "seed {seed}: {:.1} ms, max depth {max_d:.2} m, glass {:.3} mirror {:.3} dark {:.3}",
            dt * 1e3,
            frac(1),
            frac(2),
            frac(3)
        );
    }
    println!(
        "mean {:.1} ms/frame wall, {:.1} ms/frame CPU at {h}x{w} over {count} frames ({} threads)",
        total / count as f64 * 1e3,
        cpu_total / count as f64 * 1e3,
        rayon::current_num_threads()
    );
    Ok(())
}
