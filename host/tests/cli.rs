//! The real `depthor` binary on hand-made and malformed recordings.

mod common;

use common::{arg as s, depthor, depthor_ok, entries, write_hand_made, GREY};
use depthor_host::viz::turbo;
use std::path::Path;

#[test]
fn project_draws_turbo_discs_at_the_projected_zone_centres() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    let out = tmp.path().join("proj.png");
    let o = depthor(&["project", s(&rec), "--frame", "000000", "--out", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("zones 4  projected 3  invalid_status 1  bad_distance 0"),
        "{stdout}"
    );

    // The titled figure: the 64×48 frame scaled up beside a colour bar. The pixel layout of
    // the discs is checked in `viz`'s unit tests; here: the three zone colours (1 m blue end,
    // 2 m middle, 3 m red end of the bar's range) are drawn, the no-target zone is not.
    let img = image::open(&out).unwrap().to_rgb8();
    assert!(
        img.width() > 64 * 4 && img.height() > 48 * 4,
        "{:?}",
        img.dimensions()
    );
    let has = |c: image::Rgb<u8>| img.pixels().any(|p| *p == c);
    for t in [0.0, 0.5, 1.0] {
        assert!(has(turbo(t)), "no disc of colour turbo({t})");
    }
    let title_ink = (0..img.width()).any(|x| (0..30).any(|y| img.get_pixel(x, y)[0] < 80));
    assert!(title_ink, "no title text");
    assert!(has(GREY));
    // The zone points beside the picture.
    let csv = std::fs::read_to_string(tmp.path().join("proj.csv")).unwrap();
    assert_eq!(csv.lines().next(), Some("zone,u_px,v_px,depth_m"));
    assert_eq!(csv.lines().count(), 1 + 3, "{csv}");
    assert_eq!(entries(tmp.path()), vec!["proj.csv", "proj.png", "rec"]);
}

