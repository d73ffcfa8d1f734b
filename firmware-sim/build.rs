//! Puts `memory.x` on the linker's search path (cortex-m-rt's `link.x` includes it) and copies the
//! replay image to embed into `OUT_DIR/replay.img`.
//!
//! The image is the file named by the environment variable `DEPTHOR_REPLAY_IMAGE` (absolute, or
//! relative to `firmware-sim/`) or, when it is unset, the committed `images/default.dri`
//! (5 synthetic `mcu` frames from `make-image --frames 5`).

use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let here = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));

    fs::copy(here.join("memory.x"), out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");

    println!("cargo:rerun-if-env-changed=DEPTHOR_REPLAY_IMAGE");
    let image = match env::var_os("DEPTHOR_REPLAY_IMAGE") {
        Some(p) if !p.is_empty() => here.join(p),
        _ => here.join("images/default.dri"),
    };
    println!("cargo:rerun-if-changed={}", image.display());
    if let Err(e) = fs::copy(&image, out.join("replay.img")) {
        panic!("replay image {}: {e}", image.display());
    }
}
