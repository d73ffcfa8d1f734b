//! The quantizer on the exported `mcu` network (models/mcu, written by models/ Python):
//! the f32 execution of graph.json against the Python golden tensors, the int8 engine on the
//! blob against the f32 graph on simulated frames, and the committed blob's sizes.
//! Figures: `cargo test -p depthor-host --test quantize -- --nocapture`.

use depthor_core::engine::{required_arena_bytes, Engine};
use depthor_host::quantize::calibrate::simulated_frames;
use depthor_host::quantize::check::{compare, golden_diff, op_fidelity};
use depthor_host::quantize::fold::fold;
use depthor_host::quantize::golden::read_golden;
use depthor_host::quantize::graph::Graph;
use depthor_host::quantize::net::Net;
use depthor_host::quantize::quantize;
use std::path::PathBuf;

fn models() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models")
}

fn mcu() -> Net {
    let g = Graph::load(&models().join("mcu/graph.json"), None).unwrap();
    fold(&g).unwrap()
}

/// The core's f32 ops (its own `exp`, ≈2 ULP) against PyTorch's golden tensors: the final depth
/// within 1e-4 m, every intermediate within 1e-3 (the largest activations are tens, so this is a
/// few f32 ULP of relative error accumulated through the layers).
#[test]
fn float_graph_matches_python_golden() {
    let net = mcu();
    let golden = read_golden(&models().join("mcu/golden/index.json")).unwrap();
    let diffs = golden_diff(&net, &golden).unwrap();
    for (name, d) in &diffs {
        println!("f32 graph vs Python golden {name}: max |diff| {d:.3e}");
    }
    let get = |n: &str| diffs.iter().find(|(k, _)| k == n).map(|(_, d)| *d).unwrap();
    assert!(get("prior.relu") <= 1e-5, "exp-free prior output");
    assert!(get("depth") <= 1e-4, "final depth, metres");
    assert!(diffs.iter().all(|(_, d)| *d <= 1e-3));
}

#[test]
fn int8_engine_tracks_float_graph() {
    let net = mcu();
    let calib = simulated_frames("mcu", net.height, net.width, 8, 0).unwrap();
    let q = quantize(&net, &calib).unwrap();
    let eval = simulated_frames("mcu", net.height, net.width, 20, 1000).unwrap();
    let c = compare(&q.blob, &net, &eval).unwrap();
    let (m, lo) = c.depth_mean_min();
    let (cm, clo) = c.centred_mean_min();
    println!(
        "depth SQNR over {} frames: mean {m:.1} dB, min {lo:.1} dB",
        eval.len()
    );
    println!("depth − mean SQNR: mean {cm:.1} dB, min {clo:.1} dB");
    let pooled = c.depth_pooled_db();
    println!("depth SQNR pooled over the frames: {pooled:.1} dB");
    for l in c.worst_layers(8) {
        println!("worst op {:3} {:36} {:6.1} dB", l.op, l.name, l.sqnr_db);
    }
    assert!(pooled >= 30.0, "depth SQNR {pooled} dB < 30 dB");
    assert!(c
        .layers
        .iter()
        .all(|l| l.sqnr_db.is_finite() || l.max_abs_err == 0.0));
}

/// Every int8 op of the committed blob against its own model (the f32 op on the engine's
/// inputs, rounded to the output's parameters): only weight rounding and ties may separate them.
/// A kernel that rounds twice (the element-wise rescale did, up to a code per element, until
/// `Requant::apply_rounded`) reads as tenths of a code here.
#[test]
fn every_int8_op_follows_its_model() {
    let net = mcu();
    let blob = std::fs::read(models().join("mcu/depthor.dblob")).unwrap();
    let frames = simulated_frames("mcu", net.height, net.width, 2, 2000).unwrap();
    let fidelity = op_fidelity(&blob, &net, &frames).unwrap();
    assert!(fidelity.len() > 50, "int8 ops checked: {}", fidelity.len());
    for f in &fidelity {
        println!(
            "op {:3} {:36} mean {:.4} codes, max {}",
            f.op, f.name, f.mean_abs_codes, f.max_abs_codes
        );
    }
    for f in &fidelity {
        assert!(
            f.mean_abs_codes <= 0.03 && f.max_abs_codes <= 1,
            "op {} {}: mean {:.3} codes, max {}",
            f.op,
            f.name,
            f.mean_abs_codes,
            f.max_abs_codes
        );
    }
}

