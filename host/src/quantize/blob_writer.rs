//! The int8 model blob, format v1 (docs/blob.md), from a [`Net`]: [`write_blob`] quantises its
//! parameters (symmetric per-output-channel int8 weights, int32 bias in units of `s_in · s_w[o]`),
//! bakes the element-wise LUTs with the core's `build_lut` and float references, and writes
//! them through the byte-level [`BlobWriter`] and attribute encoders of [`super::blob_format`]
//! (the one writer of the format).

pub use super::blob_format::BlobWriter;
use super::blob_format::{
    bins_head_attrs, conv_attrs, pixel_shuffle_attrs, refine_attrs, upsample_attrs,
};
use super::net::{Net, OpKind, Storage, UpsampleSize};
use depthor_core::blob::format::{
    dtype, opcode, upsample_mode, MAX_INPUTS, MAX_OPS, MAX_TENSORS, NONE,
};
use depthor_core::kernels::elementwise::build_lut;
use depthor_core::kernels::float;
use depthor_core::kernels::requant::QParams;

/// Why a network cannot be written as a blob.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BlobError {
    /// More tensors or ops than the core's tables hold.
    #[error("{what}: {count} exceeds the core's limit {limit}")]
    TooMany {
        /// Tensors or ops.
        what: &'static str,
        /// How many the network has.
        count: usize,
        /// The core's capacity.
        limit: usize,
    },
    /// A value does not fit a 16-bit field of the format.
    #[error("{what} = {value} does not fit the blob's 16-bit field")]
    Field {
        /// Which field.
        what: &'static str,
        /// The value.
        value: usize,
    },
    /// `qparams` does not have one entry per value.
    #[error("{got} quantisation parameters for {values} values")]
    Params {
        /// Entries given.
        got: usize,
        /// Values in the network.
        values: usize,
    },
}

/// Symmetric per-output-channel int8 weights for `out_c` channels of `weight` (row-major,
/// channel-major) and the int32 bias in units of `s_in · s_w[o]`. The scale is
/// `max|w[o]|/127`, raised where needed so the bias fits in ±2³⁰ (all-zero channels).
/// Returns `(weights, bias, scales)`.
pub fn quantize_channels(
    weight: &[f32],
    bias: &[f32],
    out_c: usize,
    s_in: f32,
) -> (Vec<i8>, Vec<i32>, Vec<f32>) {
    let per = weight.len() / out_c.max(1);
    let mut wq = Vec::with_capacity(weight.len());
    let mut bq = Vec::with_capacity(out_c);
    let mut sc = Vec::with_capacity(out_c);
    for o in 0..out_c {
        let ws = &weight[o * per..(o + 1) * per];
        let m = ws.iter().fold(0f32, |a, &v| a.max(v.abs()));
        let b = bias.get(o).copied().unwrap_or(0.0);
        let s = (m / 127.0)
            .max(b.abs() / (s_in * (1u32 << 30) as f32))
            .max(f32::MIN_POSITIVE);
        wq.extend(
            ws.iter()
                .map(|&v| (v / s).round().clamp(-127.0, 127.0) as i8),
        );
        bq.push((b as f64 / (s_in as f64 * s as f64)).round() as i32);
        sc.push(s);
    }
    (wq, bq, sc)
}

fn u16_of(what: &'static str, value: usize) -> Result<u16, BlobError> {
    u16::try_from(value).map_err(|_| BlobError::Field { what, value })
}

