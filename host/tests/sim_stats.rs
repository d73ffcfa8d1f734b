//! Statistical and behavioural tests of the dToF simulator on synthetic piecewise-planar scenes.
//!
//! Tolerances: fractions measured over ≥ 200 frames (≥ 12 800 zones for 8×8, ≥ 240 000 for
//! 40×30) have a binomial standard error ≤ 0.2 %, so the ±1.5 % (anomalies) and ±5 % (dark loss)
//! bands are > 7σ wide; they fail on a wrong model, not on bad luck.

use depthor_host::rng::Rng;
use depthor_host::sim::grid::GridConfig;
use depthor_host::sim::{preset, simulate, SimConfig, SimError, SimInput, SimOutput, ZoneEvents};

/// A synthetic frame: a tilted background plane, nearer boxes, optional material and dark patches.
struct Frame {
    w: u32,
    h: u32,
    depth: Vec<f32>,
    rgb: Vec<u8>,
    labels: Vec<u8>,
    second: Vec<f32>,
}

/// Scene options.
#[derive(Clone, Copy)]
struct Opts {
    /// Background depth range (m) at the plane's near edge.
    bg: [f32; 2],
    /// Number of dark patches (V < 30).
    dark: usize,
    /// Number of transparent/specular patches.
    materials: usize,
}

impl Frame {
    fn input(&self) -> SimInput<'_> {
        SimInput {
            width: self.w,
            height: self.h,
            depth_m: &self.depth,
            rgb: &self.rgb,
            labels: Some(&self.labels),
            reflectance: None,
            second_depth_m: Some(&self.second),
        }
    }
}

/// A random rectangle `[y0, x0, y1, x1]` covering 15–45 % of each side.
fn rect(r: &mut Rng, w: u32, h: u32) -> [usize; 4] {
    let (hh, ww) = (
        h as f32 * r.range(0.15, 0.45),
        w as f32 * r.range(0.15, 0.45),
    );
    let y0 = r.range(0.0, h as f32 - hh) as usize;
    let x0 = r.range(0.0, w as f32 - ww) as usize;
    [y0, x0, y0 + hh as usize, x0 + ww as usize]
}

fn scene(seed: u64, w: u32, h: u32, o: Opts) -> Frame {
    let mut r = Rng::derive(seed, 0x5CE4E);
    let n = (w * h) as usize;
    let (a, gy, gx) = (
        r.range(o.bg[0], o.bg[1]),
        r.range(0.0, 2.0),
        r.range(-1.0, 1.0),
    );
    let mut depth = vec![0.0f32; n];
    let mut rgb = vec![0u8; 3 * n];
    for y in 0..h as usize {
        for x in 0..w as usize {
            let i = y * w as usize + x;
            depth[i] = (a + gy * (1.0 - y as f32 / h as f32) + gx * x as f32 / w as f32).max(0.3);
            let v = 80 + ((x / 8 + y / 8) % 2) as u8 * 100;
            rgb[3 * i..3 * i + 3].copy_from_slice(&[v, v / 2, v / 3]);
        }
    }
    for _ in 0..r.below(4) + 1 {
        let rc = rect(&mut r, w, h);
        let d = r.range(0.5, 2.5);
        for y in rc[0]..rc[2] {
            for x in rc[1]..rc[3] {
                depth[y * w as usize + x] = d;
            }
        }
    }
    // A few unknown-depth holes.
    for _ in 0..2 {
        let [y0, x0, _, _] = rect(&mut r, w, h);
        for y in y0..(y0 + 4).min(h as usize) {
            for x in x0..(x0 + 4).min(w as usize) {
                depth[y * w as usize + x] = 0.0;
            }
        }
    }
    for _ in 0..o.dark {
        let rc = rect(&mut r, w, h);
        let v = r.below(30) as u8;
        for y in rc[0]..rc[2] {
            for x in rc[1]..rc[3] {
                let i = y * w as usize + x;
                rgb[3 * i..3 * i + 3].copy_from_slice(&[v, v, v / 2]);
            }
        }
    }
    let mut labels = vec![0u8; n];
    let mut second = vec![0.0f32; n];
    for k in 0..o.materials {
        let rc = rect(&mut r, w, h);
        let label = 1 + (k % 2) as u8;
        let behind = r.range(0.5, 3.0);
        for y in rc[0]..rc[2] {
            for x in rc[1]..rc[3] {
                let i = y * w as usize + x;
                labels[i] = label;
                // Only glass knows the surface behind it; mirrors use the farther factor.
                second[i] = if label == 1 { depth[i] + behind } else { 0.0 };
            }
        }
    }
    Frame {
        w,
        h,
        depth,
        rgb,
        labels,
        second,
    }
}

