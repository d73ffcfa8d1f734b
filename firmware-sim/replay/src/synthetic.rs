//! Deterministic synthetic frames for the `mcu` layout (120×160 RGB, 8×8 zones), used by the
//! `make-image` tool and the tests until `depthor firmware-image` converts real recordings.
//!
//! The content is chosen to exercise every projection path, not to look like a room: a tilted
//! plane with a nearer box, valid statuses 5 and 9, "no target" (255), an invalid status (4), a
//! zero distance and a distance beyond the sensor's range, all moving from frame to frame.

use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};

use crate::writer::FrameData;

/// Image height of the `mcu` variant (docs/design.md, model variants).
pub const MCU_HEIGHT: u32 = 120;
/// Image width of the `mcu` variant.
pub const MCU_WIDTH: u32 = 160;
/// Zone rows and columns of the `mcu` variant (VL53L5CX class, 8×8).
pub const MCU_ZONES: u16 = 8;

/// A made-up `mcu` calibration (not a measured one): 160×120 camera with `fx = fy = 140` px,
/// 8×8 zones over 45°×45° (VL53L5CX datasheet FoV), z distances up to 4 m, and a sensor 12 mm
/// to the right of the camera, turned 0.5° about y and 0.3° about x so that the rigid
/// transform is not trivial.
pub fn mcu_calibration() -> Calibration<'static> {
    let (ay, ax) = (0.5f64.to_radians(), 0.3f64.to_radians());
    let (sy, cy) = ay.sin_cos();
    let (sx, cx) = ax.sin_cos();
    // R = R_y(ay) · R_x(ax)
    let r = [
        [cy, sy * sx, sy * cx],
        [0.0, cx, -sx],
        [-sy, cy * sx, cy * cx],
    ];
    Calibration {
        camera: CameraIntrinsics {
            width: MCU_WIDTH,
            height: MCU_HEIGHT,
            fx: 140.0,
            fy: 140.0,
            cx: 79.5,
            cy: 59.5,
        },
        dtof: DtofGeometry {
            rows: MCU_ZONES,
            cols: MCU_ZONES,
            fov_deg: [45.0, 45.0],
            distance: DistanceKind::Z,
            max_range_m: 4.0,
        },
        dtof_to_camera: Extrinsics {
            rotation: r.map(|row| row.map(|v| v as f32)),
            translation_m: [0.012, 0.0, 0.0],
        },
        zone_rects_px: None,
    }
}

/// Frame `index` for a `rows × cols` grid and an `h × w` image.
pub fn frame(index: u32, rows: u16, cols: u16, h: u32, w: u32) -> FrameData {
    let (rows, cols) = (usize::from(rows), usize::from(cols));
    let zones = rows * cols;
    let k = index as i32;
    let mut distance_mm = Vec::with_capacity(zones);
    let mut status = Vec::with_capacity(zones);
    for z in 0..zones {
        let (r, c) = ((z / cols) as i32, (z % cols) as i32);
        let in_box = (2..5).contains(&r) && (3 + k % 3..6 + k % 3).contains(&c);
        let d = if in_box {
            600 + 15 * k + 7 * c
        } else {
            900 + 40 * r + 25 * c + 60 * k
        };
        distance_mm.push(d as i16);
        status.push(if (z + index as usize).is_multiple_of(5) {
            9
        } else {
            5
        });
    }
    if zones > 0 {
        let pick = |salt: usize| (index as usize * 7 + salt) % zones;
        status[pick(1)] = 255;
        status[pick(3)] = 4;
        distance_mm[pick(5)] = 0;
        distance_mm[pick(11)] = 12_000;
    }
    let mut rgb = Vec::with_capacity(3 * (h * w) as usize);
    for y in 0..h {
        for x in 0..w {
            // 8×8-pixel blocks: a colour ramp and a checkerboard moving one block per frame
            // (blocky, so the committed default image compresses well in git).
            let (bx, by) = (x / 8, y / 8);
            rgb.push((bx * 12 % 256) as u8);
            rgb.push((by * 16 % 256) as u8);
            rgb.push(if (bx + by + index).is_multiple_of(2) {
                40
            } else {
                220
            });
        }
    }
    FrameData {
        rgb,
        distance_mm,
        status,
    }
}

/// `n` frames at the [`mcu_calibration`] sizes.
pub fn mcu_frames(n: u32) -> Vec<FrameData> {
    (0..n)
        .map(|i| frame(i, MCU_ZONES, MCU_ZONES, MCU_HEIGHT, MCU_WIDTH))
        .collect()
}
