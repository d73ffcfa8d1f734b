//! The host build of the firmware loop (`std`): the same [`ReplayLoop`], the same engine and
//! blob ([`crate::model`]), with heap buffers in place of the firmware's statics.

use depthor_core::hal::ZoneFrame;
use embedded_hal::delay::DelayNs;

use crate::format::Image;
use crate::model::{prepare, ARENA_BUDGET_BYTES, MCU_BLOB};
use crate::pipeline::{FrameOutput, LoopError, ReplayLoop, Workspace, VL53_IO_BYTES};

/// A [`DelayNs`] that sleeps for real (the simulated sensor answers at once, so the driver
/// never waits in practice).
#[derive(Clone, Copy, Debug, Default)]
pub struct StdDelay;

impl DelayNs for StdDelay {
    fn delay_ns(&mut self, ns: u32) {
        std::thread::sleep(std::time::Duration::from_nanos(u64::from(ns)));
    }
}

/// Runs every frame of `image` through the loop with the embedded model and the VL53L5CX driver
/// over the simulated sensor (as the firmware does), holding up to `N` zones (the firmware holds
/// 64), and calls `emit` with each frame's output; returns the frame count.
pub fn replay_image<const N: usize>(
    image: Image<'_>,
    delay: impl DelayNs,
    emit: impl FnMut(&FrameOutput),
) -> Result<u32, LoopError> {
    let (h, w) = image.size();
    let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
    let mut slot = Box::new(core::mem::MaybeUninit::uninit());
    let engine = prepare(&mut slot, MCU_BLOB, &mut arena, h, w).map_err(LoopError::Engine)?;
    let mut bridge = [0f32; N];
    let mut zones = ZoneFrame::<N>::new();
    let mut ws = Workspace {
        bridge_mm: &mut bridge,
        zones: &mut zones,
    };
    let mut io = vec![0u8; VL53_IO_BYTES];
    ReplayLoop::with_vl53l5cx(image, delay, &mut io, || 0).run_all(engine, &mut ws, emit)
}

/// The `frame …` lines the host build of the loop prints for the replay image `bytes` (what the
/// firmware must print bit for bit); panics on an image the host refuses (a test helper).
pub fn host_lines(bytes: &[u8]) -> Vec<String> {
    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }
    let image = Image::parse(bytes).expect("host parses the image");
    let mut lines = Vec::new();
    replay_image::<64>(image, NoDelay, |out| lines.push(out.to_string())).expect("host loop runs");
    lines
}

/// Per frame of the replay image `bytes`, what the firmware built with its `adversarial` feature
/// must print: `Ok(line)`, the frame's `frame …` line, or `Err(code)` for a frame the core refuses
/// (exit code 17 in the default build: no valid zone), which that build reports and skips; panics
/// on an image the host refuses or another loop error (a test helper).
pub fn host_results(bytes: &[u8]) -> Vec<Result<String, u8>> {
    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }
    let image = Image::parse(bytes).expect("host parses the image");
    let (h, w) = image.size();
    let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
    let mut slot = Box::new(core::mem::MaybeUninit::uninit());
    let engine = prepare(&mut slot, MCU_BLOB, &mut arena, h, w).expect("engine");
    let mut bridge = [0f32; 64];
    let mut zones = ZoneFrame::<64>::new();
    let mut ws = Workspace {
        bridge_mm: &mut bridge,
        zones: &mut zones,
    };
    let mut io = vec![0u8; VL53_IO_BYTES];
    let mut replay = ReplayLoop::with_vl53l5cx(image, NoDelay, &mut io, || 0);
    let mut out = Vec::new();
    loop {
        match replay.process(engine, &mut ws) {
            Ok(Some(p)) => {
                let depth = engine.output_m().expect("engine output");
                out.push(Ok(FrameOutput::new(&p, depth).to_string()));
            }
            Ok(None) => return out,
            Err(e @ LoopError::Frame(_)) => out.push(Err(e.exit_code())),
            Err(e) => panic!("host loop stopped at frame {}: {e}", out.len()),
        }
    }
}

/// Runs the Cortex-M4 firmware `elf` under `qemu-system-arm` (mps2-an386, `-icount shift=0`,
/// semihosting) and returns (exit status, stdout); panics, naming what to install, when QEMU is
/// missing, and when the run exceeds `timeout` (a hung firmware). A test helper shared by the Rust
/// and the C firmware tests.
pub fn run_qemu_m4(elf: &std::path::Path, timeout: std::time::Duration) -> (i32, String) {
    run_qemu(elf, "mps2-an386", "cortex-m4", timeout)
}

