//! Fuzzes zone frames into the projection (`zone_ray`, `project_zone`, `for_each_point`,
//! `project_to_sparse`) with an arbitrary calibration: any `f32` bit pattern in the intrinsics,
//! field of view, range, rotation, translation, zone rectangles and distances, any status byte,
//! grids up to 16×16 and images up to 255×255, views whose shape or length disagree with the
//! calibration, output buffers of the wrong length.
//!
//! Input: `rows, cols, kind, flags, width, height, 19 × f32 calibration, per zone: f32
//! distance, u8 status, [4 × f32 rectangle]` (missing bytes read as 0). `flags` bit 0: zone
//! rectangles; bit 1: a view of another shape; bit 2: one zone short; bit 3: an output one
//! longer.
//!
//! Checks the module's promises: nothing panics; `projected` plus the skips equal `zones`;
//! every point lies inside the image with a finite depth > 0; `project_to_sparse` writes only
//! 0 or such depths and nothing at all when it fails; `project_zone` agrees with
//! `for_each_point`.
#![no_main]

#[path = "common.rs"]
mod common;

use common::Bytes;
use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};
use depthor_core::hal::{status_is_valid, ZoneView};
use depthor_core::projection::{for_each_point, project_to_sparse, project_zone, zone_ray};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    let mut b = Bytes::new(input);
    let (rows, cols) = (u16::from(b.u8() % 17), u16::from(b.u8() % 17));
    let distance = if b.u8() & 1 == 0 {
        DistanceKind::Z
    } else {
        DistanceKind::Radial
    };
    let flags = b.u8();
    let (width, height) = (u32::from(b.u8()), u32::from(b.u8()));
    let mut f = [0f32; 19];
    for v in &mut f {
        *v = b.f32();
    }
    let zones = usize::from(rows) * usize::from(cols);
    let mut distance_mm = Vec::with_capacity(zones);
    let mut status = Vec::with_capacity(zones);
    let mut rects = Vec::new();
    for _ in 0..zones {
        distance_mm.push(b.f32());
        status.push(b.u8());
        if flags & 1 != 0 {
            rects.push([b.f32(), b.f32(), b.f32(), b.f32()]);
        }
    }
    let cal = Calibration {
        camera: CameraIntrinsics {
            width,
            height,
            fx: f[0],
            fy: f[1],
            cx: f[2],
            cy: f[3],
        },
        dtof: DtofGeometry {
            rows,
            cols,
            fov_deg: [f[4], f[5]],
            distance,
            max_range_m: f[6],
        },
        dtof_to_camera: Extrinsics {
            rotation: [
                [f[7], f[8], f[9]],
                [f[10], f[11], f[12]],
                [f[13], f[14], f[15]],
            ],
            translation_m: [f[16], f[17], f[18]],
        },
        zone_rects_px: (flags & 1 != 0).then_some(&rects[..]),
    };
    let (mut view_rows, view_cols) = (rows, cols);
    if flags & 2 != 0 {
        view_rows = view_rows.wrapping_add(1);
    }
    let short = usize::from(flags & 4 != 0);
    let view = ZoneView {
        rows: view_rows,
        cols: view_cols,
        distance_mm: &distance_mm[..zones.saturating_sub(short)],
        status: &status,
    };

    for zone in 0..=zones {
        let _ = zone_ray(&cal, zone);
    }
    let mut seen = Vec::new();
    let result = for_each_point(&cal, &view, |p| seen.push(p));
    if let Ok(stats) = result {
        assert_eq!(stats.zones as usize, zones);
        assert_eq!(stats.projected + stats.skipped(), stats.zones);
        assert_eq!(stats.projected as usize, seen.len());
        assert_eq!(stats.collisions, 0);
        for p in &seen {
            assert!(
                p.x < width && p.y < height,
                "{p:?} outside {width}×{height}"
            );
            assert!(p.depth_m.is_finite() && p.depth_m > 0.0, "{p:?}");
            let z = usize::from(p.zone);
            assert!(status_is_valid(status[z]));
            assert_eq!(project_zone(&cal, z, distance_mm[z]), Ok(*p));
        }
    } else {
        assert!(seen.is_empty(), "points reported before an error");
    }

    let len = width as usize * height as usize + usize::from(flags & 8 != 0);
    let mut out = vec![-7.0f32; len];
    match project_to_sparse(&cal, &view, &mut out) {
        Ok(stats) => {
            assert_eq!(Ok(stats.projected), result.map(|s| s.projected));
            assert!(stats.collisions <= stats.projected);
            let written = out.iter().filter(|&&v| v != 0.0).count();
            assert_eq!(written as u32, stats.projected - stats.collisions);
            assert!(out.iter().all(|&v| v == 0.0 || (v.is_finite() && v > 0.0)));
        }
        Err(_) => assert!(out.iter().all(|&v| v == -7.0), "output touched on error"),
    }
});
