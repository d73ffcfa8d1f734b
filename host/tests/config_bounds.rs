//! Physical bounds of every numeric field of `SimConfig` and `SceneConfig`: an absurd value is
//! one error naming the field and its allowed range, refused before anything is allocated; a
//! run whose memory estimate is over the limit is refused (exit 2, nothing written).

mod common;

use depthor_host::scene::SceneConfig;
use depthor_host::sim::{preset, SimConfig, SimError};
use serde_json::Value;
use std::time::{Duration, Instant};

/// Every numeric leaf of `v` as (JSON path, pointer).
fn numeric_leaves(v: &Value, path: String, ptr: String, out: &mut Vec<(String, String)>) {
    match v {
        Value::Number(_) => out.push((path, ptr)),
        Value::Object(m) => {
            for (k, c) in m {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                numeric_leaves(c, p, format!("{ptr}/{k}"), out);
            }
        }
        Value::Array(a) => {
            for (i, c) in a.iter().enumerate() {
                numeric_leaves(c, format!("{path}[{i}]"), format!("{ptr}/{i}"), out);
            }
        }
        _ => {}
    }
}

fn with(doc: &Value, ptr: &str, x: Value) -> String {
    let mut d = doc.clone();
    *d.pointer_mut(ptr).unwrap() = x;
    d.to_string()
}

/// The error names the field itself or, for a pair/rectangle checked as a whole, its parent.
fn names(msg: &str, path: &str) -> bool {
    let parent = path.split('[').next().unwrap_or(path);
    msg.starts_with(&format!("{path}:")) || msg.starts_with(&format!("{parent}:"))
}

#[test]
fn every_numeric_sim_field_is_bounded_and_named() {
    for name in depthor_host::sim::PRESETS {
        let doc = serde_json::to_value(preset(name).unwrap()).unwrap();
        let mut leaves = Vec::new();
        numeric_leaves(&doc, String::new(), String::new(), &mut leaves);
        assert!(leaves.len() > 40, "{}", leaves.len());
        for (path, ptr) in &leaves {
            for bad in [1e9, -1e9, 65535.0, 1e300] {
                let text = with(&doc, ptr, serde_json::json!(bad));
                let err = SimConfig::from_json(&text)
                    .expect_err(&format!("{name}: {path} = {bad} was accepted"));
                let msg = err.to_string();
                assert!(names(&msg, path), "{name}: {path} = {bad}: {msg}");
                assert_eq!(msg.lines().count(), 1, "{msg}");
                if let SimError::InvalidConfig { .. } = err {
                    assert!(msg.contains("(allowed "), "{path}: {msg}");
                }
            }
        }
    }
}

#[test]
fn sim_type_errors_name_the_field() {
    let doc = serde_json::to_value(preset("l5").unwrap()).unwrap();
    let cases = [
        ("/grid/rows", serde_json::json!("8"), "grid.rows"),
        ("/grid/ifov/1", serde_json::json!(null), "grid.ifov[1]"),
        ("/dark/p_loss", serde_json::json!([1]), "dark.p_loss"),
        ("/range/ramp", serde_json::json!("cubic"), "range.ramp"),
        (
            "/calibration_shift/max_shift_zones/0",
            serde_json::json!(300),
            "calibration_shift.max_shift_zones[0]",
        ),
    ];
    for (ptr, v, field) in cases {
        let msg = SimConfig::from_json(&with(&doc, ptr, v))
            .unwrap_err()
            .to_string();
        assert!(msg.starts_with(&format!("{field}: ")), "{msg}");
    }
    let mut d = doc.clone();
    d["dark"]
        .as_object_mut()
        .unwrap()
        .insert("p_losss".into(), 0.5.into());
    let msg = SimConfig::from_json(&d.to_string())
        .unwrap_err()
        .to_string();
    assert!(msg.starts_with("dark.p_losss: "), "{msg}");
    d = doc.clone();
    d["grid"].as_object_mut().unwrap().remove("cols");
    let msg = SimConfig::from_json(&d.to_string())
        .unwrap_err()
        .to_string();
    assert!(msg.starts_with("grid.cols: "), "{msg}");
    let msg = SimConfig::from_json("{").unwrap_err().to_string();
    assert!(msg.starts_with("JSON syntax: "), "{msg}");
}

