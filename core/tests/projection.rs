//! Projection: hand-computed cases (expected values worked out in the comments, checked with
//! plain f64 arithmetic, never with the code under test), skip accounting, errors, and a
//! property test over random and garbage calibrations and measurements.

use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};
use depthor_core::hal::ZoneView;
use depthor_core::projection::{
    for_each_point, project_to_sparse, project_zone, zone_ray, ProjectedPoint, ProjectionError,
    ProjectionStats, Skip,
};
use proptest::prelude::*;

const PX_TOL: f64 = 1e-4;

/// 640×480 camera, fx = fy = 200, principal point at the centre (320, 240).
fn camera() -> CameraIntrinsics {
    CameraIntrinsics {
        width: 640,
        height: 480,
        fx: 200.0,
        fy: 200.0,
        cx: 320.0,
        cy: 240.0,
    }
}

/// 2×2 zones over 90°×90°: tan(45°) = 1, so the zone rays are (±0.5, ±0.5, 1):
/// zone 0 (−0.5, −0.5), zone 1 (+0.5, −0.5), zone 2 (−0.5, +0.5), zone 3 (+0.5, +0.5).
fn cal_2x2(distance: DistanceKind, extrinsics: Extrinsics) -> Calibration<'static> {
    Calibration {
        camera: camera(),
        dtof: DtofGeometry {
            rows: 2,
            cols: 2,
            fov_deg: [90.0, 90.0],
            distance,
            max_range_m: 4.0,
        },
        dtof_to_camera: extrinsics,
        zone_rects_px: None,
    }
}

fn view<'a>(rows: u16, cols: u16, d: &'a [f32], s: &'a [u8]) -> ZoneView<'a> {
    ZoneView {
        rows,
        cols,
        distance_mm: d,
        status: s,
    }
}

fn assert_point(p: &ProjectedPoint, u: f64, v: f64, depth: f64) {
    assert!(
        (f64::from(p.u) - u).abs() < PX_TOL,
        "u {} vs {u} (zone {})",
        p.u,
        p.zone
    );
    assert!(
        (f64::from(p.v) - v).abs() < PX_TOL,
        "v {} vs {v} (zone {})",
        p.v,
        p.zone
    );
    assert!(
        (f64::from(p.depth_m) - depth).abs() < 1e-6 * depth.max(1.0),
        "depth {} vs {depth}",
        p.depth_m
    );
    assert_eq!(p.x, (u + 0.5).floor() as u32);
    assert_eq!(p.y, (v + 0.5).floor() as u32);
}

#[test]
fn zone_rays_on_the_tangent_grid() {
    // 3 rows × 4 cols over [60°, 45°]: tan 30° = 1/√3, tan 22.5° = √2 − 1.
    // Zone 9 = (r 2, c 1): tx = (1/√3)(2·1.5/4 − 1) = −0.25/√3, ty = (√2 − 1)(2·2.5/3 − 1)
    // = (√2 − 1)·2/3.
    let mut cal = cal_2x2(DistanceKind::Z, Extrinsics::IDENTITY);
    cal.dtof.rows = 3;
    cal.dtof.cols = 4;
    cal.dtof.fov_deg = [60.0, 45.0];
    let r = zone_ray(&cal, 9).unwrap();
    let tx = -0.25 / 3f64.sqrt();
    let ty = (2f64.sqrt() - 1.0) * 2.0 / 3.0;
    assert!((f64::from(r[0]) - tx).abs() < 1e-7, "{r:?}");
    assert!((f64::from(r[1]) - ty).abs() < 1e-7, "{r:?}");
    assert_eq!(r[2], 1.0);
    // Zone 0 is top-left: both components negative.
    let r0 = zone_ray(&cal, 0).unwrap();
    assert!(r0[0] < 0.0 && r0[1] < 0.0);
    assert_eq!(zone_ray(&cal, 12), None);
    cal.dtof.fov_deg = [f32::NAN, 45.0];
    assert_eq!(zone_ray(&cal, 0), None);
    cal.dtof.fov_deg = [180.0, 45.0];
    assert_eq!(zone_ray(&cal, 0), None);
}

#[test]
fn identity_extrinsics_z_distance() {
    // P = 2·(tx, ty, 1); u = 200·tx + 320, v = 200·ty + 240; depth = 2.
    // zone 0: (220, 140), zone 1: (420, 140), zone 2: (220, 340), zone 3: (420, 340).
    let cal = cal_2x2(DistanceKind::Z, Extrinsics::IDENTITY);
    let want = [
        (220.0, 140.0),
        (420.0, 140.0),
        (220.0, 340.0),
        (420.0, 340.0),
    ];
    for (zone, &(u, v)) in want.iter().enumerate() {
        let p = project_zone(&cal, zone, 2000.0).unwrap();
        assert_eq!(p.zone as usize, zone);
        assert_point(&p, u, v, 2.0);
    }
}

