//! Copies the int8 model blob both builds embed into `OUT_DIR/model.dblob`.
//!
//! The blob is the file named by the environment variable `DEPTHOR_MODEL_BLOB` (absolute, or
//! relative to `firmware-sim/replay/`) or, when it is unset, the shipped
//! `models/mcu_lite/depthor.dblob` (the network sized for a microcontroller, issue 16). Another
//! blob (e.g. `models/mcu/depthor.dblob`) measures that model's instructions and arena on the
//! same firmware; the replay image's frames must have the blob's input size.

use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let here = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    println!("cargo:rerun-if-env-changed=DEPTHOR_MODEL_BLOB");
    let (blob, default) = match env::var_os("DEPTHOR_MODEL_BLOB") {
        Some(p) if !p.is_empty() => (here.join(p), false),
        _ => (here.join("../../models/mcu_lite/depthor.dblob"), true),
    };
    // `model::ARENA_BUDGET_BYTES` sizes the arena to the default blob's need; another blob gets
    // the 384 KiB goal unless `DEPTHOR_ARENA_KIB` says otherwise.
    println!(
        "cargo:rustc-env=DEPTHOR_DEFAULT_BLOB={}",
        if default { "1" } else { "0" }
    );
    println!("cargo:rerun-if-changed={}", blob.display());
    if let Err(e) = fs::copy(&blob, out.join("model.dblob")) {
        panic!("model blob {}: {e}", blob.display());
    }
}