/// As [`run_qemu_m4`] on QEMU's `mps2-an500` board, a Cortex-M7 (the same ELF: its code and RAM
/// sit where the AN386's do).
pub fn run_qemu_m7(elf: &std::path::Path, timeout: std::time::Duration) -> (i32, String) {
    run_qemu(elf, "mps2-an500", "cortex-m7", timeout)
}

/// Runs `elf` on QEMU's `machine` with `cpu` (see [`run_qemu_m4`]).
fn run_qemu(
    elf: &std::path::Path,
    machine: &str,
    cpu: &str,
    timeout: std::time::Duration,
) -> (i32, String) {
    use std::process::{Command, Stdio};
    let spawned = Command::new("qemu-system-arm")
        .args(["-machine", machine, "-cpu", cpu])
        .args(["-icount", "shift=0"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args([
            "-nographic",
            "-monitor",
            "none",
            "-serial",
            "none",
            "-kernel",
        ])
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn();
    let mut child = match spawned {
        Ok(c) => c,
        Err(e) => panic!(
            "cannot run qemu-system-arm ({e}); install it: `bash scripts/setup.sh` or \
             `apt-get install -y qemu-system-arm` (Debian). This test must not be skipped."
        ),
    };
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for qemu") {
            break status;
        }
        if start.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            panic!("qemu-system-arm ran longer than {timeout:?}: firmware hung");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let out = child.wait_with_output().expect("collect qemu output");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let code = status
        .code()
        .unwrap_or_else(|| panic!("qemu killed by a signal:\n{stdout}\n{stderr}"));
    (code, stdout)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{mcu_calibration, mcu_frames};
    use crate::writer::image_bytes;

    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }

    #[test]
    fn replays_every_frame_deterministically() {
        let bytes = image_bytes(&mcu_calibration(), &mcu_frames(2)).unwrap();
        let mut a = Vec::new();
        let n = replay_image::<64>(Image::parse(&bytes).unwrap(), NoDelay, |o| {
            a.push(o.to_string())
        })
        .unwrap();
        assert_eq!(n, 2);
        let mut b = Vec::new();
        replay_image::<64>(Image::parse(&bytes).unwrap(), NoDelay, |o| b.push(*o)).unwrap();
        assert_eq!(a, b.iter().map(|o| o.to_string()).collect::<Vec<_>>());
        assert!(a[0].starts_with("frame 0 depth_fnv1a64="), "{}", a[0]);
        assert_ne!(b[0].hash, b[1].hash);
    }

    #[test]
    fn host_results_go_on_past_refused_frames() {
        let mut frames = mcu_frames(3);
        frames[1].status.fill(4);
        let results = host_results(&image_bytes(&mcu_calibration(), &frames).unwrap());
        let good = host_lines(&image_bytes(&mcu_calibration(), &mcu_frames(1)).unwrap());
        assert_eq!(results.len(), 3);
        assert_eq!(results[0].as_ref().unwrap(), &good[0]);
        assert_eq!(results[1], Err(17));
        assert!(results[2].as_ref().unwrap().starts_with("frame 2 "));
    }

    #[test]
    fn adversarial_frames_cover_the_listed_cases() {
        use crate::synthetic::adversarial_frames;
        let named = adversarial_frames();
        let names: Vec<_> = named.iter().map(|(n, _)| *n).collect();
        for want in [
            "normal_0",
            "no_target",
            "invalid_status",
            "max_range",
            "min_max",
            "extreme",
            "white",
            "black",
            "random_0",
        ] {
            assert!(names.contains(&want), "{want} missing from {names:?}");
        }
        // The first five are the default image's frames.
        let default = mcu_frames(5);
        for (i, f) in default.iter().enumerate() {
            assert_eq!(&named[i].1, f);
        }
        // Everything fits the format; the two invalid frames are the only refused ones.
        let frames: Vec<_> = named.into_iter().map(|(_, f)| f).collect();
        let results = host_results(&image_bytes(&mcu_calibration(), &frames).unwrap());
        let refused: Vec<_> = results
            .iter()
            .enumerate()
            .filter(|(_, r)| r.is_err())
            .map(|(i, _)| names[i])
            .collect();
        assert_eq!(refused, ["no_target", "invalid_status"]);
    }
}