const PLAIN: Opts = Opts {
    bg: [2.0, 4.0],
    dark: 0,
    materials: 0,
};

fn run(cfg: &SimConfig, f: &Frame, seed: u64) -> SimOutput {
    simulate(cfg, &f.input(), seed).unwrap()
}

fn count(out: &SimOutput, e: ZoneEvents) -> usize {
    out.truth.iter().filter(|t| t.events.contains(e)).count()
}

fn assert_within(name: &str, got: f64, want: f64, tol: f64) {
    assert!(
        (got - want).abs() <= tol,
        "{name}: {got:.4} not within {want} ± {tol}"
    );
}

#[test]
fn anomalies_noise_and_blank_fractions_l5_and_phone() {
    for (name, w, h, frames) in [("mcu", 160, 120, 300), ("phone", 120, 160, 200)] {
        let on = preset(name).unwrap();
        let mut off = on.clone();
        off.anomalies.enabled = false;
        let (mut zones, mut noise_t, mut blank_t) = (0usize, 0usize, 0usize);
        let (mut noise_o, mut valid_off, mut blanked_o) = (0usize, 0usize, 0usize);
        for s in 0..frames {
            let f = scene(
                s,
                w,
                h,
                Opts {
                    materials: 2,
                    dark: 1,
                    ..PLAIN
                },
            );
            let a = run(&on, &f, s);
            let b = run(&off, &f, s);
            zones += a.status.len();
            noise_t += count(&a, ZoneEvents::NOISE);
            blank_t += count(&a, ZoneEvents::BLANK);
            for z in 0..a.status.len() {
                if a.is_valid(z) && (!b.is_valid(z) || a.distance_mm[z] != b.distance_mm[z]) {
                    noise_o += 1;
                }
                if b.is_valid(z) {
                    valid_off += 1;
                    blanked_o += usize::from(!a.is_valid(z));
                }
            }
        }
        let z = zones as f64;
        assert_within(
            &format!("{name} noise (truth)"),
            noise_t as f64 / z,
            0.05,
            0.015,
        );
        assert_within(
            &format!("{name} blank (truth)"),
            blank_t as f64 / z,
            0.05,
            0.015,
        );
        assert_within(
            &format!("{name} noise (outputs)"),
            noise_o as f64 / z,
            0.05,
            0.015,
        );
        // A zone valid without anomalies ends invalid when blanked (5 %), not when noised.
        assert_within(
            &format!("{name} blank (outputs)"),
            blanked_o as f64 / valid_off as f64,
            0.05,
            0.015,
        );
    }
}

