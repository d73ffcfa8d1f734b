//! Gap tool, issue 44 item 3 ("any shape"): on 32 rendered 120×160 frames (the `mcu` preset), a
//! periodic range error whose period is not the library's 0.3 m is named `bin_wiggle` with its
//! period found by the search, noise growing with scene brightness (not range) is named as a
//! noise curve along brightness, and the null recording of the same scenes names nothing. The
//! shapes are the shape bench's own injections (`gap::shapes::ANY_SHAPE`) at 4× the library
//! form's unit (equal mean effect).

use std::sync::OnceLock;

use depthor_host::gap::bench::render_scenes;
use depthor_host::gap::shapes::{run_shape_case, ShapeCase, ShapeResult, ANY_SHAPE};
use depthor_host::gap::{Analysis, GapOptions};
use depthor_host::scene::SceneFrame;
use depthor_host::sim::learned::TermKind;
use depthor_host::sim::preset;

fn scenes() -> &'static [SceneFrame] {
    static S: OnceLock<Vec<SceneFrame>> = OnceLock::new();
    S.get_or_init(|| render_scenes(32, 160, 120, 1000))
}

/// Runs `shape` (a name in `ANY_SHAPE`, or `None` for the null) at 4× the library unit.
fn run(shape: Option<&str>, seed: u64) -> (ShapeResult, Analysis) {
    let base = preset("mcu").unwrap();
    let shape = shape.map(|n| *ANY_SHAPE.iter().find(|s| s.name == n).unwrap());
    let case = ShapeCase {
        label: shape.map_or("null".into(), |s| format!("{}/{}@4x", s.family, s.name)),
        shape,
        size: 4.0,
        unit: 1.0,
        scenes: "sim",
    };
    run_shape_case(scenes(), &base, &case, &GapOptions::default(), seed).unwrap()
}

#[test]
fn off_library_period_is_searched_and_named() {
    let (r, a) = run(Some("period_0.47"), 31);
    let log = a.selection.log.join("\n");
    assert_eq!(
        r.named.first().map(String::as_str),
        Some("bin_wiggle"),
        "{log}"
    );
    let p = r.first_period_m.unwrap();
    assert!((p - 0.47).abs() < 0.047, "period {p}\n{log}");
    assert!(r.top1());
    assert!(r.finding_gains.iter().all(|&g| g > 0.0), "{log}");
}

#[test]
fn brightness_driven_noise_is_named_along_brightness() {
    let (r, a) = run(Some("bright_noise"), 32);
    let log = a.selection.log.join("\n");
    assert!(!r.named.is_empty(), "nothing named\n{log}");
    assert_eq!(r.first_kind, Some(TermKind::Noise), "{:?}\n{log}", r.named);
    assert!(
        r.first_covariates.iter().any(|c| c == "brightness"),
        "{:?}\n{log}",
        r.first_covariates
    );
    assert!(r.top1());
    assert!(r.finding_gains.iter().all(|&g| g > 0.0), "{log}");
}

#[test]
fn null_names_nothing_with_the_whole_vocabulary() {
    let (r, a) = run(None, 33);
    let log = a.selection.log.join("\n");
    assert!(r.named.is_empty(), "{:?}\n{log}", r.named);
    // The vocabulary was offered: the residual candidate and the periodic error were fitted.
    assert!(
        log.contains("learned") && log.contains("bin_wiggle"),
        "{log}"
    );
}
