//! ULD result dumps: text files (`*.txt`, `*.log`, `*.dump`; a folder of them or one file) of
//! what ST's VL53L5CX Ultra Lite Driver returned (`VL53L5CX_ResultsData` after
//! `vl53l5cx_get_ranging_data`, one target per zone). Two layouts, told apart line by line:
//!
//! - **One frame a line**: `field=v,v,…` groups separated by spaces, named after the
//!   `VL53L5CX_ResultsData` fields: `distance_mm` and `target_status` (required),
//!   `range_sigma_mm`, `signal_per_spad`, `ambient_per_spad`, `nb_target_detected` (optional);
//!   others (`reflectance`, `nb_spads_enabled`, `silicon_temp_degc`, …) are ignored. 16 or 64
//!   values per field. Example:
//!   `distance_mm=812,790,… target_status=5,5,… range_sigma_mm=3,4,…`
//! - **ST's example printout** (ST's `Example_1_ranging_basic.c` style): a frame starts at a line
//!   `Print data no : <n>` and has one line per zone, `Zone : <k>, Status : <s>, Distance : <d> mm`,
//!   optionally followed by more `Key : value` pairs (`Signal`, `Ambient`, `Sigma`, `Targets`).
//!
//! Other lines (blank, banners, `#` comments) are skipped. Units are the ULD's converted ones:
//! mm, kcps per SPAD, ST status codes (5 and 9 valid; 255 no target). A zone whose
//! `nb_target_detected` is 0 gets status 255, as the ULD does. The recording has zones only, on a
//! virtual 160×160 camera with the sensor's 45° × 45° field of view (as `vl53l5cx-log`).

use std::path::Path;

use image::RgbImage;

use super::{ImportError, ImportedDtof, ImportedFrame};
use crate::recording::{DistanceMeta, DtofFrame, DtofMeta};

use super::vl53l5cx_log::{files_with_extensions, virtual_camera, FOV_DEG, SIDE};

/// One frame being read.
#[derive(Default)]
struct Partial {
    distance: Vec<f32>,
    status: Vec<u8>,
    targets: Option<Vec<u8>>,
    sigma: Option<Vec<f32>>,
    signal: Option<Vec<f32>>,
    ambient: Option<Vec<f32>>,
}

impl Partial {
    fn finish(self, path: &Path, line: usize) -> Result<DtofFrame, ImportError> {
        let n = self.distance.len();
        if n != 16 && n != 64 {
            return Err(ImportError::invalid(
                path,
                format!("frame ending at line {line}: {n} zones (expected 16 or 64)"),
            ));
        }
        let lens = [
            Some(self.status.len()),
            self.targets.as_ref().map(Vec::len),
            self.sigma.as_ref().map(Vec::len),
            self.signal.as_ref().map(Vec::len),
            self.ambient.as_ref().map(Vec::len),
        ];
        if lens.iter().flatten().any(|&l| l != n) {
            return Err(ImportError::invalid(
                path,
                format!("frame ending at line {line}: fields of different lengths"),
            ));
        }
        let mut status = self.status;
        if let Some(t) = &self.targets {
            for (s, &t) in status.iter_mut().zip(t) {
                if t == 0 {
                    *s = 255;
                }
            }
        }
        Ok(DtofFrame {
            distance_mm: self.distance,
            status,
            sigma_mm: self.sigma,
            signal_kcps: self.signal,
            ambient_kcps: self.ambient,
        })
    }
}

fn number(path: &Path, line: usize, what: &str, text: &str) -> Result<f64, ImportError> {
    let t = text.trim().trim_end_matches("mm").trim();
    t.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            ImportError::invalid(
                path,
                format!("line {line}: {what}: {text:?} is not a number"),
            )
        })
}

fn byte(path: &Path, line: usize, what: &str, text: &str) -> Result<u8, ImportError> {
    let v = number(path, line, what, text)?;
    if (0.0..=255.0).contains(&v) && v.fract() == 0.0 {
        Ok(v as u8)
    } else {
        Err(ImportError::invalid(
            path,
            format!("line {line}: {what}: {text:?} is not 0–255"),
        ))
    }
}