#[test]
fn every_numeric_scene_field_is_bounded_and_named() {
    let doc = serde_json::to_value(SceneConfig::default()).unwrap();
    let mut leaves = Vec::new();
    numeric_leaves(&doc, String::new(), String::new(), &mut leaves);
    for (path, ptr) in &leaves {
        for bad in [1e9, -1e9, 65535.0] {
            let key = path.split('[').next().unwrap();
            let patch = serde_json::json!({ key: serde_json::from_str::<Value>(&with(&doc, ptr, serde_json::json!(bad))).unwrap()[key] });
            let msg = SceneConfig::default()
                .with_overrides(&patch.to_string())
                .expect_err(&format!("{path} = {bad} was accepted"))
                .to_string();
            assert!(names(&msg, path), "{path} = {bad}: {msg}");
        }
    }
}

#[test]
fn memory_estimate_refuses_huge_windows_before_allocating() {
    let mut cfg = preset("l5").unwrap();
    cfg.grid.rows = 128;
    cfg.grid.cols = 128;
    cfg.grid.ifov = [1.0, 1.0];
    cfg.validate().unwrap();
    let t = Instant::now();
    let err = cfg
        .check_memory(640, 480, 2, 32, 8 << 30)
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("grid.ifov: ") && err.contains("(allowed at most 8192 MiB"),
        "{err}"
    );
    // simulate() checks it too (one frame), so library callers cannot abort either.
    let (w, h) = (640u32, 480u32);
    let depth = vec![2.0f32; (w * h) as usize];
    let rgb = vec![128u8; (3 * w * h) as usize];
    let input = depthor_host::sim::SimInput {
        width: w,
        height: h,
        depth_m: &depth,
        rgb: &rgb,
        labels: None,
        reflectance: None,
        second_depth_m: None,
    };
    let e = depthor_host::sim::simulate(&cfg, &input, 0).unwrap_err();
    assert!(matches!(e, SimError::TooMuchMemory { .. }), "{e}");
    assert!(t.elapsed() < Duration::from_secs(2));
    // The shipped presets are far below the limit.
    for name in depthor_host::sim::PRESETS {
        let m = preset(name).unwrap().memory_estimate(640, 480, 16, 32);
        assert!(m.total() < 1 << 30, "{name}: {m:?}");
    }
}

#[test]
fn cli_refuses_absurd_configs_fast_with_file_field_and_range() {
    let tmp = tempfile::tempdir().unwrap();
    let doc = serde_json::to_value(preset("l5").unwrap()).unwrap();
    let cases = [
        (
            "/grid/ifov/0",
            serde_json::json!(65535),
            "grid.ifov[0]",
            "(allowed",
        ),
        (
            "/grid/ifov/1",
            serde_json::json!(1e9),
            "grid.ifov[1]",
            "(allowed",
        ),
        (
            "/grid/rows",
            serde_json::json!(65535),
            "grid.rows",
            "(allowed 1 to 128",
        ),
    ];
    for (i, (ptr, v, field, allowed)) in cases.into_iter().enumerate() {
        let cfg = tmp.path().join(format!("cfg{i}.json"));
        std::fs::write(&cfg, with(&doc, ptr, v)).unwrap();
        let out = tmp.path().join(format!("out{i}"));
        let t = Instant::now();
        let o = common::depthor(&[
            "sim",
            "--config",
            common::arg(&cfg),
            "--scenes",
            "2",
            "--width",
            "160",
            "--height",
            "120",
            "--out",
            common::arg(&out),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(&format!("cfg{i}.json: {field}: ")), "{err}");
        assert!(err.contains(allowed), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
        assert!(!out.exists());
        assert_eq!(
            common::entries(tmp.path())
                .iter()
                .filter(|e| e.contains("partial"))
                .count(),
            0
        );
    }
    // Valid fields, absurd product: 128×128 zones each sampling the whole 640×480 image.
    let mut big = doc.clone();
    big["grid"]["rows"] = 128.into();
    big["grid"]["cols"] = 128.into();
    big["grid"]["ifov"] = serde_json::json!([1.0, 1.0]);
    let cfg = tmp.path().join("big.json");
    std::fs::write(&cfg, big.to_string()).unwrap();
    let out = tmp.path().join("big_out");
    let o = common::depthor(&[
        "sim",
        "--config",
        common::arg(&cfg),
        "--scenes",
        "2",
        "--width",
        "640",
        "--height",
        "480",
        "--out",
        common::arg(&out),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("big.json: grid.ifov: the run needs about"),
        "{err}"
    );
    assert!(err.contains("(allowed at most"), "{err}");
    assert!(!out.exists());
}
