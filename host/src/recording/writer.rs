//! Writing a recording atomically ([`crate::atomic`]): everything goes into a sibling directory
//! `<name>.partial-<pid>` that is renamed onto the destination only by
//! [`RecordingWriter::finish`]; a writer dropped before that removes it.

use super::error::{Invalid, RecordingError};
use super::files;
use super::meta::{FrameMeta, RecordingMeta};
use super::reader::{check_labels, check_size, Frame};
use crate::atomic::{AtomicDir, Existing, OutputError};
use depthor_core::calibration::CameraIntrinsics;
use image::{GrayImage, ImageBuffer, ImageFormat, Luma};
use std::path::{Path, PathBuf};

/// Options of [`RecordingWriter::create_with`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteOptions {
    /// Replace a non-empty existing destination (refused otherwise).
    pub overwrite: bool,
}

/// Writes a recording frame by frame.
#[derive(Debug)]
pub struct RecordingWriter {
    out_dir: PathBuf,
    tmp_dir: PathBuf,
    dir: AtomicDir,
    meta: RecordingMeta,
}

impl From<OutputError> for RecordingError {
    fn from(e: OutputError) -> Self {
        RecordingError::new(e.path, e.what, e.message)
    }
}

/// Depth in metres → the 16-bit millimetres of `depth.png`: rounded, clamped to 65535;
/// non-finite and non-positive values become 0 (unknown).
pub fn depth_m_to_mm(d: f32) -> u16 {
    if d.is_finite() && d > 0.0 {
        (d as f64 * 1000.0).round().min(u16::MAX as f64) as u16
    } else {
        0
    }
}

fn write_png<P, C>(path: &Path, img: &ImageBuffer<P, C>) -> Result<(), RecordingError>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    img.save_with_format(path, ImageFormat::Png)
        .map_err(|e| RecordingError::new(path, "write", e))
}

impl RecordingWriter {
    /// Starts a recording at `out_dir` with header `meta` (its `frames` must be empty); refuses
    /// a non-empty existing `out_dir`.
    pub fn create(out_dir: impl AsRef<Path>, meta: RecordingMeta) -> Result<Self, RecordingError> {
        Self::create_with(out_dir, meta, WriteOptions::default())
    }

    /// [`RecordingWriter::create`] with options.
    pub fn create_with(
        out_dir: impl AsRef<Path>,
        meta: RecordingMeta,
        options: WriteOptions,
    ) -> Result<Self, RecordingError> {
        let out_dir = out_dir.as_ref().to_path_buf();
        let header = out_dir.join(files::RECORDING_JSON);
        if !meta.frames.is_empty() {
            return Err(RecordingError::new(
                header,
                "frames",
                "must be empty when creating a writer (add frames with add_frame)",
            ));
        }
        meta.validate()
            .map_err(|e| RecordingError::at(&header, e))?;
        let existing = if options.overwrite {
            Existing::Replace
        } else {
            Existing::Refuse
        };
        let dir = AtomicDir::create(&out_dir, existing)?;
        let tmp_dir = dir.path().to_path_buf();
        std::fs::create_dir_all(tmp_dir.join(files::FRAMES))
            .map_err(|e| RecordingError::io(&tmp_dir, "create", e))?;
        Ok(RecordingWriter {
            out_dir,
            tmp_dir,
            dir,
            meta,
        })
    }

    /// The header written so far.
    pub fn meta(&self) -> &RecordingMeta {
        &self.meta
    }

