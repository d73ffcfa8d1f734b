//! int16 storage for chosen values (TFLite's 16×8 scheme, `depthor quantize --int16 NAME`):
//! the values whose int8 rounding costs the most accuracy (`models/depthor_models/
//! int8_sensitivity.py` ranks them) are stored as int16 codes, symmetric per tensor. The core
//! runs them where a conv or a concat writes them and convs and concats read them
//! (`depthor_core::kernels::wide`); [`widen`] refuses any other value, naming it and the op.

use super::net::{Net, OpKind, Storage};
use depthor_core::kernels::wide::MAX_TAPS_WIDE;

/// Why a value cannot be stored as int16.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WidenError {
    /// No int8 value of the folded network has this name.
    #[error("--int16 {0}: no int8 value of the folded graph has this name")]
    UnknownValue(String),
    /// The value is written by an op other than a conv or a concat.
    #[error("--int16 {value}: written by {op}, not by a conv or a concat")]
    Producer {
        /// Value name.
        value: String,
        /// The op writing it.
        op: String,
    },
    /// An op that reads the value cannot read int16.
    #[error("--int16 {value}: read by {op}, which reads int8 only (convs and concats read int16)")]
    Reader {
        /// Value name.
        value: String,
        /// The reading op.
        op: String,
    },
    /// A conv reading the value sums more taps than an int16 input allows.
    #[error("--int16 {value}: {op} sums {taps} taps per output, more than {MAX_TAPS_WIDE} on an int16 input")]
    Taps {
        /// Value name.
        value: String,
        /// The conv.
        op: String,
        /// Its taps per output.
        taps: usize,
    },
}

/// Marks the values named in `names` as int16 ([`Storage::I16`]) after checking that a conv or
/// a concat writes each, only convs (of at most [`MAX_TAPS_WIDE`] taps) and concats read it, and it is
/// not the output. Nothing changes on an error.
pub fn widen(net: &mut Net, names: &[String]) -> Result<(), WidenError> {
    let mut chosen = Vec::with_capacity(names.len());
    for name in names {
        let v = net
            .values
            .iter()
            .position(|v| &v.name == name && v.storage == Storage::I8)
            .filter(|&v| v != net.output)
            .ok_or_else(|| WidenError::UnknownValue(name.clone()))?;
        // An op is named by the value it writes.
        let op_name = |o: &super::net::Op| format!("the op writing {}", net.values[o.output].name);
        match net.ops.iter().find(|o| o.output == v) {
            Some(o) if matches!(o.kind, OpKind::Conv { .. } | OpKind::Concat) => {}
            Some(o) => {
                return Err(WidenError::Producer {
                    value: name.clone(),
                    op: op_name(o),
                })
            }
            None => {
                return Err(WidenError::Producer {
                    value: name.clone(),
                    op: "the graph input".into(),
                })
            }
        }
        for o in net.ops.iter().filter(|o| o.inputs.contains(&v)) {
            match &o.kind {
                OpKind::Concat => {}
                OpKind::Conv { geometry, .. } if o.inputs[0] == v => {
                    let in_c = net.values[v].shape.c;
                    let taps =
                        in_c / geometry.groups.max(1) * geometry.kernel[0] * geometry.kernel[1];
                    if taps > MAX_TAPS_WIDE {
                        return Err(WidenError::Taps {
                            value: name.clone(),
                            op: op_name(o),
                            taps,
                        });
                    }
                }
                _ => {
                    return Err(WidenError::Reader {
                        value: name.clone(),
                        op: op_name(o),
                    })
                }
            }
        }
        chosen.push(v);
    }
    for v in chosen {
        net.values[v].storage = Storage::I16;
    }
    Ok(())
}
