//! Writing a recording atomically: everything goes into a hidden sibling directory
//! `.<name>.partial-<pid>` that is renamed onto the destination only by
//! [`RecordingWriter::finish`]; a writer dropped before that removes it.

use super::error::{Invalid, RecordingError};
use super::files;
use super::meta::{FrameMeta, RecordingMeta};
use super::reader::{check_labels, check_size, Frame};
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
    meta: RecordingMeta,
    options: WriteOptions,
    finished: bool,
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

fn sibling(out_dir: &Path, tag: &str) -> Result<PathBuf, RecordingError> {
    let name = out_dir.file_name().ok_or_else(|| {
        RecordingError::new(out_dir, "output", "must name a directory (not `/` or `..`)")
    })?;
    let parent = match out_dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Ok(parent.join(format!(
        ".{}.{tag}-{}",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Fails when `out_dir` holds something and `overwrite` is not set.
fn check_destination(out_dir: &Path, options: WriteOptions) -> Result<(), RecordingError> {
    if options.overwrite || !out_dir.exists() {
        return Ok(());
    }
    let empty_dir = std::fs::read_dir(out_dir)
        .map(|mut it| it.next().is_none())
        .unwrap_or(false);
    if empty_dir {
        Ok(())
    } else {
        Err(RecordingError::new(
            out_dir,
            "output",
            "exists and is not empty (set overwrite to replace it)",
        ))
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
        check_destination(&out_dir, options)?;
        let tmp_dir = sibling(&out_dir, "partial")?;
        if tmp_dir.exists() {
            std::fs::remove_dir_all(&tmp_dir)
                .map_err(|e| RecordingError::io(&tmp_dir, "remove stale", e))?;
        }
        std::fs::create_dir_all(tmp_dir.join(files::FRAMES))
            .map_err(|e| RecordingError::io(&tmp_dir, "create", e))?;
        Ok(RecordingWriter {
            out_dir,
            tmp_dir,
            meta,
            options,
            finished: false,
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
        let cam_meta = *frame_meta.camera.as_ref().unwrap_or(&self.meta.camera);
        let cam: CameraIntrinsics = cam_meta.into();
        let n = cam_meta.pixels();
        let dir = self.out_dir.join(files::FRAMES).join(&frame.id);

        // Validate everything before writing anything.
        check_size(&dir.join(files::RGB), frame.rgb.dimensions(), &cam)?;
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
        write_png(&tmp.join(files::RGB), &frame.rgb)?;
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
    pub fn finish(mut self) -> Result<PathBuf, RecordingError> {
        let path = self.tmp_dir.join(files::RECORDING_JSON);
        let text = serde_json::to_vec_pretty(&self.meta)
            .map_err(|e| RecordingError::new(&path, "encode", e))?;
        std::fs::write(&path, text).map_err(|e| RecordingError::io(&path, "write", e))?;
        check_destination(&self.out_dir, self.options)?;
        let out = &self.out_dir;
        if out.is_dir() {
            if self.options.overwrite {
                let old = sibling(out, "old")?;
                std::fs::rename(out, &old).map_err(|e| RecordingError::io(out, "move aside", e))?;
                std::fs::rename(&self.tmp_dir, out)
                    .map_err(|e| RecordingError::io(out, "rename onto", e))?;
                // The new recording is in place; failing to delete the old one loses nothing.
                let _ = std::fs::remove_dir_all(&old);
                self.finished = true;
                return Ok(self.out_dir.clone());
            }
            std::fs::remove_dir(out).map_err(|e| RecordingError::io(out, "replace empty", e))?;
        } else if out.exists() {
            std::fs::remove_file(out).map_err(|e| RecordingError::io(out, "replace", e))?;
        }
        std::fs::rename(&self.tmp_dir, out)
            .map_err(|e| RecordingError::io(out, "rename onto", e))?;
        self.finished = true;
        Ok(self.out_dir.clone())
    }
}

impl Drop for RecordingWriter {
    fn drop(&mut self) {
        if !self.finished {
            let _ = std::fs::remove_dir_all(&self.tmp_dir);
        }
    }
}
