//! Scenario `replay` (the default `cargo run --release`): replays the embedded image through the
//! shared loop ([`depthor_replay::pipeline`]), prints one hash line per frame (identical to the
//! host build's `replay-host`), then the instruction, RAM and flash figures, `TEST OK`, and
//! exits 0. A bad image or a loop error prints `ERROR <code>: <what>` and exits with the code.
//!
//! Feature `adversarial` (the frame-time check, README "Frame time on adversarial frames"): a
//! frame without one valid zone prints its `icount frame … refused` line instead of stopping the
//! run with exit 17, and the run ends with the `adversarial: … min … max … mean … spread …%`
//! line over the frames with depth ([`depthor_replay::frametime`]).
#![no_std]
#![no_main]

use core::mem::{size_of, MaybeUninit};
use cortex_m_rt::entry;
#[cfg(feature = "profile")]
use depthor_core::blob::format::op_name;
#[cfg(feature = "profile")]
use depthor_core::calibration::Calibration;
use depthor_core::engine::Engine;
use depthor_core::hal::ZoneFrame;
#[cfg(feature = "profile")]
use depthor_core::projection::project_to_sparse;
use depthor_firmware_sim::{console, cycles, memory, println};
use depthor_replay::format::Image;
use depthor_replay::model::{self, ARENA_BUDGET_BYTES, MCU_BLOB};
use depthor_replay::pipeline::{
    FrameOutput, LoopError, Probe, ReplayLoop, Stage, Workspace, VL53_IO_BYTES,
};

/// 4-byte alignment for the embedded image, so its (4-aligned) RGB records copy by words.
#[repr(C, align(4))]
struct Aligned<B: ?Sized>(B);

static ALIGNED_IMAGE: &Aligned<[u8]> =
    &Aligned(*include_bytes!(concat!(env!("OUT_DIR"), "/replay.img")));

/// The replay image, copied into `OUT_DIR` by `build.rs` (flash, via `.rodata`).
static IMAGE: &[u8] = &ALIGNED_IMAGE.0;

/// Stages timed per frame (all but [`Stage::Done`]).
const STAGES: [Stage; 4] = [Stage::Camera, Stage::Dtof, Stage::Projection, Stage::Model];

/// Accumulates SysTick ticks per stage from the loop's stage marks.
#[derive(Default)]
struct TickProbe {
    current: Option<usize>,
    since: u64,
    ticks: [u64; STAGES.len()],
}

impl Probe for TickProbe {
    fn mark(&mut self, stage: Stage) {
        let now = cycles::ticks();
        if let Some(slot) = self.current.and_then(|i| self.ticks.get_mut(i)) {
            *slot += now - self.since;
        }
        self.current = STAGES.iter().position(|s| *s == stage);
        self.since = now;
    }
}

/// Image size the profiling build's buffers hold: the `mcu` variants' 120×160 (docs/design.md).
#[cfg(feature = "profile")]
const PIXELS: usize = 120 * 160;
/// Zones this build holds: 8×8 (VL53L5CX class).
const ZONES: usize = 64;

/// The engine's arena: a `.bss` static in SSRAM (`RAM` in `memory.x`), 16-byte aligned like the
/// engine's buffers (it would realign a misaligned one at the cost of up to 15 bytes).
#[repr(C, align(16))]
struct Arena([u8; ARENA_BUDGET_BYTES]);

/// Busy-wait delay for the dToF driver's waits (the simulated VL53L5CX answers at once, so
/// only the ULD's fixed boot waits run: 1 ms + 100 ms + one 10 ms wait per command poll). Assumes the 25 MHz core clock of the board model.
struct SpinDelay;

impl embedded_hal::delay::DelayNs for SpinDelay {
    fn delay_ns(&mut self, ns: u32) {
        cortex_m::asm::delay(ns.div_ceil(1_000_000_000 / cycles::SYSCLK_HZ));
    }
}

/// Most op kinds the per-kind summary holds.
#[cfg(feature = "profile")]
const KINDS: usize = 24;

