//! ZJU-L5 (Deltar, ECCV 2022; the benchmark DEPTHOR reports on): one HDF5 file per frame, as the
//! public Deltar and DEPTHOR loaders read them:
//!
//! | dataset | shape | meaning |
//! |---|---|---|
//! | `rgb` | H × W × 3, uint8 | colour image (RGB order) |
//! | `depth` | H × W, float | RealSense reference depth, metres (0 = none) |
//! | `hist_data` | 64 × 2, float | per zone: mean and standard deviation of its depth distribution, metres |
//! | `fr` | 64 × 4, int or float | per zone: rectangle `[y0, x0, y1, x1]` in image pixels |
//! | `mask` | 64, bool or int | zone valid |
//!
//! A frame becomes an 8×8 zone frame of the recording: `distance_mm` = mean, `sigma_mm` =
//! standard deviation (the files keep the fitted distribution, not the raw histogram bins),
//! `status` 5 (valid) where `mask` is set else 255 (no target), and the rectangles become the
//! recording's `zone_rects_px` (so zones project where the set's calibration put them). Files
//! are found recursively under the folder, sorted by path; ids are the relative paths without
//! `.h5`, `/` replaced by `_`. The files carry no intrinsics: a RealSense D435 colour camera is
//! assumed (noted); projection with `zone_rects_px` does not use it.

use std::path::{Path, PathBuf};

use depthor_core::calibration::CameraIntrinsics;
use image::RgbImage;

use super::{ImportError, ImportedDtof, ImportedFrame};
use crate::recording::{DistanceMeta, DtofFrame, DtofMeta};

/// Zones of the VL53L5CX in its 8×8 mode.
const ZONES: usize = 64;
/// Focal length assumed for the colour camera, pixels at 640 × 480 (RealSense D435 colour,
/// ≈ 69° × 42° field of view), scaled with the image width.
const ASSUMED_FX_640: f32 = 605.0;