#[test]
fn project_takes_the_frame_by_index_or_id_and_out_is_a_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    let out = tmp.path().join("proj");
    for frame in ["0", "000000"] {
        let o = depthor(&[
            "project",
            "--recording",
            s(&rec),
            "--frame",
            frame,
            "--out",
            s(&out),
            "--overwrite",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_eq!(
        entries(&out),
        vec!["project_000000.csv", "project_000000.png"]
    );
    // Without --overwrite an existing picture is refused.
    let o = depthor(&["project", "--recording", s(&rec), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--overwrite"));
    // An index past the end names the range.
    let o = depthor(&["project", "-r", s(&rec), "--frame", "7", "--out", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("indices 0 to 0"), "{err}");
}

#[test]
fn every_subcommand_has_examples_in_its_help() {
    for cmd in [
        "bench",
        "demo",
        "eval",
        "firmware-image",
        "firmware-replay",
        "gap",
        "gap-bench",
        "import",
        "info",
        "merge",
        "sim",
        "project",
        "quantize",
    ] {
        let o = depthor(&[cmd, "--help"]);
        let help = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{cmd}: {help}");
        assert!(
            help.contains("Examples:") && help.contains(&format!("depthor {cmd}")),
            "{cmd} --help has no examples:\n{help}"
        );
    }
}

#[test]
fn info_json_is_machine_readable() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    let o = depthor(&["info", "--recording", s(&rec), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["frames"], 1);
    assert_eq!(v["per_frame"][0]["zones_valid"], 3);
    assert_eq!(v["per_frame"][0]["depth"]["median_m"], 1.5);
}

#[test]
fn info_reports_depth_statistics_and_valid_zones() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    let o = depthor(&["info", s(&rec)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("frames     1"), "{stdout}");
    assert!(stdout.contains("64×48"), "{stdout}");
    // Left half at 1.5 m: 50 % valid, min = median = max = 1.5.
    assert!(
        stdout.contains("depth valid  50.0 %  min 1.500 median 1.500 max 1.500 m"),
        "{stdout}"
    );
    assert!(stdout.contains("zones valid 3/4"), "{stdout}");
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Runs `info` and `project` on a broken recording: each must print exactly one `error:` line
/// naming `file` and `field`, exit 2, and leave nothing behind.
fn assert_clean_failure(tmp: &Path, rec: &Path, file: &str, field: &str) {
    let before = entries(tmp);
    let out = tmp.join("out.png");
    for args in [
        vec!["info", s(rec)],
        vec!["project", s(rec), "--frame", "000000", "--out", s(&out)],
    ] {
        let o = depthor(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
        assert!(lines[0].starts_with("error: "), "{stderr}");
        assert!(
            lines[0].contains(file),
            "{args:?}: want {file:?} in {stderr}"
        );
        assert!(
            lines[0].contains(field),
            "{args:?}: want {field:?} in {stderr}"
        );
        assert!(!out.exists());
        assert_eq!(entries(tmp), before, "nothing written");
    }
}

#[test]
fn truncated_recording_json_is_one_clean_error() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    let text = std::fs::read_to_string(rec.join("recording.json")).unwrap();
    std::fs::write(rec.join("recording.json"), &text[..text.len() / 2]).unwrap();
    assert_clean_failure(tmp.path(), &rec, "rec/recording.json", "JSON syntax");
}

#[test]
fn wrong_zone_count_names_dtof_json_and_distance_mm() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    std::fs::write(
        rec.join("frames/000000/dtof.json"),
        r#"{"distance_mm": [1000, 2000, 3000], "status": [5, 9, 5, 255]}"#,
    )
    .unwrap();
    assert_clean_failure(
        tmp.path(),
        &rec,
        "rec/frames/000000/dtof.json",
        "distance_mm: expected 4 values (2×2 zones), found 3",
    );
}

#[test]
fn eight_bit_depth_png_is_rejected() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    image::GrayImage::from_pixel(64, 48, image::Luma([7]))
        .save(rec.join("frames/000000/depth.png"))
        .unwrap();
    assert_clean_failure(
        tmp.path(),
        &rec,
        "rec/frames/000000/depth.png",
        "color type: expected 16-bit grayscale",
    );
}

#[test]
fn missing_frame_directory_names_the_frame_entry() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    std::fs::write(
        rec.join("recording.json"),
        common::recording_json(&["000000", "000001"]),
    )
    .unwrap();
    assert_clean_failure(
        tmp.path(),
        &rec,
        "rec/frames/000001",
        "frames[1].id: frame directory does not exist",
    );
}

#[test]
fn wrong_field_type_names_the_nested_field() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    let text = common::recording_json(&["000000"]).replace("\"fx\": 32.0", "\"fx\": \"32\"");
    std::fs::write(rec.join("recording.json"), text).unwrap();
    assert_clean_failure(
        tmp.path(),
        &rec,
        "rec/recording.json",
        "camera.fx: expected a number, found a string",
    );
}

#[test]
fn unknown_frame_id_is_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    let out = tmp.path().join("o.png");
    let o = depthor(&["project", s(&rec), "--frame", "nope", "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(String::from_utf8_lossy(&o.stderr).lines().count(), 1);
    assert!(!out.exists());
}

/// A reader that closes the pipe before `depthor` writes (as `depthor … | head` does) ends it
/// quietly: without the default SIGPIPE action the first `println!` panicked with a backtrace.
#[cfg(unix)]
#[test]
fn closed_stdout_ends_quietly_not_in_a_panic() {
    use std::process::{Command, Stdio};
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_hand_made(&tmp.path().join("rec"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_depthor"))
        .args(["info", "--recording", s(&rec)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_ne!(out.status.code(), Some(101), "{err}");
}

#[test]
fn bench_engine_runs_one_runtime_alone_and_refuses_an_unknown_one() {
    let args = |runtime: &'static str| {
        [
            "bench",
            "engine",
            "--model",
            "mcu_lite",
            "--runs",
            "1",
            "--kernels",
            "portable",
            "--runtime",
            runtime,
        ]
    };
    // Each runtime alone prints its own figures and none of the other's (no ratio, no SQNR).
    let core = depthor_ok(&args("core"));
    assert!(core.contains("core int8 alone"), "{core}");
    assert!(core.contains("core int8 portable"), "{core}");
    assert!(core.contains("MACs per frame"), "{core}");
    assert!(!core.contains("tract"), "{core}");
    assert!(!core.contains("SQNR"), "{core}");
    let tract = depthor_ok(&args("tract"));
    assert!(tract.contains("tract f32 alone"), "{tract}");
    assert!(tract.contains("tract f32  "), "{tract}");
    assert!(tract.contains("MACs per frame"), "{tract}");
    assert!(!tract.contains("core int8"), "{tract}");
    assert!(!tract.contains("arena bytes"), "{tract}");
    // Both (the default) prints both and their ratio.
    let both = depthor_ok(&args("both"));
    assert!(
        both.contains("tract f32  ") && both.contains("tract / core"),
        "{both}"
    );
    // A bad value is a usage error that names the allowed ones.
    let o = depthor(&args("gpu"));
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--runtime") && err.contains("both") && err.contains("tract"),
        "{err}"
    );
    assert!(o.stdout.is_empty());
}
