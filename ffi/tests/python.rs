//! The `depthor` Python package (`ffi/python/`, ctypes over `libdepthor_ffi.so`): `pip install`
//! into a fresh venv, then its unittest compares `Engine.run` with the Rust engine bit for bit
//! (this test writes the inputs and `Engine::run`'s output), and the package's status table
//! equals the Rust constants.
//!
//! Needs `python3` with `venv` and network access (or a pip cache) for numpy and setuptools;
//! without `python3` it prints `SKIPPED: …` and passes. The wheel's library is built by a
//! nested `cargo build` into `target/ffi-python/cargo` (the outer `cargo test` holds `target/`).
//! Run: `cargo test -p depthor-ffi --test python -- --nocapture`.

use std::path::{Path, PathBuf};
use std::process::Command;

use depthor_core::engine::Engine;
use depthor_replay::model::MCU_BLOB;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn run(cmd: &mut Command, what: &str) -> String {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot run: {e}"));
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{text}",
        out.status
    );
    text
}

#[test]
fn python_status_table_equals_the_rust_constants() {
    let src = std::fs::read_to_string(repo().join("ffi/python/depthor/__init__.py")).unwrap();
    let mut table = Vec::new();
    for line in src.lines() {
        let l = line.trim();
        if let Some(rest) = l.strip_prefix("\"DEPTHOR_") {
            let (name, value) = rest.split_once("\":").unwrap();
            let v: i32 = value.trim().trim_end_matches(',').parse().unwrap();
            table.push((format!("DEPTHOR_{name}"), v));
        }
    }
    let codes: Vec<i32> = table.iter().map(|t| t.1).collect();
    assert_eq!(codes, depthor_ffi::ALL_STATUS.to_vec(), "{table:?}");
    assert_eq!(
        table[7],
        ("DEPTHOR_E_ARENA".to_owned(), depthor_ffi::DEPTHOR_E_ARENA)
    );
    assert_eq!(table[12].0, "DEPTHOR_E_INTERNAL");
}

#[test]
fn pip_installed_package_is_bit_exact_with_the_rust_engine() {
    if Command::new("python3").arg("--version").output().is_err() {
        println!("SKIPPED: python3 not found on PATH");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();

    // Inputs and the Rust engine's output at the blob's native size.
    let g = depthor_core::blob::parse(MCU_BLOB).unwrap();
    let (h, w) = (g.height, g.width);
    let n = h * w;
    let rgb: Vec<u8> = (0..3 * n).map(|i| (i * 31 % 253) as u8).collect();
    let sparse: Vec<f32> = (0..n)
        .map(|i| {
            if i % 301 == 0 {
                0.4 + (i % 17) as f32 * 0.3
            } else {
                0.0
            }
        })
        .collect();
    let mut arena = vec![0u8; depthor_core::engine::required_arena_bytes(MCU_BLOB, h, w).unwrap()];
    let mut engine = Engine::new(MCU_BLOB, &mut arena).unwrap();
    let mut depth = vec![0f32; n];
    engine.run(&rgb, &sparse, &mut depth).unwrap();
    let le = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    std::fs::write(d.join("model.dblob"), MCU_BLOB).unwrap();
    std::fs::write(d.join("rgb.bin"), &rgb).unwrap();
    std::fs::write(d.join("sparse.bin"), le(&sparse)).unwrap();
    std::fs::write(d.join("depth.bin"), le(&depth)).unwrap();
    std::fs::write(d.join("shape.txt"), format!("{h} {w}")).unwrap();
    assert_ne!(h, w, "the package's shape checks need a non-square input");

    // A fresh venv, the package installed from the repository.
    let venv = d.join("venv");
    run(
        Command::new("python3").arg("-m").arg("venv").arg(&venv),
        "python3 -m venv",
    );
    let py = venv.join("bin/python");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let pip = run(
        Command::new(&py)
            .args(["-m", "pip", "install", "--quiet"])
            .arg(repo().join("ffi/python"))
            .env("CARGO", cargo)
            .env("CARGO_TARGET_DIR", repo().join("target/ffi-python/cargo"))
            .env_remove("RUSTFLAGS")
            .env_remove("CARGO_ENCODED_RUSTFLAGS")
            .env_remove("CARGO_BUILD_TARGET"),
        "pip install ffi/python (network or a pip cache for numpy and setuptools)",
    );
    println!("{pip}");
    // The installed copy, not the source tree: run from the temporary directory.
    let out = run(
        Command::new(&py)
            .args(["-m", "unittest", "discover", "-v", "-s"])
            .arg(repo().join("ffi/python/tests"))
            .current_dir(d)
            .env("DEPTHOR_TEST_DIR", d)
            .env_remove("DEPTHOR_FFI_LIB"),
        "python unittest",
    );
    println!("{out}");
    assert!(out.contains("Ran 4 tests"), "{out}");
    assert!(out.contains("OK") && !out.contains("skipped"), "{out}");
    let where_ = run(
        Command::new(&py)
            .args(["-c", "import depthor; print(depthor.__file__)"])
            .current_dir(d),
        "import depthor",
    );
    assert!(where_.contains("site-packages"), "{where_}");
}
