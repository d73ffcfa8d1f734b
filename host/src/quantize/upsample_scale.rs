//! Upsamples written at the scale of the concat that reads them (`depthor quantize
//! --upsample-at-concat-scale`): by default an int8 upsample keeps its input's parameters, so an
//! interpolated value is rounded twice, once to the input's codes and again where the concat
//! rescales it to its own; quantisation-aware training (`models/depthor_models/qat.py`) sees only
//! the second. Written at the concat's parameters, the core's upsample rounds once
//! (`depthor_core::kernels::resize::ResizeRescale`) and the concat copies the codes.

use super::net::{Net, OpKind, Storage};

/// Gives every int8 upsample whose only reader is an int8 concat that concat's quantisation
/// parameters ([`super::net::Value::params_of`]); returns the names of the upsamples changed.
pub fn upsample_at_concat_scale(net: &mut Net) -> Vec<String> {
    let mut changed = Vec::new();
    for op in &net.ops {
        let v = op.output;
        if !matches!(op.kind, OpKind::Upsample(_)) || net.values[v].storage != Storage::I8 {
            continue;
        }
        let mut readers = net.ops.iter().filter(|o| o.inputs.contains(&v));
        let (Some(r), None) = (readers.next(), readers.next()) else {
            continue;
        };
        if matches!(r.kind, OpKind::Concat)
            && net.values[r.output].storage == Storage::I8
            && v != net.output
        {
            changed.push((v, r.output));
        }
    }
    for &(v, c) in &changed {
        net.values[v].params_of = Some(c);
    }
    changed
        .into_iter()
        .map(|(v, _)| net.values[v].name.clone())
        .collect()
}
