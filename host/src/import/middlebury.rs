//! Middlebury 2014 stereo (MiddEval3 layout): every `<scene>/` of the set folder holding
//! `calib.txt`, `im0.png` (left view, 8-bit RGB) and `disp0GT.pfm` (left disparity, pixels).
//!
//! Depth from disparity (Scharstein et al., GCPR 2014; the set's `calib.txt` description):
//! `Z[mm] = baseline[mm] · f[px] / (d[px] + doffs[px])`, with `f` the `cam0` focal length.
//! `+inf` (unknown), non-finite and non-positive disparities, and non-positive depths become 0.

use std::path::Path;

use depthor_core::calibration::CameraIntrinsics;

use super::decode::{read_rgb, read_text};
use super::pfm::read_pfm;
use super::{ImportError, ImportedFrame, Loaded};

/// The `calib.txt` fields the importer uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Calib {
    /// `cam0` as intrinsics (`fx`, `fy`, `cx`, `cy`; width and height from the file).
    pub cam0: CameraIntrinsics,
    /// x-difference of the principal points, `doffs = cx1 − cx0`, pixels.
    pub doffs: f64,
    /// Camera baseline, millimetres.
    pub baseline_mm: f64,
}

/// What is wrong with a `calib.txt`: the field, and what is wrong with it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CalibError {
    /// A `key=` line is absent.
    #[error("missing field {key}")]
    Missing {
        /// The key.
        key: &'static str,
    },
    /// A value that is not a finite number.
    #[error("{key}: {value:?} is not a number")]
    NotNumber {
        /// The key (`cam0` for a matrix entry).
        key: &'static str,
        /// The text.
        value: String,
    },
    /// A value that is not a positive integer.
    #[error("{key}: {value:?} is not a positive integer")]
    NotPositiveInt {
        /// The key.
        key: &'static str,
        /// The text.
        value: String,
    },
    /// `cam0` is not in brackets.
    #[error("cam0: expected [fx 0 cx; 0 fy cy; 0 0 1], found {found:?}")]
    Cam0Brackets {
        /// The value.
        found: String,
    },
    /// `cam0` does not hold nine numbers.
    #[error("cam0: expected 9 numbers, found {found}")]
    Cam0Count {
        /// How many it holds.
        found: usize,
    },
    /// `cam0`'s last row or lower triangle is not a pinhole camera's.
    #[error("cam0: not a pinhole matrix [fx s cx; 0 fy cy; 0 0 1]: {inner:?}")]
    NotPinhole {
        /// The matrix text.
        inner: String,
    },
    /// A focal length is not positive.
    #[error("cam0: focal lengths must be positive, found fx={fx} fy={fy}")]
    Focal {
        /// fx.
        fx: f64,
        /// fy.
        fy: f64,
    },
    /// The baseline is not positive.
    #[error("baseline: must be positive, found {0}")]
    Baseline(f64),
}

/// Parses `calib.txt` (`key=value` lines; `cam0=[fx 0 cx; 0 fy cy; 0 0 1]`).
/// The error names the field and what is wrong with it.
pub(crate) fn parse_calib(text: &str) -> Result<Calib, CalibError> {
    let field = |key: &'static str| -> Result<&str, CalibError> {
        text.lines()
            .filter_map(|l| l.split_once('='))
            .find(|(k, _)| k.trim() == key)
            .map(|(_, v)| v.trim())
            .ok_or(CalibError::Missing { key })
    };
    let number = |key: &'static str| -> Result<f64, CalibError> {
        let v = field(key)?;
        v.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| CalibError::NotNumber {
                key,
                value: v.to_string(),
            })
    };
    let positive_int = |key: &'static str| -> Result<u32, CalibError> {
        let v = field(key)?;
        v.parse::<u32>()
            .ok()
            .filter(|&x| x > 0)
            .ok_or_else(|| CalibError::NotPositiveInt {
                key,
                value: v.to_string(),
            })
    };
    let cam = field("cam0")?;
    let inner = cam
        .strip_prefix('[')
        .and_then(|c| c.strip_suffix(']'))
        .ok_or_else(|| CalibError::Cam0Brackets {
            found: cam.to_string(),
        })?;
    let m: Vec<f64> = inner
        .split(|c: char| c == ';' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| CalibError::NotNumber {
                    key: "cam0",
                    value: t.to_string(),
                })
        })
        .collect::<Result<_, _>>()?;
    if m.len() != 9 {
        return Err(CalibError::Cam0Count { found: m.len() });
    }
    if m[3] != 0.0 || m[6] != 0.0 || m[7] != 0.0 || m[8] != 1.0 {
        return Err(CalibError::NotPinhole {
            inner: inner.to_string(),
        });
    }
    if m[0] <= 0.0 || m[4] <= 0.0 {
        return Err(CalibError::Focal { fx: m[0], fy: m[4] });
    }
    let baseline_mm = number("baseline")?;
    if baseline_mm <= 0.0 {
        return Err(CalibError::Baseline(baseline_mm));
    }
    Ok(Calib {
        cam0: CameraIntrinsics {
            width: positive_int("width")?,
            height: positive_int("height")?,
            fx: m[0] as f32,
            fy: m[4] as f32,
            cx: m[2] as f32,
            cy: m[5] as f32,
        },
        doffs: number("doffs")?,
        baseline_mm,
    })
}

