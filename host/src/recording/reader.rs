//! Reading and validating a recording.

use super::error::{Invalid, RecordingError};
use super::files;
use super::meta::{CalibrationData, DtofFrame, RecordingMeta, MAX_LABEL};
use depthor_core::calibration::CameraIntrinsics;
use image::{DynamicImage, ImageFormat, RgbImage};
use std::path::{Path, PathBuf};

/// One frame's data.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Frame id (its directory name).
    pub id: String,
    /// The RGB image at the frame's camera size.
    pub rgb: RgbImage,
    /// Reference depth in metres, row-major `width * height`, 0 = unknown.
    pub depth_m: Option<Vec<f32>>,
    /// Material class per pixel (0..=3), row-major.
    pub labels: Option<Vec<u8>>,
    /// Zone measurements.
    pub dtof: Option<DtofFrame>,
}

/// An opened, validated recording. Frames are read on demand.
#[derive(Clone, Debug)]
pub struct Recording {
    dir: PathBuf,
    meta: RecordingMeta,
}

/// Reads and parses a JSON file, reporting syntax errors with their position.
pub(crate) fn read_json(path: &Path) -> Result<serde_json::Value, RecordingError> {
    let bytes = std::fs::read(path).map_err(|e| RecordingError::io(path, "read", e))?;
    serde_json::from_slice(&bytes).map_err(|e| RecordingError::new(path, "JSON syntax", e))
}

fn decode_png(path: &Path) -> Result<DynamicImage, RecordingError> {
    let file = std::fs::File::open(path).map_err(|e| RecordingError::io(path, "read", e))?;
    image::ImageReader::with_format(std::io::BufReader::new(file), ImageFormat::Png)
        .decode()
        .map_err(|e| RecordingError::new(path, "PNG", e))
}

/// Checks an image of `size` (width, height) matches the frame's camera.
pub(crate) fn check_size(
    path: &Path,
    size: (u32, u32),
    cam: &CameraIntrinsics,
) -> Result<(), RecordingError> {
    if size == (cam.width, cam.height) {
        Ok(())
    } else {
        Err(RecordingError::new(
            path,
            "size",
            format_args!(
                "expected {}×{} (the frame's camera), found {}×{}",
                cam.width, cam.height, size.0, size.1
            ),
        ))
    }
}

fn wrong_type(path: &Path, expected: &str, img: &DynamicImage) -> RecordingError {
    RecordingError::new(
        path,
        "color type",
        format_args!("expected {expected}, found {:?}", img.color()),
    )
}

impl Recording {
    /// Opens `dir`: parses and validates `recording.json` and checks every frame directory
    /// exists. Images and zone files are checked when read.
    pub fn open(dir: impl AsRef<Path>) -> Result<Recording, RecordingError> {
        let dir = dir.as_ref().to_path_buf();
        let path = dir.join(files::RECORDING_JSON);
        let value = read_json(&path)?;
        let meta = RecordingMeta::from_json(&value).map_err(|e| RecordingError::at(&path, e))?;
        for (i, f) in meta.frames.iter().enumerate() {
            let fdir = dir.join(files::FRAMES).join(&f.id);
            if !fdir.is_dir() {
                return Err(RecordingError::new(
                    fdir,
                    format!("frames[{i}].id"),
                    "frame directory does not exist",
                ));
            }
        }
        Ok(Recording { dir, meta })
    }

    /// The recording's directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The parsed `recording.json`.
    pub fn meta(&self) -> &RecordingMeta {
        &self.meta
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.meta.frames.len()
    }

    /// True when the recording has no frames.
    pub fn is_empty(&self) -> bool {
        self.meta.frames.is_empty()
    }

