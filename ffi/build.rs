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
    let mut text = Vec::new();
    bindings.write(&mut text);
    let text = String::from_utf8(text).expect("cbindgen writes UTF-8");
    std::fs::write(&out, parenthesise_negative_defines(&text))
        .unwrap_or_else(|e| panic!("writing {}: {e}", out.display()));

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

/// `#define NAME -N` becomes `#define NAME (-N)`: cbindgen writes negative constants bare, and a
/// bare `-N` in a macro can merge with the tokens around it (`x-DEPTHOR_E_NULL` would read
/// `x--1`).
fn parenthesise_negative_defines(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 64);
    for line in text.split_inclusive('\n') {
        let body = line.trim_end_matches('\n');
        let mut parts = body.splitn(3, ' ');
        match (parts.next(), parts.next(), parts.next()) {
            (Some("#define"), Some(name), Some(value))
                if value.starts_with('-') && value[1..].bytes().all(|b| b.is_ascii_digit()) =>
            {
                out.push_str(&format!("#define {name} ({value})"));
                out.push_str(&line[body.len()..]);
            }
            _ => out.push_str(line),
        }
    }
    out
}
