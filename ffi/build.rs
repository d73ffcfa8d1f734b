//! Generates `depthor.h` from `src/lib.rs` with cbindgen (`cbindgen.toml`) into
//! `$OUT_DIR/depthor.h`. The committed `include/depthor.h` is that file: `tests/header.rs`
//! compares them byte for byte. `DEPTHOR_WRITE_HEADER=1 cargo build -p depthor-ffi` also
//! copies the generated header over `include/depthor.h` (the only time the build writes into
//! the source tree).
//!
//! Build scripts run on the host, so this works for every target, thumbv7em included.

use std::env;
use std::path::PathBuf;

fn main() {
    let dir = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    println!("cargo:rerun-if-changed=src");
    println!("cargo:rerun-if-changed=cbindgen.toml");
    println!("cargo:rerun-if-env-changed=DEPTHOR_WRITE_HEADER");

    let config = cbindgen::Config::from_file(dir.join("cbindgen.toml"))
        .unwrap_or_else(|e| panic!("ffi/cbindgen.toml: {e}"));
    let bindings = cbindgen::Builder::new()
        .with_config(config)
        .with_src(dir.join("src/lib.rs"))
        .generate()
        .unwrap_or_else(|e| panic!("cbindgen could not generate depthor.h: {e}"));
    let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR")).join("depthor.h");
    bindings.write_to_file(&out);

    if env::var_os("DEPTHOR_WRITE_HEADER").is_some_and(|v| v == "1") {
        let committed = dir.join("include/depthor.h");
        std::fs::copy(&out, &committed)
            .unwrap_or_else(|e| panic!("copying to {}: {e}", committed.display()));
        println!(
            "cargo:warning=DEPTHOR_WRITE_HEADER=1: wrote {}",
            committed.display()
        );
    }
}