    /// Validates `frame` against the header and writes it. `frame_meta.id` must equal
    /// `frame.id` and be new; the RGB (and depth, labels) must have the frame's camera size;
    /// `frame.dtof` must be present exactly when the header has a `dtof`.
    pub fn add_frame(
        &mut self,
        frame_meta: FrameMeta,
        frame: &Frame,
    ) -> Result<(), RecordingError> {
        let i = self.meta.frames.len();
        let field = format!("frames[{i}]");
        let header = self.out_dir.join(files::RECORDING_JSON);
        let at_header = |e: Invalid| RecordingError::at(&header, e);
        frame_meta.validate(&field).map_err(at_header)?;
        if frame_meta.id != frame.id {
            return Err(at_header(Invalid::new(
                format!("{field}.id"),
                format_args!(
                    "{:?} differs from the frame's id {:?}",
                    frame_meta.id, frame.id
                ),
            )));
        }
        if self.meta.frames.iter().any(|f| f.id == frame.id) {
            return Err(at_header(Invalid::new(
                format!("{field}.id"),
                format_args!("duplicate frame id {:?}", frame.id),
            )));
        }
        let cam: CameraIntrinsics = *frame_meta.camera.as_ref().unwrap_or(&self.meta.camera);
        let n = cam.width as usize * cam.height as usize;
        let dir = self.out_dir.join(files::FRAMES).join(&frame.id);

        // Validate everything before writing anything.
        if self.meta.rgb {
            check_size(&dir.join(files::RGB), frame.rgb.dimensions(), &cam)?;
        }
        let len_err = |name: &str, got: usize| {
            RecordingError::new(
                dir.join(name),
                "size",
                format_args!("expected {n} pixels, found {got}"),
            )
        };
        if let Some(d) = &frame.depth_m {
            if d.len() != n {
                return Err(len_err(files::DEPTH, d.len()));
            }
        }
        if let Some(l) = &frame.labels {
            if l.len() != n {
                return Err(len_err(files::LABELS, l.len()));
            }
            check_labels(l, cam.width)
                .map_err(|e| RecordingError::at(&dir.join(files::LABELS), e))?;
        }
        match (&self.meta.dtof, &frame.dtof) {
            (Some(g), Some(z)) => z
                .validate(g)
                .map_err(|e| RecordingError::at(&dir.join(files::DTOF), e))?,
            (None, None) => {}
            (Some(_), None) => {
                return Err(RecordingError::new(
                    dir.join(files::DTOF),
                    "dtof",
                    "missing: the recording has a dToF, every frame needs zones",
                ))
            }
            (None, Some(_)) => {
                return Err(RecordingError::new(
                    dir.join(files::DTOF),
                    "dtof",
                    "given but the recording header has no \"dtof\" geometry",
                ))
            }
        }

        let tmp = self.tmp_dir.join(files::FRAMES).join(&frame.id);
        std::fs::create_dir_all(&tmp).map_err(|e| RecordingError::io(&tmp, "create", e))?;
        if self.meta.rgb {
            write_png(&tmp.join(files::RGB), &frame.rgb)?;
        }
        if let Some(d) = &frame.depth_m {
            let mm: Vec<u16> = d.iter().map(|&x| depth_m_to_mm(x)).collect();
            let img = ImageBuffer::<Luma<u16>, _>::from_raw(cam.width, cam.height, mm)
                .ok_or_else(|| len_err(files::DEPTH, d.len()))?;
            write_png(&tmp.join(files::DEPTH), &img)?;
        }
        if let Some(l) = &frame.labels {
            let img = GrayImage::from_raw(cam.width, cam.height, l.clone())
                .ok_or_else(|| len_err(files::LABELS, l.len()))?;
            write_png(&tmp.join(files::LABELS), &img)?;
        }
        if let Some(z) = &frame.dtof {
            let path = tmp.join(files::DTOF);
            let text =
                serde_json::to_vec(z).map_err(|e| RecordingError::new(&path, "encode", e))?;
            std::fs::write(&path, text).map_err(|e| RecordingError::io(&path, "write", e))?;
        }
        self.meta.frames.push(frame_meta);
        Ok(())
    }

    /// Writes `recording.json` and moves the recording onto the destination; returns its path.
    pub fn finish(self) -> Result<PathBuf, RecordingError> {
        Ok(self.seal()?.commit()?)
    }

    /// Writes `recording.json` into the temporary folder and hands it back uncommitted, so a
    /// caller can add files (previews) to the complete recording before
    /// [`AtomicDir::commit`] moves it into place; dropping it removes everything.
    pub fn seal(self) -> Result<AtomicDir, RecordingError> {
        let path = self.tmp_dir.join(files::RECORDING_JSON);
        let text = serde_json::to_vec_pretty(&self.meta)
            .map_err(|e| RecordingError::new(&path, "encode", e))?;
        std::fs::write(&path, text).map_err(|e| RecordingError::io(&path, "write", e))?;
        Ok(self.dir)
    }
}
