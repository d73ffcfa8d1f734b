//! Nothing half-written: a `depthor sim` killed with SIGKILL at any moment leaves its `--out`
//! absent or complete (the next run removes the partial sibling and names it), and commands
//! that fail on a bad input leave nothing at `--out`.

mod common;

use depthor_host::recording::Recording;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Names in `dir` that are temporary siblings of an output.
fn partials(dir: &Path) -> Vec<String> {
    common::entries(dir)
        .into_iter()
        .filter(|e| e.contains(".partial-") || e.contains(".old-"))
        .collect()
}

/// `out` is absent, or a recording with all `n` frames.
fn absent_or_complete(out: &Path, n: usize) {
    if !out.exists() {
        return;
    }
    let rec = Recording::open(out).expect("a complete recording");
    assert_eq!(rec.len(), n);
    for i in 0..n {
        rec.read_frame(i).expect("every frame readable");
    }
}

#[test]
fn sigkill_mid_sim_leaves_out_absent_or_complete_and_the_next_run_cleans_up() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 12;
    let mut killed_mid_run = 0;
    // From "before it started" to "probably done": the invariant must hold at every moment.
    for (k, delay_ms) in [0u64, 150, 400, 800, 1500, 3000, 6000]
        .into_iter()
        .enumerate()
    {
        let out = tmp.path().join(format!("rec{k}"));
        let mut child = Command::new(env!("CARGO_BIN_EXE_depthor"))
            .args([
                "sim",
                "--preset",
                "mcu",
                "--scenes",
                &n.to_string(),
                "--seed",
                "3",
            ])
            .args(["--preview", "--out", common::arg(&out)])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(delay_ms));
        let finished = child.try_wait().unwrap().is_some();
        child.kill().ok(); // SIGKILL on Unix
        child.wait().unwrap();
        absent_or_complete(&out, n);
        if !finished && !out.exists() {
            killed_mid_run += 1;
        }
    }
    assert!(
        killed_mid_run >= 2,
        "no run was killed mid-way ({killed_mid_run})"
    );

    // A long run killed once frames are being written: the partial sibling is there …
    let out = tmp.path().join("long");
    let mut child = Command::new(env!("CARGO_BIN_EXE_depthor"))
        .args([
            "sim",
            "--preset",
            "mcu",
            "--scenes",
            "100000",
            "--out",
            common::arg(&out),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let partial = tmp.path().join(format!("long.partial-{}", child.id()));
    let t = Instant::now();
    while !partial.join("frames").join("000001").exists() {
        assert!(t.elapsed() < Duration::from_secs(120), "no frame written");
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!out.exists());
    assert!(partial.exists());
    // … and the next run for the same --out removes it and says so.
    let o = common::depthor(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "2",
        "--out",
        common::arg(&out),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("removed") && err.contains("long.partial-"),
        "{err}"
    );
    absent_or_complete(&out, 2);
    assert!(out.exists());
    let left: Vec<String> = partials(tmp.path())
        .into_iter()
        .filter(|e| e.starts_with("long."))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn failing_commands_leave_nothing_at_out() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec");
    common::depthor_ok(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "3",
        "--out",
        common::arg(&rec),
    ]);
    // The last frame's RGB is not a PNG: eval, demo and firmware-image fail on it, after work.
    std::fs::write(rec.join("frames/000002/rgb.png"), b"not a png").unwrap();
    let ev = tmp.path().join("ev");
    let demo = tmp.path().join("demo");
    let img = tmp.path().join("img.dri");
    // firmware-image needs one camera for all frames: a hand-made one-frame recording.
    let hand = common::write_hand_made(&tmp.path().join("hand"));
    std::fs::write(hand.join("frames/000000/rgb.png"), b"not a png").unwrap();
    let sim_out = tmp.path().join("sim_from");
    let runs: [Vec<&str>; 4] = [
        vec![
            "eval",
            "--model",
            "mcu",
            "--no-float",
            "--recording",
            common::arg(&rec),
            "--out",
            common::arg(&ev),
        ],
        vec![
            "demo",
            "--recording",
            common::arg(&rec),
            "--frames",
            "3",
            "--out",
            common::arg(&demo),
        ],
        vec![
            "firmware-image",
            common::arg(&hand),
            "--frames",
            "1",
            "--out",
            common::arg(&img),
        ],
        vec![
            "sim",
            "--preset",
            "mcu",
            "--from",
            common::arg(&rec),
            "--out",
            common::arg(&sim_out),
        ],
    ];
    for args in runs {
        let o = common::depthor(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("/rgb.png"), "{args:?}: {err}");
        let errors = err.lines().filter(|l| l.starts_with("error:")).count();
        assert_eq!(errors, 1, "{args:?}: {err}");
    }
    for p in [&ev, &demo, &img, &sim_out] {
        assert!(!p.exists(), "{} was left behind", p.display());
    }
    assert!(
        partials(tmp.path()).is_empty(),
        "{:?}",
        partials(tmp.path())
    );
}
