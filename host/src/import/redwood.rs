//! Redwood-style RGB-D sequence of Open3D's test data (PrimeSense/Asus Xtion, structured light):
//! `color/*.jpg` with `depth/*.png` (16-bit, millimetres, 0 = unknown, registered to the colour),
//! paired by `rgbd.match` (`depth/x.png color/x.jpg` per line), intrinsics from
//! `camera_primesense.json` (Open3D's `PinholeCameraIntrinsic`: `intrinsic_matrix` column-major).

use std::path::Path;

use depthor_core::calibration::CameraIntrinsics;
use serde::Deserialize;

use super::decode::{check_size, read_json, read_rgb, read_text, read_u16_grey, scaled_depth};
use super::resample::depth_at_rgb_size;
use super::{ImportError, ImportedFrame, Loaded};

/// Nominal frame rate of the Redwood captures (Choi et al., CVPR 2015: 30 Hz PrimeSense).
const FRAME_RATE_HZ: f64 = 30.0;

#[derive(Deserialize)]
struct Open3dIntrinsic {
    width: u32,
    height: u32,
    intrinsic_matrix: Vec<f32>,
}

/// Reads Open3D's `camera_primesense.json`.
fn read_camera(path: &Path) -> Result<CameraIntrinsics, ImportError> {
    let j: Open3dIntrinsic = read_json(path)?;
    let m = &j.intrinsic_matrix;
    if m.len() != 9 {
        return Err(ImportError::invalid(
            path,
            format!("intrinsic_matrix: expected 9 numbers, found {}", m.len()),
        ));
    }
    // Column-major: [fx, 0, 0, s, fy, 0, cx, cy, 1].
    if m[1] != 0.0 || m[2] != 0.0 || m[5] != 0.0 || m[8] != 1.0 || m[0] <= 0.0 || m[4] <= 0.0 {
        return Err(ImportError::invalid(
            path,
            format!("intrinsic_matrix: not a column-major pinhole matrix: {m:?}"),
        ));
    }
    Ok(CameraIntrinsics {
        width: j.width,
        height: j.height,
        fx: m[0],
        fy: m[4],
        cx: m[6],
        cy: m[7],
    })
}

/// `(depth, colour)` relative paths from `rgbd.match`.
fn read_match(path: &Path) -> Result<Vec<(String, String)>, ImportError> {
    let text = read_text(path)?;
    let mut pairs = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            [] => {}
            [d, c] => pairs.push((d.to_string(), c.to_string())),
            _ => {
                return Err(ImportError::invalid(
                    path,
                    format!(
                        "line {}: expected \"depth/<f>.png color/<f>.jpg\", found {line:?}",
                        n + 1
                    ),
                ))
            }
        }
    }
    if pairs.is_empty() {
        return Err(ImportError::invalid(path, "no depth/colour pairs"));
    }
    Ok(pairs)
}

/// Loads the sequence in `rgbd.match` order.
pub(crate) fn load(src: &Path) -> Result<Loaded, ImportError> {
    let camera = read_camera(&src.join("camera_primesense.json"))?;
    let pairs = read_match(&src.join("rgbd.match"))?;
    let mut notes = vec![
        format!(
            "redwood: rgbd.match has no times; t_s = index / {FRAME_RATE_HZ} Hz assumes consecutive frames"
        ),
        "redwood: the stand-alone depth.png (no matching colour) is not imported".to_owned(),
    ];
    let mut frames = Vec::with_capacity(pairs.len());
    for (i, (d, c)) in pairs.iter().enumerate() {
        let (rgb_path, depth_path) = (src.join(c), src.join(d));
        let rgb = read_rgb(&rgb_path)?;
        check_size(&rgb_path, &rgb, &camera)?;
        let (dw, dh, raw) = read_u16_grey(&depth_path)?;
        let depth_m = depth_at_rgb_size(
            "redwood",
            &depth_path,
            scaled_depth(&raw, 1e-3),
            (dw, dh),
            &rgb,
            &mut notes,
        );
        let id = rgb_path
            .file_stem()
            .map_or_else(|| format!("{i:06}"), |s| s.to_string_lossy().into_owned());
        frames.push(ImportedFrame {
            id,
            t_s: i as f64 / FRAME_RATE_HZ,
            rgb,
            depth_m,
            camera,
        });
    }
    Ok((frames, notes))
}