#[test]
fn translated_sensor() {
    // t = (0.1, −0.05, 0.02) m, zone 0 at 2000 mm (z): P = (−1, −1, 2) → Q = (−0.9, −1.05, 2.02).
    // u = 320 − 200·0.9/2.02 = 230.891089…, v = 240 − 200·1.05/2.02 = 136.039603…, depth 2.02;
    // pixel (231, 136).
    let ext = Extrinsics {
        rotation: Extrinsics::IDENTITY.rotation,
        translation_m: [0.1, -0.05, 0.02],
    };
    let cal = cal_2x2(DistanceKind::Z, ext);
    let p = project_zone(&cal, 0, 2000.0).unwrap();
    assert_point(&p, 320.0 - 180.0 / 2.02, 240.0 - 210.0 / 2.02, 2.02);
    assert_eq!((p.x, p.y), (231, 136));
}

#[test]
fn rotated_sensor() {
    // Rotation about y with cos = 0.8, sin = 0.6: R = [[0.8, 0, 0.6], [0, 1, 0], [−0.6, 0, 0.8]].
    // Zone 0 at 1000 mm (z): P = (−0.5, −0.5, 1) → Q = (−0.4 + 0.6, −0.5, 0.3 + 0.8)
    // = (0.2, −0.5, 1.1): u = 320 + 200·0.2/1.1 = 356.3636…, v = 240 − 100/1.1 = 149.0909…
    // Zone 3: P = (0.5, 0.5, 1) → Q = (1.0, 0.5, 0.5): u = 720 ≥ 640 → out of image.
    let ext = Extrinsics {
        rotation: [[0.8, 0.0, 0.6], [0.0, 1.0, 0.0], [-0.6, 0.0, 0.8]],
        translation_m: [0.0; 3],
    };
    let cal = cal_2x2(DistanceKind::Z, ext);
    let p = project_zone(&cal, 0, 1000.0).unwrap();
    assert_point(&p, 320.0 + 40.0 / 1.1, 240.0 - 100.0 / 1.1, 1.1);
    assert_eq!(project_zone(&cal, 3, 1000.0), Err(Skip::OutOfImage));
}

#[test]
fn radial_versus_z() {
    // Radial 3000 mm along (−0.5, −0.5, 1), |ray| = √1.5: P = (3/√1.5)·(−0.5, −0.5, 1)
    // = (−1.2247449, −1.2247449, 2.4494897). With identity extrinsics the pixel is the same as
    // for z (220, 140) and the depth is 3/√1.5 = 2.4494897 instead of 3.
    let z = project_zone(&cal_2x2(DistanceKind::Z, Extrinsics::IDENTITY), 0, 3000.0).unwrap();
    assert_point(&z, 220.0, 140.0, 3.0);
    let radial = cal_2x2(DistanceKind::Radial, Extrinsics::IDENTITY);
    let r = project_zone(&radial, 0, 3000.0).unwrap();
    let s = 3.0 / 1.5f64.sqrt();
    assert_point(&r, 220.0, 140.0, s);
    // With t = (0.1, −0.05, 0.02) the pixel now depends on the scale:
    // Q = (−0.5s + 0.1, −0.5s − 0.05, s + 0.02).
    let ext = Extrinsics {
        rotation: Extrinsics::IDENTITY.rotation,
        translation_m: [0.1, -0.05, 0.02],
    };
    let r = project_zone(&cal_2x2(DistanceKind::Radial, ext), 0, 3000.0).unwrap();
    let q = [-0.5 * s + 0.1, -0.5 * s - 0.05, s + 0.02];
    assert_point(
        &r,
        200.0 * q[0] / q[2] + 320.0,
        200.0 * q[1] / q[2] + 240.0,
        q[2],
    );
}