/// Parses a `field=v,v,…` line.
fn frame_line(path: &Path, line: usize, text: &str) -> Result<DtofFrame, ImportError> {
    let mut p = Partial::default();
    let (mut has_d, mut has_s) = (false, false);
    for group in text.split_whitespace() {
        let Some((key, values)) = group.split_once('=') else {
            return Err(ImportError::invalid(
                path,
                format!("line {line}: {group:?} is not field=v,v,…"),
            ));
        };
        let vals: Vec<&str> = values.split(',').filter(|v| !v.is_empty()).collect();
        let floats = || -> Result<Vec<f32>, ImportError> {
            vals.iter()
                .map(|v| number(path, line, key, v).map(|x| x as f32))
                .collect()
        };
        let bytes = || -> Result<Vec<u8>, ImportError> {
            vals.iter().map(|v| byte(path, line, key, v)).collect()
        };
        match key {
            "distance_mm" => {
                p.distance = floats()?;
                has_d = true;
            }
            "target_status" => {
                p.status = bytes()?;
                has_s = true;
            }
            "nb_target_detected" => p.targets = Some(bytes()?),
            "range_sigma_mm" => p.sigma = Some(floats()?),
            "signal_per_spad" => p.signal = Some(floats()?),
            "ambient_per_spad" => p.ambient = Some(floats()?),
            _ => {}
        }
    }
    if !has_d || !has_s {
        return Err(ImportError::invalid(
            path,
            format!("line {line}: distance_mm and target_status are required"),
        ));
    }
    p.finish(path, line)
}

/// Parses a `Zone : k, Status : s, Distance : d mm, …` line into `p`.
fn zone_line(path: &Path, line: usize, text: &str, p: &mut Partial) -> Result<(), ImportError> {
    let mut zone = None;
    let (mut status, mut distance) = (None, None);
    let (mut sigma, mut signal, mut ambient, mut targets) = (None, None, None, None);
    for pair in text.split(',') {
        let Some((key, value)) = pair.split_once(':') else {
            continue;
        };
        let key = key.trim().to_ascii_lowercase();
        let value = value.split_whitespace().next().unwrap_or("");
        match key.as_str() {
            "zone" => zone = Some(number(path, line, "Zone", value)? as usize),
            "status" => status = Some(byte(path, line, "Status", value)?),
            "distance" => distance = Some(number(path, line, "Distance", value)? as f32),
            "sigma" => sigma = Some(number(path, line, "Sigma", value)? as f32),
            "signal" => signal = Some(number(path, line, "Signal", value)? as f32),
            "ambient" => ambient = Some(number(path, line, "Ambient", value)? as f32),
            "targets" | "nb_target_detected" => targets = Some(byte(path, line, "Targets", value)?),
            _ => {}
        }
    }
    let (Some(zone), Some(status), Some(distance)) = (zone, status, distance) else {
        return Err(ImportError::invalid(
            path,
            format!("line {line}: a zone line needs Zone, Status and Distance"),
        ));
    };
    if zone != p.distance.len() {
        return Err(ImportError::invalid(
            path,
            format!(
                "line {line}: zone {zone} out of order (expected {})",
                p.distance.len()
            ),
        ));
    }
    p.distance.push(distance);
    p.status.push(status);
    let push = |v: &mut Option<Vec<f32>>, x: Option<f32>| {
        if let Some(x) = x {
            v.get_or_insert_with(Vec::new).push(x);
        }
    };
    push(&mut p.sigma, sigma);
    push(&mut p.signal, signal);
    push(&mut p.ambient, ambient);
    if let Some(t) = targets {
        p.targets.get_or_insert_with(Vec::new).push(t);
    }
    Ok(())
}

/// The frames of one dump's text.
fn parse(path: &Path, text: &str) -> Result<Vec<DtofFrame>, ImportError> {
    let mut frames = Vec::new();
    let mut open: Option<Partial> = None;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let t = raw.trim();
        let lower = t.to_ascii_lowercase();
        if lower.starts_with("print data no") {
            if let Some(p) = open.take() {
                frames.push(p.finish(path, line)?);
            }
            open = Some(Partial::default());
        } else if lower.starts_with("zone") && t.contains(':') {
            let Some(p) = open.as_mut() else {
                return Err(ImportError::invalid(
                    path,
                    format!("line {line}: a zone line before any `Print data no`"),
                ));
            };
            zone_line(path, line, t, p)?;
        } else if t.starts_with("distance_mm=")
            || (t.contains("distance_mm=") && t.contains("target_status="))
        {
            if let Some(p) = open.take() {
                frames.push(p.finish(path, line)?);
            }
            frames.push(frame_line(path, line, t)?);
        }
    }
    if let Some(p) = open.take() {
        frames.push(p.finish(path, text.lines().count())?);
    }
    Ok(frames)
}

