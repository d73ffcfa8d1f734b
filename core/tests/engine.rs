//! End-to-end: a tiny graph using every op, quantised from a float network by the test writer,
//! run by the engine and compared with the float run; plan and arena properties.

mod common;

use common::{frame, rgb_planar, sqnr_db, tiny_net, tiny_net_with};
use depthor_core::blob::parse;
use depthor_core::engine::{plan, required_arena_bytes, Engine, Error};
use depthor_core::kernels::refine::Neighbourhood;

const H: usize = 12;
const W: usize = 16;

fn blob_and_float() -> (Vec<u8>, Vec<f32>, Vec<u8>, Vec<f32>) {
    blob_and_float_with(Neighbourhood::Window)
}

fn blob_and_float_with(nb: Neighbourhood) -> (Vec<u8>, Vec<f32>, Vec<u8>, Vec<f32>) {
    let net = tiny_net_with(H, W, nb);
    let (rgb, sparse) = frame(H, W);
    let vals = net.run_float(&rgb_planar(&rgb, H, W), &sparse);
    let blob = net.to_blob(&vals);
    let depth = vals.last().unwrap().1.clone();
    (blob, depth, rgb, sparse)
}

/// Minimum SQNR of the int8 engine's depth against the float network (dB). Measured 60.5 dB (27.0 dB on the variation) with the
/// command `cargo test -p depthor-core --test engine -- --nocapture`.
const MIN_SQNR_DB: f64 = 45.0;
/// Minimum SQNR on the depth variation (mean removed), dB.
const MIN_AC_SQNR_DB: f64 = 22.0;

#[test]
fn int8_engine_matches_float_network() {
    for nb in [Neighbourhood::Window, Neighbourhood::Dilated] {
        engine_matches_float_network(nb);
    }
}

