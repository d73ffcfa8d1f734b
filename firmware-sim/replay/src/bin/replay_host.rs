//! `replay-host IMAGE`: the host build of the firmware loop. Prints the same per-frame lines as
//! the QEMU firmware (`frame i sparse_fnv1a64=…`) and exits with the same status codes
//! (see the crate doc). Later exposed as `depthor firmware-replay`.

use std::process::ExitCode;

use depthor_core::hal::ZoneFrame;
use depthor_replay::format::Image;
use depthor_replay::pipeline::{ReplayLoop, Workspace};

/// Sleeps for real; the simulated bridge is always ready, so it is never called in practice.
struct StdDelay;

impl embedded_hal::delay::DelayNs for StdDelay {
    fn delay_ns(&mut self, ns: u32) {
        std::thread::sleep(std::time::Duration::from_nanos(u64::from(ns)));
    }
}

/// Zone capacity, as in the firmware (8×8).
const ZONES: usize = 64;

fn main() -> ExitCode {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: replay-host IMAGE");
        return ExitCode::from(1);
    };
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("{path}: {e}");
            return ExitCode::from(1);
        }
    };
    let image = match Image::parse(&bytes) {
        Ok(i) => i,
        Err(e) => {
            println!("ERROR {}: {e}", e.exit_code());
            return ExitCode::from(e.exit_code());
        }
    };
    let (h, w) = image.size();
    let pixels = usize::from(h) * usize::from(w);
    let mut rgb = vec![0u8; 3 * pixels];
    let mut sparse = vec![0f32; pixels];
    let mut bridge = [0f32; ZONES];
    let mut zones = ZoneFrame::<ZONES>::new();
    let mut ws = Workspace {
        rgb: &mut rgb,
        sparse_m: &mut sparse,
        bridge_mm: &mut bridge,
        zones: &mut zones,
    };
    let mut replay = ReplayLoop::new(image, StdDelay);
    match replay.run_all(&mut ws, |out| println!("{out}")) {
        Ok(n) => {
            println!("frames {n}");
            println!("TEST OK");
            ExitCode::SUCCESS
        }
        Err(e) => {
            println!("ERROR {}: {e}", e.exit_code());
            ExitCode::from(e.exit_code())
        }
    }
}
