//! The TUM RGB-D frame of Open3D's test data: `other_formats/TUM_color.png` (8-bit RGB) and
//! `other_formats/TUM_depth.png` (16-bit, `depth_m = png / 5000`, 0 = unknown; TUM's depth is
//! registered to the colour camera by the OpenNI driver).

use std::path::Path;

use depthor_core::calibration::CameraIntrinsics;

use super::decode::{check_size, read_rgb, read_u16_grey, scaled_depth};
use super::resample::depth_at_rgb_size;
use super::{ImportError, ImportedFrame, Loaded};

/// TUM depth scale: 5000 units per metre (TUM RGB-D "File Formats" page).
const UNITS_PER_M: f32 = 5000.0;

/// Freiburg 1 colour intrinsics (TUM RGB-D "Camera calibration" page, `fr1/rgb`).
/// fr2 (520.9, 521.0, 325.1, 249.7) and fr3 (535.4, 539.2, 320.1, 247.6) differ by up to 4 %.
pub(crate) const FR1_RGB: CameraIntrinsics = CameraIntrinsics {
    width: 640,
    height: 480,
    fx: 517.3,
    fy: 516.5,
    cx: 318.6,
    cy: 255.3,
};

/// Loads the single TUM frame.
pub(crate) fn load(src: &Path) -> Result<Loaded, ImportError> {
    let dir = src.join("other_formats");
    let (rgb_path, depth_path) = (dir.join("TUM_color.png"), dir.join("TUM_depth.png"));
    let rgb = read_rgb(&rgb_path)?;
    check_size(&rgb_path, &rgb, &FR1_RGB)?;
    let (dw, dh, raw) = read_u16_grey(&depth_path)?;
    let mut notes = vec![
        "tum: the frame's sequence is not stated; Freiburg 1 intrinsics (fx 517.3, fy 516.5, cx 318.6, \
         cy 255.3) are assumed; fr2/fr3 differ by up to 4 %"
            .to_owned(),
        "tum: the frame's distortion (fr1 d0 0.26, …) is ignored; depth = png/5000".to_owned(),
    ];
    let depth_m = depth_at_rgb_size(
        "tum",
        &depth_path,
        scaled_depth(&raw, 1.0 / UNITS_PER_M),
        (dw, dh),
        &rgb,
        &mut notes,
    );
    let frame = ImportedFrame {
        id: "000000".to_owned(),
        t_s: 0.0,
        rgb,
        depth_m,
        camera: FR1_RGB,
    };
    Ok((vec![frame], notes))
}
