//! `depthor sim --measurement-mix`: a one-condition mix is the same run as `--config`, a seed
//! gives the same bytes, the frames spread over the conditions by weight, bad mixes name the
//! condition and the field, and the shipped training mixes parse.

mod common;

use common::tree;
use std::path::Path;

/// Runs `depthor` with `args`: (exit code, stdout, stderr).
fn depthor(args: &[&str]) -> (i32, String, String) {
    let out = common::depthor(args);
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `depthor sim --preset mcu --scenes n --seed 5` with `extra` arguments into `out`; stdout.
fn sim(out: &Path, n: &str, extra: &[&str]) -> String {
    let mut args = vec![
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        n,
        "--seed",
        "5",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let (code, stdout, err) = depthor(&args);
    assert_eq!(code, 0, "{err}");
    stdout
}

const NOISY: &str = r#"{"range_noise": {"enabled": true, "sigma_per_m": 0.03},
                       "anomalies": {"enabled": false}}"#;

#[test]
fn one_condition_mix_equals_config_and_same_seed_same_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let config = tmp.path().join("noisy.json");
    std::fs::write(&config, NOISY).unwrap();
    let mix = tmp.path().join("mix.json");
    std::fs::write(
        &mix,
        format!(
            r#"{{"base": {{}}, "conditions": [{{"name": "noisy", "weight": 1, "config": {NOISY}}}]}}"#
        ),
    )
    .unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    sim(&a, "3", &["--config", config.to_str().unwrap()]);
    let printed = sim(&b, "3", &["--measurement-mix", mix.to_str().unwrap()]);
    assert!(
        printed.contains("frames per condition: noisy 3"),
        "{printed}"
    );
    assert!(
        tree(&a) == tree(&b),
        "a one-condition mix must write the bytes of the same --config run"
    );

    // Ranges: same seed, same bytes; and the drawn values really vary the zones.
    let ranged = tmp.path().join("ranged.json");
    std::fs::write(
        &ranged,
        r#"{"base": {"anomalies": {"enabled": false}}, "conditions": [
             {"name": "noisy", "weight": 1, "on_base": true,
              "config": {"range_noise": {"enabled": true, "sigma_per_m": {"uniform": [0.0, 0.05]}}}}]}"#,
    )
    .unwrap();
    let (c, d) = (tmp.path().join("c"), tmp.path().join("d"));
    sim(&c, "3", &["--measurement-mix", ranged.to_str().unwrap()]);
    sim(&d, "3", &["--measurement-mix", ranged.to_str().unwrap()]);
    let (tc, td) = (tree(&c), tree(&d));
    assert!(tc == td, "same seed must give identical bytes");
    let dtof_differs = tree(&a)
        .iter()
        .zip(&tc)
        .filter(|(x, y)| x.0.to_string_lossy().contains("dtof") && x.1 != y.1)
        .count();
    assert!(
        dtof_differs >= 2,
        "per-frame noise levels must change the zones ({dtof_differs})"
    );
}

#[test]
fn frames_spread_over_conditions_by_weight() {
    let tmp = tempfile::tempdir().unwrap();
    let mix = tmp.path().join("mix.json");
    std::fs::write(
        &mix,
        r#"{"base": {}, "conditions": [
             {"name": "heavy", "weight": 3, "config": {}},
             {"name": "light", "weight": 1, "config": {"zone_estimator": {"estimator": {"choice": ["mean", "nearest"]}}}}]}"#,
    )
    .unwrap();
    let out = tmp.path().join("r");
    let printed = sim(
        &out,
        "64",
        &[
            "--measurement-mix",
            mix.to_str().unwrap(),
            "--height",
            "48",
            "--width",
            "64",
        ],
    );
    let line = printed
        .lines()
        .find(|l| l.contains("frames per condition"))
        .unwrap_or_else(|| panic!("no tally in {printed}"));
    let count = |name: &str| -> u32 {
        let after = line.split(&format!("{name} ")).nth(1).unwrap();
        after
            .split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let (heavy, light) = (count("heavy"), count("light"));
    assert_eq!(heavy + light, 64, "{line}");
    // 3:1 over 64 frames: expectation 48:16; a binomial spread of ±3.5 σ.
    assert!((36..=60).contains(&heavy), "{line}");
}

#[test]
fn bad_mixes_name_the_condition_and_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let cases = [
        (
            r#"{"base": {}, "conditions": [{"name": "n", "weight": 1,
               "config": {"range_noise": {"sigma_per_m": {"uniform": [0.0, -5.0]}}}}]}"#,
            "conditions[0] (n).config.range_noise.sigma_per_m",
        ),
        (
            r#"{"base": {}, "conditions": [{"name": "ok", "weight": 1, "config": {}},
               {"name": "neg", "weight": 1, "config": {"range_noise": {"sigma_per_m": {"uniform": [-1.0, 0.0]}}}}]}"#,
            "conditions[1] (neg).config.range_noise.sigma_per_m",
        ),
        (
            r#"{"base": {}, "conditions": [{"name": "w", "weight": 0, "config": {}}]}"#,
            "conditions[0] (w).weight",
        ),
        (
            r#"{"base": {}, "conditions": [{"name": "g", "weight": 1, "config": {"grid": {"cols": 4, "rows": 4}}}]}"#,
            "grid",
        ),
        (r#"{"base": {}, "conditions": []}"#, "conditions"),
        (
            r#"{"base": {}, "conditions": [{"name": "e", "weight": 1,
               "config": {"zone_estimator": {"estimator": {"choice": []}}}}]}"#,
            "conditions[0] (e).config.zone_estimator.estimator",
        ),
    ];
    for (k, (text, field)) in cases.iter().enumerate() {
        let path = tmp.path().join(format!("bad{k}.json"));
        std::fs::write(&path, text).unwrap();
        let out = tmp.path().join(format!("out{k}"));
        let (code, _, err) = depthor(&[
            "sim",
            "--preset",
            "mcu",
            "--scenes",
            "1",
            "--measurement-mix",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_ne!(code, 0, "case {k} must fail");
        assert!(err.contains(field), "case {k}: want `{field}` in: {err}");
        assert!(
            err.contains(&format!("bad{k}.json")),
            "case {k} names the file: {err}"
        );
        assert!(!out.exists(), "case {k} wrote nothing");
    }
}

#[test]
fn shipped_training_mixes_parse_over_their_preset() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/mixes");
    let mut seen = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let path = e.unwrap().path();
        if path.extension().and_then(|x| x.to_str()) != Some("json") {
            continue;
        }
        let preset = if path
            .file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with("phone")
        {
            "phone"
        } else {
            "mcu"
        };
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("r");
        let (code, stdout, err) = depthor(&[
            "sim",
            "--preset",
            preset,
            "--scenes",
            "2",
            "--height",
            "48",
            "--width",
            "64",
            "--measurement-mix",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{}: {err}", path.display());
        assert!(stdout.contains("frames per condition"), "{stdout}");
        seen += 1;
    }
    assert!(seen >= 1, "models/mixes holds the training mixes");
}
