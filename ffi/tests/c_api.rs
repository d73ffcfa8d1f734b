//! depthor.h from C and C++, against the x86-64 static library `cargo test` just built
//! (`target/<profile>/deps/libdepthor_ffi.a`, the lib target's staticlib output):
//!
//! - the header alone compiles with `gcc -std=c99 -Wall -Wextra -Werror -pedantic` and
//!   `g++ -std=c++17 -Wall -Wextra -Werror -pedantic`;
//! - `ffi/c/test_api.c` (built with the same C99 flags) passes every error-path check, prints
//!   the structs' layout equal to Rust's `offset_of!`, and runs a replay image's frames with
//!   hash lines equal to the Rust host loop (`depthor_replay::host`);
//! - the same program under `-fsanitize=address,undefined` runs clean (exit 0, no report);
//! - the C++ host example `ffi/examples/host.cpp` prints the host's lines;
//! - on aarch64 Linux under `qemu-aarch64` (cross gcc/g++), the C program and the C++ example
//!   print the host's lines too.
//!
//! Without `gcc` (or `g++` for the C++ checks, or the aarch64 cross tools and `qemu-aarch64`
//! for the aarch64 test) the tests concerned print `SKIPPED: …` and pass.
//! Run: `cargo test -p depthor-ffi --test c_api -- --nocapture`.

use std::mem::offset_of;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use depthor_ffi::{depthor_calibration, depthor_projection_stats};
use depthor_replay::format::Image;
use depthor_replay::host::replay_image;
use depthor_replay::model::MCU_BLOB;
use depthor_replay::{synthetic, writer};

/// Native libraries a std staticlib needs on Linux (`--print native-static-libs`).
const NATIVE_LIBS: [&str; 7] = [
    "-lgcc_s",
    "-lutil",
    "-lrt",
    "-lpthread",
    "-lm",
    "-ldl",
    "-lc",
];
const C_FLAGS: [&str; 6] = [
    "-std=c99",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-pedantic",
    "-O1",
];
const CXX_FLAGS: [&str; 6] = [
    "-std=c++17",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-pedantic",
    "-O1",
];

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn have(tool: &str) -> bool {
    let found = Command::new(tool).arg("--version").output().is_ok();
    if !found {
        println!("SKIPPED: `{tool}` not found on PATH (apt-get install -y build-essential)");
    }
    found
}

/// The staticlib built with this test binary (same profile, same sources).
fn staticlib() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let deps = exe.parent().expect("deps dir");
    let lib = deps.join("libdepthor_ffi.a");
    assert!(
        lib.exists(),
        "{} missing: cargo builds it with the lib target (crate-type staticlib)",
        lib.display()
    );
    lib
}

fn run_ok(cmd: &mut Command, what: &str) -> Output {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot run: {e}"));
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Blob and a 3-frame synthetic replay image in `dir`, and the host loop's lines for it.
fn inputs(dir: &Path) -> (PathBuf, PathBuf, Vec<String>) {
    let bytes = writer::image_bytes(&synthetic::mcu_calibration(), &synthetic::mcu_frames(3))
        .expect("make image");
    let image = dir.join("frames.dri");
    std::fs::write(&image, &bytes).unwrap();
    let blob = dir.join("model.dblob");
    std::fs::write(&blob, MCU_BLOB).unwrap();
    struct NoDelay;
    impl embedded_hal::delay::DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }
    let mut host = Vec::new();
    replay_image::<64>(Image::parse(&bytes).unwrap(), NoDelay, |o| {
        host.push(o.to_string())
    })
    .expect("host loop");
    assert_eq!(host.len(), 3);
    (blob, image, host)
}

fn frame_lines(stdout: &str) -> Vec<String> {
    stdout
        .lines()
        .filter(|l| l.starts_with("frame "))
        .map(str::to_owned)
        .collect()
}

/// Compiles `test_api.c` + `replay.c` with `extra` flags into `dir/name`.
fn build_test_api(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let exe = dir.join(name);
    let r = repo();
    run_ok(
        Command::new("gcc")
            .args(C_FLAGS)
            .args(extra)
            .arg("-I")
            .arg(r.join("ffi/include"))
            .arg("-I")
            .arg(r.join("firmware-sim/c"))
            .arg(r.join("ffi/c/test_api.c"))
            .arg(r.join("firmware-sim/c/replay.c"))
            .arg(staticlib())
            .args(NATIVE_LIBS)
            .arg("-o")
            .arg(&exe),
        &format!("gcc {name}"),
    );
    exe
}

