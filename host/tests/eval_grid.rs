//! Partial simulator configurations (`depthor sim --preset P --config partial.json`), the effective
//! configuration (`--print-config`) and the evaluation grid (`depthor eval-grid`) end to end.

mod common;

use common::{arg as s, depthor, depthor_ok};
use depthor_host::sim::{preset, SimConfig};

#[test]
fn a_partial_config_overrides_only_the_fields_it_names() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("partial.json");
    std::fs::write(
        &cfg,
        r#"{"anomalies": {"enabled": false}, "grid": {"rows": 6},
            "misregistration": {"enabled": true, "shift_zones": 0.5}}"#,
    )
    .unwrap();
    let printed = depthor_ok(&[
        "sim",
        "--preset",
        "mcu",
        "--config",
        s(&cfg),
        "--print-config",
    ]);
    let got = SimConfig::from_json(&printed).unwrap();
    let mut want = preset("mcu").unwrap();
    want.anomalies.enabled = false; // its rates stay the preset's
    want.grid.rows = 6; // cols, bounds and iFoV stay
    want.misregistration.enabled = true;
    want.misregistration.shift_zones = 0.5;
    assert_eq!(got, want);
    assert_ne!(got, preset("mcu").unwrap());

    // The preset alone prints the preset.
    let printed = depthor_ok(&["sim", "--preset", "phone", "--print-config"]);
    assert_eq!(
        SimConfig::from_json(&printed).unwrap(),
        preset("phone").unwrap()
    );
}

#[test]
fn print_config_fed_back_through_config_reproduces_it() {
    let tmp = tempfile::tempdir().unwrap();
    let partial = tmp.path().join("partial.json");
    std::fs::write(
        &partial,
        r#"{"zone_estimator": {"estimator": "nearest"}, "range_noise": {"enabled": true, "sigma_per_m": 0.03}}"#,
    )
    .unwrap();
    let first = depthor_ok(&[
        "sim",
        "--preset",
        "phone",
        "--config",
        s(&partial),
        "--print-config",
    ]);
    let full = tmp.path().join("full.json");
    std::fs::write(&full, &first).unwrap();
    // Alone (a complete file) and over any preset, the printed file gives the same text.
    let alone = depthor_ok(&["sim", "--config", s(&full), "--print-config"]);
    let over_mcu = depthor_ok(&[
        "sim",
        "--preset",
        "mcu",
        "--config",
        s(&full),
        "--print-config",
    ]);
    assert_eq!(alone, first);
    assert_eq!(over_mcu, first);
    // And it simulates alike: the same scenes (the preset also picks the scene generator's
    // ranges) with the partial file and with the printed one give the same zones.
    let a = tmp.path().join("a");
    let b = tmp.path().join("b");
    let common_args = [
        "--scenes", "1", "--width", "64", "--height", "48", "--seed", "5",
    ];
    depthor_ok(
        &[
            &[
                "sim",
                "--preset",
                "phone",
                "--config",
                s(&partial),
                "--out",
                s(&a),
            ][..],
            &common_args,
        ]
        .concat(),
    );
    depthor_ok(
        &[
            &[
                "sim",
                "--preset",
                "phone",
                "--config",
                s(&full),
                "--out",
                s(&b),
            ][..],
            &common_args,
        ]
        .concat(),
    );
    let dtof =
        |d: &std::path::Path| std::fs::read_to_string(d.join("frames/000000/dtof.json")).unwrap();
    assert_eq!(dtof(&a), dtof(&b));
}

