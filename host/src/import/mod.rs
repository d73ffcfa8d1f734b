//! Importers of the real RGB-D sets kept under `data/real/<folder>` (each folder's `README.txt`
//! states its formats): every loader turns one set into [`ImportedFrame`]s of 8-bit RGB, planar z
//! depth in metres at the RGB size (0 = unknown) and the RGB camera's intrinsics, plus `notes` on
//! every assumption it had to make. Writing them as a `depthor-recording/1` is the CLI's job.
//!
//! One file per kind of set; [`pfm`] is the Portable Float Map reader Middlebury needs,
//! `decode` and `resample` hold the helpers the loaders share.

mod arkit;
mod decode;
mod middlebury;
mod nyu;
mod nyu_raw;
pub mod pfm;
mod redwood;
mod resample;
mod sun;
mod tum;
mod uld_dump;
mod vl53l5cx_log;
mod zjul5;

use std::path::{Path, PathBuf};

use depthor_core::calibration::CameraIntrinsics;
use image::RgbImage;

/// Which kind of set [`load`] reads. CLI names: `middlebury`, `nyu`, `redwood`, `tum`, `sun`,
/// `nyu-raw`, `arkit`, `zjul5`, `vl53l5cx-log`, `uld-dump`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ImportKind {
    /// Middlebury 2014 stereo (MiddEval3, `<scene>/{im0.png,disp0GT.pfm,calib.txt}`): every scene.
    Middlebury,
    /// NYU Depth v2 test frames of the Metric3D demo (`rgb/`, `depth/`, `test_annotations.json`).
    Nyu,
    /// Redwood-style sequence of Open3D's test data (`color/`, `depth/`, `camera_primesense.json`).
    Redwood,
    /// The TUM RGB-D frame of Open3D's test data (`other_formats/TUM_*`).
    Tum,
    /// The SUN RGB-D frame of Open3D's test data (`other_formats/SUN_*`).
    Sun,
    /// The raw NYU v2 Kinect frame of Open3D's test data (`other_formats/NYU_*`).
    NyuRaw,
    /// The PromptDA iPhone example: `image.jpg` + ARKit LiDAR `arkit_depth.png`.
    Arkit,
    /// ZJU-L5 (Deltar): `.h5` files with rgb, depth, hist_data, fr, mask; zones kept.
    Zjul5,
    /// VL53L5CX zone logs (`*.json`, `{"tof": {"distances": [[64 mm]…]}}`): zones only, no RGB.
    #[value(name = "vl53l5cx-log")]
    Vl53l5cxLog,
    /// ST ULD result dumps (`*.txt`/`*.log`/`*.dump`: `VL53L5CX_ResultsData` fields one frame a
    /// line, or ST's example printout): zones only, no RGB.
    #[value(name = "uld-dump")]
    UldDump,
}

impl ImportKind {
    /// The kind's CLI name (`nyu-raw`, …).
    pub fn cli_name(self) -> &'static str {
        match self {
            ImportKind::Middlebury => "middlebury",
            ImportKind::Nyu => "nyu",
            ImportKind::Redwood => "redwood",
            ImportKind::Tum => "tum",
            ImportKind::Sun => "sun",
            ImportKind::NyuRaw => "nyu-raw",
            ImportKind::Arkit => "arkit",
            ImportKind::Zjul5 => "zjul5",
            ImportKind::Vl53l5cxLog => "vl53l5cx-log",
            ImportKind::UldDump => "uld-dump",
        }
    }
}

/// One imported RGB-D frame.
#[derive(Clone, Debug)]
pub struct ImportedFrame {
    /// Frame id, usable as a directory name (`frames/<id>/`).
    pub id: String,
    /// Capture time in seconds from the set's first frame (an ordinal where the set has no times;
    /// the set's notes say which).
    pub t_s: f64,
    /// 8-bit sRGB image.
    pub rgb: RgbImage,
    /// Planar z depth in metres, row-major, `rgb.width() × rgb.height()`, 0 = unknown.
    pub depth_m: Vec<f32>,
    /// Intrinsics of `rgb` (its width and height included).
    pub camera: CameraIntrinsics,
}

/// Summary of a depth map's valid pixels (finite and > 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthStats {
    /// Number of valid pixels.
    pub valid: usize,
    /// Number of pixels.
    pub total: usize,
    /// Smallest valid depth, metres (`+inf` when none is valid).
    pub min_m: f32,
    /// Largest valid depth, metres (`-inf` when none is valid).
    pub max_m: f32,
}

impl DepthStats {
    /// Statistics of one depth map.
    pub fn of(depth_m: &[f32]) -> Self {
        let mut s = DepthStats {
            valid: 0,
            total: depth_m.len(),
            min_m: f32::INFINITY,
            max_m: f32::NEG_INFINITY,
        };
        for &z in depth_m {
            if z.is_finite() && z > 0.0 {
                s.valid += 1;
                s.min_m = s.min_m.min(z);
                s.max_m = s.max_m.max(z);
            }
        }
        s
    }

    /// Pools two summaries (e.g. over the frames of a set).
    pub fn merge(self, o: DepthStats) -> Self {
        DepthStats {
            valid: self.valid + o.valid,
            total: self.total + o.total,
            min_m: self.min_m.min(o.min_m),
            max_m: self.max_m.max(o.max_m),
        }
    }

