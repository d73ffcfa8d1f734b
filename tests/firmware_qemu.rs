//! Host vs firmware, bit for bit: builds `firmware-sim` for thumbv7em-none-eabihf with a replay
//! image made here, runs it under `qemu-system-arm` (mps2-an386, a Cortex-M4, and the same ELF
//! on mps2-an500, a Cortex-M7; `-icount shift=0`), and requires exit status 0 and per-frame hash
//! lines equal to the host build of the same loop on both.
//! Bad images must make the firmware print `ERROR <code>` and exit with that code, not panic.
//! The adversarial frames (feature `adversarial`) must all complete, and the printed spread of
//! the instructions per frame must be the one of the per-frame counts, within 1 % of the mean.
//!
//! Needs `qemu-system-arm` and the `thumbv7em-none-eabihf` Rust target (`bash scripts/setup.sh`
//! installs both; the test command `bash scripts/test.sh` runs it first); without them these
//! tests FAIL with a message saying what to install.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::Duration;

use depthor_replay::format::HEADER_LEN;
use depthor_replay::host::{host_lines, host_results, run_qemu_m4, run_qemu_m7};
use depthor_replay::{synthetic, writer};

const TARGET: &str = "thumbv7em-none-eabihf";
/// Wall-clock limit for one QEMU run. With the model, a 120×160 frame is ≈ 1.4 G instructions
/// (DSP kernels): 5 frames plus the per-op profiling frame took ≈ 30 s of wall time on a loaded
/// 2-core machine (QEMU 10.0, `-icount shift=0`).
const QEMU_TIMEOUT: Duration = Duration::from_secs(600);

/// One firmware build at a time: the image is baked in at build time and all builds share
/// `firmware-sim/target`, so build + copy of the ELF must not interleave between tests.
static BUILD: Mutex<()> = Mutex::new(());

fn firmware_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("firmware-sim")
}

/// Builds the `bin` scenario with `image` embedded and copies the ELF into `dir`.
fn build_firmware(bin: &str, image: &Path, dir: &Path) -> PathBuf {
    build_firmware_with(bin, &[], image, dir)
}

/// [`build_firmware`] with the firmware's cargo `features` on.
fn build_firmware_with(bin: &str, features: &[&str], image: &Path, dir: &Path) -> PathBuf {
    let _guard = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let fw = firmware_dir();
    let target_dir = fw.join("target");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(&fw)
        .args([
            "build",
            "--release",
            "--bin",
            bin,
            "--target",
            TARGET,
            "--target-dir",
        ])
        .arg(&target_dir)
        .args(if features.is_empty() {
            vec![]
        } else {
            vec!["--features".to_owned(), features.join(",")]
        })
        .env("DEPTHOR_REPLAY_IMAGE", image)
        // The outer `cargo test` sets these for the root package; the firmware must not see them.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .output()
        .expect("run cargo to build firmware-sim");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "building firmware-sim failed (is the Rust target installed? \
         `bash scripts/setup.sh` or `rustup target add {TARGET}`):\n{stderr}"
    );
    let elf = target_dir.join(TARGET).join("release").join(bin);
    let copy = dir.join(format!("{bin}{}.elf", features.join("+")));
    std::fs::copy(&elf, &copy).expect("copy firmware ELF");
    copy
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write image");
    path
}

#[test]
fn qemu_hashes_equal_host_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let frames = 5;
    let bytes = writer::image_bytes(
        &synthetic::mcu_calibration(),
        &synthetic::mcu_frames(frames),
    )
    .expect("make image");
    let image = write(dir.path(), "good.dri", &bytes);
    let host = host_lines(&bytes);
    assert_eq!(host.len(), frames as usize);

    let elf = build_firmware("replay", &image, dir.path());
    for (cpu, run) in [
        (
            "Cortex-M4",
            run_qemu_m4 as fn(&Path, Duration) -> (i32, String),
        ),
        ("Cortex-M7", run_qemu_m7),
    ] {
        check_replay_run(cpu, run(&elf, QEMU_TIMEOUT), &host);
    }
}