#[test]
fn dark_zones_lose_80_percent_phone() {
    let full = preset("phone").unwrap();
    // Outputs: dark on vs off, with the zone-moving and random aspects off in both.
    let mut on = full.clone();
    on.calibration_shift.enabled = false;
    on.anomalies.enabled = false;
    let mut off = on.clone();
    off.dark.enabled = false;
    let (mut dark_valid_off, mut lost, mut truth_dark, mut truth_lost) =
        (0usize, 0usize, 0usize, 0usize);
    for s in 0..200 {
        let f = scene(
            s,
            120,
            160,
            Opts {
                dark: 2,
                materials: 1,
                ..PLAIN
            },
        );
        let a = run(&on, &f, s);
        let b = run(&off, &f, s);
        for z in 0..a.status.len() {
            if a.truth[z].events.contains(ZoneEvents::DARK) && b.is_valid(z) {
                dark_valid_off += 1;
                lost += usize::from(!a.is_valid(z));
            }
        }
        // Truth, full preset: losses among dark zones that still had a return when dark ran.
        let c = run(&full, &f, s);
        let surf_loss = ZoneEvents::TRANSPARENT_LOSS | ZoneEvents::SPECULAR_LOSS;
        for t in &c.truth {
            if t.events.contains(ZoneEvents::DARK)
                && t.peak_m > 0.0
                && !t.events.intersects(surf_loss)
            {
                truth_dark += 1;
                truth_lost += usize::from(t.events.contains(ZoneEvents::DARK_LOSS));
            }
        }
    }
    assert!(
        dark_valid_off > 5000,
        "too few dark zones: {dark_valid_off}"
    );
    assert_within(
        "dark loss (outputs)",
        lost as f64 / dark_valid_off as f64,
        0.8,
        0.05,
    );
    assert_within(
        "dark loss (truth)",
        truth_lost as f64 / truth_dark as f64,
        0.8,
        0.05,
    );
}

#[test]
fn no_valid_zone_beyond_the_limit() {
    for (name, limit_mm) in [("l5", 4100.0f32), ("phone", 8100.0)] {
        let cfg = preset(name).unwrap();
        let mut beyond = 0;
        let (w, h) = if name == "l5" { (160, 120) } else { (120, 160) };
        for s in 0..200 {
            let out = run(
                &cfg,
                &scene(
                    s,
                    w,
                    h,
                    Opts {
                        bg: [3.0, 11.0],
                        ..PLAIN
                    },
                ),
                s,
            );
            for z in 0..out.status.len() {
                if out.is_valid(z) {
                    assert!(
                        out.distance_mm[z] <= limit_mm + 0.5,
                        "{name}: {} mm",
                        out.distance_mm[z]
                    );
                }
                beyond += usize::from(out.truth[z].peak_m * 1000.0 > limit_mm);
            }
        }
        assert!(
            beyond > 1000,
            "{name}: the scenes must reach beyond the limit ({beyond})"
        );
    }
}

#[test]
fn range_loss_rises_between_practical_and_limit() {
    let mut cfg = SimConfig::ideal(preset("phone").unwrap().grid);
    cfg.overall_distribution = preset("phone").unwrap().overall_distribution;
    cfg.range = preset("phone").unwrap().range;
    // Bins of 0.35 m from 5.3 m to 9.5 m.
    let edges: Vec<f32> = (0..13).map(|k| 5.3 + 0.35 * k as f32).collect();
    let mut n = vec![0usize; edges.len() - 1];
    let mut lost = vec![0usize; edges.len() - 1];
    for s in 0..200 {
        let f = scene(
            s,
            120,
            160,
            Opts {
                bg: [4.0, 9.0],
                ..PLAIN
            },
        );
        let out = run(&cfg, &f, s);
        for t in &out.truth {
            if let Some(k) = edges
                .windows(2)
                .position(|e| t.peak_m >= e[0] && t.peak_m < e[1])
            {
                n[k] += 1;
                lost[k] += usize::from(t.events.contains(ZoneEvents::RANGE_LOSS));
            }
        }
    }
    let rate: Vec<f64> = n
        .iter()
        .zip(&lost)
        .map(|(&n, &l)| l as f64 / n.max(1) as f64)
        .collect();
    for k in 0..rate.len() {
        assert!(n[k] >= 300, "bin {k} has only {} zones: {n:?}", n[k]);
        let mid = 0.5 * (edges[k] + edges[k + 1]) as f64;
        // Linear ramp 6 → 8.1 m, averaged over the bin (bins straddling 6.0 / 8.1 are in between).
        let lo = ((edges[k] as f64 - 6.0) / 2.1).clamp(0.0, 1.0);
        let hi = ((edges[k + 1] as f64 - 6.0) / 2.1).clamp(0.0, 1.0);
        assert!(
            rate[k] >= lo - 0.06 && rate[k] <= hi + 0.06,
            "bin {mid:.2} m: {:.3} ∉ [{lo:.2}, {hi:.2}]",
            rate[k]
        );
        if k > 0 {
            assert!(rate[k] + 0.03 >= rate[k - 1], "not monotone: {rate:?}");
        }
    }
    assert_eq!(rate[0], 0.0);
    assert_eq!(*rate.last().unwrap(), 1.0);
}