/// Runs the last frame's inputs once more through [`Engine::run_observed`], reading SysTick after
/// every op, and prints the instructions of each op (with its first input's and its output's
/// shapes, and a conv's kernel, stride and groups) and of each op kind (feature `profile`: its
/// output buffer is 4·H·W bytes the shipping build does not hold).
#[cfg(feature = "profile")]
#[inline(never)]
fn profile_ops<const N: usize>(
    engine: &mut Engine<'_>,
    ws: &mut Workspace<'_, N>,
    image: &Image<'_>,
    last: u32,
) {
    let cal: Calibration = image.calibration();
    let Some(frame) = image.frame(last) else {
        return;
    };
    let ops = engine.graph().ops.len();
    let mut per_op = [0u64; depthor_core::blob::format::MAX_OPS];
    // The frame's inputs are gone from the arena: project its zones again, take its RGB from
    // the image, into buffers of the profiling build only.
    let scratch = ProfileScratch::take();
    if let Err(e) = project_to_sparse(&cal, &ws.zones.view(), scratch.sparse) {
        println!("op profile: projection error {e}");
        return;
    }
    let mut last = cycles::ticks();
    let result = engine.run_observed(frame.rgb, scratch.sparse, scratch.depth, &mut |i, _| {
        let now = cycles::ticks();
        if let Some(t) = per_op.get_mut(i) {
            *t = now - last;
        }
        last = cycles::ticks();
    });
    if let Err(e) = result {
        println!("op profile: engine error {e}");
        return;
    }
    let mut kinds: [(&str, u64, u64); KINDS] = [("", 0, 0); KINDS];
    let mut total = 0u64;
    // An op fused into another (affinity heads into the refinement, a concat into its conv)
    // runs inside it: its MACs are counted there.
    let plan = engine.plan();
    let macs_of = |i: usize| -> u64 {
        if plan.fused_into(i).is_some() {
            return 0;
        }
        (0..ops)
            .filter(|&j| j == i || plan.fused_into(j) == Some(i))
            .map(|j| plan.op_macs(engine.graph(), j))
            .sum()
    };
    for (i, op) in engine.graph().ops.iter().enumerate().take(ops) {
        let fused = plan.fused_into(i).is_some();
        let name = if fused {
            "(fused)"
        } else {
            op_name(op.code).unwrap_or("?")
        };
        let n = cycles::instructions(per_op[i]);
        let macs = macs_of(i);
        total += n;
        let sh = |t: u16| plan.shape(t).unwrap_or_default();
        let (o, x) = (
            sh(op.output),
            sh(op.inputs.first().copied().unwrap_or(op.output)),
        );
        let geo = match op.attrs {
            depthor_core::blob::parse::Attrs::Conv { geometry, .. } => geometry.0,
            _ => [0; 9],
        };
        println!(
            "op {i} {name} macs={macs} instructions={n} in={}x{}x{} out={}x{}x{} k={}x{} s={} g={}",
            x.c, x.h, x.w, o.c, o.h, o.w, geo[0], geo[1], geo[2], geo[8]
        );
        if let Some(k) = kinds.iter_mut().find(|k| k.0 == name || k.0.is_empty()) {
            k.0 = name;
            k.1 += n;
            k.2 += macs;
        }
    }
    for (name, n, macs) in kinds.iter().filter(|k| !k.0.is_empty()) {
        let per_mac = (*n * 100).checked_div(*macs).unwrap_or(0) as u32;
        println!(
            "op kind {name}: instructions={n} ({}.{}% of {total}) macs={macs} instructions/MAC={}.{:02}",
            n * 100 / total.max(1),
            (n * 1000 / total.max(1)) % 10,
            per_mac / 100,
            per_mac % 100
        );
    }
}

/// The input and output buffers of the profiling run (the shipping build holds none: its frames
/// live in the engine's arena).
#[cfg(feature = "profile")]
struct ProfileScratch {
    sparse: &'static mut [f32],
    depth: &'static mut [f32],
}