/// The `.h5` files under `dir`, sorted.
fn h5_files(dir: &Path) -> Result<Vec<PathBuf>, ImportError> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = std::fs::read_dir(&d).map_err(|err| ImportError::Io {
            path: d.clone(),
            err,
        })?;
        for e in entries {
            let p = e
                .map_err(|err| ImportError::Io {
                    path: d.clone(),
                    err,
                })?
                .path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "h5" || x == "hdf5") {
                out.push(p);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// One dataset of `file` as `f32` with its shape; errors name the file and the dataset.
fn read_f32(
    file: &hdf5_pure::File,
    path: &Path,
    name: &str,
) -> Result<(Vec<f32>, Vec<u64>), ImportError> {
    let ds = file
        .dataset(name)
        .map_err(|e| ImportError::invalid(path, format!("{name}: {e}")))?;
    let shape = ds
        .shape()
        .map_err(|e| ImportError::invalid(path, format!("{name}: shape: {e}")))?;
    let v = ds
        .read::<f32>()
        .map_err(|e| ImportError::invalid(path, format!("{name}: {e}")))?;
    Ok((v, shape))
}

fn expect_shape(path: &Path, name: &str, shape: &[u64], want: &[u64]) -> Result<(), ImportError> {
    if shape != want {
        return Err(ImportError::invalid(
            path,
            format!("{name}: shape {shape:?}, expected {want:?}"),
        ));
    }
    Ok(())
}

/// One file: the frame and its zones.
fn load_file(
    path: &Path,
    id: String,
    t_s: f64,
) -> Result<(ImportedFrame, DtofFrame, Vec<[f32; 4]>), ImportError> {
    let file = hdf5_pure::File::open(path)
        .map_err(|e| ImportError::invalid(path, format!("not a readable HDF5 file: {e}")))?;
    let rgb_ds = file
        .dataset("rgb")
        .map_err(|e| ImportError::invalid(path, format!("rgb: {e}")))?;
    let shape = rgb_ds
        .shape()
        .map_err(|e| ImportError::invalid(path, format!("rgb: shape: {e}")))?;
    let [h, w, 3] = shape[..] else {
        return Err(ImportError::invalid(
            path,
            format!("rgb: shape {shape:?}, expected [H, W, 3]"),
        ));
    };
    let rgb = rgb_ds
        .read::<u8>()
        .map_err(|e| ImportError::invalid(path, format!("rgb: {e}")))?;
    let (h, w) = (h as u32, w as u32);
    let rgb = RgbImage::from_raw(w, h, rgb)
        .ok_or_else(|| ImportError::invalid(path, "rgb: fewer values than its shape"))?;
    let (mut depth, dshape) = read_f32(&file, path, "depth")?;
    // Some exports keep a trailing channel axis of 1.
    if dshape != [u64::from(h), u64::from(w)] && dshape != [u64::from(h), u64::from(w), 1] {
        return Err(ImportError::invalid(
            path,
            format!("depth: shape {dshape:?}, expected [{h}, {w}] like rgb"),
        ));
    }
    for d in &mut depth {
        if !(d.is_finite() && *d > 0.0) {
            *d = 0.0;
        }
    }
    let (hist, hshape) = read_f32(&file, path, "hist_data")?;
    expect_shape(path, "hist_data", &hshape, &[ZONES as u64, 2])?;
    let (fr, fshape) = read_f32(&file, path, "fr")?;
    expect_shape(path, "fr", &fshape, &[ZONES as u64, 4])?;
    let mask_ds = file
        .dataset("mask")
        .map_err(|e| ImportError::invalid(path, format!("mask: {e}")))?;
    let mask = mask_ds
        .read::<u8>()
        .map_err(|e| ImportError::invalid(path, format!("mask: {e}")))?;
    if mask.len() != ZONES {
        return Err(ImportError::invalid(
            path,
            format!("mask: {} values, expected {ZONES}", mask.len()),
        ));
    }
    let mut distance_mm = Vec::with_capacity(ZONES);
    let mut sigma_mm = Vec::with_capacity(ZONES);
    let mut status = Vec::with_capacity(ZONES);
    for z in 0..ZONES {
        let (mean, sd) = (hist[2 * z], hist[2 * z + 1]);
        let ok = mask[z] != 0 && mean.is_finite() && mean > 0.0;
        distance_mm.push(if mean.is_finite() { 1000.0 * mean } else { 0.0 });
        sigma_mm.push(if sd.is_finite() {
            1000.0 * sd.abs()
        } else {
            0.0
        });
        status.push(if ok { 5 } else { 255 });
    }
    let rects: Vec<[f32; 4]> = fr
        .chunks_exact(4)
        .map(|r| [r[0], r[1], r[2], r[3]])
        .collect();
    if let Some((z, r)) = rects
        .iter()
        .enumerate()
        .find(|(_, r)| !r.iter().all(|v| v.is_finite()) || r[0] > r[2] || r[1] > r[3])
    {
        return Err(ImportError::invalid(
            path,
            format!("fr: zone {z}: rectangle {r:?} is not [y0, x0, y1, x1] with y0 ≤ y1, x0 ≤ x1"),
        ));
    }
    let fx = ASSUMED_FX_640 * w as f32 / 640.0;
    let camera = CameraIntrinsics {
        width: w,
        height: h,
        fx,
        fy: fx,
        cx: (w as f32 - 1.0) / 2.0,
        cy: (h as f32 - 1.0) / 2.0,
    };
    let frame = ImportedFrame {
        id,
        t_s,
        rgb,
        depth_m: depth,
        camera,
    };
    let dtof = DtofFrame {
        distance_mm,
        status,
        sigma_mm: Some(sigma_mm),
        signal_kcps: None,
        ambient_kcps: None,
    };
    Ok((frame, dtof, rects))
}

/// Loads every `.h5` file under `src`.
pub(super) fn load(src: &Path) -> Result<(super::Loaded, ImportedDtof), ImportError> {
    let files = h5_files(src)?;
    if files.is_empty() {
        return Err(ImportError::invalid(src, "no .h5 files under this folder"));
    }
    let (mut frames, mut zones) = (Vec::new(), Vec::new());
    let mut rects: Option<(PathBuf, Vec<[f32; 4]>)> = None;
    for (i, path) in files.iter().enumerate() {
        let rel = path.strip_prefix(src).unwrap_or(path).with_extension("");
        let id: String = rel
            .to_string_lossy()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        let (frame, dtof, r) = load_file(path, id, i as f64)?;
        match &rects {
            None => rects = Some((path.clone(), r)),
            Some((first, r0)) => {
                let worst = r0
                    .iter()
                    .zip(&r)
                    .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
                    .fold(0.0f32, f32::max);
                if worst > 0.5 {
                    return Err(ImportError::invalid(
                        path,
                        format!(
                            "fr: zone rectangles differ from {}'s by {worst:.1} px; a recording \
                             holds one calibration (import the files of each calibration apart)",
                            first.display()
                        ),
                    ));
                }
            }
        }
        if frame.camera
            != frames
                .first()
                .map_or(frame.camera, |f: &ImportedFrame| f.camera)
        {
            return Err(ImportError::invalid(
                path,
                "rgb: other image size than the first file's",
            ));
        }
        frames.push(frame);
        zones.push(dtof);
    }
    let (_, rects) = rects.unwrap_or_default();
    let w = frames[0].camera.width;
    let notes = vec![
        format!(
            "ZJU-L5 files carry no intrinsics: assumed RealSense D435 colour, fx = fy = {:.1} px at \
             {w} px width, principal point at the centre (zones are placed by the files' `fr` \
             rectangles, which do not use it)",
            frames[0].camera.fx
        ),
        "zones: distance = hist_data mean, sigma = hist_data standard deviation (the files keep \
         the fitted distribution, not histogram bins); status 5 where mask is set, else 255"
            .to_string(),
        "t_s is the file's index in path order (the files carry no time stamps)".to_string(),
    ];
    let meta = DtofMeta {
        rows: 8,
        cols: 8,
        fov_deg: [45.0, 45.0],
        distance: DistanceMeta::Z,
        max_range_m: 4.0,
        zone_rects_px: Some(rects),
    };
    Ok((
        (frames, notes),
        ImportedDtof {
            meta,
            frames: zones,
        },
    ))
}
