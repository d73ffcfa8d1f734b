//! int16 storage (`depthor quantize --int16 NAME`, TFLite's 16×8 scheme) on the exported
//! `mcu_lite` network: the values `widen` accepts run on the engine as their f32 ops say, come
//! out closer to the float network than in int8, and the blob parser refuses int16 where no op
//! handles it. Figures: `cargo test -p depthor-host --test quantize_int16 -- --nocapture`.

use depthor_core::blob::checksum::crc32;
use depthor_core::blob::format::{dtype, HEADER_LEN, TENSOR_ENTRY_LEN};
use depthor_core::engine::{required_arena_bytes, Engine};
use depthor_host::quantize::calibrate::simulated_frames;
use depthor_host::quantize::check::{compare, op_fidelity};
use depthor_host::quantize::fold::fold;
use depthor_host::quantize::graph::Graph;
use depthor_host::quantize::net::{Net, OpKind, Storage};
use depthor_host::quantize::quantize;
use depthor_host::quantize::widen::{widen, WidenError};
use std::path::PathBuf;

fn mcu_lite() -> Net {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models/mcu_lite");
    fold(&Graph::load(&dir.join("graph.json"), None).unwrap()).unwrap()
}

/// Every value `widen` accepts on its own.
fn widenable(net: &Net) -> Vec<String> {
    net.values
        .iter()
        .map(|v| v.name.clone())
        .filter(|n| widen(&mut net.clone(), std::slice::from_ref(n)).is_ok())
        .collect()
}

/// Three accepted values spread over the network (early, middle, late: pointwise, depthwise
/// and dense readers, concat readers) and a concat output stored as int16: each int16 op gives its f32 model's
/// codes, each value's SQNR against the float network rises, and the depth does not get worse.
#[test]
fn int16_values_follow_their_ops_and_come_closer_to_float() {
    let net = mcu_lite();
    let names = widenable(&net);
    assert!(
        names.len() >= 6,
        "values that can be int16: {}",
        names.len()
    );
    let mut picked: Vec<String> = [0, names.len() / 2, names.len() - 1]
        .iter()
        .map(|&k| names[k].clone())
        .collect();
    // and a concat output (int8 and int16 parts in, int16 out), if none of those is one
    let is_concat = |n: &String| {
        let v = net.values.iter().position(|v| &v.name == n).unwrap();
        net.ops
            .iter()
            .any(|o| o.output == v && matches!(o.kind, OpKind::Concat))
    };
    if !picked.iter().any(is_concat) {
        let c = names
            .iter()
            .find(|n| is_concat(n))
            .expect("a concat can be int16");
        if !picked.contains(c) {
            picked.push(c.clone());
        }
    }
    let mut wide = net.clone();
    widen(&mut wide, &picked).unwrap();
    let calib = simulated_frames("mcu", net.height, net.width, 4, 0).unwrap();
    let eval = simulated_frames("mcu", net.height, net.width, 4, 3000).unwrap();
    let q8 = quantize(&net, &calib).unwrap();
    let q16 = quantize(&wide, &calib).unwrap();
    let c8 = compare(&q8.blob, &net, &eval).unwrap();
    let c16 = compare(&q16.blob, &wide, &eval).unwrap();
    for (k, name) in picked.iter().enumerate() {
        let v = wide.values.iter().position(|v| &v.name == name).unwrap();
        assert_eq!(wide.values[v].storage, Storage::I16);
        let op = v - 2;
        let (a, b) = (&c8.layers[op], &c16.layers[op]);
        println!(
            "{name}: SQNR int8 {:.1} dB, int16 {:.1} dB",
            a.sqnr_db, b.sqnr_db
        );
        // The earliest value's error is its own rounding, which int16 all but removes. Later
        // values carry the int8 error of everything upstream (≈ 25 dB in the middle of the
        // network), so their own storage moves their SQNR by no more than the 4 frames' noise
        // (a few tenths of a dB either way, with the weights of 2026-12-06): they must not lose.
        if k == 0 {
            assert!(
                b.sqnr_db > a.sqnr_db + 3.0,
                "{name}: {} vs {}",
                b.sqnr_db,
                a.sqnr_db
            );
        } else {
            assert!(
                b.sqnr_db > a.sqnr_db - 0.3,
                "{name}: {} vs {}",
                b.sqnr_db,
                a.sqnr_db
            );
        }
    }
    let (d8, d16) = (c8.depth_pooled_db(), c16.depth_pooled_db());
    println!("depth SQNR pooled: int8 {d8:.2} dB, with int16 values {d16:.2} dB");
    assert!(d16 >= d8 - 0.1, "depth {d16} dB < int8 {d8} dB");
    let fidelity = op_fidelity(&q16.blob, &wide, &eval[..2]).unwrap();
    for name in &picked {
        let f = fidelity.iter().find(|f| &f.name == name).unwrap();
        println!(
            "{name}: engine vs its f32 op, mean {:.3} int16 codes, max {}",
            f.mean_abs_codes, f.max_abs_codes
        );
        // Weight rounding is in the model; f32 sums and the Q31 multiplier leave ties, more
        // often than in int8 as an int16 step is 256× finer.
        assert!(f.max_abs_codes <= 1 && f.mean_abs_codes <= 0.25, "{name}");
    }
    let more = required_arena_bytes(&q16.blob, net.height, net.width).unwrap();
    let less = required_arena_bytes(&q8.blob, net.height, net.width).unwrap();
    println!("arena: int8 {less} B, with int16 values {more} B");
    assert!(more > less);
}