#[cfg(feature = "profile")]
impl ProfileScratch {
    fn take() -> Self {
        static mut SPARSE: [f32; PIXELS] = [0.0; PIXELS];
        static mut DEPTH: [f32; PIXELS] = [0.0; PIXELS];
        // SAFETY: called once, from `main` after the loop, single-threaded; nothing else
        // refers to these statics.
        unsafe {
            ProfileScratch {
                sparse: &mut *core::ptr::addr_of_mut!(SPARSE),
                depth: &mut *core::ptr::addr_of_mut!(DEPTH),
            }
        }
    }
}

/// What the frame loop measured.
struct Totals {
    /// Instructions per frame of every frame (feature `adversarial`: refused frames apart).
    #[cfg(feature = "adversarial")]
    times: depthor_replay::frametime::FrameTimes,
    frames: u64,
    min: u64,
    max: u64,
    stage_totals: [u64; STAGES.len()],
    driver_total: u64,
    device_total: u64,
}

/// Runs every frame of the image, printing each frame's lines; out of line so that `main`'s
/// frame (preparation, report) is not under the engine's deep frames.
#[inline(never)]
fn run_frames<const N: usize>(
    engine: &mut Engine<'_>,
    replay: &mut ReplayLoop<'_, SpinDelay>,
    ws: &mut Workspace<'_, N>,
) -> Totals {
    let (mut driver_total, mut device_total) = (0u64, 0u64);
    let (mut frames, mut min, mut max) = (0u64, u64::MAX, 0u64);
    let mut stage_totals = [0u64; STAGES.len()];
    #[cfg(feature = "adversarial")]
    let mut times = depthor_replay::frametime::FrameTimes::new();
    loop {
        let mut probe = TickProbe::default();
        let result = replay.process_probed(engine, ws, &mut probe);
        match result {
            Ok(Some(processed)) => {
                let per_stage = probe.ticks.map(cycles::instructions);
                let instructions: u64 = per_stage.iter().sum();
                // The dense depth in metres, in the arena: hashed as the host hashes it, then
                // turned into millimetres in place (what the firmware passes on).
                let depth_m = match engine.output_m() {
                    Ok(d) => d,
                    Err(e) => fail(LoopError::Engine(e)),
                };
                println!("{}", FrameOutput::new(&processed, depth_m));
                match engine.output_mm() {
                    Ok(mm) => println!(
                        "depth_mm frame {} (u16, in place in the arena) centre={} first={}",
                        processed.index,
                        mm.get(mm.len() / 2 + 80).copied().unwrap_or(0),
                        mm.first().copied().unwrap_or(0)
                    ),
                    Err(e) => fail(LoopError::Engine(e)),
                }
                println!(
                    "icount frame {} instructions={instructions} camera={} dtof={} projection={} \
                     model={}",
                    processed.index, per_stage[0], per_stage[1], per_stage[2], per_stage[3]
                );
                let vl53 = replay.vl53_stats();
                if processed.index == 0 {
                    println!(
                        "vl53l5cx init (once, before frame 0): instructions={} (of which \
                         simulated sensor {}) transactions={} bytes_written={} bytes_read={}",
                        cycles::instructions(vl53.init_ticks),
                        cycles::instructions(vl53.init.device_ticks),
                        vl53.init.transactions,
                        vl53.init.bytes_written,
                        vl53.init.bytes_read
                    );
                }
                let device = cycles::instructions(vl53.frame.device_ticks);
                let driver = per_stage[1].saturating_sub(device);
                driver_total += driver;
                device_total += device;
                println!(
                    "vl53l5cx frame {} driver_instructions={driver} simulated_sensor={device} \
                     transactions={} bytes_read={} bytes_written={}",
                    processed.index,
                    vl53.frame.transactions,
                    vl53.frame.bytes_read,
                    vl53.frame.bytes_written
                );
                frames += 1;
                for (total, n) in stage_totals.iter_mut().zip(per_stage) {
                    *total += n;
                }
                min = min.min(instructions);
                max = max.max(instructions);
                #[cfg(feature = "adversarial")]
                times.add(instructions);
            }
            Ok(None) => break,
            // Feature `adversarial`: a frame without one valid zone is refused by the core (the
            // model does not run); the firmware reports it and goes on with the next frame.
            #[cfg(feature = "adversarial")]
            Err(e @ LoopError::Frame(_)) => {
                probe.mark(Stage::Done);
                let per_stage = probe.ticks.map(cycles::instructions);
                let instructions: u64 = per_stage.iter().sum();
                println!(
                    "icount frame {} instructions={instructions} camera={} dtof={} projection={} \
                     model={} refused ({e}: the model does not run)",
                    replay.next_index().saturating_sub(1),
                    per_stage[0],
                    per_stage[1],
                    per_stage[2],
                    per_stage[3]
                );
                times.add_refused(instructions);
            }
            Err(e) => {
                println!("ERROR {}: {e}", e.exit_code());
                console::exit(e.exit_code());
            }
        }
    }
    Totals {
        #[cfg(feature = "adversarial")]
        times,
        frames,
        min,
        max,
        stage_totals,
        driver_total,
        device_total,
    }
}

