//! Random and mutated bytes as `recording.json` / `dtof.json` never panic the reader; mutated
//! scene and simulator configurations and measurement mixes are one error naming the field, or
//! they render/simulate.

mod common;

use depthor_host::recording::Recording;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_bytes_as_recording_json(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let tmp = tempfile::tempdir().unwrap();
        let rec = common::write_hand_made(&tmp.path().join("rec"));
        std::fs::write(rec.join("recording.json"), &bytes).unwrap();
        let err = Recording::open(&rec).unwrap_err();
        prop_assert!(!err.to_string().contains('\n'));
    }

    #[test]
    fn mutated_recording_json(pos in 0usize..10_000, len in 0usize..8, fill in any::<u8>()) {
        let tmp = tempfile::tempdir().unwrap();
        let rec = common::write_hand_made(&tmp.path().join("rec"));
        let mut bytes = common::recording_json(&["000000"]).into_bytes();
        let at = pos % bytes.len();
        let end = (at + len).min(bytes.len());
        bytes[at..end].fill(fill);
        std::fs::write(rec.join("recording.json"), &bytes).unwrap();
        if let Ok(r) = Recording::open(&rec) {
            if !r.is_empty() {
                let _ = r.read_frame(0);
            }
        }
    }

    #[test]
    fn random_and_mutated_bytes_as_dtof_json(
        bytes in proptest::collection::vec(any::<u8>(), 0..200),
        pos in 0usize..10_000,
        fill in any::<u8>(),
    ) {
        let tmp = tempfile::tempdir().unwrap();
        let rec = common::write_hand_made(&tmp.path().join("rec"));
        let r = Recording::open(&rec).unwrap();
        let dtof = rec.join("frames/000000/dtof.json");
        std::fs::write(&dtof, &bytes).unwrap();
        prop_assert!(r.read_frame(0).is_err());
        let mut text = common::DTOF_JSON.as_bytes().to_vec();
        let at = pos % text.len();
        text[at] = fill;
        std::fs::write(&dtof, &text).unwrap();
        if let Err(e) = r.read_frame(0) {
            prop_assert!(e.path.ends_with("frames/000000/dtof.json"), "{}", e);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Mutated `--scene-config` files are either one error naming what is wrong or a config
    /// that renders a (small) scene without panicking.
    #[test]
    fn mutated_scene_config(pos in 0usize..10_000, len in 1usize..4, fill in any::<u8>(), seed in 0u64..1000) {
        use depthor_host::scene::{camera_for, render_scene, SceneConfig};
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../models/scenes/close_range.json");
        let mut bytes = std::fs::read(path).unwrap();
        let at = pos % bytes.len();
        let end = (at + len).min(bytes.len());
        bytes[at..end].fill(fill);
        let text = String::from_utf8_lossy(&bytes);
        match SceneConfig::default().with_overrides(&text) {
            Err(e) => {
                let msg = e.to_string();
                prop_assert!(!msg.contains('\n'), "{}", msg);
                // One line naming the field, or the JSON syntax where no field is to blame.
                let field = msg.split(": ").next().unwrap_or("");
                let known = field.starts_with("JSON") || field == "(root)"
                    || serde_json::to_value(SceneConfig::default()).unwrap()
                        .get(field.split('[').next().unwrap_or("")).is_some()
                    || matches!(e, depthor_host::scene::SceneConfigError::UnknownField(_));
                prop_assert!(known, "{}", msg);
            }
            Ok(cfg) => {
                let frame = render_scene(&cfg, seed, camera_for(&cfg, seed, 24, 18));
                prop_assert_eq!(frame.depth_m.len(), 24 * 18);
            }
        }
    }
}

/// The JSON paths of every value of `v` (`grid.ifov[0]`, `dark`), containers included.
fn json_paths(v: &serde_json::Value, path: String, out: &mut Vec<String>) {
    if !path.is_empty() {
        out.push(path.clone());
    }
    match v {
        serde_json::Value::Object(m) => {
            for (k, c) in m {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                json_paths(c, p, out);
            }
        }
        serde_json::Value::Array(a) => {
            for (i, c) in a.iter().enumerate() {
                json_paths(c, format!("{path}[{i}]"), out);
            }
        }
        _ => {}
    }
}

/// Simulates a small flat scene with `cfg` (must not panic).
fn simulate_small(cfg: &depthor_host::sim::SimConfig) {
    let (w, h) = (40u32, 30u32);
    let depth = vec![2.0f32; (w * h) as usize];
    let rgb = vec![90u8; (3 * w * h) as usize];
    let input = depthor_host::sim::SimInput {
        width: w,
        height: h,
        depth_m: &depth,
        rgb: &rgb,
        labels: None,
        reflectance: None,
        second_depth_m: None,
    };
    // Ok, or a clean error (the memory estimate may refuse a huge grid).
    let _ = depthor_host::sim::simulate(cfg, &input, 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Mutated bytes of a preset's JSON: one line naming a path of the document (or `JSON
    /// syntax` / `JSON`), or a configuration that simulates without panicking.
    #[test]
    fn mutated_sim_config_bytes(pos in 0usize..100_000, len in 1usize..4, fill in any::<u8>(), p in 0usize..3) {
        use depthor_host::sim::{preset, SimConfig, PRESETS};
        let base = preset(PRESETS[p % PRESETS.len()]).unwrap().to_json();
        let mut bytes = base.clone().into_bytes();
        let at = pos % bytes.len();
        let end = (at + len).min(bytes.len());
        bytes[at..end].fill(fill);
        let text = String::from_utf8_lossy(&bytes);
        match SimConfig::from_json(&text) {
            Ok(cfg) => simulate_small(&cfg),
            Err(e) => {
                let msg = e.to_string();
                prop_assert!(!msg.contains('\n'), "{}", msg);
                let field = msg.split(": ").next().unwrap_or("");
                let mut paths = Vec::new();
                json_paths(&serde_json::from_str(&base).unwrap(), String::new(), &mut paths);
                let known = field.starts_with("JSON")
                    || field == "(root)"
                    || paths.iter().any(|p| p == field || field.starts_with(&format!("{p}.")))
                    || serde_json::from_str::<serde_json::Value>(&text).is_ok();
                prop_assert!(known, "{}", msg);
            }
        }
    }

    /// Any number in any numeric field of a preset: accepted (and it simulates) or refused
    /// naming that field.
    #[test]
    fn any_number_in_any_sim_field(k in 0usize..1000, x in prop_oneof![any::<f64>(), -1e4f64..1e4, 0f64..2.0], p in 0usize..3) {
        use depthor_host::sim::{preset, SimConfig, PRESETS};
        let mut doc = serde_json::to_value(preset(PRESETS[p % PRESETS.len()]).unwrap()).unwrap();
        let mut paths = Vec::new();
        json_paths(&doc, String::new(), &mut paths);
        let numeric: Vec<String> = paths
            .into_iter()
            .filter(|p| {
                let ptr = format!("/{}", p.replace(['.', '['], "/").replace(']', ""));
                doc.pointer(&ptr).is_some_and(|v| v.is_number())
            })
            .collect();
        let path = &numeric[k % numeric.len()];
        let ptr = format!("/{}", path.replace(['.', '['], "/").replace(']', ""));
        let Some(num) = serde_json::Number::from_f64(x) else { return Ok(()) };
        *doc.pointer_mut(&ptr).unwrap() = serde_json::Value::Number(num);
        match SimConfig::from_json(&doc.to_string()) {
            Ok(cfg) => simulate_small(&cfg),
            Err(e) => {
                let msg = e.to_string();
                let parent = path.split('[').next().unwrap_or(path);
                // A cross-field rule (`limit_m ≥ practical_m`) names the other field first and
                // this one in the message.
                let leaf = parent.rsplit('.').next().unwrap_or(parent);
                if msg.contains(&format!(" {leaf}")) {
                    return Ok(());
                }
                prop_assert!(
                    msg.starts_with(&format!("{path}:")) || msg.starts_with(&format!("{parent}:")),
                    "{} = {}: {}", path, x, msg
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Mutated bytes of the shipped training mix: one error line (the file's condition and
    /// field, or JSON), or a mix whose every frame draw is a configuration that simulates.
    #[test]
    fn mutated_measurement_mix_bytes(pos in 0usize..100_000, len in 1usize..4, fill in any::<u8>(), seed in 0u64..1000) {
        use depthor_host::sim::{preset, MeasurementMix};
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/mixes/mcu_train.json");
        let mut bytes = std::fs::read(path).unwrap();
        let at = pos % bytes.len();
        let end = (at + len).min(bytes.len());
        bytes[at..end].fill(fill);
        let text = String::from_utf8_lossy(&bytes);
        match MeasurementMix::from_json(&preset("mcu").unwrap(), &text) {
            Ok(mix) => {
                for i in 0..4 {
                    let (_, cfg) = mix.draw(seed, i).map_err(|e| TestCaseError::fail(e.to_string()))?;
                    simulate_small(&cfg);
                }
            }
            Err(e) => prop_assert!(!e.to_string().contains('\n'), "{}", e),
        }
    }
}