fn engine_matches_float_network(nb: Neighbourhood) {
    let (blob, want, rgb, sparse) = blob_and_float_with(nb);
    let need = required_arena_bytes(&blob, H, W).unwrap();
    let mut arena = vec![0u8; need];
    let mut eng = Engine::new(&blob, &mut arena).unwrap();
    assert_eq!(eng.input_shape(), (H, W));
    let mut out = vec![0f32; H * W];
    let stats = eng.run(&rgb, &sparse, &mut out).unwrap();
    assert_eq!(stats.ops, tiny_net_with(H, W, nb).ops.len());
    assert!(stats.macs > 0);
    let db = sqnr_db(&want, &out);
    // Also against the depth *variation* (mean removed), which a constant output cannot fake.
    let mean = want.iter().sum::<f32>() / want.len() as f32;
    let ac_want: Vec<f32> = want.iter().map(|v| v - mean).collect();
    let ac_out: Vec<f32> = out.iter().map(|v| v - mean).collect();
    let ac_db = sqnr_db(&ac_want, &ac_out);
    let spread = want.iter().fold(0f32, |m, v| m.max(v - mean).max(mean - v));
    println!("{nb:?}: depth SQNR int8 vs f32: {db:.1} dB ({ac_db:.1} dB on the variation, ±{spread:.3} m), arena {need} B, macs {}", stats.macs);
    assert!(
        spread > 0.05,
        "float depth is nearly constant: the test would be weak"
    );
    assert!(db >= MIN_SQNR_DB, "SQNR {db:.1} dB < {MIN_SQNR_DB}");
    assert!(
        ac_db >= MIN_AC_SQNR_DB,
        "variation SQNR {ac_db:.1} dB < {MIN_AC_SQNR_DB}"
    );
    assert!(out
        .iter()
        .all(|v| v.is_finite() && (0.1..=10.0).contains(v)));

    // run() is repeatable bit for bit, and run_in_place (sparse in, dense out in one buffer)
    // gives the same bits.
    let mut again = vec![0f32; H * W];
    eng.run(&rgb, &sparse, &mut again).unwrap();
    assert_eq!(out, again);
    let mut in_place = sparse.clone();
    eng.run_in_place(&rgb, &mut in_place).unwrap();
    assert!(out
        .iter()
        .zip(&in_place)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
}

#[test]
fn runs_at_another_size() {
    let (blob, ..) = blob_and_float();
    let (h, w) = (8, 10);
    let need = required_arena_bytes(&blob, h, w).unwrap();
    assert!(need < required_arena_bytes(&blob, H, W).unwrap());
    let mut arena = vec![0u8; need];
    let mut eng = Engine::with_size(&blob, &mut arena, h, w).unwrap();
    let (rgb, sparse) = frame(h, w);
    let mut out = vec![0f32; h * w];
    eng.run(&rgb, &sparse, &mut out).unwrap();
    let net = tiny_net(h, w);
    let want = net
        .run_float(&rgb_planar(&rgb, h, w), &sparse)
        .last()
        .unwrap()
        .1
        .clone();
    assert!(sqnr_db(&want, &out) > 20.0);
}

#[test]
fn arena_too_small_and_bad_buffers_are_errors() {
    let (blob, _, rgb, sparse) = blob_and_float();
    let need = required_arena_bytes(&blob, H, W).unwrap();
    let mut small = vec![0u8; need - 16];
    match Engine::new(&blob, &mut small) {
        Err(Error::ArenaTooSmall { need: n, have }) => {
            assert_eq!((n, have), (need, need - 16));
        }
        other => panic!("expected ArenaTooSmall, got {other:?}"),
    }
    let mut arena = vec![0u8; need];
    let mut eng = Engine::new(&blob, &mut arena).unwrap();
    let mut out = vec![0f32; H * W];
    assert!(matches!(
        eng.run(&rgb[1..], &sparse, &mut out),
        Err(Error::ShapeMismatch { what: "rgb", .. })
    ));
    assert!(matches!(
        eng.run(&rgb, &sparse[1..], &mut out),
        Err(Error::ShapeMismatch { .. })
    ));
    assert!(matches!(
        eng.run(&rgb, &sparse, &mut out[1..]),
        Err(Error::ShapeMismatch { .. })
    ));
    // Display is informative.
    let msg = format!("{}", Error::ArenaTooSmall { need: 10, have: 5 });
    assert!(msg.contains("need 10"));
}

#[test]
fn arena_base_misalignment_is_absorbed() {
    let (blob, _, rgb, sparse) = blob_and_float();
    let need = required_arena_bytes(&blob, H, W).unwrap();
    let mut buf = vec![0u8; need + 16];
    let mut reference = None;
    for shift in [1usize, 3, 8, 15] {
        let mut eng = Engine::new(&blob, &mut buf[shift..shift + need]).unwrap();
        let mut out = vec![0f32; H * W];
        eng.run(&rgb, &sparse, &mut out).unwrap();
        if let Some(r) = &reference {
            assert_eq!(r, &out);
        }
        reference = Some(out);
    }
}

#[test]
fn no_two_live_buffers_overlap() {
    let (blob, ..) = blob_and_float();
    let g = parse(&blob).unwrap();
    for (h, w) in [(H, W), (8, 10), (64, 80)] {
        let p = plan(&g, h, w).unwrap();
        let bufs: Vec<_> = p.buffers().collect();
        for (i, (a, oa)) in bufs.iter().enumerate() {
            assert_eq!(oa % 16, 0);
            assert!(oa + a.bytes <= p.activation_bytes());
            for (b, ob) in &bufs[..i] {
                if a.bytes > 0 && b.bytes > 0 && a.first <= b.last && b.first <= a.last {
                    assert!(
                        oa + a.bytes <= *ob || ob + b.bytes <= *oa,
                        "overlap at {h}x{w}"
                    );
                }
            }
        }
        // Liveness reuse pays: less than the sum of all buffers.
        let sum: usize = bufs.iter().map(|(b, _)| b.bytes).sum();
        assert!(p.activation_bytes() < sum);
        assert_eq!(p.arena_bytes(), required_arena_bytes(&blob, h, w).unwrap());
    }
}

#[test]
fn engine_struct_size_is_known() {
    let size = core::mem::size_of::<Engine>();
    println!("size_of::<Engine>() = {size} bytes");
    // 48 KiB of tables, + 256 B since the plan holds its run order (`Plan::order`, a byte per op).
    assert!(size <= 48 * 1024 + 256, "Engine grew to {size} bytes");
}

/// Arena of the test network at the `mcu` size, with its largest buffers (a figure for the
/// report; the real `mcu` graph's budget test belongs with its blob).
#[test]
fn arena_at_mcu_size() {
    let (blob, ..) = blob_and_float();
    let g = parse(&blob).unwrap();
    let p = plan(&g, 120, 160).unwrap();
    let mut bufs: Vec<_> = p
        .buffers()
        .enumerate()
        .filter(|(_, (b, _))| b.bytes > 0)
        .collect();
    bufs.sort_by_key(|(_, (b, _))| std::cmp::Reverse(b.bytes));
    println!(
        "tiny net at 120x160: arena {} B = persistent {} + activations {} (sum of buffers {})",
        p.arena_bytes(),
        p.persistent_bytes(),
        p.activation_bytes(),
        bufs.iter().map(|(_, (b, _))| b.bytes).sum::<usize>()
    );
    for (i, (b, off)) in bufs.iter().take(6) {
        println!(
            "  buffer {i}: {} B at {off}, steps {}..={}",
            b.bytes, b.first, b.last
        );
    }
    assert!(p.arena_bytes() < 4 << 20);
}

/// The streamed plan (affinity heads fused into the refinement, run row by row; concats read in
/// place by their conv) gives the whole plan's bits, at the native size and at one taller than a refinement window, and needs
/// less arena.
#[test]
fn streamed_refinement_equals_whole_maps() {
    for nb in [Neighbourhood::Window, Neighbourhood::Dilated] {
        streamed_equals_whole(nb);
    }
}

fn streamed_equals_whole(nb: Neighbourhood) {
    use depthor_core::engine::{plan_with, required_arena_bytes_with, Memory};
    let (blob, _, rgb, sparse) = blob_and_float_with(nb);
    let g = parse(&blob).unwrap();
    // With 8 neighbours per branch the affinity maps of a 12×16 image are smaller than the
    // rings that replace them, so the planner fuses only at a larger size.
    let (ph, pw) = match nb {
        Neighbourhood::Window => (H, W),
        Neighbourhood::Dilated => (120, 160),
    };
    let streamed = plan_with(&g, ph, pw, Memory::Streamed).unwrap();
    let refine = (0..g.ops.len())
        .find(|&i| streamed.fused_heads(i).is_some())
        .expect("the test net's refinement has three single-use conv heads");
    for j in streamed.fused_heads(refine).unwrap() {
        assert_eq!(streamed.fused_into(j), Some(refine));
    }
    assert!(
        (0..g.ops.len()).any(|i| streamed.concat_in_place(i).is_some()),
        "the test net has a concat read in place by its conv"
    );
    let whole = plan_with(&g, H, W, Memory::Whole).unwrap();
    assert!((0..g.ops.len()).all(|i| whole.fused_into(i).is_none()));
    let sizes = [(H, W), (36, 20), (ph, pw)];
    for &(h, w) in &sizes[..if (ph, pw) == (H, W) { 2 } else { 3 }] {
        let (rgb, sparse) = if (h, w) == (H, W) {
            (rgb.clone(), sparse.clone())
        } else {
            common::frame(h, w)
        };
        let mut outs = Vec::new();
        for memory in [Memory::Whole, Memory::Streamed, Memory::Budget(usize::MAX)] {
            let need = required_arena_bytes_with(&blob, h, w, memory).unwrap();
            let mut arena = vec![0u8; need];
            let mut eng = Engine::with_memory(&blob, &mut arena, h, w, memory).unwrap();
            let mut out = vec![0f32; h * w];
            eng.run(&rgb, &sparse, &mut out).unwrap();
            outs.push((need, out));
        }
        for (k, other) in outs.iter().enumerate().skip(1) {
            let same = outs[0]
                .1
                .iter()
                .zip(&other.1)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                same,
                "{nb:?} {h}x{w}: plan {k}'s output differs from whole maps"
            );
        }
        assert!(
            outs[1].0 < outs[0].0,
            "{h}x{w}: arena {} !< {}",
            outs[1].0,
            outs[0].0
        );
    }
    let (a, b) = (
        required_arena_bytes_with(&blob, 120, 160, Memory::Whole).unwrap(),
        required_arena_bytes_with(&blob, 120, 160, Memory::Streamed).unwrap(),
    );
    println!("{nb:?} tiny net at 120x160: arena whole {a} B, streamed {b} B");
}
