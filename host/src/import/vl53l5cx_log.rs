//! VL53L5CX zone logs: JSON files `{"tof": {"distances": [[64 values, mm]…]}, "pos": {…}}`, one
//! per flight (e.g. `data/real/vecihi-vl53l5cx-flights`, a UAV's 8×8 sensor). Distances are
//! row-major 8×8 in millimetres, −1 for a zone filtered upstream.
//!
//! The recording has zones only: no colour images (`"rgb": false`, docs/recording.md), no
//! reference depth. Its camera is a virtual 160×160 pinhole with the sensor's 45° × 45° field of
//! view, so the zones project onto a grid of their own. Zones with −1 get status 255 (no
//! target), the others 5 (valid: the logs keep no status). Frame ids are `<file stem>_<index>`;
//! `t_s` is the index within its file (the logs keep no times). Poses (`pos`) are not imported.

use std::path::{Path, PathBuf};

use depthor_core::calibration::CameraIntrinsics;
use image::RgbImage;

use super::{ImportError, ImportedDtof, ImportedFrame};
use crate::recording::{DistanceMeta, DtofFrame, DtofMeta};

/// Side of the virtual camera, pixels.
pub(super) const SIDE: u32 = 160;
/// The sensor's field of view, degrees (ST datasheet: 45° horizontal and vertical).
pub(super) const FOV_DEG: f32 = 45.0;

/// The files under `src` (one file, or a folder's files whose extension is one of `exts`), sorted.
pub(super) fn files_with_extensions(
    src: &Path,
    exts: &[&str],
) -> Result<Vec<PathBuf>, ImportError> {
    if src.is_file() {
        return Ok(vec![src.to_path_buf()]);
    }
    let entries = std::fs::read_dir(src).map_err(|err| ImportError::Io {
        path: src.to_path_buf(),
        err,
    })?;
    let mut out: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|x| x.to_str())
                .is_some_and(|x| exts.contains(&x))
        })
        .collect();
    out.sort();
    Ok(out)
}

/// The virtual `SIDE × SIDE` pinhole camera with the sensor's field of view that zone-only
/// recordings carry.
pub(super) fn virtual_camera() -> CameraIntrinsics {
    let f = SIDE as f32 / 2.0 / (FOV_DEG.to_radians() / 2.0).tan();
    CameraIntrinsics {
        width: SIDE,
        height: SIDE,
        fx: f,
        fy: f,
        cx: (SIDE as f32 - 1.0) / 2.0,
        cy: (SIDE as f32 - 1.0) / 2.0,
    }
}

/// Loads every log under `src` (a folder of `.json` logs, or one log).
pub(super) fn load(src: &Path) -> Result<(super::Loaded, ImportedDtof), ImportError> {
    let files = files_with_extensions(src, &["json"])?;
    if files.is_empty() {
        return Err(ImportError::invalid(src, "no .json zone logs here"));
    }
    let camera = virtual_camera();
    let (mut frames, mut zones) = (Vec::new(), Vec::new());
    for path in &files {
        let text = std::fs::read_to_string(path).map_err(|err| ImportError::Io {
            path: path.clone(),
            err,
        })?;
        let v: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| ImportError::invalid(path, format!("not JSON: {e}")))?;
        let rows = v
            .pointer("/tof/distances")
            .and_then(|d| d.as_array())
            .ok_or_else(|| {
                ImportError::invalid(path, "tof.distances: missing (an array of frames)")
            })?;
        let stem = path
            .file_stem()
            .map_or_else(|| "log".into(), |s| s.to_string_lossy().into_owned());
        let stem: String = stem
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        for (i, row) in rows.iter().enumerate() {
            let values = row.as_array().filter(|a| a.len() == 64).ok_or_else(|| {
                ImportError::invalid(path, format!("tof.distances[{i}]: expected 64 numbers"))
            })?;
            let mut distance_mm = Vec::with_capacity(64);
            let mut status = Vec::with_capacity(64);
            for (z, d) in values.iter().enumerate() {
                let d = d.as_f64().filter(|d| d.is_finite()).ok_or_else(|| {
                    ImportError::invalid(
                        path,
                        format!("tof.distances[{i}][{z}]: expected a number"),
                    )
                })?;
                let valid = d >= 0.0;
                distance_mm.push(if valid { d as f32 } else { 0.0 });
                status.push(if valid { 5 } else { 255 });
            }
            frames.push(ImportedFrame {
                id: format!("{stem}_{i:06}"),
                t_s: i as f64,
                rgb: RgbImage::new(SIDE, SIDE),
                depth_m: Vec::new(),
                camera,
            });
            zones.push(DtofFrame {
                distance_mm,
                status,
                sigma_mm: None,
                signal_kcps: None,
                ambient_kcps: None,
            });
        }
    }
    let notes = vec![
        format!(
            "zone logs only: no colour images (\"rgb\": false) and no reference depth; the camera \
             is a virtual {SIDE}×{SIDE} pinhole with the sensor's {FOV_DEG}°×{FOV_DEG}° field of view"
        ),
        "zones of -1 mm became status 255 (no target), the others status 5 (the logs keep no status)"
            .to_string(),
        "t_s is the frame's index in its log (the logs keep no times); poses (pos) not imported"
            .to_string(),
    ];
    let meta = DtofMeta {
        rows: 8,
        cols: 8,
        fov_deg: [FOV_DEG, FOV_DEG],
        distance: DistanceMeta::Z,
        max_range_m: 4.0,
        zone_rects_px: None,
    };
    Ok((
        (frames, notes),
        ImportedDtof {
            meta,
            frames: zones,
        },
    ))
}