#[test]
fn committed_mcu_blob_loads_and_fits_budgets() {
    let blob = std::fs::read(models().join("mcu/depthor.dblob")).unwrap();
    let net = mcu();
    let arena = required_arena_bytes(&blob, 120, 160).unwrap();
    let weights = net.weight_count();
    println!(
        "mcu: blob {} bytes, int8 weights {weights} bytes, arena at 120×160 {arena} bytes",
        blob.len()
    );
    assert!(weights <= 512 * 1024, "docs/design.md: weights ≤ 512 KiB");
    assert!(arena <= 2 * 1024 * 1024, "docs/design.md: arena ≤ 2 MiB");
    let mut mem = vec![0u8; arena + 64];
    let e = Engine::new(&blob, &mut mem).unwrap();
    assert_eq!(e.input_shape(), (120, 160));
    assert_eq!(e.graph().ops.len(), net.ops.len());
}

#[test]
fn blob_runs_at_another_input_size() {
    // Upsamples are written "like tensor k", so the native-size blob runs at 2× the size.
    let blob = std::fs::read(models().join("mcu/depthor.dblob")).unwrap();
    let (h, w) = (240, 320);
    let need = required_arena_bytes(&blob, h, w).unwrap();
    let mut mem = vec![0u8; need + 64];
    let mut e = Engine::with_size(&blob, &mut mem, h, w).unwrap();
    let rgb: Vec<u8> = (0..h * w * 3).map(|i| (i * 7 % 251) as u8).collect();
    let mut sparse = vec![0f32; h * w];
    sparse[(h / 2) * w + w / 2] = 2.0;
    let mut out = vec![0f32; h * w];
    e.run(&rgb, &sparse, &mut out).unwrap();
    assert!(out
        .iter()
        .all(|d| d.is_finite() && (0.05..=10.5).contains(d)));
}

/// `--ranges-file`: the named values take the given ranges (their blob parameters follow), the
/// others keep the calibrated ones; an unknown name or a reversed range is refused.
#[test]
fn given_ranges_replace_calibrated_ones() {
    use depthor_host::quantize::calibrate::{affine_params, RangeFileError, RangeRule};
    use depthor_host::quantize::{quantize_with, quantize_with_ranges, QuantizeError};
    let net = mcu();
    let calib = simulated_frames("mcu", net.height, net.width, 2, 0).unwrap();
    let plain = quantize_with(&net, &calib, RangeRule::MinMax).unwrap();
    let v = (2..net.values.len())
        .find(|&v| net.values[v].storage == depthor_host::quantize::net::Storage::I8)
        .unwrap();
    let name = net.values[v].name.clone();
    let given = vec![(name.clone(), [-1.5f32, 7.25])];
    let q = quantize_with_ranges(&net, &calib, RangeRule::MinMax, &given).unwrap();
    assert_eq!((q.ranges.min[v], q.ranges.max[v]), (-1.5, 7.25));
    assert_eq!(q.qparams[v], affine_params(-1.5, 7.25));
    assert_ne!(q.blob, plain.blob, "{name}: its parameters are in the blob");
    for u in (0..net.values.len()).filter(|&u| u != v) {
        assert_eq!(
            q.ranges.min[u], plain.ranges.min[u],
            "{}",
            net.values[u].name
        );
        assert_eq!(
            q.ranges.max[u], plain.ranges.max[u],
            "{}",
            net.values[u].name
        );
    }
    let unknown = vec![("no.such.value".to_string(), [0.0f32, 1.0])];
    assert!(matches!(
        quantize_with_ranges(&net, &calib, RangeRule::MinMax, &unknown),
        Err(QuantizeError::Ranges(RangeFileError::UnknownValue(n))) if n == "no.such.value"
    ));
    let reversed = vec![(name.clone(), [2.0f32, 1.0])];
    assert!(matches!(
        quantize_with_ranges(&net, &calib, RangeRule::MinMax, &reversed),
        Err(QuantizeError::Ranges(RangeFileError::BadRange { .. }))
    ));
    let nan = vec![(name, [f32::NAN, 1.0])];
    assert!(quantize_with_ranges(&net, &calib, RangeRule::MinMax, &nan).is_err());
}