/// Loads every dump under `src` (a folder of dumps, or one dump).
pub(super) fn load(src: &Path) -> Result<(super::Loaded, ImportedDtof), ImportError> {
    let files = files_with_extensions(src, &["txt", "log", "dump"])?;
    if files.is_empty() {
        return Err(ImportError::invalid(
            src,
            "no .txt/.log/.dump ULD dumps here",
        ));
    }
    let camera = virtual_camera();
    let (mut frames, mut zones) = (Vec::new(), Vec::<DtofFrame>::new());
    for path in &files {
        let text = std::fs::read_to_string(path).map_err(|err| ImportError::Io {
            path: path.clone(),
            err,
        })?;
        let stem: String = path
            .file_stem()
            .map_or_else(|| "dump".into(), |s| s.to_string_lossy().into_owned())
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        for (i, z) in parse(path, &text)?.into_iter().enumerate() {
            if let Some(first) = zones.first() {
                if first.distance_mm.len() != z.distance_mm.len() {
                    return Err(ImportError::invalid(
                        path,
                        format!(
                            "frame {i}: {} zones, the first frame had {}",
                            z.distance_mm.len(),
                            first.distance_mm.len()
                        ),
                    ));
                }
            }
            frames.push(ImportedFrame {
                id: format!("{stem}_{i:06}"),
                t_s: i as f64,
                rgb: RgbImage::new(SIDE, SIDE),
                depth_m: Vec::new(),
                camera,
            });
            zones.push(z);
        }
    }
    let Some(first) = zones.first() else {
        return Err(ImportError::invalid(src, "no frames in the ULD dumps"));
    };
    let side: u16 = if first.distance_mm.len() == 16 { 4 } else { 8 };
    let notes = vec![
        format!(
            "ULD result dumps: zones only, no colour images (\"rgb\": false) and no reference \
             depth; the camera is a virtual {SIDE}×{SIDE} pinhole with the sensor's \
             {FOV_DEG}°×{FOV_DEG}° field of view"
        ),
        "zones in ULD order, row-major; status as ST reports it (255 where nb_target_detected \
         is 0)"
            .to_string(),
        "t_s is the frame's index in its dump (dumps keep no times)".to_string(),
    ];
    let meta = DtofMeta {
        rows: side,
        cols: side,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn list(n: usize, f: impl Fn(usize) -> String) -> String {
        (0..n).map(f).collect::<Vec<_>>().join(",")
    }

    #[test]
    fn one_frame_a_line() {
        let line = format!(
            "distance_mm={} target_status={} nb_target_detected={} range_sigma_mm={} \
             reflectance={}",
            list(16, |k| format!("{}", 500 + k)),
            list(16, |k| if k == 3 { "9".into() } else { "5".into() }),
            list(16, |k| if k == 7 { "0".into() } else { "1".into() }),
            list(16, |k| format!("{}", k % 4)),
            list(16, |_| "20".into()),
        );
        let text = format!("# dump\n\n{line}\n{line}\n");
        let frames = parse(Path::new("d.txt"), &text).unwrap();
        assert_eq!(frames.len(), 2);
        let f = &frames[0];
        assert_eq!(f.distance_mm[15], 515.0);
        assert_eq!(f.status[3], 9);
        assert_eq!(f.status[7], 255, "no target detected");
        assert_eq!(f.sigma_mm.as_ref().unwrap()[5], 1.0);
        assert!(f.signal_kcps.is_none());
    }

    #[test]
    fn st_example_printout() {
        let mut text = String::from("VL53L5CX ULD ready ! (Version : VL53L5CX_1.3.0)\n");
        for frame in 0..2 {
            text += &format!("Print data no : {frame:3}\n");
            for z in 0..64 {
                text += &format!(
                    "Zone : {z:3}, Status : {:3}, Distance : {:4} mm, Signal : {} kcps/SPADs\n",
                    if z == 10 { 255 } else { 5 },
                    1000 + z + frame,
                    40 + z
                );
            }
            text += "\n";
        }
        let frames = parse(Path::new("d.log"), &text).unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[1].distance_mm[63], 1064.0);
        assert_eq!(frames[0].status[10], 255);
        assert_eq!(frames[0].signal_kcps.as_ref().unwrap()[2], 42.0);
        assert!(frames[0].sigma_mm.is_none());
    }

    #[test]
    fn malformed_dumps_name_the_line() {
        let p = Path::new("bad.txt");
        let cases = [
            ("distance_mm=1,2,3 target_status=5,5,5\n", "line 1: 3 zones"),
            (
                &*format!("distance_mm={}\n", list(16, |_| "1".into())),
                "line 1: distance_mm and target_status are required",
            ),
            (
                &*format!(
                    "distance_mm={} target_status={}\n",
                    list(16, |_| "1".into()),
                    list(16, |_| "300".into())
                ),
                "line 1: target_status: \"300\" is not 0–255",
            ),
            (
                "Zone : 0, Status : 5, Distance : 10 mm\n",
                "line 1: a zone line before",
            ),
            (
                "Print data no : 0\nZone : 1, Status : 5, Distance : 10 mm\n",
                "line 2: zone 1 out of order",
            ),
            (
                "Print data no : 0\nZone : 0, Status : 5, Distance : x mm\n",
                "line 2: Distance: \"x\" is not a number",
            ),
        ];
        for (text, want) in cases {
            let err = parse(p, text).unwrap_err().to_string();
            assert!(err.contains(want), "{text:?}: {err}");
        }
    }
}
