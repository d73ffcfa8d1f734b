//! Upsamples written at the scale of the concat that reads them (`depthor quantize
//! --upsample-at-concat-scale`) on the exported `mcu_lite` network: the pass picks exactly the
//! int8 upsamples read only by an int8 concat, the blob gives them that concat's parameters, the
//! engine's rescaling upsample follows its f32 model, and the concats they feed, rounded once
//! instead of twice, come closer to the float network. Figures: `cargo test -p depthor-host
//! --test quantize_upsample_scale -- --nocapture`.

use depthor_host::quantize::calibrate::simulated_frames;
use depthor_host::quantize::check::{compare, op_fidelity};
use depthor_host::quantize::fold::fold;
use depthor_host::quantize::graph::Graph;
use depthor_host::quantize::net::{Net, OpKind, Storage};
use depthor_host::quantize::quantize;
use depthor_host::quantize::upsample_scale::upsample_at_concat_scale;
use std::path::PathBuf;

fn mcu_lite() -> Net {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models/mcu_lite");
    fold(&Graph::load(&dir.join("graph.json"), None).unwrap()).unwrap()
}

#[test]
fn upsamples_at_concat_scale_round_once_and_come_closer_to_float() {
    let net = mcu_lite();
    let mut at = net.clone();
    let names = upsample_at_concat_scale(&mut at);
    // Exactly the int8 upsamples whose one reader is an int8 concat.
    let expected: Vec<String> = net
        .ops
        .iter()
        .filter(|o| matches!(o.kind, OpKind::Upsample(_)))
        .filter(|o| net.values[o.output].storage == Storage::I8)
        .filter(|o| {
            let r: Vec<_> = net
                .ops
                .iter()
                .filter(|r| r.inputs.contains(&o.output))
                .collect();
            r.len() == 1 && matches!(r[0].kind, OpKind::Concat)
        })
        .map(|o| net.values[o.output].name.clone())
        .collect();
    assert!(names.len() >= 2, "upsamples changed: {names:?}");
    assert_eq!(names, expected);
    let calib = simulated_frames("mcu", net.height, net.width, 4, 0).unwrap();
    let eval = simulated_frames("mcu", net.height, net.width, 16, 3000).unwrap();
    let (q0, q1) = (
        quantize(&net, &calib).unwrap(),
        quantize(&at, &calib).unwrap(),
    );
    let (c0, c1) = (
        compare(&q0.blob, &net, &eval).unwrap(),
        compare(&q1.blob, &at, &eval).unwrap(),
    );
    let fidelity = op_fidelity(&q1.blob, &at, &eval[..2]).unwrap();
    let mut gained = 0.0;
    for name in &names {
        let v = at.values.iter().position(|v| &v.name == name).unwrap();
        let c = at
            .ops
            .iter()
            .find(|o| o.inputs.contains(&v))
            .unwrap()
            .output;
        assert_eq!(
            q1.qparams[v], q1.qparams[c],
            "{name} at its concat's parameters"
        );
        assert_ne!(
            q0.qparams[v], q0.qparams[c],
            "{name}: by default its input's"
        );
        let f = fidelity.iter().find(|f| &f.name == name).unwrap();
        assert!(
            f.max_abs_codes <= 1 && f.mean_abs_codes <= 0.05,
            "{name}: {f:?}"
        );
        let (a, b) = (&c0.layers[c - 2], &c1.layers[c - 2]);
        println!(
            "{name} → {}: SQNR twice rounded {:.2} dB, once {:.2} dB",
            at.values[c].name, a.sqnr_db, b.sqnr_db
        );
        // One rounding instead of two: no concat noticeably further from float (the other
        // parts' and upstream errors are the same), and closer on average.
        assert!(b.sqnr_db >= a.sqnr_db - 0.1, "{name}");
        gained += b.sqnr_db - a.sqnr_db;
    }
    let mean = gained / names.len() as f64;
    println!("concats fed: mean SQNR change {mean:+.3} dB");
    assert!(mean > 0.05, "concats fed: mean SQNR change {mean:+.3} dB");
    let (d0, d1) = (c0.depth_pooled_db(), c1.depth_pooled_db());
    println!("depth SQNR pooled: default {d0:.2} dB, upsamples at concat scale {d1:.2} dB");
    assert!(d1 >= d0 - 0.2, "depth {d1} dB < {d0} dB");
}