#[test]
fn calibration_shift_moves_only_background_zones_by_at_most_two() {
    let on = preset("phone").unwrap();
    let mut off = on.clone();
    off.calibration_shift.enabled = false;
    let mut seen = [[false; 5]; 5];
    let (mut with_depth, mut background) = (0usize, 0usize);
    for s in 0..200 {
        let f = scene(
            s,
            120,
            160,
            Opts {
                materials: 1,
                dark: 1,
                ..PLAIN
            },
        );
        let a = run(&on, &f, s);
        let b = run(&off, &f, s);
        let cols = a.cols as i32;
        for z in 0..a.status.len() {
            let t = a.truth[z];
            let bg = t.events.contains(ZoneEvents::BACKGROUND);
            let [dr, dc] = t.shift;
            assert!(dr.abs() <= 2 && dc.abs() <= 2, "shift {:?}", t.shift);
            if t.shift != [0, 0] {
                assert!(bg && t.events.contains(ZoneEvents::SHIFTED));
                seen[(dr + 2) as usize][(dc + 2) as usize] = true;
            }
            if !bg {
                assert_eq!(t.shift, [0, 0]);
                assert_eq!(
                    (a.status[z], a.distance_mm[z].to_bits()),
                    (b.status[z], b.distance_mm[z].to_bits())
                );
            } else if t.events.contains(ZoneEvents::SHIFTED)
                && !t.events.intersects(ZoneEvents::NOISE | ZoneEvents::BLANK)
            {
                // A shifted zone reports what the off run measured at (r + dr, c + dc).
                let (r, c) = (z as i32 / cols + dr as i32, z as i32 % cols + dc as i32);
                if r >= 0 && r < a.rows as i32 && c >= 0 && c < cols {
                    let src = (r * cols + c) as usize;
                    let src_noise = b.truth[src]
                        .events
                        .intersects(ZoneEvents::NOISE | ZoneEvents::BLANK);
                    // Anomalies run after the shift: skip sources the off run anomalised.
                    if !src_noise {
                        assert_eq!(a.distance_mm[z], b.distance_mm[src], "zone {z} ← {src}");
                    }
                } else {
                    assert!(!a.is_valid(z));
                }
            }
            if t.peak_m > 0.0 {
                with_depth += 1;
                background += usize::from(bg);
            }
        }
    }
    assert!(
        seen.iter().flatten().filter(|&&s| s).count() >= 20,
        "shifts seen: {seen:?}"
    );
    // The threshold is the q-quantile, q ~ U[0.2, 0.4]: on average ≈ 70 % of zones are deeper.
    assert_within(
        "background fraction",
        background as f64 / with_depth as f64,
        0.70,
        0.05,
    );
}

#[test]
fn no_valid_point_outside_fov_or_image() {
    for name in ["l5", "phone"] {
        let cfg = preset(name).unwrap();
        let (w, h) = if name == "l5" { (160, 120) } else { (120, 160) };
        let [t, b, l, r] = cfg.grid.fov_bounds;
        for s in 0..200 {
            let f = scene(s, w, h, PLAIN);
            let out = run(&cfg, &f, s);
            for (z, rc) in out.zone_rects_px.iter().enumerate() {
                let (cy, cx) = ((rc[0] + rc[2]) / 2.0, (rc[1] + rc[3]) / 2.0);
                assert!(
                    cy >= t * h as f32
                        && cy <= b * h as f32
                        && cx >= l * w as f32
                        && cx <= r * w as f32
                );
                if out.is_valid(z) {
                    assert!(cy >= 0.0 && cx >= 0.0 && cy < h as f32 && cx < w as f32);
                }
            }
        }
    }
    // A grid reaching above the image: its top row is centred outside and never valid, noise included.
    let mut cfg = preset("l5").unwrap();
    cfg.grid.fov_bounds[0] = -0.5;
    cfg.anomalies.noise_fraction = 0.5;
    for s in 0..50 {
        let out = run(&cfg, &scene(s, 160, 120, PLAIN), s);
        for z in 0..8 {
            assert!(!out.is_valid(z));
            assert!(out.truth[z].events.contains(ZoneEvents::OUT_OF_IMAGE));
        }
    }
}

