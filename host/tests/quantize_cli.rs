//! `depthor quantize` on the committed `mcu` export: calibration frames from a scene
//! configuration or a recording are counted and drawn, the blob is written, the report runs on a
//! recording's frames, and a bad scene configuration or recording is one clean error naming it.

mod common;

use common::{arg, depthor, depthor_ok};
use std::path::PathBuf;

fn models() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models")
}

/// `depthor quantize --graph GRAPH --out OUT --frames N` followed by `extra`.
fn quantize_args<'a>(
    graph: &'a str,
    out: &'a str,
    frames: &'a str,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut v = vec![
        "quantize", "--graph", graph, "--out", out, "--frames", frames,
    ];
    v.extend_from_slice(extra);
    v
}

#[test]
fn scene_config_frames_join_the_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("m.dblob");
    let graph = models().join("mcu/graph.json");
    let close = models().join("scenes/close_range.json");
    let stdout = depthor_ok(&quantize_args(
        arg(&graph),
        arg(&out),
        "2",
        &["--scene-config", arg(&close), "--scene-config-frames", "2"],
    ));
    assert!(
        stdout.contains("calibration: 4 frames (2 of them from"),
        "{stdout}"
    );
    let blob = std::fs::read(&out).unwrap();
    assert_eq!(
        blob.len(),
        std::fs::metadata(models().join("mcu/depthor.dblob"))
            .unwrap()
            .len() as usize
    );
}

#[test]
fn bad_scene_config_names_its_file_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("bad_scenes.json");
    std::fs::write(&cfg, r#"{"room_depth_m": [4.0, 1.0]}"#).unwrap();
    let out = tmp.path().join("m.dblob");
    let o = depthor(&quantize_args(
        arg(&models().join("mcu/graph.json")),
        arg(&out),
        "1",
        &["--scene-config", arg(&cfg), "--scene-config-frames", "1"],
    ));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("bad_scenes.json"), "{err}");
    assert!(err.contains("room_depth_m"), "{err}");
    assert!(!out.exists());
}

/// A 2-frame rendered recording at the mcu preset's size.
fn tiny_recording(dir: &std::path::Path) -> PathBuf {
    let rec = dir.join("rec");
    depthor_ok(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "2",
        "--seed",
        "77",
        "--out",
        arg(&rec),
    ]);
    rec
}

#[test]
fn recording_frames_join_the_calibration_and_the_report() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tiny_recording(tmp.path());
    let graph = models().join("mcu/graph.json");
    let plain = tmp.path().join("plain.dblob");
    depthor_ok(&quantize_args(arg(&graph), arg(&plain), "1", &[]));
    let out = tmp.path().join("m.dblob");
    let stdout = depthor_ok(&quantize_args(
        arg(&graph),
        arg(&out),
        "1",
        &[
            "--calibration-recording",
            arg(&rec),
            "--report",
            "--report-recording",
            arg(&rec),
            "--eval-frames",
            "1",
        ],
    ));
    assert!(
        stdout.contains("calibration: 3 frames (2 of them from recording"),
        "{stdout}"
    );
    assert!(
        stdout.contains("int8 vs f32 on 1 frames (recording"),
        "{stdout}"
    );
    // the recording's frames moved some activation ranges
    assert_ne!(std::fs::read(&out).unwrap(), std::fs::read(&plain).unwrap());
}

#[test]
fn missing_calibration_recording_names_it_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("no_such_recording");
    let out = tmp.path().join("m.dblob");
    let o = depthor(&quantize_args(
        arg(&models().join("mcu/graph.json")),
        arg(&out),
        "1",
        &["--calibration-recording", arg(&missing)],
    ));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("no_such_recording"), "{err}");
    assert!(!out.exists());
}

/// `--ranges-file`: malformed JSON, an unknown value name and a reversed range are each one
/// error naming the file (and the value), and no blob is written.
#[test]
fn bad_ranges_file_names_its_file_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("m.dblob");
    let graph = models().join("mcu/graph.json");
    for (body, needle) in [
        ("{\"prior.relu\": [0.0]}", "expected"),
        ("{\"no.such.value\": [0.0, 1.0]}", "no.such.value"),
        ("{\"prior.relu\": [3.0, 1.0]}", "prior.relu"),
    ] {
        let file = tmp.path().join("bad_ranges.json");
        std::fs::write(&file, body).unwrap();
        let o = depthor(&quantize_args(
            arg(&graph),
            arg(&out),
            "1",
            &["--ranges-file", arg(&file)],
        ));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{body}");
        assert!(err.contains("bad_ranges.json"), "{body}: {err}");
        assert!(err.contains(needle), "{body}: {err}");
        assert!(!out.exists(), "{body}");
    }
}
