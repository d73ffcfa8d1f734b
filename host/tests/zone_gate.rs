//! The shipped phone_lite zone gate in the core (`depthor_core::zone_gate`) against PyTorch's
//! forward of the same weights on a 32×32 test vector cut from a rendered training frame
//! (`models/phone_lite/zone_gate_golden.bin`, written by `depthor_models.zone_gate export`).

use depthor_core::zone_gate::{ZoneGate, CANDIDATES};
use std::path::PathBuf;

fn models() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models/phone_lite")
}

fn le_u32(b: &[u8], at: usize) -> usize {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize
}

fn le_f32s(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

#[test]
fn the_core_gate_matches_pytorch_on_the_golden_vector() {
    let gate_bytes = std::fs::read(models().join("zone_gate.bin")).unwrap();
    let gate = ZoneGate::parse(&gate_bytes).unwrap();
    let golden = std::fs::read(models().join("zone_gate_golden.bin")).unwrap();
    let (w, h) = (le_u32(&golden, 0), le_u32(&golden, 4));
    let n = w * h;
    let cands = le_f32s(&golden[8..8 + 4 * CANDIDATES * n]);
    let rgb_at = 8 + 4 * CANDIDATES * n;
    let rgb = &golden[rgb_at..rgb_at + 3 * n];
    let want = le_f32s(&golden[rgb_at + 3 * n..]);
    assert_eq!(want.len(), n, "golden file size");

    let mut scratch = vec![0.0; gate.scratch_floats(w, h)];
    let mut out = vec![0.0; n];
    gate.run(
        [&cands[..n], &cands[n..2 * n], &cands[2 * n..]],
        rgb,
        (w, h),
        &mut scratch,
        &mut out,
    )
    .unwrap();
    let worst = out
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 2e-4, "worst |core − torch| = {worst} m");
    // The vector exercises the blend: the output is neither candidate alone.
    for k in 0..CANDIDATES {
        let c = &cands[k * n..(k + 1) * n];
        let off = out
            .iter()
            .zip(c)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(off > 1e-3, "output equals candidate {k}");
    }
    assert_eq!(gate.macs(240, 320), 29_721_600);
}

mod common;

/// `depthor demo --model phone_lite` scores the gated output beside the network alone, and a
/// model folder with a broken gate file is refused with the file and the field named.
#[test]
fn phone_lite_demo_scores_the_gate_and_a_broken_gate_is_named() {
    let json = common::depthor_ok(&[
        "demo",
        "--model",
        models().to_str().unwrap(),
        "--frames",
        "1",
        "--seed",
        "5",
        "--json",
        "--out",
        common::arg(&tempfile::tempdir().unwrap().path().join("demo")),
    ]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let rmse = |k: &str| v["methods"][k]["rmse"].as_f64().unwrap();
    assert!(rmse("int8_gate").is_finite() && rmse("int8_gate") > 0.0);
    assert_ne!(rmse("int8_gate"), rmse("int8"));

    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("phone_lite");
    std::fs::create_dir(&dir).unwrap();
    for f in ["depthor.dblob", "graph.json", "card.json"] {
        std::fs::copy(models().join(f), dir.join(f)).unwrap();
    }
    let mut gate = std::fs::read(models().join("zone_gate.bin")).unwrap();
    gate[6] = 0; // channels = 0
    gate[7] = 0;
    std::fs::write(dir.join("zone_gate.bin"), &gate).unwrap();
    let out = common::depthor(&["demo", "--model", common::arg(&dir), "--frames", "1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("zone_gate.bin") && err.contains("channels"),
        "{err}"
    );
}
