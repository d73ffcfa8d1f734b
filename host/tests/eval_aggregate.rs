//! `depthor eval --aggregate image` reproduces the training code's per-image figure: the int8
//! predictions `--save-depth` wrote and the recording's reference, handed to
//! `models/depthor_models/train.py`'s `metrics()` (RMSE, δ1, Rel averaged per image), give the
//! summary's numbers; `--aggregate pixel` gives the pooled ones, which differ.
//!
//! Needs models/.venv (made by `bash models/smoke.sh`, which the test command runs first);
//! without it the comparison with Python is skipped with a message, the Rust half still runs.

mod common;

use common::{arg as s, depthor_ok};
use depthor_host::recording::Recording;
use std::path::Path;

fn summary(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn image_aggregate_matches_train_py_metrics() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec");
    depthor_ok(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "3",
        "--seed",
        "77",
        "--out",
        s(&rec),
    ]);
    let img = tmp.path().join("img");
    let pix = tmp.path().join("pix");
    let base = [
        "eval",
        "--no-float",
        "--mosaics",
        "0",
        "--recording",
        s(&rec),
    ];
    depthor_ok(&[&base[..], &["--save-depth", "--out", s(&img)]].concat());
    depthor_ok(&[&base[..], &["--aggregate", "pixel", "--out", s(&pix)]].concat());
    let (si, sp) = (summary(&img), summary(&pix));
    assert_eq!(si["aggregate"], "image");
    assert_eq!(sp["aggregate"], "pixel");
    assert_eq!(si["scored_at"], "model");
    assert_eq!(si["blob_sha256"].as_str().map(str::len), Some(64));
    let (ri, rp) = (
        si["methods"]["int8"]["rmse"].as_f64().unwrap(),
        sp["methods"]["int8"]["rmse"].as_f64().unwrap(),
    );
    assert!(
        (ri - rp).abs() > 1e-6,
        "per-image {ri} vs pooled {rp}: the two must differ"
    );

    // The Python half: predictions (mm PNGs) and references as raw little-endian f32.
    let py = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/.venv/bin/python");
    if !py.is_file() {
        eprintln!(
            "SKIPPED the train.py comparison: {} missing (run `bash models/smoke.sh`)",
            py.display()
        );
        return;
    }
    let r = Recording::open(&rec).unwrap();
    let (mut pred, mut gt) = (Vec::<u8>::new(), Vec::<u8>::new());
    let (mut h, mut w) = (0, 0);
    for i in 0..r.len() {
        let f = r.read_frame(i).unwrap();
        let png = img.join(format!("depth/rec/int8/{}.png", f.id));
        let p = image::open(&png).unwrap().to_luma16();
        (w, h) = p.dimensions();
        assert_eq!(
            f.rgb.dimensions(),
            (w, h),
            "mcu recordings are at the model's size"
        );
        for v in p.as_raw() {
            pred.extend_from_slice(&(f32::from(*v) / 1000.0).to_le_bytes());
        }
        for v in f.depth_m.as_ref().unwrap() {
            gt.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(tmp.path().join("pred.f32"), pred).unwrap();
    std::fs::write(tmp.path().join("gt.f32"), gt).unwrap();
    let script = format!(
        "import json, numpy as np\n\
         from depthor_models.train import metrics\n\
         p = np.fromfile('pred.f32', '<f4').reshape(-1, {h}, {w})\n\
         g = np.fromfile('gt.f32', '<f4').reshape(-1, {h}, {w})\n\
         print(json.dumps(metrics(p, g)))\n"
    );
    let o = std::process::Command::new(&py)
        .current_dir(tmp.path())
        .env(
            "PYTHONPATH",
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../models"),
        )
        .args(["-c", &script])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let ours = &si["methods"]["int8"];
    for (theirs, key, tol) in [
        ("rmse", "rmse", 1e-3),
        ("delta1", "delta1", 1e-3),
        ("rel", "abs_rel", 1e-3),
    ] {
        let (a, b) = (m[theirs].as_f64().unwrap(), ours[key].as_f64().unwrap());
        println!("{key}: train.py {a:.6}  depthor eval --aggregate image {b:.6}");
        // The saved predictions are rounded to 1 mm: RMSE and Rel move by less than that.
        assert!((a - b).abs() <= tol, "{key}: train.py {a} vs depthor {b}");
    }
    // And the pooled figure is not what train.py computes (it would pass by accident otherwise).
    let a = m["rmse"].as_f64().unwrap();
    println!("rmse pooled {rp:.6}");
    assert!(
        (a - ri).abs() < (a - rp).abs(),
        "per-image {ri} closer to train.py {a} than pooled {rp}"
    );
}
