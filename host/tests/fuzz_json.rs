//! Random and mutated bytes as `recording.json` / `dtof.json` never panic the reader.

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
