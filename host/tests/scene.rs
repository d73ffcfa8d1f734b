//! Scene generator contract: determinism, buffer shapes and ranges, geometric consistency of depth
//! and normals, and how often the hard cases (far regions, glass, mirrors, dark objects) occur.
use depthor_host::scene::{camera_near, render_scene, SceneConfig, SceneFrame};

const W: u32 = 160;
const H: u32 = 120;

fn frame(seed: u64) -> SceneFrame {
    render_scene(&SceneConfig::default(), seed, camera_near(seed, W, H, 63.0))
}

/// Camera-frame ray of pixel `i` with z = 1.
fn ray(f: &SceneFrame, i: usize) -> [f32; 3] {
    let (x, y) = ((i % f.width as usize) as f32, (i / f.width as usize) as f32);
    [
        (x - f.camera.cx) / f.camera.fx,
        (y - f.camera.cy) / f.camera.fy,
        1.0,
    ]
}

#[test]
fn same_seed_same_buffers_regardless_of_threads() {
    let a = frame(11);
    let b = frame(11);
    assert!(a == b);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let c = pool.install(|| frame(11));
    assert!(a == c, "one thread gave a different frame");
}

#[test]
fn different_seeds_differ() {
    let a = frame(1);
    let b = frame(2);
    assert_ne!(a.rgb, b.rgb);
    assert_ne!(a.depth_m, b.depth_m);
}

fn check_invariants(f: &SceneFrame) {
    let n = (f.width * f.height) as usize;
    assert_eq!(f.rgb.len(), 3 * n);
    for len in [
        f.depth_m.len(),
        f.second_depth_m.len(),
        f.reflectance.len(),
        f.labels.len(),
        f.normals.len(),
    ] {
        assert_eq!(len, n);
    }
    for i in 0..n {
        let (d, d2, l) = (f.depth_m[i], f.second_depth_m[i], f.labels[i]);
        assert!(d.is_finite() && d > 0.0, "depth {d} at {i}");
        assert!(l <= 3, "label {l}");
        let r = f.reflectance[i];
        assert!((0.0..=1.0).contains(&r), "reflectance {r}");
        if l == 1 || l == 2 {
            assert!(
                d2.is_finite() && d2 > d,
                "label {l}: second {d2} <= depth {d}"
            );
        } else {
            assert_eq!(d2, 0.0);
        }
        if l == 3 {
            assert!(r <= 0.07, "dark reflectance {r}");
        }
        if l == 1 {
            assert!(r <= 0.1, "glass reflectance {r}");
        }
        let nn = f.normals[i];
        let len = (nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-3, "normal length {len}");
        let v = ray(f, i);
        assert!(
            nn[0] * v[0] + nn[1] * v[1] + nn[2] * v[2] <= 1e-4,
            "normal faces away"
        );
    }
}

#[test]
fn buffers_have_the_right_shape_and_ranges() {
    for seed in 100..104 {
        check_invariants(&frame(seed));
    }
    // Portrait phone-like frame too.
    let f = render_scene(&SceneConfig::default(), 5, camera_near(5, 60, 80, 50.0));
    check_invariants(&f);
}

#[test]
fn empty_room_points_lie_on_their_face_planes() {
    // With nothing in it the room is six planes: all pixels sharing a normal must back-project
    // to one plane, i.e. n·P is the same for all of them (P = depth · ray).
    let cfg = SceneConfig {
        objects: [0, 0],
        thin_structures: [0, 0],
        slanted_planes: [0, 0],
        wall_items: [0, 0],
        glass_prob: 0.0,
        mirror_prob: 0.0,
        dark_prob: 0.0,
        opening_prob: 0.0,
        ..SceneConfig::default()
    };
    for seed in 0..3 {
        let f = render_scene(&cfg, seed, camera_near(seed, W, H, 63.0));
        check_invariants(&f);
        let mut planes: Vec<([f32; 3], f32)> = vec![];
        for i in 0..f.depth_m.len() {
            let n = f.normals[i];
            let v = ray(&f, i);
            let p = [v[0] * f.depth_m[i], v[1] * f.depth_m[i], f.depth_m[i]];
            let dist = n[0] * p[0] + n[1] * p[1] + n[2] * p[2];
            match planes.iter().find(|(m, _)| {
                (m[0] - n[0]).abs() + (m[1] - n[1]).abs() + (m[2] - n[2]).abs() < 1e-3
            }) {
                Some((_, d0)) => assert!(
                    (dist - d0).abs() < 2e-3 * d0.abs().max(1.0),
                    "seed {seed} px {i}: {dist} vs {d0}"
                ),
                None => planes.push((n, dist)),
            }
        }
        assert!((2..=6).contains(&planes.len()), "{} planes", planes.len());
        assert!(f.labels.iter().all(|&l| l == 0));
    }
}

#[test]
fn hard_cases_occur_often_enough() {
    let scenes = 50;
    let (mut far, mut glass, mut mirror, mut dark) = (0, 0, 0, 0);
    for seed in 0..scenes {
        let f = frame(1000 + seed);
        check_invariants(&f);
        let n = f.labels.len();
        let count = |l: u8| f.labels.iter().filter(|&&v| v == l).count();
        // A "region": at least 1 % of the image.
        far += usize::from(f.depth_m.iter().filter(|&&d| d > 6.0).count() * 100 >= n);
        glass += usize::from(count(1) * 100 >= n);
        mirror += usize::from(count(2) * 100 >= n);
        dark += usize::from(count(3) * 100 >= n);
    }
    println!("of {scenes} scenes: far {far}, glass {glass}, mirror {mirror}, dark {dark}");
    assert!(far >= 18, "scenes with >6 m regions: {far}/{scenes}");
    assert!(glass >= 15, "scenes with glass: {glass}/{scenes}");
    assert!(mirror >= 9, "scenes with mirrors: {mirror}/{scenes}");
    assert!(dark >= 17, "scenes with dark objects: {dark}/{scenes}");
}
