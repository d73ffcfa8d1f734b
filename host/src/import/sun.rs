//! The SUN RGB-D frame of Open3D's test data: `other_formats/SUN_color.jpg` (8-bit RGB) and
//! `other_formats/SUN_depth.png` (16-bit, millimetres stored rotated right by 3 bits:
//! `mm = (d >> 3) | (d << 13)` in 16 bits, as SUN RGB-D's toolbox and Open3D's
//! `CreateFromSUNFormat` decode it; 0 = unknown).

use std::path::Path;

use super::decode::{check_size, read_rgb, read_u16_grey};
use super::nyu_raw::NYU_RGB;
use super::resample::depth_at_rgb_size;
use super::{ImportError, ImportedFrame, Loaded};

/// SUN RGB-D's stored sample → millimetres (a 16-bit rotation right by 3).
pub(crate) fn sun_mm(d: u16) -> u16 {
    d.rotate_right(3)
}

/// Loads the single SUN RGB-D frame.
pub(crate) fn load(src: &Path) -> Result<Loaded, ImportError> {
    let dir = src.join("other_formats");
    let (rgb_path, depth_path) = (dir.join("SUN_color.jpg"), dir.join("SUN_depth.png"));
    let rgb = read_rgb(&rgb_path)?;
    check_size(&rgb_path, &rgb, &NYU_RGB)?;
    let (dw, dh, raw) = read_u16_grey(&depth_path)?;
    let mut notes = vec![format!(
        "sun: SUN RGB-D intrinsics depend on the sensor and are not given with this frame; \
         NYU v2 Kinect v1 colour intrinsics (fx {:.4}, fy {:.4}, cx {:.4}, cy {:.4}) are assumed for its 640×480 image",
        NYU_RGB.fx, NYU_RGB.fy, NYU_RGB.cx, NYU_RGB.cy
    )];
    let depth_m: Vec<f32> = raw.iter().map(|&d| f32::from(sun_mm(d)) * 1e-3).collect();
    let depth_m = depth_at_rgb_size("sun", &depth_path, depth_m, (dw, dh), &rgb, &mut notes);
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
    use super::sun_mm;

    #[test]
    fn bit_rotation() {
        // 1057 mm = 0b100_0010_0001 is stored as 1057 << 3 = 8456.
        assert_eq!(sun_mm(8456), 1057);
        // Low 3 bits come back as the high 3: 0b101 → 0b101 << 13.
        assert_eq!(sun_mm(0b101), 0b101 << 13);
        assert_eq!(sun_mm(0), 0);
    }
}
