//! Runs `N` frames of a blob through [`Engine`] with one kernel set and prints the output's
//! hash: the workload that `scripts/count_instructions.sh` counts instructions of under QEMU
//! (per frame = the count at 3 frames minus the count at 1 frame, halved), and a check that
//! every set gives the same bits (the hash is the same for each). It also prints the MACs of
//! one frame (the plan's count: convs, linears, bins head).
//!
//! `cargo run --release -p depthor-core --example frames -- <depthor.dblob> <set|best> <N>`

use depthor_core::engine::{required_arena_bytes, Engine};
use depthor_core::kernels::isa::Isa;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 4 {
        eprintln!("usage: frames <depthor.dblob> <kernel set|best> <frames>");
        std::process::exit(2);
    }
    let blob = std::fs::read(&args[1]).expect("reading the blob");
    let isa = match args[2].as_str() {
        "best" => Isa::best(),
        n => Isa::from_name(n).expect("unknown kernel set"),
    };
    let frames: usize = args[3].parse().expect("frames: a number");
    let g = depthor_core::blob::parse(&blob).expect("parsing the blob");
    let (h, w) = (g.height, g.width);
    let mut arena = vec![0u8; required_arena_bytes(&blob, h, w).expect("planning") + 64];
    let mut e = Engine::new(&blob, &mut arena).expect("engine");
    e.set_kernels(isa).expect("kernel set not on this CPU");
    // A deterministic frame: textured RGB, a sparse grid of depths between 1 and 3 m.
    let rgb: Vec<u8> = (0..h * w * 3)
        .map(|i| ((i * 37) ^ (i / (3 * w) * 11)) as u8)
        .collect();
    let sparse: Vec<f32> = (0..h * w)
        .map(|i| {
            let (y, x) = (i / w, i % w);
            if y % 5 == 2 && x % 7 == 3 {
                1.0 + (i % 101) as f32 / 50.0
            } else {
                0.0
            }
        })
        .collect();
    let mut depth = vec![0f32; h * w];
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    let mut macs = 0;
    for _ in 0..frames {
        macs = e.run(&rgb, &sparse, &mut depth).expect("run").macs;
        for d in &depth {
            for b in d.to_bits().to_le_bytes() {
                hash = (hash ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    println!(
        "{} {h}x{w} frames {frames} set {} macs per frame {macs} output hash {hash:016x}",
        args[1],
        isa.name()
    );
}
