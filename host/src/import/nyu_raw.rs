//! The raw NYU Depth v2 Kinect frame of Open3D's test data: `other_formats/NYU_color.ppm`
//! (8-bit RGB) and `other_formats/NYU_depth.pgm` (16-bit raw Kinect v1 disparity, 11 bits used,
//! 2047 = no reading), converted with the NYU toolbox's `depth = 351.3 / (1092.5 − raw)` metres.
//!
//! The Netpbm spec makes 16-bit PGM samples big-endian, and `image` decodes them so; this file
//! was written little-endian (README: "PIL reads big-endian → byte-swap"). The loader picks the
//! byte order in which every sample fits the 11-bit Kinect range and notes which it used.

use std::path::Path;

use depthor_core::calibration::CameraIntrinsics;

use super::decode::{check_size, read_rgb, read_u16_grey};
use super::resample::depth_at_rgb_size;
use super::{ImportError, ImportedFrame, Loaded};

/// NYU Depth v2 colour camera intrinsics at 640×480 (NYU toolbox `camera_params.m`:
/// fx_rgb 518.8579, fy_rgb 519.4696, cx_rgb 325.5824, cy_rgb 253.7362).
pub(crate) const NYU_RGB: CameraIntrinsics = CameraIntrinsics {
    width: 640,
    height: 480,
    fx: 518.857_9,
    fy: 519.469_6,
    cx: 325.582_45,
    cy: 253.736_17,
};

/// Largest raw Kinect v1 disparity; it also marks "no reading".
const RAW_INVALID: u16 = 2047;
/// NYU toolbox disparity-to-depth constants: `depth_m = A / (B − raw)`.
const A: f32 = 351.3;
/// See [`A`].
const B: f32 = 1092.5;

/// Depth in metres of one raw Kinect disparity; 0 for 2047 and for non-positive depths.
pub(crate) fn depth_from_raw(raw: u16) -> f32 {
    if raw >= RAW_INVALID {
        return 0.0;
    }
    let z = A / (B - f32::from(raw));
    if z.is_finite() && z > 0.0 {
        z
    } else {
        0.0
    }
}

/// The raw samples in the byte order where all fit 11 bits, and whether they had to be swapped.
fn kinect_order(path: &Path, samples: Vec<u16>) -> Result<(Vec<u16>, bool), ImportError> {
    if samples.iter().all(|&v| v <= RAW_INVALID) {
        return Ok((samples, false));
    }
    let swapped: Vec<u16> = samples.iter().map(|v| v.swap_bytes()).collect();
    if swapped.iter().all(|&v| v <= RAW_INVALID) {
        return Ok((swapped, true));
    }
    Err(ImportError::invalid(
        path,
        "samples exceed the 11-bit Kinect range (0..=2047) in either byte order",
    ))
}

/// Loads the single raw NYU frame.
pub(crate) fn load(src: &Path) -> Result<Loaded, ImportError> {
    let dir = src.join("other_formats");
    let (rgb_path, depth_path) = (dir.join("NYU_color.ppm"), dir.join("NYU_depth.pgm"));
    let rgb = read_rgb(&rgb_path)?;
    check_size(&rgb_path, &rgb, &NYU_RGB)?;
    let (dw, dh, samples) = read_u16_grey(&depth_path)?;
    let (raw, swapped) = kinect_order(&depth_path, samples)?;
    let mut notes = vec![
        format!(
            "nyu-raw: NYU_depth.pgm samples read {} (Kinect disparity must fit 0..=2047)",
            if swapped { "little-endian, against the PGM spec's big-endian" } else { "big-endian as the PGM spec says" }
        ),
        "nyu-raw: depth = 351.3/(1092.5 − raw) m (NYU toolbox), raw 2047 or depth ≤ 0 → unknown".to_owned(),
        "nyu-raw: raw depth is NOT registered to the RGB (it is in the depth camera's frame, fx_d ≈ 582.6, \
         ≈2.5 cm baseline); the NYU v2 colour intrinsics are used for the frame, so depth edges are offset \
         by a few pixels"
            .to_owned(),
    ];
    let depth_m: Vec<f32> = raw.iter().map(|&r| depth_from_raw(r)).collect();
    let depth_m = depth_at_rgb_size("nyu-raw", &depth_path, depth_m, (dw, dh), &rgb, &mut notes);
    let frame = ImportedFrame {
        id: "000000".to_owned(),
        t_s: 0.0,
        rgb,
        depth_m,
        camera: NYU_RGB,
    };
    Ok((vec![frame], notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disparity_to_depth() {
        // 351.3 / (1092.5 − 839) = 1.38580 m: the README's nearest 1.39 m.
        assert!((depth_from_raw(839) - 1.385_80).abs() < 1e-5);
        assert_eq!(depth_from_raw(2047), 0.0);
        assert_eq!(depth_from_raw(1093), 0.0); // beyond the pole: negative depth
        assert_eq!(depth_from_raw(1500), 0.0);
    }

    #[test]
    fn picks_byte_order() {
        let p = Path::new("x.pgm");
        assert_eq!(
            kinect_order(p, vec![2047, 839]).unwrap(),
            (vec![2047, 839], false)
        );
        assert_eq!(
            kinect_order(p, vec![0xff07, 0x4703]).unwrap(),
            (vec![2047, 839], true)
        );
        let e = kinect_order(p, vec![0xffff]).unwrap_err().to_string();
        assert!(e.starts_with("x.pgm: samples exceed"), "{e}");
    }
}