/// Prints `ERROR <code>: <e>` and exits with the code.
fn fail(e: LoopError) -> ! {
    println!("ERROR {}: {e}", e.exit_code());
    console::exit(e.exit_code())
}

/// Prints the RAM figures: `ram: statics … + stack high-water … = total`, then one `ram buffer`
/// line per named static (and the stack), largest first.
fn print_ram(buffers: &[(&str, usize)], statics: usize, stack: usize, arena_used: usize) {
    println!(
        "ram: statics {statics} B + stack high-water {stack} B = {} B (arena reserved {} B, \
         used {arena_used} B; {} B of RAM left for the stack)",
        statics + stack,
        ARENA_BUDGET_BYTES,
        memory::stack_region_bytes()
    );
    let named: usize = buffers.iter().map(|b| b.1).sum();
    let mut shown = [false; 16];
    for _ in buffers {
        let Some((i, (name, bytes))) = buffers
            .iter()
            .enumerate()
            .filter(|(i, _)| !shown.get(*i).copied().unwrap_or(true))
            .max_by_key(|(i, b)| (b.1, usize::MAX - i))
        else {
            break;
        };
        if let Some(s) = shown.get_mut(i) {
            *s = true;
        }
        println!("ram buffer {name}: {bytes} B");
    }
    println!(
        "ram buffer other statics: {} B",
        statics.saturating_sub(named)
    );
    println!("ram buffer stack (high-water): {stack} B");
}

/// Builds the replay loop (VL53L5CX driver over the simulated sensor) in `slot`; out of line so
/// that the value under construction stays out of `main`'s frame.
#[inline(never)]
fn init_replay(
    slot: &'static mut MaybeUninit<ReplayLoop<'static, SpinDelay>>,
    image: Image<'static>,
    io: &'static mut [u8],
) -> &'static mut ReplayLoop<'static, SpinDelay> {
    // dToF: the VL53L5CX driver over the simulated sensor (ST's ULD protocol); the clock lets
    // the loop count the ticks spent inside the simulation, to tell the driver's share apart.
    slot.write(ReplayLoop::with_vl53l5cx(
        image,
        SpinDelay,
        io,
        cycles::ticks,
    ))
}