/// Planar depth in metres of one disparity, 0 when unknown or invalid.
pub(crate) fn depth_from_disparity(d: f32, calib: &Calib) -> f32 {
    if !d.is_finite() || d <= 0.0 {
        return 0.0;
    }
    let z_mm = calib.baseline_mm * f64::from(calib.cam0.fx) / (f64::from(d) + calib.doffs);
    if z_mm.is_finite() && z_mm > 0.0 {
        (z_mm / 1000.0) as f32
    } else {
        0.0
    }
}

/// Loads one scene folder.
fn load_scene(dir: &Path, id: String, t_s: f64) -> Result<ImportedFrame, ImportError> {
    let calib_path = dir.join("calib.txt");
    let calib = parse_calib(&read_text(&calib_path)?)
        .map_err(|e| ImportError::invalid(&calib_path, e.to_string()))?;
    let (w, h) = (calib.cam0.width, calib.cam0.height);
    let pfm_path = dir.join("disp0GT.pfm");
    let disp = read_pfm(&pfm_path)?;
    if (disp.width, disp.height) != (w, h) {
        return Err(ImportError::invalid(
            &pfm_path,
            format!(
                "size {}×{} differs from calib.txt's {w}×{h}",
                disp.width, disp.height
            ),
        ));
    }
    let rgb_path = dir.join("im0.png");
    let rgb = read_rgb(&rgb_path)?;
    if rgb.dimensions() != (w, h) {
        return Err(ImportError::invalid(
            &rgb_path,
            format!(
                "size {}×{} differs from calib.txt's {w}×{h}",
                rgb.width(),
                rgb.height()
            ),
        ));
    }
    let depth_m = disp
        .data
        .iter()
        .map(|&d| depth_from_disparity(d, &calib))
        .collect();
    Ok(ImportedFrame {
        id,
        t_s,
        rgb,
        depth_m,
        camera: calib.cam0,
    })
}

/// Loads every scene (sub-folder with a `calib.txt`) of `src`, in name order.
pub(crate) fn load(src: &Path) -> Result<Loaded, ImportError> {
    let entries = std::fs::read_dir(src).map_err(|err| ImportError::Io {
        path: src.to_path_buf(),
        err,
    })?;
    let mut scenes = Vec::new();
    for e in entries {
        let e = e.map_err(|err| ImportError::Io {
            path: src.to_path_buf(),
            err,
        })?;
        if e.path().join("calib.txt").is_file() {
            scenes.push(e.path());
        }
    }
    scenes.sort();
    if scenes.is_empty() {
        return Err(ImportError::invalid(
            src,
            "no scene folder with a calib.txt",
        ));
    }
    let frames = scenes
        .iter()
        .enumerate()
        .map(|(i, dir)| {
            let id = dir
                .file_name()
                .map_or_else(|| format!("{i:06}"), |n| n.to_string_lossy().into_owned());
            load_scene(dir, id, i as f64)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let notes = vec![
        "middlebury: depth = baseline·f/(d + doffs) from disp0GT.pfm and calib.txt (cam0 fx as f); \
         +inf/non-finite/non-positive disparity → 0 (unknown); mask0nocc.png is not applied, so \
         occluded pixels keep their ground-truth depth"
            .to_owned(),
        "middlebury: each scene is one frame with its own camera (cam0); scenes are unrelated stills, \
         t_s is the scene's ordinal"
            .to_owned(),
    ];
    Ok((frames, notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ADIRONDACK: &str = "cam0=[ 1038.018 0 322.037 ; 0 1038.018 243.393 ; 0 0 1 ] \n\
        cam1=[ 1038.018 0 375.308 ; 0 1038.018 243.393 ; 0 0 1 ]\n doffs= 53.271 \nbaseline= 176.252\n \
        width= 718\nheight= 496\n ndisp= 73\n";

    #[test]
    fn parses_calib_and_converts_disparity() {
        let c = parse_calib(ADIRONDACK).unwrap();
        assert_eq!(
            c.cam0,
            CameraIntrinsics {
                width: 718,
                height: 496,
                fx: 1038.018,
                fy: 1038.018,
                cx: 322.037,
                cy: 243.393
            }
        );
        assert_eq!((c.doffs, c.baseline_mm), (53.271, 176.252));
        // 176.252 · 1038.018 / (8 + 53.271) = 2985.96 mm (README: vmin 8 ↔ the far end).
        assert!((depth_from_disparity(8.0, &c) - 2.985_96).abs() < 1e-5);
        for bad in [f32::INFINITY, f32::NAN, 0.0, -3.0] {
            assert_eq!(depth_from_disparity(bad, &c), 0.0);
        }
    }

    #[test]
    fn calib_errors_name_the_field() {
        let no_doffs = ADIRONDACK.replace("doffs", "dofs");
        assert_eq!(
            parse_calib(&no_doffs).unwrap_err().to_string(),
            "missing field doffs"
        );
        let short = ADIRONDACK.replacen(" 0 0 1 ]", " 0 0 ]", 1);
        assert_eq!(
            parse_calib(&short).unwrap_err().to_string(),
            "cam0: expected 9 numbers, found 8"
        );
        let nan = ADIRONDACK.replace("baseline= 176.252", "baseline= abc");
        assert_eq!(
            parse_calib(&nan).unwrap_err().to_string(),
            "baseline: \"abc\" is not a number"
        );
        let w0 = ADIRONDACK.replace("width= 718", "width= 0");
        assert_eq!(
            parse_calib(&w0).unwrap_err().to_string(),
            "width: \"0\" is not a positive integer"
        );
    }
}
