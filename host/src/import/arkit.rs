//! The PromptDA iPhone example: `image.jpg` (1920×1440 wide-camera RGB) and `arkit_depth.png`
//! (256×192 ARKit LiDAR depth, 16-bit millimetres, densified by Apple, same field of view as the
//! image: ARKit's depth map is aligned to the captured image, 7.5× smaller).
//!
//! Output resolution: 640×480. The RGB is box-downsampled by exactly 3 (no interpolation, exact
//! intrinsics scaling); the depth is upsampled 2.5× by nearest neighbour, which keeps every
//! measured value and invents no mixed depths at edges. 640×480 matches the other real sets, so
//! one evaluation covers them all; 256×192 would throw away most of the RGB detail the network
//! uses to sharpen the coarse depth, and 1920×1440 would make the depth 7.5× replicated blocks.
//!
//! Intrinsics are not shipped with the example (ARKit reports them per frame). Assumption: the
//! wide camera's 26 mm full-frame-equivalent focal length (Apple's spec for the iPhone 12 Pro to
//! 15 Pro wide camera), taken on the 4:3 image diagonal: `f = 26/43.27 · diagonal_px`, i.e.
//! 1442 px at 1920×1440 (horizontal FoV 67.3°), principal point at the image centre.

use std::path::Path;

use depthor_core::calibration::CameraIntrinsics;

use super::decode::{read_rgb, read_u16_grey, scaled_depth};
use super::resample::{depth_nearest, rgb_box_downsample, scale_intrinsics};
use super::{ImportError, ImportedFrame, Loaded};

/// Output width and height (see the module docs).
const OUT: (u32, u32) = (640, 480);
/// iPhone wide camera, 35 mm-equivalent focal length in mm (Apple tech specs, iPhone 12–15 Pro).
const EQUIV_FOCAL_MM: f64 = 26.0;
/// Diagonal of the 36×24 mm full frame the equivalence refers to, mm.
const FULL_FRAME_DIAGONAL_MM: f64 = 43.267;

/// Assumed intrinsics of a `w × h` capture: `f = 26/43.267 · √(w² + h²)`, centre principal point.
pub(crate) fn assumed_intrinsics(w: u32, h: u32) -> CameraIntrinsics {
    let diag = f64::from(w).hypot(f64::from(h));
    let f = (EQUIV_FOCAL_MM / FULL_FRAME_DIAGONAL_MM * diag) as f32;
    CameraIntrinsics {
        width: w,
        height: h,
        fx: f,
        fy: f,
        cx: (w as f32 - 1.0) / 2.0,
        cy: (h as f32 - 1.0) / 2.0,
    }
}

/// Loads the single ARKit frame at 640×480.
pub(crate) fn load(src: &Path) -> Result<Loaded, ImportError> {
    let (rgb_path, depth_path) = (src.join("image.jpg"), src.join("arkit_depth.png"));
    let full = read_rgb(&rgb_path)?;
    let (w, h) = full.dimensions();
    let k = w / OUT.0;
    if k == 0 || (w, h) != (OUT.0 * k, OUT.1 * k) {
        return Err(ImportError::invalid(
            &rgb_path,
            format!(
                "size {w}×{h}: expected an integer multiple of {}×{} (ARKit 4:3 capture)",
                OUT.0, OUT.1
            ),
        ));
    }
    let (dw, dh, raw) = read_u16_grey(&depth_path)?;
    if u64::from(dw) * u64::from(h) != u64::from(dh) * u64::from(w) {
        return Err(ImportError::invalid(
            &depth_path,
            format!("size {dw}×{dh} does not have the image's {w}:{h} aspect, so the fields of view differ"),
        ));
    }
    let rgb = rgb_box_downsample(&full, k);
    let camera = scale_intrinsics(&assumed_intrinsics(w, h), k);
    let depth_m = depth_nearest(&scaled_depth(&raw, 1e-3), dw, dh, OUT.0, OUT.1);
    let notes = vec![
        format!(
            "arkit: intrinsics assumed from the iPhone wide camera's 26 mm equivalent focal length on the \
             image diagonal: f = {:.1} px at {w}×{h} (horizontal FoV {:.1}°), centred principal point; \
             the device's true values (ARKit reports them per frame) may differ by several percent",
            assumed_intrinsics(w, h).fx,
            2.0 * (f64::from(w) / 2.0 / f64::from(assumed_intrinsics(w, h).fx)).atan().to_degrees()
        ),
        format!(
            "arkit: RGB {w}×{h} box-downsampled by {k} to {}×{}; depth {dw}×{dh} (mm/1000) upsampled to \
             {}×{} by nearest neighbour; ARKit depth is already densified by Apple (not raw zones)",
            OUT.0, OUT.1, OUT.0, OUT.1
        ),
    ];
    let frame = ImportedFrame {
        id: "000000".to_owned(),
        t_s: 0.0,
        rgb,
        depth_m,
        camera,
    };
    Ok((vec![frame], notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wide_camera_assumption() {
        // 26/43.267 · 2400 px = 1442.2 px; /3 = 480.7 px at 640×480, centre (319.5, 239.5).
        let full = assumed_intrinsics(1920, 1440);
        assert!((full.fx - 1442.17).abs() < 0.05, "{}", full.fx);
        let s = scale_intrinsics(&full, 3);
        assert!((s.fx - 480.72).abs() < 0.02);
        assert_eq!((s.width, s.height, s.cx, s.cy), (640, 480, 319.5, 239.5));
    }
}