#[test]
fn zone_rects_use_rect_centres() {
    // Rect [y0, x0, y1, x1] = [10, 20, 30, 60] → (u, v) = (40, 20), pixel (40, 20).
    // z: depth = 2 m. Radial: camera ray ((40 − 320)/200, (20 − 240)/200, 1) = (−1.4, −1.1, 1),
    // |ray| = √4.17, depth = 2/√4.17 = 0.979404…
    // Extrinsics and FoV are unused: NaN there must not matter.
    let rects = [[10.0, 20.0, 30.0, 60.0]];
    let mut cal = Calibration {
        camera: camera(),
        dtof: DtofGeometry {
            rows: 1,
            cols: 1,
            fov_deg: [f32::NAN, 0.0],
            distance: DistanceKind::Z,
            max_range_m: 4.0,
        },
        dtof_to_camera: Extrinsics {
            rotation: [[f32::NAN; 3]; 3],
            translation_m: [f32::INFINITY; 3],
        },
        zone_rects_px: Some(&rects),
    };
    assert_point(&project_zone(&cal, 0, 2000.0).unwrap(), 40.0, 20.0, 2.0);
    cal.dtof.distance = DistanceKind::Radial;
    assert_point(
        &project_zone(&cal, 0, 2000.0).unwrap(),
        40.0,
        20.0,
        2.0 / 4.17f64.sqrt(),
    );
}

#[test]
fn pixel_rounding_and_image_border() {
    // Pixel centres at integers: x = floor(u + 0.5). u = 219.5 → 220; u = −0.5 → 0 (inside);
    // u = 639.5 → 640 (outside a 640-wide image); v = 479.49 → 479.
    type Pixel = Result<(u32, u32), Skip>;
    let cases: [([f32; 4], Pixel); 5] = [
        ([0.0, 0.0, 0.0, 439.0], Ok((220, 0))),
        ([0.0, -0.5, 0.0, -0.5], Ok((0, 0))),
        ([0.0, -0.6, 0.0, -0.6], Err(Skip::OutOfImage)),
        ([0.0, 639.5, 0.0, 639.5], Err(Skip::OutOfImage)),
        ([479.49, 0.0, 479.49, 0.0], Ok((0, 479))),
    ];
    for (rect, want) in cases {
        let rects = [rect];
        let cal = Calibration {
            camera: camera(),
            dtof: DtofGeometry {
                rows: 1,
                cols: 1,
                fov_deg: [45.0, 45.0],
                distance: DistanceKind::Z,
                max_range_m: 4.0,
            },
            dtof_to_camera: Extrinsics::IDENTITY,
            zone_rects_px: Some(&rects),
        };
        let got = project_zone(&cal, 0, 1000.0).map(|p| (p.x, p.y));
        assert_eq!(got, want, "rect {rect:?}");
    }
}

#[test]
fn collision_keeps_the_nearer_point() {
    // Three zones on one pixel (rect centre (100, 50)) at 2.0, 1.5 and 1.8 m, a fourth elsewhere.
    let rects = [
        [50.0, 100.0, 50.0, 100.0],
        [40.0, 90.0, 60.0, 110.0],
        [50.0, 100.0, 50.0, 100.0],
        [10.0, 10.0, 10.0, 10.0],
    ];
    let cal = Calibration {
        camera: camera(),
        dtof: DtofGeometry {
            rows: 2,
            cols: 2,
            fov_deg: [45.0, 45.0],
            distance: DistanceKind::Z,
            max_range_m: 4.0,
        },
        dtof_to_camera: Extrinsics::IDENTITY,
        zone_rects_px: Some(&rects),
    };
    let d = [2000.0, 1500.0, 1800.0, 1000.0];
    let s = [5, 9, 5, 5];
    let mut out = vec![7.0f32; 640 * 480];
    let stats = project_to_sparse(&cal, &view(2, 2, &d, &s), &mut out).unwrap();
    assert_eq!(out[50 * 640 + 100], 1.5);
    assert_eq!(out[10 * 640 + 10], 1.0);
    assert_eq!(out.iter().filter(|&&v| v != 0.0).count(), 2, "zero-filled");
    assert_eq!(
        stats,
        ProjectionStats {
            zones: 4,
            projected: 4,
            collisions: 2,
            ..Default::default()
        }
    );
}