#[test]
fn bimodal_zone_reports_the_peak_not_the_mean() {
    // One zone covering the whole 100×100 image: 70 % wall at 3 m, 30 % box at 1 m.
    let grid = GridConfig {
        rows: 1,
        cols: 1,
        fov_bounds: [0.0, 1.0, 0.0, 1.0],
        ifov: [1.0, 1.0],
    };
    let mut cfg = SimConfig::ideal(grid);
    cfg.overall_distribution.enabled = true;
    cfg.overall_distribution.max_translation = 0.0;
    cfg.overall_distribution.max_rotation_deg = 0.0;
    let depth: Vec<f32> = (0..100 * 100)
        .map(|i| if i % 100 < 30 { 1.0 } else { 3.0 })
        .collect();
    let rgb = vec![200u8; 3 * 100 * 100];
    let input = SimInput {
        width: 100,
        height: 100,
        depth_m: &depth,
        rgb: &rgb,
        labels: None,
        reflectance: None,
        second_depth_m: None,
    };
    let out = simulate(&cfg, &input, 1).unwrap();
    assert_eq!(out.distance_mm, vec![3000.0]);
    // With OD off, the zone is the centre pixel (x = 50: wall).
    cfg.overall_distribution.enabled = false;
    assert_eq!(simulate(&cfg, &input, 1).unwrap().distance_mm, vec![3000.0]);
}