/// `widen` names the value and the op it cannot serve, and changes nothing then.
#[test]
fn widen_refuses_values_no_op_can_serve() {
    let net = mcu_lite();
    let mut n = net.clone();
    assert_eq!(
        widen(&mut n, &["no.such.value".into()]),
        Err(WidenError::UnknownValue("no.such.value".into()))
    );
    // Written by an op other than a conv or a concat (an add, a table, a resize…).
    let other = net
        .ops
        .iter()
        .find(|o| {
            !matches!(o.kind, OpKind::Conv { .. } | OpKind::Concat)
                && net.values[o.output].storage == Storage::I8
                && o.output != net.output
        })
        .unwrap();
    let name = net.values[other.output].name.clone();
    assert!(matches!(
        widen(&mut n, std::slice::from_ref(&name)),
        Err(WidenError::Producer { value, .. }) if value == name
    ));
    // A conv output read by an op other than a conv or a concat (an add, a table, a resize…).
    let read_elsewhere = net
        .ops
        .iter()
        .filter(|o| matches!(o.kind, OpKind::Conv { .. }))
        .map(|o| o.output)
        .find(|&v| {
            net.ops.iter().any(|r| {
                r.inputs.contains(&v) && !matches!(r.kind, OpKind::Conv { .. } | OpKind::Concat)
            })
        })
        .unwrap();
    let name = net.values[read_elsewhere].name.clone();
    let ok = widenable(&net)[0].clone();
    assert!(matches!(
        widen(&mut n, &[ok, name.clone()]),
        Err(WidenError::Reader { value, .. }) if value == name
    ));
    assert_eq!(n, net, "nothing changes on an error");
}

/// A blob with an int16 tensor where no op reads or writes int16, or with a zero point, is
/// refused by the engine with the byte offset of the field.
#[test]
fn parser_refuses_int16_where_no_op_handles_it() {
    let net = mcu_lite();
    let calib = simulated_frames("mcu", net.height, net.width, 2, 0).unwrap();
    let mut wide = net.clone();
    let name = widenable(&net)[0].clone();
    widen(&mut wide, &[name]).unwrap();
    let blob = quantize(&wide, &calib).unwrap().blob;
    let entry = |t: usize| HEADER_LEN + t * TENSOR_ENTRY_LEN;
    let patched = |edit: &dyn Fn(&mut Vec<u8>)| {
        let mut b = blob.clone();
        edit(&mut b);
        let len = u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize;
        let crc = crc32(&b[HEADER_LEN..HEADER_LEN + len]);
        b[12..16].copy_from_slice(&crc.to_le_bytes());
        let mut arena = vec![0u8; 1 << 21];
        Engine::new(&b, &mut arena)
            .map(|_| ())
            .map_err(|e| format!("{e}"))
    };
    assert_eq!(patched(&|_| {}), Ok(()));
    // The int16 value with a zero point.
    let v16 = wide
        .values
        .iter()
        .position(|v| v.storage == Storage::I16)
        .unwrap();
    let e = patched(&|b| b[entry(v16) + 8..entry(v16) + 12].copy_from_slice(&3i32.to_le_bytes()));
    assert!(e.unwrap_err().contains("int16"));
    // An int8 value read by a resize, made int16.
    let resized = net
        .ops
        .iter()
        .find(|o| {
            matches!(o.kind, OpKind::Upsample(_)) && net.values[o.inputs[0]].storage == Storage::I8
        })
        .unwrap()
        .inputs[0];
    let e = patched(&|b| {
        b[entry(resized)] = dtype::I16;
        b[entry(resized) + 8..entry(resized) + 12].copy_from_slice(&0i32.to_le_bytes());
    });
    assert!(e.is_err(), "int16 into a resize must be refused");
    // The rgb input as int16.
    let e = patched(&|b| {
        b[entry(0)] = dtype::I16;
        b[entry(0) + 8..entry(0) + 12].copy_from_slice(&0i32.to_le_bytes());
    });
    assert!(e.unwrap_err().contains("int8 or f32"));
}
