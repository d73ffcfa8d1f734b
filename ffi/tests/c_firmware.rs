//! The C firmware (`firmware-sim/c/`, arm-none-eabi-gcc + newlib) linking the Cortex-M static
//! library, under `qemu-system-arm` (mps2-an386, `-icount shift=0`): its per-frame hash lines
//! must equal the Rust host loop's (which `tests/firmware_qemu.rs` holds equal to the Rust
//! firmware's), with the library built with and without the core's `arm-dsp` kernels; a bad
//! image must make it print `ERROR <code>` and exit with the Rust firmware's code.
//!
//! Needs the `thumbv7em-none-eabihf` Rust target, `arm-none-eabi-gcc` with newlib and
//! `qemu-system-arm` (`bash scripts/setup.sh` installs them); without them these tests FAIL
//! with a message saying what to install, like the Rust firmware's.
//! Run: `cargo test -p depthor-ffi --test c_firmware -- --nocapture`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::Duration;

use depthor_replay::format::Image;
use depthor_replay::host::{host_lines, run_qemu_m4};
use depthor_replay::model::MCU_BLOB;
use depthor_replay::{synthetic, writer};

const TARGET: &str = "thumbv7em-none-eabihf";
/// 5 `mcu_lite` frames take ≈ 2 s of QEMU wall time; generous for a loaded machine.
const QEMU_TIMEOUT: Duration = Duration::from_secs(300);

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Builds the Cortex-M staticlib (profile `ffi-mcu`, as `ffi/build-libs.sh`) once per feature
/// list (`""`, `"arm-dsp"`, …), in its own target dir (the outer `cargo test` holds the
/// workspace's), and returns its path.
fn cortex_m_lib(features: &str) -> PathBuf {
    static LIBS: Mutex<BTreeMap<String, PathBuf>> = Mutex::new(BTreeMap::new());
    let mut libs = LIBS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(p) = libs.get(features) {
        return p.clone();
    }
    let target_dir = repo().join("target/ffi-firmware");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(repo())
        .args(["rustc", "-p", "depthor-ffi", "--profile", "ffi-mcu"])
        .args([
            "--target",
            TARGET,
            "--crate-type",
            "staticlib",
            "--no-default-features",
        ])
        .arg("--target-dir")
        .arg(&target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET");
    if !features.is_empty() {
        cmd.args(["--features", features]);
    }
    let out = cmd.output().expect("run cargo");
    assert!(
        out.status.success(),
        "building the {TARGET} staticlib failed (is the Rust target installed? \
         `bash scripts/setup.sh` or `rustup target add {TARGET}`):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let built = target_dir.join(TARGET).join("ffi-mcu/libdepthor_ffi.a");
    let keep = target_dir.join(format!("libdepthor_ffi-[{}].a", features.replace(',', "+")));
    std::fs::copy(&built, &keep).expect("copy staticlib");
    libs.insert(features.to_owned(), keep.clone());
    keep
}

/// `make -C firmware-sim/c` with `lib` and `image` into `out`; the ELF.
fn build_firmware(lib: &Path, image: &Path, blob: &Path, out: &Path) -> PathBuf {
    build_firmware_with(lib, image, blob, out, "")
}

/// [`build_firmware`] with extra C flags (`CDEFS`).
fn build_firmware_with(lib: &Path, image: &Path, blob: &Path, out: &Path, cdefs: &str) -> PathBuf {
    let res = Command::new("make")
        .arg("-s")
        .arg(format!("CDEFS={cdefs}"))
        .arg("-C")
        .arg(repo().join("firmware-sim/c"))
        .arg(format!("LIB={}", lib.display()))
        .arg(format!("IMAGE={}", image.display()))
        .arg(format!("BLOB={}", blob.display()))
        .arg(format!("OUT={}", out.display()))
        .output();
    let res = match res {
        Ok(r) => r,
        Err(e) => panic!("cannot run make ({e}): apt-get install -y make"),
    };
    assert!(
        res.status.success(),
        "building the C firmware failed (arm-none-eabi-gcc and newlib installed? \
         `bash scripts/setup.sh` or `apt-get install -y gcc-arm-none-eabi \
         libnewlib-arm-none-eabi`):\n{}\n{}",
        String::from_utf8_lossy(&res.stdout),
        String::from_utf8_lossy(&res.stderr)
    );
    println!("{}", String::from_utf8_lossy(&res.stdout));
    out.join("replay-c.elf")
}

fn image_bytes(frames: u32) -> Vec<u8> {
    writer::image_bytes(
        &synthetic::mcu_calibration(),
        &synthetic::mcu_frames(frames),
    )
    .expect("make image")
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn hashes_equal_host(dsp: bool) {
    let dir = tempfile::tempdir().unwrap();
    let bytes = image_bytes(5);
    let image = write(dir.path(), "good.dri", &bytes);
    let blob = write(dir.path(), "model.dblob", MCU_BLOB);
    let host = host_lines(&bytes);
    assert_eq!(host.len(), 5);
    let elf = build_firmware(
        &cortex_m_lib(if dsp { "arm-dsp" } else { "" }),
        &image,
        &blob,
        &dir.path().join("out"),
    );
    let (code, stdout) = run_qemu_m4(&elf, QEMU_TIMEOUT);
    println!("{stdout}");
    assert_eq!(code, 0, "C firmware exit status; output:\n{stdout}");
    let firmware: Vec<String> = stdout
        .lines()
        .filter(|l| l.starts_with("frame "))
        .map(str::to_owned)
        .collect();
    assert_eq!(firmware, host, "C firmware (arm-dsp {dsp}) vs Rust host");
    for needle in [
        "replay image: 5 frames",
        "engine: blob",
        "icount frame 4 projection=",
        "stack high-water: ",
        "flash: ",
        "TEST OK",
    ] {
        assert!(stdout.contains(needle), "missing {needle:?}:\n{stdout}");
    }
    assert!(!stdout.contains("PANIC"), "{stdout}");
}

#[test]
fn c_firmware_hashes_equal_host_with_dsp_kernels() {
    hashes_equal_host(true);
}

#[test]
fn c_firmware_hashes_equal_host_with_portable_kernels() {
    hashes_equal_host(false);
}

#[test]
fn c_firmware_rejects_bad_images_with_the_rust_codes() {
    let dir = tempfile::tempdir().unwrap();
    let blob = write(dir.path(), "model.dblob", MCU_BLOB);
    let good = image_bytes(1);
    let mut crc = good.clone();
    let last = crc.len() - 1;
    crc[last] ^= 0xff;
    let mut magic = good.clone();
    magic[0] = b'X';
    let mut extra = good.clone();
    extra.push(0);
    for (name, bytes, code) in [
        ("crc.dri", crc, 7),
        ("magic.dri", magic, 2),
        ("extra.dri", extra, 6),
    ] {
        let image = write(dir.path(), name, &bytes);
        let expected = Image::parse(&bytes).expect_err(name).exit_code();
        assert_eq!(i32::from(expected), code, "{name}: the Rust parser's code");
        let elf = build_firmware(
            &cortex_m_lib("arm-dsp"),
            &image,
            &blob,
            &dir.path().join(format!("out-{name}")),
        );
        let (status, stdout) = run_qemu_m4(&elf, QEMU_TIMEOUT);
        assert_eq!(status, code, "{name}: exit status; output:\n{stdout}");
        assert!(
            stdout.contains(&format!("ERROR {code}: ")),
            "{name}:\n{stdout}"
        );
        assert!(
            !stdout.contains("TEST OK") && !stdout.contains("PANIC"),
            "{stdout}"
        );
    }
}

/// A panic inside the no_std library (the test-only `depthor_probe_panic`, feature
/// `panic-probe`) runs its panic handler's `udf`: the firmware's HardFault handler prints
/// `PANIC: HardFault` and exits 101; nothing returns into C.
#[test]
fn c_firmware_panic_in_the_library_is_a_hardfault() {
    let dir = tempfile::tempdir().unwrap();
    let image = write(dir.path(), "good.dri", &image_bytes(1));
    let blob = write(dir.path(), "model.dblob", MCU_BLOB);
    let elf = build_firmware_with(
        &cortex_m_lib("arm-dsp,panic-probe"),
        &image,
        &blob,
        &dir.path().join("out"),
        "-DDEPTHOR_PANIC_PROBE",
    );
    let (code, stdout) = run_qemu_m4(&elf, QEMU_TIMEOUT);
    assert_eq!(code, 101, "exit status; output:\n{stdout}");
    assert!(
        stdout.contains("probe: calling depthor_probe_panic"),
        "{stdout}"
    );
    assert!(stdout.contains("PANIC: HardFault"), "{stdout}");
    assert!(!stdout.contains("probe: returned"), "{stdout}");
}