#[test]
fn header_alone_compiles_as_c99_and_cpp17() {
    let dir = tempfile::tempdir().unwrap();
    let inc = repo().join("ffi/include");
    if have("gcc") {
        let src = dir.path().join("h.c");
        std::fs::write(
            &src,
            "#include \"depthor.h\"\nint main(void) { return DEPTHOR_OK; }\n",
        )
        .unwrap();
        run_ok(
            Command::new("gcc")
                .args(C_FLAGS)
                .arg("-I")
                .arg(&inc)
                .arg("-fsyntax-only")
                .arg(&src),
            "gcc -std=c99 -pedantic on depthor.h",
        );
    }
    if have("g++") {
        let src = dir.path().join("h.cpp");
        std::fs::write(
            &src,
            "#include \"depthor.h\"\n#include \"depthor.h\"\n\
             static_assert(sizeof(depthor_calibration) == 92, \"layout\");\n\
             int main() { return depthor_status_message(DEPTHOR_OK) ? 0 : 1; }\n",
        )
        .unwrap();
        run_ok(
            Command::new("g++")
                .args(CXX_FLAGS)
                .arg("-I")
                .arg(&inc)
                .arg("-fsyntax-only")
                .arg(&src),
            "g++ -std=c++17 on depthor.h",
        );
    }
}

/// `name=value` pairs of a `layout NAME …` line.
fn layout(stdout: &str, name: &str) -> Vec<(String, usize)> {
    let line = stdout
        .lines()
        .find(|l| l.starts_with(&format!("layout {name} ")))
        .unwrap_or_else(|| panic!("no layout line for {name}:\n{stdout}"));
    line.split_whitespace()
        .skip(2)
        .map(|kv| {
            let (k, v) = kv.split_once('=').unwrap();
            (k.to_owned(), v.parse().unwrap())
        })
        .collect()
}

fn pairs(v: &[(&str, usize)]) -> Vec<(String, usize)> {
    v.iter().map(|(k, n)| (k.to_string(), *n)).collect()
}

#[test]
fn c_program_passes_every_error_path_and_matches_the_host() {
    if !have("gcc") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (blob, image, host) = inputs(dir.path());
    let exe = build_test_api(dir.path(), "test_api", &[]);
    let out = Command::new(&exe).arg(&blob).arg(&image).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "test_api exit {}:\n{stdout}",
        out.status
    );
    let checks: Vec<&str> = stdout.lines().filter(|l| l.starts_with("check ")).collect();
    assert!(checks.len() >= 55, "{} checks:\n{stdout}", checks.len());
    assert!(checks.iter().all(|l| !l.ends_with("FAIL")), "{stdout}");
    // Every error code appears as a wanted result at least once.
    for code in depthor_ffi::ALL_STATUS {
        if code != depthor_ffi::DEPTHOR_E_INTERNAL {
            assert!(
                checks.iter().any(|l| l.ends_with(&format!("want={code}"))),
                "no C check wants status {code}"
            );
        }
    }
    assert!(stdout.contains("errors 0"), "{stdout}");
    assert_eq!(frame_lines(&stdout), host, "C frames vs Rust host");

    type C = depthor_calibration;
    let cal = pairs(&[
        ("size", size_of::<C>()),
        ("width", offset_of!(C, width)),
        ("height", offset_of!(C, height)),
        ("fx", offset_of!(C, fx)),
        ("fy", offset_of!(C, fy)),
        ("cx", offset_of!(C, cx)),
        ("cy", offset_of!(C, cy)),
        ("zone_rows", offset_of!(C, zone_rows)),
        ("zone_cols", offset_of!(C, zone_cols)),
        ("distance_kind", offset_of!(C, distance_kind)),
        ("fov_h_deg", offset_of!(C, fov_h_deg)),
        ("fov_v_deg", offset_of!(C, fov_v_deg)),
        ("max_range_m", offset_of!(C, max_range_m)),
        ("rotation", offset_of!(C, rotation)),
        ("translation_m", offset_of!(C, translation_m)),
    ]);
    assert_eq!(layout(&stdout, "depthor_calibration"), cal);
    type S = depthor_projection_stats;
    let stats = pairs(&[
        ("size", size_of::<S>()),
        ("zones", offset_of!(S, zones)),
        ("projected", offset_of!(S, projected)),
        ("invalid_status", offset_of!(S, invalid_status)),
        ("bad_distance", offset_of!(S, bad_distance)),
        ("behind_camera", offset_of!(S, behind_camera)),
        ("out_of_image", offset_of!(S, out_of_image)),
        ("collisions", offset_of!(S, collisions)),
        ("skipped", offset_of!(S, skipped)),
    ]);
    assert_eq!(layout(&stdout, "depthor_projection_stats"), stats);
    let storage = pairs(&[
        ("size", depthor_ffi::DEPTHOR_ENGINE_STORAGE_BYTES),
        ("engine_size", depthor_ffi::depthor_engine_size()),
        ("engine_align", depthor_ffi::depthor_engine_align()),
    ]);
    assert_eq!(layout(&stdout, "depthor_engine_storage"), storage);
}