/// One QEMU run of the replay firmware on `cpu`: exit 0, the host's frame lines, the figures.
fn check_replay_run(cpu: &str, (code, stdout): (i32, String), host: &[String]) {
    assert_eq!(code, 0, "firmware exit status on {cpu}; output:\n{stdout}");
    assert!(stdout.contains(&format!("cpu: {cpu} ")), "{stdout}");
    let firmware: Vec<String> = stdout
        .lines()
        .filter(|l| l.starts_with("frame "))
        .map(str::to_owned)
        .collect();
    for (i, (h, f)) in host.iter().zip(&firmware).enumerate() {
        assert_eq!(
            h, f,
            "frame {i}: host and QEMU ({cpu}) differ; firmware output:\n{stdout}"
        );
    }
    assert_eq!(firmware.len(), host.len(), "frame count; output:\n{stdout}");
    for needle in [
        "engine: blob",
        "instructions/frame: mean",
        "estimate (not a measurement)",
        "ram: statics",
        "ram buffer arena",
        "ram buffer stack (high-water)",
        "flash: ",
        "vl53l5cx init (once, before frame 0): instructions=",
        "vl53l5cx frame 0 driver_instructions=",
        "vl53l5cx: mean driver instructions/frame",
        "TEST OK",
    ] {
        assert!(stdout.contains(needle), "missing {needle:?} in:\n{stdout}");
    }
    assert!(!stdout.contains("PANIC"), "{stdout}");
    // Issue 41: the whole firmware (statics + stack high-water) in 320 KiB with mcu_lite.
    let total: usize = stdout
        .lines()
        .find_map(|l| l.strip_prefix("ram: statics "))
        .and_then(|l| l.split(" = ").nth(1))
        .and_then(|l| l.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no RAM total on {cpu}:\n{stdout}"));
    assert!(
        total <= RAM_BUDGET_BYTES,
        "firmware RAM {total} B on {cpu} grew past {RAM_BUDGET_BYTES} B"
    );
}

/// The firmware's RAM budget with the default blob (`mcu_lite`): 320 KiB (issue 41; 327 188 B
/// measured on 2026-12-06).
const RAM_BUDGET_BYTES: usize = 320 * 1024;

/// Runs the firmware on a defective image: it must report `ERROR <code>` and exit with it.
fn assert_firmware_rejects(name: &str, bytes: &[u8], code: u8) {
    let dir = tempfile::tempdir().expect("tempdir");
    let image = write(dir.path(), name, bytes);
    let elf = build_firmware("replay", &image, dir.path());
    let (status, stdout) = run_qemu_m4(&elf, QEMU_TIMEOUT);
    assert_eq!(
        status,
        i32::from(code),
        "exit status for {name}; output:\n{stdout}"
    );
    assert!(
        stdout.contains(&format!("ERROR {code}: ")),
        "{name}:\n{stdout}"
    );
    assert!(
        !stdout.contains("PANIC") && !stdout.contains("TEST OK"),
        "{name}:\n{stdout}"
    );
}

fn good_bytes(frames: u32) -> Vec<u8> {
    writer::image_bytes(
        &synthetic::mcu_calibration(),
        &synthetic::mcu_frames(frames),
    )
    .expect("make image")
}

#[test]
fn qemu_rejects_truncated_image() {
    let mut bytes = good_bytes(2);
    bytes.truncate(bytes.len() - 1000);
    assert_firmware_rejects("truncated.dri", &bytes, 5);
}

#[test]
fn qemu_rejects_zone_count_mismatch() {
    // Frame 1's zone count says 63 while the header's grid is 8×8; CRC recomputed so only the
    // count is wrong.
    let mut bytes = good_bytes(2);
    let record = (bytes.len() - HEADER_LEN - 4) / 2;
    let at = HEADER_LEN + record;
    bytes[at..at + 2].copy_from_slice(&63u16.to_le_bytes());
    writer::reseal(&mut bytes);
    assert_firmware_rejects("zone_count.dri", &bytes, 8);
}

#[test]
fn qemu_rejects_more_zones_than_the_build_holds() {
    // A valid image with a 10×10 grid: the firmware holds 8×8, so the loop stops (code 13).
    let mut cal = synthetic::mcu_calibration();
    cal.dtof.rows = 10;
    cal.dtof.cols = 10;
    let frames: Vec<_> = (0..2)
        .map(|i| synthetic::frame(i, 10, 10, 120, 160))
        .collect();
    let bytes = writer::image_bytes(&cal, &frames).expect("make image");
    assert_firmware_rejects("zones_10x10.dri", &bytes, 13);
}

#[test]
fn qemu_rejects_a_grid_the_vl53l5cx_does_not_have() {
    // A valid 6×6 image fits the build's 64 zones, but the VL53L5CX has 4×4 or 8×8 (code 12).
    let mut cal = synthetic::mcu_calibration();
    cal.dtof.rows = 6;
    cal.dtof.cols = 6;
    let frames: Vec<_> = (0..2)
        .map(|i| synthetic::frame(i, 6, 6, 120, 160))
        .collect();
    let bytes = writer::image_bytes(&cal, &frames).expect("make image");
    assert_firmware_rejects("zones_6x6.dri", &bytes, 12);
}

#[test]
fn qemu_instruction_count_method_checks_out() {
    // Not image-dependent; any image will do.
    let dir = tempfile::tempdir().expect("tempdir");
    let image = write(dir.path(), "any.dri", &good_bytes(1));
    let elf = build_firmware("icount_check", &image, dir.path());
    let (code, stdout) = run_qemu_m4(&elf, QEMU_TIMEOUT);
    assert_eq!(code, 0, "{stdout}");
    assert!(stdout.contains("TEST OK"), "{stdout}");
}

/// Issue 45 item 4: the frame-time spread on the Cortex-M4 over the adversarial frames, at most
/// 1 % of the mean (0.316 % measured on 2026-12-07; firmware-sim README "Frame time on
/// adversarial frames").
const SPREAD_BUDGET_MILLI_PERCENT: u64 = 1_000;

/// The number after `key` (up to the next space) in `line`.
fn field(line: &str, key: &str) -> u64 {
    let at = line
        .find(key)
        .unwrap_or_else(|| panic!("no {key:?} in {line:?}"));
    line[at + key.len()..]
        .split(' ')
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no number after {key:?} in {line:?}"))
}

#[test]
fn qemu_adversarial_frames_take_the_same_instructions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let named = synthetic::adversarial_frames();
    let frames: Vec<_> = named.iter().map(|(_, f)| f.clone()).collect();
    let bytes = writer::image_bytes(&synthetic::mcu_calibration(), &frames).expect("make image");
    let image = write(dir.path(), "adversarial.dri", &bytes);
    let host = host_results(&bytes);
    assert_eq!(host.len(), named.len());
    let elf = build_firmware_with("replay", &["adversarial"], &image, dir.path());
    let (code, stdout) = run_qemu_m4(&elf, QEMU_TIMEOUT);
    assert_eq!(code, 0, "adversarial run exit status; output:\n{stdout}");
    assert!(stdout.contains("TEST OK"), "{stdout}");
    assert!(
        !stdout.contains("PANIC") && !stdout.contains("ERROR"),
        "{stdout}"
    );

    // Every frame completes: a depth frame prints the host's hash line and its count, a frame
    // the core refuses (no valid zone) its count marked `refused`.
    let lines: Vec<&str> = stdout.lines().collect();
    let mut counts = Vec::new();
    let mut refused_counts = Vec::new();
    for (i, want) in host.iter().enumerate() {
        let icount = format!("icount frame {i} instructions=");
        let count_line = lines
            .iter()
            .find(|l| l.starts_with(&icount))
            .unwrap_or_else(|| panic!("no count for frame {i} ({}):\n{stdout}", named[i].0));
        let n = field(count_line, "instructions=");
        match want {
            Ok(hash_line) => {
                assert!(
                    lines.contains(&hash_line.as_str()),
                    "frame {i} ({}): host line {hash_line:?} missing:\n{stdout}",
                    named[i].0
                );
                assert!(!count_line.contains("refused"), "{count_line}");
                counts.push(n);
            }
            Err(code) => {
                assert_eq!(*code, 17, "frame {i}");
                assert!(count_line.contains(" refused ("), "{count_line}");
                assert!(
                    !lines.iter().any(|l| l.starts_with(&format!("frame {i} "))),
                    "refused frame {i} printed a hash:\n{stdout}"
                );
                refused_counts.push(n);
            }
        }
    }
    assert_eq!(
        refused_counts.len(),
        2,
        "the two frames without a valid zone"
    );

    // The summary is the figure of the per-frame counts: mean ⌊sum / n⌋, spread
    // ⌊(max − min) · 100 000 / mean⌋ thousandths of a percent.
    let summary = lines
        .iter()
        .find(|l| l.starts_with("adversarial: "))
        .unwrap_or_else(|| panic!("no adversarial line:\n{stdout}"));
    let (min, max) = (*counts.iter().min().unwrap(), *counts.iter().max().unwrap());
    let mean = counts.iter().sum::<u64>() / counts.len() as u64;
    let spread = (max - min) * 100_000 / mean;
    assert_eq!(field(summary, "adversarial: frames "), counts.len() as u64);
    assert_eq!(field(summary, " min "), min, "{summary}");
    assert_eq!(field(summary, " max "), max, "{summary}");
    assert_eq!(field(summary, " mean "), mean, "{summary}");
    let printed = format!(" spread {}.{:03}% ", spread / 1000, spread % 1000);
    assert!(
        summary.contains(&printed),
        "want {printed:?} in {summary:?}"
    );
    assert_eq!(field(summary, " refused "), 2, "{summary}");
    assert_eq!(
        field(summary, " at most "),
        *refused_counts.iter().max().unwrap(),
        "{summary}"
    );
    assert!(
        spread <= SPREAD_BUDGET_MILLI_PERCENT,
        "instructions per frame spread {}.{:03} % > 1 % of the mean: {summary}",
        spread / 1000,
        spread % 1000
    );
}