    /// Index of the frame with id `id`.
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.meta.frames.iter().position(|f| f.id == id)
    }

    /// Camera of frame `i` (its own or the recording's). Panics if `i >= len()`.
    pub fn camera(&self, i: usize) -> CameraIntrinsics {
        *self.meta.frame_camera(i)
    }

    /// Calibration of frame `i`, `None` when the recording has no dToF. Panics if `i >= len()`.
    pub fn calibration(&self, i: usize) -> Option<CalibrationData> {
        let dtof = self.meta.dtof.as_ref()?;
        Some(CalibrationData::new(
            self.meta.frame_camera(i),
            dtof,
            self.meta.dtof_to_camera.as_ref(),
        ))
    }

    /// Path of `name` in frame `i`'s directory. Panics if `i >= len()`.
    pub fn frame_file(&self, i: usize, name: &str) -> PathBuf {
        self.dir
            .join(files::FRAMES)
            .join(&self.meta.frames[i].id)
            .join(name)
    }

    /// Reads frame `i` completely (RGB, optional depth, labels and zones), validating each file.
    /// Panics if `i >= len()`.
    pub fn read_frame(&self, i: usize) -> Result<Frame, RecordingError> {
        Ok(Frame {
            id: self.meta.frames[i].id.clone(),
            rgb: self.read_rgb(i)?,
            depth_m: self.read_depth(i)?,
            labels: self.read_labels(i)?,
            dtof: self.read_dtof(i)?,
        })
    }

    /// Reads frame `i`'s `rgb.png`: 8-bit RGB at the frame's camera size (black when the
    /// recording has no colour images, `"rgb": false`).
    pub fn read_rgb(&self, i: usize) -> Result<RgbImage, RecordingError> {
        if !self.meta.rgb {
            let c = self.camera(i);
            return Ok(RgbImage::new(c.width, c.height));
        }
        let path = self.frame_file(i, files::RGB);
        match decode_png(&path)? {
            DynamicImage::ImageRgb8(img) => {
                check_size(&path, img.dimensions(), &self.camera(i))?;
                Ok(img)
            }
            other => Err(wrong_type(&path, "8-bit RGB", &other)),
        }
    }

    /// Reads frame `i`'s optional `depth.png` (16-bit gray, millimetres) as metres.
    pub fn read_depth(&self, i: usize) -> Result<Option<Vec<f32>>, RecordingError> {
        let path = self.frame_file(i, files::DEPTH);
        if !path.exists() {
            return Ok(None);
        }
        match decode_png(&path)? {
            DynamicImage::ImageLuma16(d) => {
                check_size(&path, d.dimensions(), &self.camera(i))?;
                Ok(Some(
                    d.into_raw()
                        .into_iter()
                        .map(|mm| mm as f32 / 1000.0)
                        .collect(),
                ))
            }
            other => Err(wrong_type(
                &path,
                "16-bit grayscale (L16, millimetres)",
                &other,
            )),
        }
    }

    /// Reads frame `i`'s optional `labels.png` (8-bit gray, classes 0..=3).
    pub fn read_labels(&self, i: usize) -> Result<Option<Vec<u8>>, RecordingError> {
        let path = self.frame_file(i, files::LABELS);
        if !path.exists() {
            return Ok(None);
        }
        let labels = match decode_png(&path)? {
            DynamicImage::ImageLuma8(l) => {
                check_size(&path, l.dimensions(), &self.camera(i))?;
                l.into_raw()
            }
            other => return Err(wrong_type(&path, "8-bit grayscale (L8)", &other)),
        };
        check_labels(&labels, self.camera(i).width).map_err(|e| RecordingError::at(&path, e))?;
        Ok(Some(labels))
    }

    /// Reads frame `i`'s `dtof.json`: required when the recording has a dToF, refused otherwise.
    pub fn read_dtof(&self, i: usize) -> Result<Option<DtofFrame>, RecordingError> {
        let path = self.frame_file(i, files::DTOF);
        match &self.meta.dtof {
            None if path.exists() => Err(RecordingError::new(
                path,
                "dtof.json",
                "present but recording.json has no \"dtof\" object to interpret it",
            )),
            None => Ok(None),
            Some(geometry) => {
                let value = read_json(&path)?;
                let frame = DtofFrame::from_json(&value, geometry)
                    .map_err(|e| RecordingError::at(&path, e))?;
                Ok(Some(frame))
            }
        }
    }
}

/// Checks every label is a known material class; names the first bad pixel.
pub(crate) fn check_labels(labels: &[u8], width: u32) -> Result<(), Invalid> {
    match labels.iter().position(|&l| l > MAX_LABEL) {
        None => Ok(()),
        Some(i) => {
            let w = width.max(1) as usize;
            Err(Invalid::new(
                format!("pixel (x {}, y {})", i % w, i / w),
                format_args!(
                    "class {} is not a material class (0..={MAX_LABEL})",
                    labels[i]
                ),
            ))
        }
    }
}