#[test]
fn c_program_is_clean_under_asan_and_ubsan() {
    if !have("gcc") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (blob, image, host) = inputs(dir.path());
    let exe = build_test_api(
        dir.path(),
        "test_api_san",
        &[
            "-g",
            "-fsanitize=address,undefined",
            "-fno-sanitize-recover=all",
            "-fno-omit-frame-pointer",
        ],
    );
    let out = Command::new(&exe)
        .arg(&blob)
        .arg(&image)
        .env(
            "ASAN_OPTIONS",
            "detect_leaks=1:abort_on_error=0:exitcode=86",
        )
        .env("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.success(),
        "sanitized test_api exit {}:\n{stdout}\n{stderr}",
        out.status
    );
    for needle in ["AddressSanitizer", "LeakSanitizer", "runtime error"] {
        assert!(!stderr.contains(needle), "{needle}:\n{stderr}");
    }
    assert!(stdout.contains("errors 0"), "{stdout}");
    assert_eq!(
        frame_lines(&stdout),
        host,
        "sanitized C frames vs Rust host"
    );
}

#[test]
fn cpp_host_example_prints_the_host_lines() {
    if !have("gcc") || !have("g++") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (blob, image, host) = inputs(dir.path());
    let r = repo();
    let obj = dir.path().join("replay.o");
    run_ok(
        Command::new("gcc")
            .args(C_FLAGS)
            .arg("-I")
            .arg(r.join("ffi/include"))
            .arg("-c")
            .arg(r.join("firmware-sim/c/replay.c"))
            .arg("-o")
            .arg(&obj),
        "gcc replay.c",
    );
    let exe = dir.path().join("host_cpp");
    run_ok(
        Command::new("g++")
            .args(CXX_FLAGS)
            .arg("-I")
            .arg(r.join("ffi/include"))
            .arg("-I")
            .arg(r.join("firmware-sim/c"))
            .arg(r.join("ffi/examples/host.cpp"))
            .arg(&obj)
            .arg(staticlib())
            .args(NATIVE_LIBS)
            .arg("-o")
            .arg(&exe),
        "g++ host.cpp",
    );
    let out = run_ok(Command::new(&exe).arg(&blob).arg(&image), "host_cpp");
    assert_eq!(
        frame_lines(&String::from_utf8_lossy(&out.stdout)),
        host,
        "C++ example vs Rust host"
    );
}

/// The aarch64 static library (nested cargo, own target dir: the outer `cargo test` holds
/// `target/`); a staticlib needs no linker, so only the Rust target is required.
fn aarch64_staticlib() -> PathBuf {
    let target_dir = repo().join("target/ffi-aarch64");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    run_ok(
        Command::new(cargo)
            .current_dir(repo())
            .args(["rustc", "-p", "depthor-ffi", "--release"])
            .args([
                "--target",
                "aarch64-unknown-linux-gnu",
                "--crate-type",
                "staticlib",
            ])
            .arg("--target-dir")
            .arg(&target_dir)
            .env_remove("RUSTFLAGS")
            .env_remove("CARGO_ENCODED_RUSTFLAGS")
            .env_remove("CARGO_BUILD_TARGET"),
        "cargo rustc depthor-ffi for aarch64 (rustup target add aarch64-unknown-linux-gnu)",
    );
    target_dir.join("aarch64-unknown-linux-gnu/release/libdepthor_ffi.a")
}

