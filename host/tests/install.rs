//! `cargo install --path host --root <tmp>` gives a `depthor` that runs the demo from a folder
//! with no models/ in it: the default `mcu` blob is embedded in the binary and nothing is looked
//! up through the source tree.
//!
//! The install is `--debug` and shares this test's target folder, so it links the artifacts the
//! test build already made (seconds, not the ≈ 10 minutes of a release build from scratch); the
//! code path of a release install is the same.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The target folder this test binary was built in (`<target>/debug/deps/install-…`).
fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.ancestors().nth(3).unwrap().to_path_buf()
}

#[test]
fn installed_binary_runs_the_demo_from_another_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let host = Path::new(env!("CARGO_MANIFEST_DIR"));
    let o = Command::new(cargo)
        .args(["install", "--locked", "--offline", "--debug", "--path"])
        .arg(host)
        .arg("--root")
        .arg(&root)
        .env("CARGO_TARGET_DIR", target_dir())
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .output()
        .expect("run cargo install");
    assert!(
        o.status.success(),
        "cargo install failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let bin = root.join("bin").join("depthor");
    assert!(bin.is_file(), "{} missing", bin.display());

    // Another folder, no models/ anywhere near it, no DEPTHOR_MODELS.
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let o = Command::new(&bin)
        .current_dir(&elsewhere)
        .env_remove("DEPTHOR_MODELS")
        .args(["demo", "--out", "d"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("int8 model (core)"), "{stdout}");
    assert!(elsewhere.join("d/depth_000000.png").is_file());
    assert!(elsewhere.join("d/mosaic_000000.png").is_file());

    // A second run into the same folder is refused without --overwrite, allowed with it.
    let again = |extra: &[&str]| {
        Command::new(&bin)
            .current_dir(&elsewhere)
            .args(["demo", "--out", "d"])
            .args(extra)
            .output()
            .unwrap()
    };
    let o = again(&[]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--overwrite") || err.contains("not empty"),
        "{err}"
    );
    assert!(again(&["--overwrite"]).status.success());
}
