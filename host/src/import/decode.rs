//! File reading and image decoding shared by the loaders; every error names the file.

use std::path::Path;

use depthor_core::calibration::CameraIntrinsics;
use image::{DynamicImage, ImageReader, RgbImage};

use super::ImportError;

/// The whole file.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, ImportError> {
    std::fs::read(path).map_err(|err| ImportError::Io {
        path: path.to_path_buf(),
        err,
    })
}

/// The whole file as UTF-8 text.
pub(crate) fn read_text(path: &Path) -> Result<String, ImportError> {
    let bytes = read_bytes(path)?;
    String::from_utf8(bytes)
        .map_err(|e| ImportError::invalid(path, format!("not UTF-8 text ({e})")))
}

/// The file's content parsed as JSON into `T`.
pub(crate) fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, ImportError> {
    let text = read_text(path)?;
    serde_json::from_str(&text).map_err(|e| ImportError::invalid(path, e.to_string()))
}

/// Decodes an image file (format from its content, then its extension).
fn decode(path: &Path) -> Result<DynamicImage, ImportError> {
    let io = |err| ImportError::Io {
        path: path.to_path_buf(),
        err,
    };
    let img = ImageReader::open(path)
        .map_err(io)?
        .with_guessed_format()
        .map_err(io)?;
    img.decode().map_err(|err| ImportError::Decode {
        path: path.to_path_buf(),
        err,
    })
}

/// An 8-bit colour image; 8-bit grey or alpha images are converted, 16-bit ones are refused
/// (they would be depth, not colour).
pub(crate) fn read_rgb(path: &Path) -> Result<RgbImage, ImportError> {
    match decode(path)? {
        DynamicImage::ImageRgb8(img) => Ok(img),
        img @ (DynamicImage::ImageLuma8(_)
        | DynamicImage::ImageLumaA8(_)
        | DynamicImage::ImageRgba8(_)) => Ok(img.to_rgb8()),
        other => Err(ImportError::invalid(
            path,
            format!("expected an 8-bit colour image, found {:?}", other.color()),
        )),
    }
}

/// A 16-bit single-channel image (depth PNG or PGM) as `(width, height, samples)`, samples
/// row-major exactly as decoded (PGM: big-endian as the Netpbm spec says).
pub(crate) fn read_u16_grey(path: &Path) -> Result<(u32, u32, Vec<u16>), ImportError> {
    match decode(path)? {
        DynamicImage::ImageLuma16(img) => Ok((img.width(), img.height(), img.into_raw())),
        other => Err(ImportError::invalid(
            path,
            format!(
                "expected a 16-bit greyscale depth image, found {:?}",
                other.color()
            ),
        )),
    }
}

/// Depth in metres from integer samples: `v · scale`, 0 stays 0 (unknown).
pub(crate) fn scaled_depth(raw: &[u16], metres_per_unit: f32) -> Vec<f32> {
    raw.iter()
        .map(|&v| f32::from(v) * metres_per_unit)
        .collect()
}

/// Fails unless the image has the size the set's fixed intrinsics were made for.
pub(crate) fn check_size(
    path: &Path,
    rgb: &RgbImage,
    cam: &CameraIntrinsics,
) -> Result<(), ImportError> {
    if rgb.dimensions() != (cam.width, cam.height) {
        return Err(ImportError::invalid(
            path,
            format!(
                "image is {}×{} but the intrinsics used for this set are for {}×{}",
                rgb.width(),
                rgb.height(),
                cam.width,
                cam.height
            ),
        ));
    }
    Ok(())
}
