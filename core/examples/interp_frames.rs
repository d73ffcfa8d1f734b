//! Runs `N` frames of [`depthor_core::interp::JointBilateral`] on a synthetic frame (a
//! `rows × cols` zone grid over a `width × height` textured image, some zones missing) and
//! prints the output's hash: the workload whose instructions per frame are counted under QEMU
//! like `frames` (per frame = the count at 3 frames minus the count at 1 frame, halved).
//!
//! `cargo run --release -p depthor-core --example interp_frames -- <width> <height> <rows> <cols> <N>`

use depthor_core::interp::{scratch_words, JointBilateral};
use depthor_core::projection::ProjectedPoint;

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("numbers: width height rows cols frames"))
        .collect();
    let [w, h, rows, cols, frames] = args[..] else {
        eprintln!("usage: interp_frames <width> <height> <rows> <cols> <frames>");
        std::process::exit(2);
    };
    let rgb: Vec<u8> = (0..h * w * 3)
        .map(|i| ((i * 37) ^ (i / (3 * w) * 11)) as u8)
        .collect();
    // Zone centres on a regular grid, every 9th zone missing, depths between 1 and 3 m.
    let points: Vec<ProjectedPoint> = (0..rows * cols)
        .filter(|z| z % 9 != 4)
        .map(|z| {
            let (r, c) = (z / cols, z % cols);
            let u = (c as f32 + 0.5) * w as f32 / cols as f32 - 0.5;
            let v = (r as f32 + 0.5) * h as f32 / rows as f32 - 0.5;
            ProjectedPoint {
                zone: z as u16,
                u,
                v,
                x: (u + 0.5) as u32,
                y: (v + 0.5) as u32,
                depth_m: 1.0 + (z % 101) as f32 / 50.0,
            }
        })
        .collect();
    let mut scratch = vec![0u32; scratch_words(w, h, rows, cols)];
    let mut depth = vec![0f32; w * h];
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for _ in 0..frames {
        let jb = JointBilateral::prepare(&points, &rgb, (w, h), (rows, cols), &mut scratch)
            .expect("prepare");
        jb.rows(0..h, &mut depth).expect("rows");
        for d in &depth {
            for b in d.to_bits().to_le_bytes() {
                hash = (hash ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    println!(
        "{w}x{h} zones {rows}x{cols} points {} frames {frames} output hash {hash:016x}",
        points.len()
    );
}
