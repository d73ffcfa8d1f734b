//! Runs `N` frames of the zone gate ([`depthor_core::zone_gate::ZoneGate::run`]) on synthetic
//! candidates over a `width × height` textured image and prints the output's hash: the
//! workload whose instructions per frame are counted under QEMU like `frames` and
//! `interp_frames` (per frame = the count at 3 frames minus the count at 1 frame, halved). The
//! gate's candidates (joint bilateral and bilinear zones) are not included: `interp_frames`
//! counts the joint bilateral one.
//!
//! `cargo run --release -p depthor-core --example gate_frames -- <gate file> <width> <height> <N>`

use depthor_core::zone_gate::ZoneGate;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [path, w, h, frames] = &args[..] else {
        eprintln!("usage: gate_frames <gate file> <width> <height> <frames>");
        std::process::exit(2);
    };
    let num = |s: &str| -> usize { s.parse().expect("width, height and frames are numbers") };
    let (w, h, frames) = (num(w), num(h), num(frames));
    let bytes = std::fs::read(path).expect("read the gate file");
    let gate = ZoneGate::parse(&bytes).expect("a valid gate file");
    let rgb: Vec<u8> = (0..h * w * 3)
        .map(|i| ((i * 37) ^ (i / (3 * w) * 11)) as u8)
        .collect();
    // Three candidates that disagree by a few per cent, 1–3 m.
    let cand: Vec<Vec<f32>> = (0..3)
        .map(|k| {
            (0..w * h)
                .map(|p| (1.0 + ((p / w + p % w) % 101) as f32 / 50.0) * (0.95 + 0.05 * k as f32))
                .collect()
        })
        .collect();
    let mut scratch = vec![0f32; gate.scratch_floats(w, h)];
    let mut depth = vec![0f32; w * h];
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for _ in 0..frames {
        gate.run(
            [&cand[0], &cand[1], &cand[2]],
            &rgb,
            (w, h),
            &mut scratch,
            &mut depth,
        )
        .expect("run");
        for d in &depth {
            for b in d.to_bits().to_le_bytes() {
                hash = (hash ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    println!(
        "{w}x{h} gate {} channels, {} MACs, frames {frames} output hash {hash:016x}",
        gate.channels(),
        gate.macs(w, h)
    );
}