/// The C test program and the C++ example on aarch64 Linux under `qemu-aarch64` user mode:
/// every check passes and both print the Rust host's lines. Needs `aarch64-linux-gnu-gcc`,
/// `aarch64-linux-gnu-g++` and `qemu-aarch64` (`.ci/run` installs them); prints `SKIPPED: …`
/// without them.
#[test]
fn aarch64_c_program_and_cpp_example_under_qemu_user() {
    if !have("aarch64-linux-gnu-gcc") || !have("aarch64-linux-gnu-g++") || !have("qemu-aarch64") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (blob, image, host) = inputs(dir.path());
    let lib = aarch64_staticlib();
    let r = repo();
    let inc = |c: &mut Command| {
        c.arg("-I")
            .arg(r.join("ffi/include"))
            .arg("-I")
            .arg(r.join("firmware-sim/c"));
    };
    let obj = dir.path().join("replay.o");
    let mut cc = Command::new("aarch64-linux-gnu-gcc");
    cc.args(C_FLAGS);
    inc(&mut cc);
    run_ok(
        cc.arg("-c")
            .arg(r.join("firmware-sim/c/replay.c"))
            .arg("-o")
            .arg(&obj),
        "aarch64 gcc replay.c",
    );
    let c_exe = dir.path().join("test_api_a64");
    let mut cc = Command::new("aarch64-linux-gnu-gcc");
    cc.args(C_FLAGS);
    inc(&mut cc);
    run_ok(
        cc.arg(r.join("ffi/c/test_api.c"))
            .arg(&obj)
            .arg(&lib)
            .args(NATIVE_LIBS)
            .arg("-o")
            .arg(&c_exe),
        "aarch64 gcc test_api.c",
    );
    let cpp_exe = dir.path().join("host_cpp_a64");
    let mut cxx = Command::new("aarch64-linux-gnu-g++");
    cxx.args(CXX_FLAGS);
    inc(&mut cxx);
    run_ok(
        cxx.arg(r.join("ffi/examples/host.cpp"))
            .arg(&obj)
            .arg(&lib)
            .args(NATIVE_LIBS)
            .arg("-o")
            .arg(&cpp_exe),
        "aarch64 g++ host.cpp",
    );
    for (exe, what) in [(&c_exe, "test_api"), (&cpp_exe, "host.cpp")] {
        let out = run_ok(
            Command::new("qemu-aarch64")
                .args(["-L", "/usr/aarch64-linux-gnu"])
                .arg(exe)
                .arg(&blob)
                .arg(&image),
            &format!("qemu-aarch64 {what}"),
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert_eq!(frame_lines(&stdout), host, "aarch64 {what} vs Rust host");
        if what == "test_api" {
            assert!(stdout.contains("errors 0"), "{stdout}");
            assert!(!stdout.contains("FAIL"), "{stdout}");
        }
    }
}

/// The sanitizer run again with the Rust library itself instrumented by AddressSanitizer
/// (`-Zsanitizer=address`, nightly only; std stays uninstrumented): every load and store of the
/// engine into the C program's buffers is checked too. Prints `SKIPPED: …` without a nightly
/// toolchain (`rustup toolchain install nightly`).
#[test]
fn c_program_with_an_asan_instrumented_rust_library() {
    if !have("gcc") {
        return;
    }
    let nightly = Command::new("cargo")
        .args(["+nightly", "--version"])
        .output();
    if !nightly.is_ok_and(|o| o.status.success()) {
        println!("SKIPPED: no nightly toolchain (`cargo +nightly`) for -Zsanitizer=address");
        return;
    }
    let target_dir = repo().join("target/ffi-asan");
    run_ok(
        Command::new("cargo")
            .current_dir(repo())
            .args(["+nightly", "rustc", "-q", "-p", "depthor-ffi", "--release"])
            .args([
                "--target",
                "x86_64-unknown-linux-gnu",
                "--crate-type",
                "staticlib",
            ])
            .arg("--target-dir")
            .arg(&target_dir)
            .env_remove("CARGO_ENCODED_RUSTFLAGS")
            .env_remove("RUSTUP_TOOLCHAIN")
            .env_remove("RUSTC")
            .env_remove("CARGO")
            .env(
                "RUSTFLAGS",
                "-Zsanitizer=address -Cunsafe-allow-abi-mismatch=sanitizer",
            ),
        "cargo +nightly rustc with -Zsanitizer=address",
    );
    let lib = target_dir.join("x86_64-unknown-linux-gnu/release/libdepthor_ffi.a");
    let dir = tempfile::tempdir().unwrap();
    let (blob, image, host) = inputs(dir.path());
    let exe = dir.path().join("test_api_rust_asan");
    let r = repo();
    run_ok(
        Command::new("gcc")
            .args(C_FLAGS)
            .args([
                "-g",
                "-fsanitize=address,undefined",
                "-fno-sanitize-recover=all",
            ])
            .arg("-I")
            .arg(r.join("ffi/include"))
            .arg("-I")
            .arg(r.join("firmware-sim/c"))
            .arg(r.join("ffi/c/test_api.c"))
            .arg(r.join("firmware-sim/c/replay.c"))
            .arg(&lib)
            .args(NATIVE_LIBS)
            .arg("-o")
            .arg(&exe),
        "gcc test_api with the instrumented library",
    );
    let out = Command::new(&exe)
        .arg(&blob)
        .arg(&image)
        .env("ASAN_OPTIONS", "detect_leaks=1:exitcode=86")
        .env("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.success(),
        "exit {}:\n{stdout}\n{stderr}",
        out.status
    );
    assert!(
        !stderr.contains("Sanitizer") && !stderr.contains("runtime error"),
        "{stderr}"
    );
    assert!(stdout.contains("errors 0"), "{stdout}");
    assert_eq!(frame_lines(&stdout), host);
}

/// `firmware-sim/c/replay.c` refuses defective replay images with the Rust parser's exit code
/// (`ImageError::exit_code`): the C firmware and the Rust one agree on bad input too.
#[test]
fn c_replay_parser_refuses_what_the_rust_parser_refuses() {
    if !have("gcc") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (blob, image, _) = inputs(dir.path());
    let good = std::fs::read(&image).unwrap();
    let exe = build_test_api(dir.path(), "test_api_images", &[]);
    let mut cases: Vec<(&str, Vec<u8>)> = Vec::new();
    let edit = |at: usize, v: u8| {
        let mut b = good.clone();
        b[at] = v;
        b
    };
    cases.push(("magic", edit(0, b'X')));
    cases.push(("version", edit(8, 2)));
    cases.push(("header length", edit(10, 100)));
    cases.push(("zero frames", {
        let mut b = good.clone();
        b[12..16].copy_from_slice(&0u32.to_le_bytes());
        b
    }));
    cases.push(("zero height", {
        let mut b = good.clone();
        b[16..18].copy_from_slice(&0u16.to_le_bytes());
        b
    }));
    cases.push(("zone rows 256", {
        let mut b = good.clone();
        b[20..22].copy_from_slice(&256u16.to_le_bytes());
        b
    }));
    cases.push(("distance kind", edit(24, 2)));
    cases.push(("reserved", edit(26, 1)));
    cases.push(("truncated", good[..good.len() - 1].to_vec()));
    cases.push(("short", good[..50].to_vec()));
    cases.push(("short, not an image", b"not an image at all".to_vec()));
    cases.push(("trailing", [good.clone(), vec![0]].concat()));
    let last = good.len() - 1;
    cases.push(("crc", edit(last, good[last] ^ 0xff)));
    for (name, bytes) in cases {
        let want = match Image::parse(&bytes) {
            Err(e) => i32::from(e.exit_code()),
            Ok(_) => panic!("{name}: the Rust parser accepts it"),
        };
        let path = dir.path().join("bad.dri");
        std::fs::write(&path, &bytes).unwrap();
        let out = Command::new(&exe).arg(&blob).arg(&path).output().unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert_eq!(
            out.status.code(),
            Some(want),
            "{name}: C vs Rust exit code\n{stdout}"
        );
        assert!(
            stdout.contains(&format!("ERROR {want}: ")),
            "{name}: {stdout}"
        );
    }
}