#[test]
fn same_seed_same_bytes_different_seed_differs() {
    let cfg = preset("phone").unwrap();
    let f = scene(
        3,
        120,
        160,
        Opts {
            materials: 2,
            dark: 1,
            ..PLAIN
        },
    );
    let a = run(&cfg, &f, 11);
    let b = run(&cfg, &f, 11);
    let bits = |o: &SimOutput| {
        o.distance_mm
            .iter()
            .map(|d| d.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.status, b.status);
    assert_eq!(a.truth, b.truth);
    let c = run(&cfg, &f, 12);
    assert_ne!(bits(&a), bits(&c));
}

#[test]
fn config_json_round_trip_and_clear_errors() {
    for name in ["l5", "phone", "mcu"] {
        let cfg = preset(name).unwrap();
        assert_eq!(SimConfig::from_json(&cfg.to_json()).unwrap(), cfg);
    }
    let json = preset("phone").unwrap().to_json();
    // Unknown field inside an aspect.
    let bad = json.replacen("\"p_loss\": 0.8", "\"p_loss\": 0.8, \"p_lose\": 0.1", 1);
    let e = SimConfig::from_json(&bad).unwrap_err().to_string();
    assert!(e.contains("p_lose"), "{e}");
    // Unknown aspect.
    let bad = json.replacen('{', "{\"multipath_typo\": {},", 1);
    let e = SimConfig::from_json(&bad).unwrap_err().to_string();
    assert!(e.contains("multipath_typo"), "{e}");
    // Out-of-range probability names the field.
    let bad = json.replacen("\"p_loss\": 0.8", "\"p_loss\": 1.5", 1);
    let e = SimConfig::from_json(&bad).unwrap_err();
    assert!(
        matches!(&e, SimError::InvalidConfig { field, .. } if field == "dark.p_loss"),
        "{e}"
    );
    assert!(e.to_string().contains("dark.p_loss"));
    let mut cfg = preset("phone").unwrap();
    cfg.range.limit_m = 5.0;
    assert!(cfg
        .validate()
        .unwrap_err()
        .to_string()
        .contains("range.limit_m"));
    let mut cfg = preset("phone").unwrap();
    cfg.calibration_shift.percentile = [0.4, 0.2];
    assert!(cfg
        .validate()
        .unwrap_err()
        .to_string()
        .contains("calibration_shift.percentile"));
    // Missing aspects are off.
    let minimal = format!(
        "{{\"grid\": {}}}",
        serde_json::to_string(&preset("l5").unwrap().grid).unwrap()
    );
    let cfg = SimConfig::from_json(&minimal).unwrap();
    assert!(!cfg.anomalies.enabled && !cfg.overall_distribution.enabled);
}

#[test]
fn bad_input_sizes_are_errors() {
    let cfg = preset("l5").unwrap();
    let f = scene(0, 160, 120, PLAIN);
    let mut input = f.input();
    input.rgb = &f.rgb[..10];
    assert!(matches!(
        simulate(&cfg, &input, 0),
        Err(SimError::InputSize { field: "rgb", .. })
    ));
    let mut input = f.input();
    input.width = 0;
    assert!(matches!(
        simulate(&cfg, &input, 0),
        Err(SimError::EmptyImage { .. })
    ));
}

/// Events each aspect may produce.
fn events_of(aspect: &str) -> ZoneEvents {
    match aspect {
        "transparent" => {
            ZoneEvents::TRANSPARENT | ZoneEvents::TRANSPARENT_LOSS | ZoneEvents::TRANSPARENT_BEHIND
        }
        "specular" => {
            ZoneEvents::SPECULAR | ZoneEvents::SPECULAR_LOSS | ZoneEvents::SPECULAR_FARTHER
        }
        "dark" => ZoneEvents::DARK | ZoneEvents::DARK_LOSS,
        "range" => ZoneEvents::RANGE_LOSS,
        "signal_loss" => ZoneEvents::SIGNAL_LOSS,
        "calibration_shift" => ZoneEvents::BACKGROUND | ZoneEvents::SHIFTED,
        "anomalies" => ZoneEvents::NOISE | ZoneEvents::BLANK,
        _ => unreachable!(),
    }
}

fn switch(cfg: &mut SimConfig, aspect: &str, on: bool) {
    match aspect {
        "transparent" => cfg.transparent.enabled = on,
        "specular" => cfg.specular.enabled = on,
        "dark" => cfg.dark.enabled = on,
        "range" => cfg.range.enabled = on,
        "signal_loss" => cfg.signal_loss.enabled = on,
        "calibration_shift" => cfg.calibration_shift.enabled = on,
        "anomalies" => cfg.anomalies.enabled = on,
        _ => unreachable!(),
    }
}

#[test]
fn each_aspect_switched_off_is_off_and_touches_only_its_zones() {
    let aspects = [
        "transparent",
        "specular",
        "dark",
        "range",
        "signal_loss",
        "calibration_shift",
        "anomalies",
    ];
    for aspect in aspects {
        let mut on = preset("phone").unwrap();
        on.signal_loss.enabled = true;
        on.signal_loss.p_loss = 0.2;
        if aspect != "calibration_shift" {
            // The shift moves measurements between zones; compare zone by zone without it.
            on.calibration_shift.enabled = false;
        }
        let mut off = on.clone();
        switch(&mut off, aspect, false);
        let mut fired = 0;
        for s in 0..60 {
            let f = scene(
                s,
                120,
                160,
                Opts {
                    bg: [3.0, 8.0],
                    dark: 2,
                    materials: 2,
                },
            );
            let a = run(&on, &f, s);
            let b = run(&off, &f, s);
            for z in 0..a.status.len() {
                assert!(
                    !b.truth[z].events.intersects(events_of(aspect)),
                    "{aspect} off but {:?}",
                    b.truth[z].events
                );
                let touched = a.truth[z].events.intersects(events_of(aspect));
                fired += usize::from(touched);
                if !touched && aspect != "calibration_shift" {
                    assert_eq!(
                        (a.status[z], a.distance_mm[z].to_bits()),
                        (b.status[z], b.distance_mm[z].to_bits()),
                        "{aspect}: untouched zone {z} changed"
                    );
                }
            }
        }
        assert!(fired > 100, "{aspect} never fired ({fired})");
    }
}

#[test]
fn distribution_off_reports_centre_pixels_and_all_off_is_ideal() {
    let grid = preset("l5").unwrap().grid;
    let cfg = SimConfig::ideal(grid.clone());
    for s in 0..20 {
        let f = scene(
            s,
            160,
            120,
            Opts {
                dark: 2,
                materials: 2,
                ..PLAIN
            },
        );
        let out = run(&cfg, &f, s);
        for (z, rc) in out.zone_rects_px.iter().enumerate() {
            let (cy, cx) = ((rc[0] + rc[2]) / 2.0, (rc[1] + rc[3]) / 2.0);
            assert_eq!(out.truth[z].center_px, [cy, cx]);
            let gt = f.depth[cy as usize * 160 + cx as usize];
            assert_eq!(out.distance_mm[z], gt * 1000.0);
            assert_eq!(out.is_valid(z), gt > 0.0);
            assert!(out.truth[z].events.bits() & !ZoneEvents::NO_DEPTH.bits() == 0);
        }
    }
    // With OD on, windows move by at most the iFoV half-size plus the rotation.
    let mut cfg = SimConfig::ideal(grid);
    cfg.overall_distribution.enabled = true;
    let mut moved = 0;
    for s in 0..20 {
        let out = run(&cfg, &scene(s, 160, 120, PLAIN), s);
        for (z, rc) in out.zone_rects_px.iter().enumerate() {
            let (cy, cx) = ((rc[0] + rc[2]) / 2.0, (rc[1] + rc[3]) / 2.0);
            let [y, x] = out.truth[z].center_px;
            // 2° about the FoV centre moves a zone ≤ 0.035·|r| ≤ 0.035·80 px at 120×160.
            assert!(
                (y - cy).abs() <= (rc[2] - rc[0]) / 2.0 + 2.8
                    && (x - cx).abs() <= (rc[3] - rc[1]) / 2.0 + 2.8
            );
            moved += usize::from((y - cy).abs() > 0.5);
        }
    }
    assert!(moved > 0);
}

#[test]
fn depth_halving_scales_deep_frames_only() {
    let mut cfg = SimConfig::ideal(preset("l5").unwrap().grid);
    let deep = scene(
        1,
        160,
        120,
        Opts {
            bg: [7.0, 7.5],
            ..PLAIN
        },
    );
    let near = scene(1, 160, 120, PLAIN);
    let a = run(&cfg, &deep, 0);
    cfg.depth_halving.enabled = true;
    let b = run(&cfg, &deep, 0);
    let c = run(&cfg, &near, 0);
    assert_eq!(
        (a.depth_scale, b.depth_scale, c.depth_scale),
        (1.0, 0.5, 1.0)
    );
    for z in 0..64 {
        assert_eq!(b.distance_mm[z], a.distance_mm[z] * 0.5);
    }
}

#[test]
fn non_lambertian_zones_lose_or_return_farther() {
    let mut cfg = SimConfig::ideal(preset("phone").unwrap().grid);
    let ph = preset("phone").unwrap();
    cfg.transparent = ph.transparent.clone();
    cfg.specular = ph.specular.clone();
    let (mut n, mut lost, mut farther) = (0usize, 0usize, 0usize);
    for s in 0..100 {
        let f = scene(
            s,
            120,
            160,
            Opts {
                materials: 2,
                ..PLAIN
            },
        );
        let out = run(&cfg, &f, s);
        for (z, t) in out.truth.iter().enumerate() {
            let d = out.distance_mm[z] / 1000.0;
            // (A zone half glass, half mirror is both; the mirror, applied later, decides.)
            if t.events.contains(ZoneEvents::TRANSPARENT)
                && !t.events.contains(ZoneEvents::SPECULAR)
                && t.peak_m > 0.0
            {
                n += 1;
                if t.events.contains(ZoneEvents::TRANSPARENT_LOSS) {
                    lost += 1;
                    assert!(!out.is_valid(z));
                } else {
                    // Glass second depths are the glass depth (≥ 0 m where unknown) + 0.5…3 m.
                    assert!(t.events.contains(ZoneEvents::TRANSPARENT_BEHIND));
                    assert!(out.is_valid(z) && d >= 0.5, "behind {d} {t:?}");
                    farther += 1;
                }
            }
            if t.events.contains(ZoneEvents::SPECULAR_FARTHER)
                && !t.events.contains(ZoneEvents::TRANSPARENT)
            {
                // No second depth for mirrors: 1.25–2 × the zone's peak.
                let k = d / t.peak_m;
                assert!((1.25 - 1e-4..=2.0 + 1e-4).contains(&k), "mirror factor {k}");
            }
        }
    }
    assert!(n > 1000, "{n}");
    assert_within("transparent loss", lost as f64 / n as f64, 0.5, 0.05);
    assert_eq!(lost + farther, n);
    // Without labels nothing is non-Lambertian.
    let f = scene(
        0,
        120,
        160,
        Opts {
            materials: 3,
            ..PLAIN
        },
    );
    let mut input = f.input();
    input.labels = None;
    let out = simulate(&cfg, &input, 0).unwrap();
    assert!(out.truth.iter().all(|t| !t
        .events
        .intersects(events_of("transparent") | events_of("specular"))));
}

#[test]
fn non_lambertian_hand_case() {
    // 2×1 grid on a 20×20 image: top half glass at 1 m with a wall behind at 3 m, bottom half a
    // mirror at 2 m with no second depth (farther factor fixed to 1.5 → 3 m).
    let grid = GridConfig {
        rows: 2,
        cols: 1,
        fov_bounds: [0.0, 1.0, 0.0, 1.0],
        ifov: [0.5, 1.0],
    };
    let mut cfg = SimConfig::ideal(grid);
    cfg.overall_distribution.enabled = true;
    cfg.overall_distribution.max_translation = 0.0;
    cfg.overall_distribution.max_rotation_deg = 0.0;
    for a in [&mut cfg.transparent, &mut cfg.specular] {
        a.enabled = true;
        a.p_loss = 0.0;
        a.farther_factor = [1.5, 1.5];
    }
    let top = |i: usize| i < 200;
    let depth: Vec<f32> = (0..400).map(|i| if top(i) { 1.0 } else { 2.0 }).collect();
    let labels: Vec<u8> = (0..400).map(|i| if top(i) { 1 } else { 2 }).collect();
    let second: Vec<f32> = (0..400).map(|i| if top(i) { 3.0 } else { 0.0 }).collect();
    let rgb = vec![200u8; 1200];
    let input = SimInput {
        width: 20,
        height: 20,
        depth_m: &depth,
        rgb: &rgb,
        labels: Some(&labels),
        reflectance: None,
        second_depth_m: Some(&second),
    };
    let out = simulate(&cfg, &input, 5).unwrap();
    assert_eq!(out.distance_mm, vec![3000.0, 3000.0]);
    assert!(out.truth[0].events.contains(ZoneEvents::TRANSPARENT_BEHIND));
    assert!(out.truth[1].events.contains(ZoneEvents::SPECULAR_FARTHER));
    cfg.transparent.p_loss = 1.0;
    cfg.specular.p_loss = 1.0;
    let out = simulate(&cfg, &input, 5).unwrap();
    assert_eq!(out.status, vec![255, 255]);
    assert!(out.truth[0].events.contains(ZoneEvents::TRANSPARENT_LOSS));
    assert!(out.truth[1].events.contains(ZoneEvents::SPECULAR_LOSS));
}
