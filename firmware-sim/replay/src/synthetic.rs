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

/// Largest distance the VL53L5CX path carries: mm × 4 in an `i16` saturates at 8 191 mm.
pub const VL53_MAX_MM: i16 = 8191;

/// A deterministic xorshift32 stream (the adversarial frames' "random" content).
struct XorShift(u32);

impl XorShift {
    fn next(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }
}

/// RGB888 of `h × w` pixels, every byte `v`.
fn flat_rgb(h: u32, w: u32, v: u8) -> Vec<u8> {
    vec![v; 3 * (h * w) as usize]
}

/// The adversarial frames of the frame-time check (firmware-sim README, "Frame time on
/// adversarial frames"), each with its name, at the [`mcu_calibration`] sizes (120×160 RGB,
/// 8×8 zones): first the five frames of the default image ([`mcu_frames`]`(5)`, so their hash
/// lines equal the default run's), then the extremes a sensor can deliver through the image
/// format (its `i16` millimetres cannot hold NaN or infinity):
///
/// - `no_target`: every zone status 255 at 0 mm; `invalid_status`: every zone status 4 with
///   normal distances (both leave no valid zone: the core refuses the frame and the model does
///   not run);
/// - `one_zone`: a single valid zone, the rest "no target";
/// - `max_range`: every zone valid at the calibration's maximum range (4 m);
/// - `min_max`: a checkerboard of 1 mm and 4 m; `saturated`: every zone at 8 191 mm, the largest
///   the VL53L5CX path carries; `extreme`: rows of `i16::MAX`, 8 191, 1 mm and `i16::MIN`;
/// - `white` and `black`: saturated (255) and black (0) RGB over the first default frame's zones;
/// - `random_0` … `random_2`: uniformly random RGB bytes and random zones (0–8 191 mm,
///   statuses 5, 9, 255 and 4).
pub fn adversarial_frames() -> Vec<(&'static str, FrameData)> {
    let (h, w) = (MCU_HEIGHT, MCU_WIDTH);
    let zones = usize::from(MCU_ZONES) * usize::from(MCU_ZONES);
    let base = frame(0, MCU_ZONES, MCU_ZONES, h, w);
    let with_zones = |distance_mm: Vec<i16>, status: Vec<u8>| FrameData {
        rgb: base.rgb.clone(),
        distance_mm,
        status,
    };
    let mut out: Vec<(&'static str, FrameData)> = ["normal_0", "normal_1", "normal_2"]
        .into_iter()
        .chain(["normal_3", "normal_4"])
        .zip(mcu_frames(5))
        .collect();
    out.push(("no_target", with_zones(vec![0; zones], vec![255; zones])));
    out.push((
        "invalid_status",
        with_zones(base.distance_mm.clone(), vec![4; zones]),
    ));
    let mut one = vec![255u8; zones];
    one[27] = 5;
    out.push(("one_zone", with_zones(vec![1500; zones], one)));
    out.push(("max_range", with_zones(vec![4000; zones], vec![5; zones])));
    let checker = (0..zones)
        .map(|z| if (z / 8 + z % 8) % 2 == 0 { 1 } else { 4000 })
        .collect();
    out.push(("min_max", with_zones(checker, vec![5; zones])));
    out.push((
        "saturated",
        with_zones(vec![VL53_MAX_MM; zones], vec![5; zones]),
    ));
    let extreme = (0..zones)
        .map(|z| [i16::MAX, VL53_MAX_MM, 1, i16::MIN][(z / 8) % 4])
        .collect();
    out.push(("extreme", with_zones(extreme, vec![9; zones])));
    for (name, v) in [("white", 255u8), ("black", 0)] {
        out.push((
            name,
            FrameData {
                rgb: flat_rgb(h, w, v),
                ..base.clone()
            },
        ));
    }
    let mut rng = XorShift(0x4445_5054);
    for name in ["random_0", "random_1", "random_2"] {
        let rgb = (0..3 * h * w).map(|_| rng.next() as u8).collect();
        let distance_mm = (0..zones)
            .map(|_| (rng.next() % (VL53_MAX_MM as u32 + 1)) as i16)
            .collect();
        let status = (0..zones)
            .map(|_| [5, 9, 255, 4][(rng.next() % 4) as usize])
            .collect();
        out.push((
            name,
            FrameData {
                rgb,
                distance_mm,
                status,
            },
        ));
    }
    out
}