    /// Fraction of valid pixels (0 for an empty map).
    pub fn valid_fraction(&self) -> f64 {
        if self.total == 0 {
            0.0
        } else {
            self.valid as f64 / self.total as f64
        }
    }
}

impl ImportedFrame {
    /// Statistics of this frame's depth.
    pub fn depth_stats(&self) -> DepthStats {
        DepthStats::of(&self.depth_m)
    }
}

/// One imported set.
#[derive(Clone, Debug)]
pub struct ImportedSet {
    /// Name usable as a file name: `<source folder>-<kind>` (e.g. `open3d-rgbd-testdata-tum`).
    pub name: String,
    /// Frames in source order.
    pub frames: Vec<ImportedFrame>,
    /// Assumptions and choices the importer made (guessed intrinsics, resampling, byte order…).
    pub notes: Vec<String>,
    /// The set's own dToF zones (ZJU-L5, VL53L5CX logs, ULD dumps), one zone frame per frame.
    pub dtof: Option<ImportedDtof>,
    /// Whether the frames have colour images (`false`: zone logs; see docs/recording.md).
    pub has_rgb: bool,
}

/// A set's own dToF sensor: its geometry and one zone frame per imported frame.
#[derive(Clone, Debug)]
pub struct ImportedDtof {
    /// Zone grid, field of view, zone rectangles.
    pub meta: crate::recording::DtofMeta,
    /// Zone measurements, in the order of [`ImportedSet::frames`].
    pub frames: Vec<crate::recording::DtofFrame>,
}

impl ImportedSet {
    /// Depth statistics pooled over all frames.
    pub fn depth_stats(&self) -> DepthStats {
        self.frames
            .iter()
            .map(ImportedFrame::depth_stats)
            .fold(DepthStats::of(&[]), DepthStats::merge)
    }
}

/// Why a set could not be imported. Every variant names the file; `Display` is one line.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// The file could not be read (missing, unreadable).
    #[error("{}: {err}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        err: std::io::Error,
    },
    /// The `image` crate could not decode the file.
    #[error("{}: {err}", path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        err: image::ImageError,
    },
    /// The file was read but its content is not what the set's format says.
    #[error("{}: {what}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The field and what is wrong with it.
        what: String,
    },
}

impl ImportError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            ImportError::Io { path, .. }
            | ImportError::Decode { path, .. }
            | ImportError::Invalid { path, .. } => path,
        }
    }

    pub(crate) fn invalid(path: &Path, what: impl Into<String>) -> Self {
        ImportError::Invalid {
            path: path.to_path_buf(),
            what: what.into(),
        }
    }
}

/// Loads the set of kind `kind` from `src`, the set's folder as under `data/real/<folder>`
/// (a folder may hold several kinds: each picks its own files).
pub fn load(kind: ImportKind, src: &Path) -> Result<ImportedSet, ImportError> {
    let (mut dtof, mut has_rgb) = (None, true);
    let (frames, notes) = match kind {
        ImportKind::Middlebury => middlebury::load(src)?,
        ImportKind::Nyu => nyu::load(src)?,
        ImportKind::Redwood => redwood::load(src)?,
        ImportKind::Tum => tum::load(src)?,
        ImportKind::Sun => sun::load(src)?,
        ImportKind::NyuRaw => nyu_raw::load(src)?,
        ImportKind::Arkit => arkit::load(src)?,
        ImportKind::Zjul5 => {
            let (loaded, zones) = zjul5::load(src)?;
            dtof = Some(zones);
            loaded
        }
        ImportKind::Vl53l5cxLog => {
            let (loaded, zones) = vl53l5cx_log::load(src)?;
            dtof = Some(zones);
            has_rgb = false;
            loaded
        }
        ImportKind::UldDump => {
            let (loaded, zones) = uld_dump::load(src)?;
            dtof = Some(zones);
            has_rgb = false;
            loaded
        }
    };
    let folder = src
        .canonicalize()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_else(|| "set".to_owned());
    Ok(ImportedSet {
        name: format!("{folder}-{}", kind.cli_name()),
        frames,
        notes,
        dtof,
        has_rgb,
    })
}

/// What every per-kind loader returns: frames and notes.
type Loaded = (Vec<ImportedFrame>, Vec<String>);

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn cli_names_match_clap() {
        for k in ImportKind::value_variants() {
            let v = k.to_possible_value().unwrap();
            assert_eq!(v.get_name(), k.cli_name());
        }
        assert_eq!(
            ImportKind::from_str("nyu-raw", false),
            Ok(ImportKind::NyuRaw)
        );
    }

    #[test]
    fn depth_stats_skip_unknown() {
        let s = DepthStats::of(&[0.0, 1.5, f32::NAN, 0.5, -1.0]);
        assert_eq!((s.valid, s.total, s.min_m, s.max_m), (2, 5, 0.5, 1.5));
        assert_eq!(s.valid_fraction(), 0.4);
        let m = s.merge(DepthStats::of(&[2.0, 0.0, 0.0]));
        assert_eq!((m.valid, m.total, m.min_m, m.max_m), (3, 8, 0.5, 2.0));
        assert_eq!(DepthStats::of(&[]).valid_fraction(), 0.0);
    }
}