// cortex-m-rt passes each `static mut` below to the real `main` as an argument.
#[allow(clippy::too_many_arguments)]
#[entry]
fn main() -> ! {
    // `static mut` inside `#[entry]`: cortex-m-rt turns each into a unique `&'static mut`.
    static mut ARENA: Arena = Arena([0; ARENA_BUDGET_BYTES]);
    static mut BRIDGE: [f32; ZONES] = [0.0; ZONES];
    static mut ZONE_FRAME: ZoneFrame<ZONES> = ZoneFrame::new();
    static mut VL53_IO: [u8; VL53_IO_BYTES] = [0; VL53_IO_BYTES];
    // The engine (op, tensor and buffer tables, ≈ 32 KiB) and the loop (the simulated sensor
    // inside it) in statics, not in `main`'s frame.
    static mut ENGINE: MaybeUninit<Engine<'static>> = MaybeUninit::uninit();
    static mut REPLAY: MaybeUninit<ReplayLoop<'static, SpinDelay>> = MaybeUninit::uninit();

    memory::paint_stack();
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        println!(
            "ERROR {}: core peripherals taken twice",
            depthor_replay::EXIT_PANIC
        );
        console::exit(depthor_replay::EXIT_PANIC);
    };
    depthor_firmware_sim::cpu::print(&peripherals.CPUID);
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

    let before = cycles::ticks();
    let engine = match model::prepare(ENGINE, MCU_BLOB, &mut ARENA.0, h, w) {
        Ok(engine) => engine,
        Err(e) => {
            let e = LoopError::Engine(e);
            println!("ERROR {}: {e}", e.exit_code());
            console::exit(e.exit_code());
        }
    };
    let arena_used = engine.plan().arena_bytes();
    println!(
        "engine: blob {} B at {:p}, arena {arena_used} B of {} B reserved ({:?} fused), {} \
         MAC/frame, prepared in {} instructions",
        MCU_BLOB.len(),
        MCU_BLOB.as_ptr(),
        ARENA_BUDGET_BYTES,
        engine.plan().fusion(),
        engine.plan().macs(),
        cycles::instructions(cycles::ticks() - before)
    );

    let mut ws = Workspace {
        bridge_mm: BRIDGE,
        zones: ZONE_FRAME,
    };
    let replay = init_replay(REPLAY, image, VL53_IO);
    let Totals {
        #[cfg(feature = "adversarial")]
        times,
        frames,
        min,
        max,
        stage_totals,
        driver_total,
        device_total,
    } = run_frames(engine, replay, &mut ws);

    #[cfg(feature = "profile")]
    if frames > 0 {
        profile_ops(engine, &mut ws, &image, (frames - 1) as u32);
    }

    let stack = memory::stack_high_water();
    let statics = memory::statics_bytes();
    let flash = memory::flash_bytes();
    println!("frames {frames}");
    let mean = |n: u64| n / frames.max(1);
    println!(
        "vl53l5cx: mean driver instructions/frame {} (dtof stage minus the simulated sensor's {})",
        mean(driver_total),
        mean(device_total)
    );
    let mean_total = mean(stage_totals.iter().sum());
    println!(
        "instructions/frame: mean {mean_total} min {min} max {max}; mean camera {} dtof {} \
         projection {} model {} (SysTick x{} under -icount shift={}, +-{} per stage)",
        mean(stage_totals[0]),
        mean(stage_totals[1]),
        mean(stage_totals[2]),
        mean(stage_totals[3]),
        cycles::INSTRUCTIONS_PER_TICK,
        cycles::ICOUNT_SHIFT,
        cycles::INSTRUCTIONS_PER_TICK
    );
    // 480 MHz at 1 instruction/cycle: frames/s = 480e6 / instructions, printed with 2 decimals.
    let centi_fps = 48_000_000_000u64 / mean_total.max(1);
    println!(
        "estimate (not a measurement): {}.{:02} frames/s on a 480 MHz Cortex-M7 at 1 \
         instruction/cycle",
        centi_fps / 100,
        centi_fps % 100
    );
    // Every static of this build, by name (the rest: cortex-m-rt's, the console's, SysTick's).
    let buffers: [(&str, usize); 6] = [
        (
            "arena (reserved; holds the RGB, sparse and dense depth maps too)",
            size_of::<Arena>(),
        ),
        ("engine", size_of::<Engine>()),
        (
            "replay loop (driver + simulated sensor)",
            size_of::<ReplayLoop<SpinDelay>>(),
        ),
        ("zone frame", size_of::<ZoneFrame<ZONES>>()),
        ("zone bridge staging", size_of::<[f32; ZONES]>()),
        ("vl53l5cx i/o", VL53_IO_BYTES),
    ];
    print_ram(&buffers, statics, stack, arena_used);
    println!(
        "flash: {flash} B = firmware {} B + model blob {} B + replay image {} B",
        flash.saturating_sub(IMAGE.len() + MCU_BLOB.len()),
        MCU_BLOB.len(),
        IMAGE.len()
    );
    #[cfg(feature = "adversarial")]
    println!("{times}");
    println!("TEST OK");
    console::exit(0)
}
