//! Hand-made recordings for the integration tests (files written directly, not by the writer).
#![allow(dead_code)]

use image::{GrayImage, ImageBuffer, Luma, Rgb, RgbImage};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Background grey of the hand-made RGB.
pub const GREY: Rgb<u8> = Rgb([100, 100, 100]);

/// 64×48 camera, f = 32 px, principal point at the image centre; a 2×2 dToF with a 90°×90°
/// FoV (zone centres at tan = ±0.5), z distance, identity extrinsics.
pub fn recording_json(frames: &[&str]) -> String {
    let frames: Vec<String> = frames
        .iter()
        .enumerate()
        .map(|(i, id)| format!(r#"{{"id": "{id}", "t_s": {}.5}}"#, i))
        .collect();
    format!(
        r#"{{
  "format": "depthor-recording/1",
  "camera": {{"width": 64, "height": 48, "fx": 32.0, "fy": 32.0, "cx": 32.0, "cy": 24.0}},
  "dtof": {{"rows": 2, "cols": 2, "fov_deg": [90.0, 90.0], "distance": "z",
           "max_range_m": 4.0, "zone_rects_px": null}},
  "dtof_to_camera": {{"rotation": [[1,0,0],[0,1,0],[0,0,1]], "translation_m": [0.0, 0.0, 0.0]}},
  "frames": [{}]
}}"#,
        frames.join(", ")
    )
}

/// Zones 1 m, 2 m, 3 m valid (status 5, 9, 5); zone 3 has no target.
pub const DTOF_JSON: &str = r#"{"distance_mm": [1000, 2000, 3000, 1500], "status": [5, 9, 5, 255], "sigma_mm": [1, 2, 3, 4]}"#;

/// Writes a one-frame recording (`000000`) with RGB, dToF and a 16-bit depth map into `dir`.
pub fn write_hand_made(dir: &Path) -> PathBuf {
    let fdir = dir.join("frames/000000");
    std::fs::create_dir_all(&fdir).unwrap();
    std::fs::write(dir.join("recording.json"), recording_json(&["000000"])).unwrap();
    std::fs::write(fdir.join("dtof.json"), DTOF_JSON).unwrap();
    RgbImage::from_pixel(64, 48, GREY)
        .save(fdir.join("rgb.png"))
        .unwrap();
    // Depth: left half 1.5 m, right half unknown.
    let depth = ImageBuffer::<Luma<u16>, Vec<u16>>::from_fn(64, 48, |x, _| {
        Luma([if x < 32 { 1500 } else { 0 }])
    });
    depth.save(fdir.join("depth.png")).unwrap();
    GrayImage::from_pixel(64, 48, Luma([1]))
        .save(fdir.join("labels.png"))
        .unwrap();
    dir.to_path_buf()
}

/// Names in `dir` (sorted).
pub fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Runs the `depthor` binary built for these tests.
pub fn depthor(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_depthor"))
        .args(args)
        .output()
        .expect("run depthor")
}

/// Runs `depthor`, requires success and returns its stdout.
pub fn depthor_ok(args: &[&str]) -> String {
    let o = depthor(args);
    assert!(
        o.status.success(),
        "depthor {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A path as `&str` for command lines.
pub fn arg(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

/// Every file below `dir` (relative path, bytes), sorted.
pub fn tree(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}
