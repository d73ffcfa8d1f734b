//! NYU Depth v2 test frames as the Metric3D demo ships them: `test_annotations.json` lists each
//! frame's `rgb` (8-bit JPEG), `depth` (16-bit PNG, `depth_m = png / depth_scale`, 0 = unknown,
//! already registered to the RGB) and `cam_in = [fx, fy, cx, cy]`.

use std::path::{Path, PathBuf};

use depthor_core::calibration::CameraIntrinsics;
use serde::Deserialize;

use super::decode::{read_json, read_rgb, read_u16_grey, scaled_depth};
use super::resample::depth_at_rgb_size;
use super::{ImportError, ImportedFrame, Loaded};

#[derive(Deserialize)]
struct Annotations {
    files: Vec<Entry>,
}

#[derive(Deserialize)]
struct Entry {
    cam_in: [f32; 4],
    rgb: String,
    depth: String,
    depth_scale: f32,
}

/// The annotation's path (relative to Metric3D's repository, `data/nyu_demo/rgb/x.jpg`) inside
/// `src`: its last two components (`rgb/x.jpg`).
fn local(src: &Path, repo_path: &str) -> PathBuf {
    let parts: Vec<&str> = repo_path.split('/').filter(|p| !p.is_empty()).collect();
    parts[parts.len().saturating_sub(2)..]
        .iter()
        .fold(src.to_path_buf(), |p, c| p.join(c))
}

/// Loads every frame listed in `src/test_annotations.json`.
pub(crate) fn load(src: &Path) -> Result<Loaded, ImportError> {
    let ann_path = src.join("test_annotations.json");
    let ann: Annotations = read_json(&ann_path)?;
    if ann.files.is_empty() {
        return Err(ImportError::invalid(&ann_path, "files: empty list"));
    }
    let mut notes =
        vec!["nyu: frames are unrelated test stills; t_s is the frame's ordinal".to_owned()];
    let mut frames = Vec::with_capacity(ann.files.len());
    for (i, e) in ann.files.iter().enumerate() {
        let [fx, fy, cx, cy] = e.cam_in;
        if !(fx > 0.0 && fy > 0.0 && cx.is_finite() && cy.is_finite()) {
            return Err(ImportError::invalid(
                &ann_path,
                format!("files[{i}].cam_in: invalid {:?}", e.cam_in),
            ));
        }
        if !(e.depth_scale > 0.0 && e.depth_scale.is_finite()) {
            return Err(ImportError::invalid(
                &ann_path,
                format!("files[{i}].depth_scale: {} is not positive", e.depth_scale),
            ));
        }
        let rgb_path = local(src, &e.rgb);
        let depth_path = local(src, &e.depth);
        let rgb = read_rgb(&rgb_path)?;
        let (dw, dh, raw) = read_u16_grey(&depth_path)?;
        let depth_m = scaled_depth(&raw, 1.0 / e.depth_scale);
        let depth_m = depth_at_rgb_size("nyu", &depth_path, depth_m, (dw, dh), &rgb, &mut notes);
        let (w, h) = rgb.dimensions();
        let id = rgb_path
            .file_stem()
            .map_or_else(|| format!("{i:06}"), |s| s.to_string_lossy().into_owned());
        let camera = CameraIntrinsics {
            width: w,
            height: h,
            fx,
            fy,
            cx,
            cy,
        };
        frames.push(ImportedFrame {
            id,
            t_s: i as f64,
            rgb,
            depth_m,
            camera,
        });
    }
    Ok((frames, notes))
}
