//! Scenario `replay` (the default `cargo run --release`): replays the embedded image through the
//! shared loop ([`depthor_replay::pipeline`]), prints one hash line per frame (identical to the
//! host build's `replay-host`), then the instruction, RAM and flash figures, `TEST OK`, and
//! exits 0. A bad image or a loop error prints `ERROR <code>: <what>` and exits with the code.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use depthor_core::hal::ZoneFrame;
use depthor_firmware_sim::{console, cycles, memory, println};
use depthor_replay::format::Image;
use depthor_replay::pipeline::{FrameOutput, ReplayLoop, Workspace};

/// The replay image, copied into `OUT_DIR` by `build.rs` (flash, via `.rodata`).
static IMAGE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/replay.img"));

/// Image size this build holds: the `mcu` variant's 120×160 (DESIGN.md).
const PIXELS: usize = 120 * 160;
/// Zones this build holds: 8×8 (VL53L5CX class).
const ZONES: usize = 64;

/// Busy-wait delay for the dToF driver's polls (the simulated bridge is always ready, so it
/// does not run in practice). Assumes the 25 MHz core clock of the board model.
struct SpinDelay;

impl embedded_hal::delay::DelayNs for SpinDelay {
    fn delay_ns(&mut self, ns: u32) {
        cortex_m::asm::delay(ns.div_ceil(1_000_000_000 / cycles::SYSCLK_HZ));
    }
}

#[entry]
fn main() -> ! {
    // `static mut` inside `#[entry]`: cortex-m-rt turns each into a unique `&'static mut`.
    static mut RGB: [u8; 3 * PIXELS] = [0; 3 * PIXELS];
    static mut SPARSE: [f32; PIXELS] = [0.0; PIXELS];
    static mut BRIDGE: [f32; ZONES] = [0.0; ZONES];
    static mut ZONE_FRAME: ZoneFrame<ZONES> = ZoneFrame::new();

    memory::paint_stack();
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        println!("ERROR {}: core peripherals taken twice", depthor_replay::EXIT_PANIC);
        console::exit(depthor_replay::EXIT_PANIC);
    };
    cycles::start(peripherals.SYST);

    let image = match Image::parse(IMAGE) {
        Ok(image) => image,
        Err(e) => {
            println!("ERROR {}: {e}", e.exit_code());
            console::exit(e.exit_code());
        }
    };
    let (h, w) = image.size();
    let (rows, cols) = image.zone_grid();
    println!(
        "replay image: {} frames, {h}x{w} RGB, {rows}x{cols} zones, {} bytes",
        image.frame_count(),
        IMAGE.len()
    );

    let mut ws = Workspace {
        rgb: RGB,
        sparse_m: SPARSE,
        bridge_mm: BRIDGE,
        zones: ZONE_FRAME,
    };
    let mut replay = ReplayLoop::new(image, SpinDelay);

    // Cost of the two `ticks()` reads themselves, subtracted from every frame.
    let overhead = {
        let t0 = cycles::ticks();
        cycles::ticks() - t0
    };
    let (mut frames, mut total, mut min, mut max) = (0u64, 0u64, u64::MAX, 0u64);
    loop {
        let t0 = cycles::ticks();
        let result = replay.process(&mut ws);
        let t1 = cycles::ticks();
        match result {
            Ok(Some(processed)) => {
                let instructions = cycles::instructions((t1 - t0).saturating_sub(overhead));
                println!("{}", FrameOutput::new(&processed, ws.sparse_m));
                println!("icount frame {} instructions={instructions}", processed.index);
                frames += 1;
                total += instructions;
                min = min.min(instructions);
                max = max.max(instructions);
            }
            Ok(None) => break,
            Err(e) => {
                println!("ERROR {}: {e}", e.exit_code());
                console::exit(e.exit_code());
            }
        }
    }

    let stack = memory::stack_high_water();
    let statics = memory::statics_bytes();
    let flash = memory::flash_bytes();
    println!("frames {frames}");
    println!(
        "instructions/frame: mean {} min {min} max {max} (camera + dToF driver + projection; \
         SysTick x{} under -icount shift={})",
        total / frames.max(1),
        cycles::INSTRUCTIONS_PER_TICK,
        cycles::ICOUNT_SHIFT
    );
    println!(
        "ram: statics {statics} B + stack high-water {stack} B = {} B (of {} B stack region)",
        statics + stack,
        memory::stack_region_bytes()
    );
    println!(
        "flash: {flash} B = firmware {} B + replay image {} B",
        flash.saturating_sub(IMAGE.len()),
        IMAGE.len()
    );
    println!("TEST OK");
    console::exit(0)
}
