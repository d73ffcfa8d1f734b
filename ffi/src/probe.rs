//! Test-only entry point (feature `panic-probe`, never in `depthor.h`): panics inside the same
//! guard as every real entry point, so tests can watch what a panic does in each build (std:
//! `DEPTHOR_E_INTERNAL`; no_std on Cortex-M: `udf`, a HardFault the firmware reports).

use crate::guard;

/// Panics under the entry points' guard; returns what the guard returns (std build only).
#[no_mangle]
pub extern "C" fn depthor_probe_panic() -> i32 {
    guard(|| panic!("depthor_probe_panic"))
}