#[test]
fn garbage_is_counted_not_projected() {
    // Statuses: 5 valid, 255 no target, 9 valid, 5 valid, 0 invalid, 5 valid.
    // Distances: NaN, 1000 (but status 255), −5, +inf, 1000 (status 0), 1e30 mm.
    let cal = Calibration {
        dtof: DtofGeometry {
            rows: 2,
            cols: 3,
            fov_deg: [30.0, 30.0],
            distance: DistanceKind::Z,
            max_range_m: 4.0,
        },
        ..cal_2x2(DistanceKind::Z, Extrinsics::IDENTITY)
    };
    let d = [f32::NAN, 1000.0, -5.0, f32::INFINITY, 1000.0, 1e30];
    let s = [5, 255, 9, 5, 0, 5];
    let mut points = 0;
    let stats = for_each_point(&cal, &view(2, 3, &d, &s), |_| points += 1).unwrap();
    // 1e30 mm is a valid (absurd) distance: not clipped at max_range here, and in view.
    assert_eq!(points, 1);
    assert_eq!(
        stats,
        ProjectionStats {
            zones: 6,
            projected: 1,
            invalid_status: 2,
            bad_distance: 3,
            ..Default::default()
        }
    );
    // Behind the camera: t_z = −5 m puts a 1 m point at Z = −4.
    let behind = Calibration {
        dtof_to_camera: Extrinsics {
            rotation: Extrinsics::IDENTITY.rotation,
            translation_m: [0.0, 0.0, -5.0],
        },
        ..cal
    };
    let stats = for_each_point(&behind, &view(2, 3, &[1000.0; 6], &[5; 6]), |_| {}).unwrap();
    assert_eq!(stats.behind_camera, 6);
    assert_eq!(stats.projected + stats.skipped(), 6);
}

#[test]
fn errors_are_reported() {
    let cal = cal_2x2(DistanceKind::Z, Extrinsics::IDENTITY);
    let d = [1000.0; 4];
    let s = [5; 4];
    let mut out = vec![0.0f32; 640 * 480];
    assert_eq!(
        project_to_sparse(&cal, &view(2, 2, &d[..3], &s[..3]), &mut out),
        Err(ProjectionError::ZoneCountMismatch {
            expected: 4,
            got: 3
        })
    );
    assert_eq!(
        project_to_sparse(&cal, &view(2, 2, &d, &s[..2]), &mut out),
        Err(ProjectionError::ZoneCountMismatch {
            expected: 4,
            got: 2
        })
    );
    // Same count, transposed shape.
    assert!(matches!(
        project_to_sparse(&cal, &view(1, 4, &d, &s), &mut out),
        Err(ProjectionError::ZoneCountMismatch { .. })
    ));
    assert_eq!(
        project_to_sparse(&cal, &view(2, 2, &d, &s), &mut out[..10]),
        Err(ProjectionError::OutputSize {
            expected: 640 * 480,
            got: 10
        })
    );
    let bad = |f: &dyn Fn(&mut Calibration<'static>)| {
        let mut c = cal;
        f(&mut c);
        let r = project_to_sparse(&c, &view(2, 2, &d, &s), &mut out.clone());
        assert!(
            matches!(r, Err(ProjectionError::BadCalibration(_))),
            "{r:?}"
        );
        // project_zone has no error channel: it says OutOfImage.
        assert_eq!(project_zone(&c, 0, 1000.0), Err(Skip::OutOfImage));
    };
    bad(&|c| c.camera.fx = 0.0);
    bad(&|c| c.camera.fy = f32::NAN);
    bad(&|c| c.camera.cx = f32::INFINITY);
    bad(&|c| c.camera.width = 0);
    bad(&|c| c.dtof.fov_deg[1] = -1.0);
    bad(&|c| c.dtof_to_camera.translation_m[2] = f32::NAN);
    static SHORT: [[f32; 4]; 3] = [[0.0; 4]; 3];
    bad(&|c| c.zone_rects_px = Some(&SHORT));
    let msg = ProjectionError::BadCalibration("x").to_string();
    assert!(msg.contains("bad calibration"), "{msg}");
}

fn special_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(0.0),
        Just(-0.0),
        Just(1e30),
        Just(-1e30),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
        any::<f32>(),
        -1000.0f32..1000.0,
        0.0f32..5000.0,
    ]
}

/// Mostly a sane value from `range`, sometimes garbage.
fn sane_or_special(range: std::ops::Range<f32>) -> impl Strategy<Value = f32> {
    prop_oneof![8 => range, 1 => special_f32()]
}

