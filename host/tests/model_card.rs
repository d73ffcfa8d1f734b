//! The shipped int8 models against their model cards: each card's `regression` entry names a
//! small fixed synthetic set (preset, seed, scenes) and the int8 RMSE measured on it by
//! `depthor eval`; this test rebuilds that set with `depthor sim`, evaluates the shipped blob with
//! `depthor eval` (int8 core and float tract), and fails if the int8 RMSE is more than 5 % worse
//! than the card's, or if int8 is worse than float by more than the model cards' tolerance (RMSE
//! 1 % relative, δ1 0.005, both against the reference depth). One-sided: int8 may land ahead of
//! float on a dozen frames by chance; the two-sided figures over 500 held-out frames are in the
//! model card.
//! Update the card (models/<variant>/card.json) in the same commit as the model.

mod common;

use common::{arg as s, depthor_ok as depthor};
use std::path::PathBuf;

fn card(variant: &str) -> serde_json::Value {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../models")
        .join(variant)
        .join("card.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn check(variant: &str) {
    let card = card(variant);
    let r = &card["regression"];
    let (preset, seed, scenes) = (
        r["preset"].as_str().expect("regression.preset"),
        r["seed"].as_u64().expect("regression.seed").to_string(),
        r["scenes"].as_u64().expect("regression.scenes").to_string(),
    );
    let want = r["int8_rmse"].as_f64().expect("regression.int8_rmse");
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("set");
    let out = tmp.path().join("eval");
    depthor(&[
        "sim",
        "--preset",
        preset,
        "--scenes",
        &scenes,
        "--seed",
        &seed,
        "--out",
        s(&rec),
    ]);
    depthor(&[
        "eval",
        "--model",
        variant,
        "--recording",
        s(&rec),
        "--out",
        s(&out),
        "--mosaics",
        "0",
        // The cards' figures pool the pixels of the set.
        "--aggregate",
        "pixel",
    ]);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let got = summary["methods"]["int8"]["rmse"].as_f64().unwrap();
    println!("{variant}: int8 RMSE {got:.4} m on the card's set (card: {want:.4} m)");
    assert!(
        got <= want * 1.05,
        "{variant}: int8 RMSE {got:.4} m regressed more than 5 % from the card's {want:.4} m"
    );
    let vs = &summary["int8_vs_float"];
    let (rmse_rel, d1) = (
        vs["rmse_rel_diff"]
            .as_f64()
            .expect("int8_vs_float.rmse_rel_diff"),
        vs["delta1_diff"]
            .as_f64()
            .expect("int8_vs_float.delta1_diff"),
    );
    println!(
        "{variant}: int8 vs float: RMSE {:+.2} %, δ1 {d1:+.4}",
        rmse_rel * 100.0
    );
    // The model cards' tolerance: int8 within 1 % of float in RMSE and 0.005 in δ1.
    assert!(
        rmse_rel <= 0.01,
        "{variant}: int8 RMSE {rmse_rel:+.4} relative to float (limit +0.01)"
    );
    assert!(
        d1 >= -0.005,
        "{variant}: int8 δ1 {d1:+.4} from float (limit -0.005)"
    );
}

#[test]
fn mcu_matches_its_model_card() {
    check("mcu");
}

#[test]
fn phone_matches_its_model_card() {
    check("phone");
}

#[test]
fn mcu_lite_matches_its_model_card() {
    check("mcu_lite");
}

#[test]
fn phone_lite_matches_its_model_card() {
    check("phone_lite");
}
