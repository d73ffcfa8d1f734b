//! `depthor eval` and `depthor demo` end to end through the real binary: files written, every
//! method scored, the comparisons the model cards quote present, and clean errors.

mod common;

use common::{arg as s, depthor, depthor_ok};

#[test]
fn eval_scores_every_method_on_every_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec");
    let rec2 = tmp.path().join("rec2");
    let out = tmp.path().join("eval");
    let args = ["sim", "--preset", "mcu", "--scenes", "3", "--seed", "31337"];
    depthor_ok(&[&args[..], &["--out", s(&rec)]].concat());
    let args = ["sim", "--preset", "mcu", "--scenes", "2", "--seed", "4242"];
    depthor_ok(&[&args[..], &["--out", s(&rec2)]].concat());
    let stdout = depthor_ok(&[
        "eval",
        "--model",
        "mcu",
        "--recording",
        s(&rec),
        "--recording",
        s(&rec2),
        "--out",
        s(&out),
        "--mosaics",
        "2",
    ]);
    assert!(stdout.contains("int8 model (core)") && stdout.contains("prior + LS fit"));

    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].starts_with("recording,frame,method,"));
    assert_eq!(lines.len(), 1 + 5 * 6, "{csv}");
    for key in [
        "int8",
        "float",
        "nearest",
        "bilinear",
        "joint_bilateral",
        "prior_fit",
    ] {
        assert_eq!(
            lines
                .iter()
                .filter(|l| l.split(',').nth(2) == Some(key))
                .count(),
            5
        );
    }

    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["frames"], 5);
    let per = summary["recordings"].as_array().unwrap();
    assert_eq!(per.len(), 2);
    assert_eq!(
        (per[0]["frames"].clone(), per[1]["frames"].clone()),
        (3.into(), 2.into())
    );
    // The union lies between the two recordings' RMSEs.
    let r: Vec<f64> = per
        .iter()
        .map(|p| p["methods"]["bilinear"]["rmse"].as_f64().unwrap())
        .collect();
    let u = summary["methods"]["bilinear"]["rmse"].as_f64().unwrap();
    assert!(u >= r[0].min(r[1]) - 1e-9 && u <= r[0].max(r[1]) + 1e-9);
    let m = &summary["methods"];
    for key in ["int8", "float", "prior_fit"] {
        let rmse = m[key]["rmse"].as_f64().unwrap();
        let d1 = m[key]["delta1"].as_f64().unwrap();
        assert!(
            rmse.is_finite() && rmse > 0.0 && (0.0..=1.0).contains(&d1),
            "{key}"
        );
    }
    // int8 and float run the same network: close, not equal.
    let q = m["int8"]["rmse"].as_f64().unwrap();
    let f = m["float"]["rmse"].as_f64().unwrap();
    assert!((q - f).abs() / f < 0.1, "int8 {q} vs float {f}");
    let ratio = summary["int8_vs_best_baseline"]["rmse_ratio"]
        .as_f64()
        .unwrap();
    let best = summary["best_baseline"]["rmse"]["value"].as_f64().unwrap();
    assert!((ratio - q / best).abs() < 1e-9);
    assert!(summary["int8_vs_float"]["delta1_diff"].is_number());

    let mosaics = std::fs::read_dir(&out)
        .unwrap()
        .filter(|e| {
            let n = e.as_ref().unwrap().file_name();
            let n = n.to_string_lossy();
            n.starts_with("mosaic_") && n.ends_with(".png")
        })
        .count();
    assert_eq!(mosaics, 4); // 2 per recording, each with its CSV beside it
}

#[test]
fn demo_writes_depth_and_mosaic_and_prints_the_table() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    let stdout = depthor_ok(&["demo", "--out", s(&out)]);
    for m in [
        "int8 model (core)",
        "nearest zone",
        "bilinear zones",
        "joint bilateral",
        "ms",
    ] {
        assert!(stdout.contains(m), "{m} missing from:\n{stdout}");
    }
    let depth = image::open(out.join("depth_000000.png")).unwrap();
    assert_eq!((depth.width(), depth.height()), (160, 120));
    assert!(matches!(depth, image::DynamicImage::ImageLuma16(_)));
    let mosaic = image::open(out.join("mosaic_000000.png")).unwrap();
    assert!(mosaic.width() > 5 * 160);
}

#[test]
fn eval_errors_name_what_is_wrong() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("no-such-recording");
    let o = depthor(&["eval", "--recording", s(&missing)]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no-such-recording"), "{err}");

    let o = depthor(&["eval", "--model", "nano", "--recording", s(&missing)]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("nano"), "{err}");
}