fn arb_calibration() -> impl Strategy<Value = (CameraIntrinsics, DtofGeometry, Extrinsics, bool)> {
    let cam = (
        prop_oneof![1 => Just(0u32), 15 => 1u32..200],
        prop_oneof![1 => Just(0u32), 15 => 1u32..200],
        sane_or_special(20.0..200.0),
        sane_or_special(20.0..200.0),
        sane_or_special(0.0..200.0),
        sane_or_special(0.0..200.0),
    )
        .prop_map(|(width, height, fx, fy, cx, cy)| CameraIntrinsics {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        });
    let geo = (
        prop_oneof![1 => Just(0u16), 10 => 1u16..7],
        prop_oneof![1 => Just(0u16), 10 => 1u16..7],
        sane_or_special(10.0..100.0),
        sane_or_special(10.0..100.0),
        any::<bool>(),
    )
        .prop_map(|(rows, cols, h, v, radial)| DtofGeometry {
            rows,
            cols,
            fov_deg: [h, v],
            distance: if radial {
                DistanceKind::Radial
            } else {
                DistanceKind::Z
            },
            max_range_m: 4.0,
        });
    let ext = (
        proptest::array::uniform3(proptest::array::uniform3(prop_oneof![
            20 => -0.3f32..0.3,
            1 => special_f32()
        ])),
        proptest::array::uniform3(sane_or_special(-0.5..0.5)),
    )
        .prop_map(|(perturbation, translation_m)| {
            // Near-identity rotations (perturbed, not orthonormal: projection does not care).
            let mut rotation = Extrinsics::IDENTITY.rotation;
            for (row, prow) in rotation.iter_mut().zip(perturbation) {
                for (r, p) in row.iter_mut().zip(prow) {
                    *r += p;
                }
            }
            Extrinsics {
                rotation,
                translation_m,
            }
        });
    (cam, geo, ext, any::<bool>())
}

static PROPTEST_CASES: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
static PROJECTED_CASES: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);

/// The property test must exercise the projecting path, not only the error paths.
#[test]
fn property_test_reaches_projected_points() {
    never_panics_and_stats_add_up();
    let all = PROPTEST_CASES.load(std::sync::atomic::Ordering::Relaxed);
    let hit = PROJECTED_CASES.load(std::sync::atomic::Ordering::Relaxed);
    eprintln!("{hit} of {all} cases projected points");
    assert!(hit * 20 >= all, "{hit} of {all}");
}

proptest! {
    #[test]
    fn never_panics_and_stats_add_up(
        (camera, dtof, ext, use_rects) in arb_calibration(),
        data in proptest::collection::vec(
            (
                sane_or_special(100.0..5000.0),
                any::<u8>(),
                proptest::array::uniform4(sane_or_special(-10.0..210.0)),
            ),
            0..50,
        ),
        mutate in proptest::bool::weighted(0.1),
    ) {
        PROPTEST_CASES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let n = dtof.zones();
        let mut d: Vec<f32> = data.iter().map(|x| x.0).cycle().take(if data.is_empty() { 0 } else { n }).collect();
        // Bias statuses towards valid so distances get exercised.
        let mut s: Vec<u8> = data.iter().map(|x| if x.1 < 128 { 5 } else { x.1 }).cycle().take(d.len()).collect();
        let rects: Vec<[f32; 4]> = data.iter().map(|x| x.2).cycle().take(d.len()).collect();
        if mutate && !d.is_empty() {
            d.pop();
            s.pop();
        }
        let cal = Calibration {
            camera,
            dtof,
            dtof_to_camera: ext,
            zone_rects_px: use_rects.then_some(&rects[..]),
        };
        let zones = view(dtof.rows, dtof.cols, &d, &s);
        let mut out = vec![-1.0f32; camera.width as usize * camera.height as usize];
        let mut points = Vec::new();
        let each = for_each_point(&cal, &zones, |p| points.push(p));
        match project_to_sparse(&cal, &zones, &mut out) {
            Ok(stats) => {
                if stats.projected > 0 {
                    PROJECTED_CASES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
                prop_assert_eq!(stats.zones as usize, n);
                prop_assert_eq!(stats.projected + stats.skipped(), stats.zones);
                let each = each.unwrap();
                prop_assert_eq!(each.projected, stats.projected);
                prop_assert_eq!(points.len() as u32, stats.projected);
                let filled = out.iter().filter(|&&v| v != 0.0).count() as u32;
                prop_assert_eq!(filled, stats.projected - stats.collisions);
                prop_assert!(out.iter().all(|&v| v == 0.0 || (v.is_finite() && v > 0.0)));
                for p in &points {
                    prop_assert!(p.x < camera.width && p.y < camera.height);
                    prop_assert!(p.depth_m.is_finite() && p.depth_m > 0.0);
                    prop_assert_eq!(project_zone(&cal, p.zone as usize, d[p.zone as usize]), Ok(*p));
                }
            }
            Err(e) => {
                let size_error = matches!(e, ProjectionError::OutputSize { .. });
                prop_assert!(each.is_err() || size_error);
                prop_assert!(points.is_empty() || each.is_ok());
                // Failure leaves the buffer untouched.
                prop_assert!(out.iter().all(|&v| v == -1.0));
            }
        }
        for zone in 0..n + 2 {
            let _ = zone_ray(&cal, zone);
            let _ = project_zone(&cal, zone, d.get(zone).copied().unwrap_or(f32::NAN));
        }
    }
}