/// Writes `net` as a blob with activation parameters `qparams` (one per value, as from
/// [`choose_qparams`](super::calibrate::choose_qparams)).
pub fn write_blob(net: &Net, qparams: &[QParams]) -> Result<Vec<u8>, BlobError> {
    let n = net.values.len();
    if qparams.len() != n {
        return Err(BlobError::Params {
            got: qparams.len(),
            values: n,
        });
    }
    if n > MAX_TENSORS {
        return Err(BlobError::TooMany {
            what: "tensors",
            count: n,
            limit: MAX_TENSORS,
        });
    }
    if net.ops.len() > MAX_OPS {
        return Err(BlobError::TooMany {
            what: "ops",
            count: net.ops.len(),
            limit: MAX_OPS,
        });
    }
    let mut bw = BlobWriter::new(u16_of("height", net.height)?, u16_of("width", net.width)?);
    for (v, q) in net.values.iter().zip(qparams) {
        let dt = match v.storage {
            Storage::I8 => dtype::I8,
            Storage::F32 => dtype::F32,
            Storage::I16 => dtype::I16,
        };
        bw.tensor(dt, u16_of("channels", v.shape.c)?, *q);
    }
    bw.io(0, 1, net.output as u16);
    for op in &net.ops {
        if op.inputs.len() > MAX_INPUTS {
            return Err(BlobError::TooMany {
                what: "op inputs",
                count: op.inputs.len(),
                limit: MAX_INPUTS,
            });
        }
        let ins: Vec<u16> = op.inputs.iter().map(|&i| i as u16).collect();
        let out = op.output as u16;
        let (qi, qo) = (qparams[op.inputs[0]], qparams[op.output]);
        let lut = |f: &dyn Fn(f32) -> f32| build_lut(qi, qo, f).map(|v| v as u8).to_vec();
        let (code, attrs) = match &op.kind {
            OpKind::Conv {
                geometry: g,
                act,
                weight,
                bias,
                linear,
            } => {
                let out_c = net.values[op.output].shape.c;
                let (wq, bq, sc) = quantize_channels(weight, bias, out_c, qi.scale);
                let refs = bw.weights(&wq, &bq, &sc);
                (
                    if *linear {
                        opcode::LINEAR
                    } else {
                        opcode::CONV2D
                    },
                    conv_attrs(g, *act, refs),
                )
            }
            OpKind::Relu => (opcode::RELU, lut(&float::relu)),
            OpKind::LeakyRelu(s) => (opcode::LEAKY_RELU, lut(&|v| float::leaky_relu(v, *s))),
            OpKind::Sigmoid => (opcode::SIGMOID, lut(&float::sigmoid)),
            OpKind::Reciprocal(e) => (opcode::RECIPROCAL, lut(&|v| float::reciprocal(v, *e))),
            OpKind::Add => (opcode::ADD, vec![]),
            OpKind::Mul(_) => (opcode::MUL, vec![]),
            OpKind::Concat => (opcode::CONCAT, vec![]),
            OpKind::Upsample(size) => {
                let (mode, a, b) = match *size {
                    UpsampleSize::Like(v) => (upsample_mode::LIKE, u16_of("upsample like", v)?, 0),
                    UpsampleSize::Fixed(h, w) => (
                        upsample_mode::FIXED,
                        u16_of("upsample rows", h)?,
                        u16_of("upsample columns", w)?,
                    ),
                };
                (opcode::UPSAMPLE_BILINEAR, upsample_attrs(mode, a, b))
            }
            OpKind::PixelShuffle(r) => (
                opcode::PIXEL_SHUFFLE,
                pixel_shuffle_attrs(u16_of("pixel_shuffle factor", *r)?),
            ),
            OpKind::GlobalAvgPool => (opcode::GLOBAL_AVG_POOL, vec![]),
            OpKind::GlobalMaxPool => (opcode::GLOBAL_MAX_POOL, vec![]),
            OpKind::ChannelMean => (opcode::CHANNEL_MEAN, vec![]),
            OpKind::ChannelMax => (opcode::CHANNEL_MAX, vec![]),
            OpKind::MinMaxNorm(e) => (opcode::MINMAX_NORM, e.to_le_bytes().to_vec()),
            OpKind::BinsHead {
                attrs,
                weight,
                bias,
            } => {
                let (wq, bq, sc) = quantize_channels(weight, bias, attrs.n_bins, qi.scale);
                let n_bins = u16_of("n_bins", attrs.n_bins)?;
                let refs = bw.weights(&wq, &bq, &sc);
                (
                    opcode::BINS_HEAD,
                    bins_head_attrs(n_bins, attrs.min_depth, attrs.max_depth, refs),
                )
            }
            OpKind::Refine(attrs) => {
                let iterations = u16_of("refine iterations", attrs.iterations)?;
                let nb = attrs.neighbourhood.code();
                (opcode::REFINE, refine_attrs(iterations, nb, attrs.sigma))
            }
        };
        bw.op(code, &ins, out, &attrs);
    }
    let _ = NONE; // every conv gets a bias (folded batch norm), so NONE is never written
    Ok(bw.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channels_quantise_by_hand() {
        // Channel 0: max |w| = 1.27 → s = 0.01; w = [1.27, −0.5] → [127, −50];
        // bias 0.2 with s_in = 0.5 → 0.2/(0.5·0.01) = 40.
        // Channel 1: all zero weights, bias 0 → a positive scale, zero codes.
        let (w, b, s) = quantize_channels(&[1.27, -0.5, 0.0, 0.0], &[0.2, 0.0], 2, 0.5);
        assert_eq!(w, vec![127, -50, 0, 0]);
        assert_eq!(b, vec![40, 0]);
        assert!((s[0] - 0.01).abs() < 1e-8 && s[1] > 0.0);
    }
}
