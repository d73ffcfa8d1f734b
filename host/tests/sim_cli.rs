//! `depthor sim` end to end: determinism of whole recordings, `--from`, `--preview`, config errors.

mod common;

use common::tree;
use std::path::Path;
use std::process::Command;

fn depthor(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_depthor"))
        .args(args)
        .output()
        .expect("run depthor");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn sim(out: &Path, seed: &str) {
    let (code, err) = depthor(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "3",
        "--seed",
        seed,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
}

#[test]
fn same_seed_gives_byte_identical_recordings_and_other_seeds_differ() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b, c) = (
        tmp.path().join("a"),
        tmp.path().join("b"),
        tmp.path().join("c"),
    );
    sim(&a, "11");
    sim(&b, "11");
    sim(&c, "12");
    let (ta, tb, tc) = (tree(&a), tree(&b), tree(&c));
    assert_eq!(
        ta.len(),
        1 + 3 * 4,
        "recording.json + rgb/depth/labels/dtof per frame"
    );
    assert!(ta == tb, "same seed must give identical bytes");
    let differing = ta.iter().zip(&tc).filter(|(x, y)| x.1 != y.1).count();
    assert!(
        differing >= 9,
        "another seed changes every frame's images ({differing})"
    );
}

#[test]
fn from_recording_resamples_simulates_and_previews() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path().join("src");
    sim(&src, "3");
    let out = tmp.path().join("resim");
    let (code, err) = depthor(&[
        "sim",
        "--preset",
        "l5",
        "--from",
        src.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--width",
        "200",
        "--height",
        "150",
        "--preview",
    ]);
    assert_eq!(code, 0, "{err}");
    let rec = depthor_host::recording::Recording::open(&out).unwrap();
    assert_eq!(rec.len(), 3);
    let f = rec.read_frame(0).unwrap();
    assert_eq!(f.rgb.dimensions(), (200, 150));
    assert_eq!(f.dtof.unwrap().distance_mm.len(), 64);
    for id in ["000000", "000001", "000002"] {
        assert!(out.join("preview").join(format!("{id}.png")).is_file());
    }
}

#[test]
fn bad_configs_are_one_clear_error_and_write_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let cfg = tmp.path().join("cfg.json");
    let base: serde_json::Value =
        serde_json::from_str(&depthor_host::sim::preset("mcu").unwrap().to_json()).unwrap();
    let mut out_of_range = base.clone();
    out_of_range["dark"]["p_loss"] = serde_json::json!(1.5);
    let mut unknown_field = base;
    unknown_field["dark"]["bogus"] = serde_json::json!(1);
    for (bad, field) in [(out_of_range, "dark.p_loss"), (unknown_field, "bogus")] {
        std::fs::write(&cfg, bad.to_string()).unwrap();
        let (code, err) = depthor(&[
            "sim",
            "--config",
            cfg.to_str().unwrap(),
            "--scenes",
            "1",
            "--width",
            "64",
            "--height",
            "48",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 2);
        assert!(err.contains(field), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn scene_config_changes_the_scenes_and_bad_ones_name_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let close = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/scenes/close_range.json");
    let run = |cfg: Option<&Path>, out: &Path| {
        let mut args = vec!["sim", "--preset", "mcu", "--scenes", "4", "--seed", "11"];
        args.extend(["--out", out.to_str().unwrap()]);
        if let Some(c) = cfg {
            args.extend(["--scene-config", c.to_str().unwrap()]);
        }
        depthor(&args)
    };
    let (plain, near) = (tmp.path().join("plain"), tmp.path().join("near"));
    assert_eq!(run(None, &plain).0, 0);
    let (code, err) = run(Some(&close), &near);
    assert_eq!(code, 0, "{err}");
    // close_range.json caps the room at 4.5 m deep: the far wall comes nearer on every frame.
    let far = |dir: &Path| -> Vec<u16> {
        (0..4)
            .map(|i| {
                let png = dir.join(format!("frames/{i:06}/depth.png"));
                let img = image::open(&png).unwrap().into_luma16();
                let mut v: Vec<u16> = img.pixels().map(|p| p.0[0]).filter(|&d| d > 0).collect();
                v.sort_unstable();
                v[v.len() * 9 / 10]
            })
            .collect()
    };
    let (fp, fnear) = (far(&plain), far(&near));
    assert!(fnear.iter().all(|&d| d < 5000), "{fnear:?}");
    let sum = |v: &[u16]| v.iter().map(|&d| u32::from(d)).sum::<u32>();
    assert!(sum(&fnear) < sum(&fp), "{fnear:?} vs {fp:?}");
    let bad = tmp.path().join("bad.json");
    std::fs::write(&bad, r#"{"room_depth_m": [5.0, 2.0]}"#).unwrap();
    let out = tmp.path().join("bad_out");
    let (code, err) = run(Some(&bad), &out);
    assert_ne!(code, 0);
    assert!(
        err.contains("bad.json") && err.contains("room_depth_m"),
        "{err}"
    );
    assert!(!out.exists());
}