#[test]
fn partial_config_errors_name_the_file_and_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("bad.json");
    let cases = [
        (
            r#"{"anomalies": {"noise_fractio": 0.1}}"#,
            "anomalies.noise_fractio",
        ),
        (r#"{"grid": {"rows": "8"}}"#, "grid.rows"),
        (r#"{"dark": {"p_loss": 1.5}}"#, "dark.p_loss"),
        (r#"{"bogus": 1}"#, "bogus"),
        (r#"[1]"#, "(root)"),
    ];
    for (text, field) in cases {
        std::fs::write(&cfg, text).unwrap();
        let out = depthor(&[
            "sim",
            "--preset",
            "mcu",
            "--config",
            s(&cfg),
            "--print-config",
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{text}: {err}");
        assert!(
            err.contains("bad.json") && err.contains(field),
            "{text}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
    // Without a preset a partial file is refused, and the message says what to add.
    std::fs::write(&cfg, r#"{"anomalies": {"enabled": false}}"#).unwrap();
    let out = depthor(&["sim", "--config", s(&cfg), "--print-config"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("missing field") && err.contains("--preset"),
        "{err}"
    );
}

/// A 2-frame held-out-style synthetic set and a grid of three conditions on it.
#[test]
fn a_tiny_grid_writes_every_cell_and_a_worse_condition_is_worse_for_the_baselines() {
    let tmp = tempfile::tempdir().unwrap();
    let set = tmp.path().join("heldout2");
    let out = tmp.path().join("grid");
    depthor_ok(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "2",
        "--seed",
        "900000",
        "--out",
        s(&set),
    ]);
    let stdout = depthor_ok(&[
        "eval-grid",
        "--model",
        "mcu_lite",
        "--set",
        s(&set),
        "--condition",
        "clean",
        "--condition",
        "outliers_10pct",
        "--condition",
        "misreg_1zone",
        "--out",
        s(&out),
    ]);
    assert!(
        stdout.contains("int8 RMSE / best baseline RMSE"),
        "{stdout}"
    );

    let grid = std::fs::read_to_string(out.join("grid.csv")).unwrap();
    let rows: Vec<Vec<&str>> = grid.lines().map(|l| l.split(',').collect()).collect();
    let header = &rows[0];
    assert_eq!(header[..3], ["condition", "set", "frames"]);
    assert_eq!(rows.len(), 1 + 3, "{grid}");
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let names: Vec<&str> = rows[1..].iter().map(|r| r[0]).collect();
    assert_eq!(names, ["clean", "outliers_10pct", "misreg_1zone"]);
    for r in &rows[1..] {
        assert_eq!(r.len(), header.len());
        assert_eq!((r[1], r[2]), ("heldout2", "2"));
        for k in [
            "int8_rmse",
            "float_rmse",
            "best_baseline_rmse",
            "rmse_ratio",
        ] {
            let v: f64 = r[col(k)].parse().unwrap();
            assert!(v.is_finite() && v > 0.0, "{k} {v}");
        }
        let ratio: f64 = r[col("rmse_ratio")].parse().unwrap();
        let int8: f64 = r[col("int8_rmse")].parse().unwrap();
        let best: f64 = r[col("best_baseline_rmse")].parse().unwrap();
        assert!((ratio - int8 / best).abs() < 1e-4 * ratio);
    }
    // The best classical baseline of the clean zones beats the best of the zones with 10 %
    // outliers and of the grid measuring a whole zone away: worse zones, worse interpolation.
    let best = |k: usize| -> f64 { rows[k][col("best_baseline_rmse")].parse().unwrap() };
    assert!(best(1) < best(2), "{grid}");
    assert!(best(1) < best(3), "{grid}");

    let frames = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    // 3 conditions × 2 frames × 6 methods.
    assert_eq!(frames.lines().count(), 1 + 3 * 2 * 6);
    assert!(frames.starts_with("condition,recording,frame,method,"));
    let methods = std::fs::read_to_string(out.join("methods.csv")).unwrap();
    assert_eq!(methods.lines().count(), 1 + 3 * 6);

    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["model"], "mcu_lite");
    assert_eq!(summary["conditions"].as_array().unwrap().len(), 3);
    let cells = summary["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 3);
    for c in cells {
        assert_eq!(c["set"], "heldout2");
        assert_eq!(c["frames"], 2);
        assert!(c["int8_vs_best_baseline"]["rmse_ratio"].as_f64().unwrap() > 0.0);
        assert!(
            c["int8_vs_best_baseline"]["abs_rel_ratio"]
                .as_f64()
                .unwrap()
                > 0.0
        );
        assert!(c["int8_vs_float"]["rmse_rel_diff"].is_f64());
        assert!(c["methods"]["joint_bilateral"]["rmse"].is_f64());
    }
    let by_cond = &summary["means"]["rmse_ratio"]["by_condition"];
    let mean: f64 = rows[1..]
        .iter()
        .map(|r| r[col("rmse_ratio")].parse::<f64>().unwrap())
        .sum::<f64>()
        / 3.0;
    let grid_mean = summary["means"]["rmse_ratio"]["grid"].as_f64().unwrap();
    assert!((grid_mean - mean).abs() < 1e-5, "{grid_mean} {mean}");
    assert!(by_cond["clean"].is_f64());

    // Each condition's configuration, as written, is what the simulator was given.
    let clean = std::fs::read_to_string(out.join("conditions/clean.json")).unwrap();
    let clean = SimConfig::from_json(&clean).unwrap();
    assert!(!clean.anomalies.enabled && !clean.calibration_shift.enabled);
    assert_eq!(
        serde_json::to_value(&clean).unwrap(),
        summary["conditions"][0]["config"]
    );

    let png = image::open(out.join("heatmap.png")).unwrap().to_rgb8();
    assert!(png.width() > 300 && png.height() > 150);
    let heat = std::fs::read_to_string(out.join("heatmap.csv")).unwrap();
    // (3 conditions + grid mean) × (1 set + mean).
    assert_eq!(heat.lines().count(), 1 + 4 * 2);
    assert!(heat.contains("grid mean,mean,"));
}

#[test]
fn eval_grid_errors_name_what_is_wrong() {
    let tmp = tempfile::tempdir().unwrap();
    let manifest = tmp.path().join("m.json");
    std::fs::write(
        &manifest,
        r#"{"conditions": [{"name": "x", "file": "x.json"}]}"#,
    )
    .unwrap();
    std::fs::write(
        tmp.path().join("x.json"),
        r#"{"misregistration": {"shift_zone": 1}}"#,
    )
    .unwrap();
    let out = depthor(&[
        "eval-grid",
        "--model",
        "mcu_lite",
        "--set",
        "nowhere",
        "--conditions",
        s(&manifest),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("x.json") && err.contains("misregistration.shift_zone"),
        "{err}"
    );
    let out = depthor(&[
        "eval-grid",
        "--model",
        "mcu_lite",
        "--set",
        "nowhere",
        "--condition",
        "nope",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--condition nope") && err.contains("clean"),
        "{err}"
    );
}

/// The grid's two new simulator knobs on a staircase: 4×4 zones over a 64×64 image, zone column
/// `c` seeing a wall at `1 + c` metres.
#[test]
fn misregistration_and_estimators_on_a_staircase() {
    use depthor_host::sim::estimator::Estimator;
    use depthor_host::sim::grid::GridConfig;
    use depthor_host::sim::{simulate, SimInput};
    let (w, h) = (64u32, 64u32);
    let depth: Vec<f32> = (0..w * h).map(|i| 1.0 + ((i % w) / 16) as f32).collect();
    let rgb = vec![128u8; (3 * w * h) as usize];
    let input = SimInput::observed(w, h, &depth, &rgb, None);
    let mut cfg = SimConfig::ideal(GridConfig {
        rows: 4,
        cols: 4,
        fov_bounds: [0.0, 1.0, 0.0, 1.0],
        ifov: [0.25, 0.25],
    });
    cfg.overall_distribution.enabled = true;
    cfg.overall_distribution.max_translation = 0.0;
    cfg.overall_distribution.max_rotation_deg = 0.0;
    let row0 = |cfg: &SimConfig| -> Vec<f32> {
        let out = simulate(cfg, &input, 3).unwrap();
        out.distance_mm[..4].iter().map(|d| d / 1000.0).collect()
    };
    assert_eq!(row0(&cfg), [1.0, 2.0, 3.0, 4.0]);
    // One zone to the right: every zone sees its right neighbour's wall; the last sees nothing.
    cfg.misregistration.enabled = true;
    cfg.misregistration.shift_zones = 1.0;
    cfg.misregistration.direction_deg = Some(0.0);
    assert_eq!(row0(&cfg), [2.0, 3.0, 4.0, 0.0]);
    // Half a zone: each window straddles two walls, half each (the last keeps its own half).
    cfg.misregistration.shift_zones = 0.5;
    assert_eq!(
        row0(&cfg),
        [1.0, 2.0, 3.0, 4.0],
        "peak: ties go to the nearer"
    );
    cfg.zone_estimator.estimator = Estimator::Mean;
    assert_eq!(row0(&cfg), [1.5, 2.5, 3.5, 4.0]);
    cfg.zone_estimator.estimator = Estimator::Nearest;
    assert_eq!(row0(&cfg), [1.0, 2.0, 3.0, 4.0]);
    // With the window motion off, a zone reports the pixel at its (moved) centre.
    cfg.overall_distribution.enabled = false;
    cfg.misregistration.shift_zones = 1.0;
    assert_eq!(row0(&cfg), [2.0, 3.0, 4.0, 0.0]);
}
