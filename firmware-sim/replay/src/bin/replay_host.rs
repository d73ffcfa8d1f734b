//! `replay-host IMAGE`: the host build of the firmware loop. Prints the same per-frame lines as
//! the QEMU firmware (`frame i depth_fnv1a64=…`) and exits with the same status codes
//! (see the crate doc). Also exposed as `depthor firmware-replay`.

use std::process::ExitCode;

use depthor_replay::format::Image;
use depthor_replay::host::{replay_image, StdDelay};

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
    match replay_image::<ZONES>(image, StdDelay, |out| println!("{out}")) {
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
