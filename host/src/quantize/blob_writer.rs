//! Writer of the int8 model blob, format v1 (`DPTH`, byte layout in
//! `depthor_core::blob::format`): a low-level [`BlobWriter`] for tensors, op records and the
//! 16-byte aligned data section, and [`write_blob`], which quantises a [`Net`]'s parameters
//! (symmetric per-output-channel int8 weights, int32 bias in units of `s_in · s_w[o]`) and
//! bakes the element-wise LUTs with the core's `build_lut` and float references.

use super::net::{Net, OpKind, Storage, UpsampleSize};
use depthor_core::blob::checksum::crc32;
use depthor_core::blob::format::{
    activation, dtype, opcode, upsample_mode, DATA_ALIGN, HEADER_LEN, MAGIC, MAX_INPUTS, MAX_OPS,
    MAX_TENSORS, NONE, VERSION,
};
use depthor_core::kernels::conv::Activation;
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

/// Byte-level builder of a v1 blob.
#[derive(Clone, Debug, Default)]
pub struct BlobWriter {
    height: u16,
    width: u16,
    tensors: Vec<[u8; 16]>,
    ops: Vec<Vec<u8>>,
    data: Vec<u8>,
    io: [u16; 3],
}

impl BlobWriter {
    /// A writer for a model whose native input is `height × width`.
    pub fn new(height: u16, width: u16) -> BlobWriter {
        BlobWriter {
            height,
            width,
            ..Default::default()
        }
    }

    /// Appends a tensor-table entry; returns its id.
    pub fn tensor(&mut self, dt: u8, channels: u16, q: QParams) -> u16 {
        let mut e = [0u8; 16];
        e[0] = dt;
        e[2..4].copy_from_slice(&channels.to_le_bytes());
        e[4..8].copy_from_slice(&q.scale.to_le_bytes());
        e[8..12].copy_from_slice(&q.zero_point.to_le_bytes());
        self.tensors.push(e);
        (self.tensors.len() - 1) as u16
    }

    /// Appends a parameter to the data section at the next 16-byte boundary; returns its offset
    /// relative to the data section start.
    pub fn param(&mut self, bytes: &[u8]) -> u32 {
        while !self.data.len().is_multiple_of(DATA_ALIGN) {
            self.data.push(0);
        }
        let off = self.data.len() as u32;
        self.data.extend_from_slice(bytes);
        off
    }

    /// Appends an op record (`attrs.len()` must be a multiple of 4).
    pub fn op(&mut self, code: u8, inputs: &[u16], output: u16, attrs: &[u8]) {
        let mut r = vec![code, inputs.len() as u8];
        r.extend_from_slice(&output.to_le_bytes());
        r.extend_from_slice(&(attrs.len() as u16).to_le_bytes());
        r.extend_from_slice(&[0, 0]);
        for i in inputs {
            r.extend_from_slice(&i.to_le_bytes());
        }
        while !r.len().is_multiple_of(4) {
            r.push(0);
        }
        r.extend_from_slice(attrs);
        self.ops.push(r);
    }

    /// Sets the rgb, sparse and output tensor ids.
    pub fn io(&mut self, rgb: u16, sparse: u16, output: u16) {
        self.io = [rgb, sparse, output];
    }

    /// The finished blob: header with payload length and CRC-32, tensor table, ops, data.
    pub fn finish(&self) -> Vec<u8> {
        let mut payload = Vec::new();
        for t in &self.tensors {
            payload.extend_from_slice(t);
        }
        for o in &self.ops {
            payload.extend_from_slice(o); // records are multiples of 4 and start 4-aligned
        }
        while !(HEADER_LEN + payload.len()).is_multiple_of(DATA_ALIGN) {
            payload.push(0);
        }
        payload.extend_from_slice(&self.data);
        let mut b = Vec::with_capacity(HEADER_LEN + payload.len());
        b.extend_from_slice(&MAGIC);
        b.extend_from_slice(&VERSION.to_le_bytes());
        b.extend_from_slice(&0u16.to_le_bytes());
        b.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        b.extend_from_slice(&crc32(&payload).to_le_bytes());
        let header = [
            self.height,
            self.width,
            self.tensors.len() as u16,
            self.ops.len() as u16,
            self.io[0],
            self.io[1],
            self.io[2],
            0,
        ];
        for v in header {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&payload);
        b
    }
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

fn le16(v: &[u16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn bytes<T: Copy>(v: &[T], f: impl Fn(T) -> [u8; 4]) -> Vec<u8> {
    v.iter().flat_map(|&x| f(x)).collect()
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
                let mut a = le16(
                    &[
                        g.kernel[0],
                        g.kernel[1],
                        g.stride[0],
                        g.stride[1],
                        g.dilation[0],
                        g.dilation[1],
                        g.padding[0],
                        g.padding[1],
                        g.groups,
                    ]
                    .map(|v| v as u16),
                );
                let (ac, alpha) = match act {
                    Activation::None => (activation::NONE, 0.0f32),
                    Activation::Relu => (activation::RELU, 0.0),
                    Activation::LeakyRelu(a) => (activation::LEAKY_RELU, *a),
                };
                a.extend_from_slice(&[ac, 0]);
                a.extend_from_slice(&alpha.to_le_bytes());
                let wr = bw.param(&wq.iter().map(|&v| v as u8).collect::<Vec<_>>());
                let br = bw.param(&bytes(&bq, i32::to_le_bytes));
                let sr = bw.param(&bytes(&sc, f32::to_le_bytes));
                for r in [wr, br, sr] {
                    a.extend_from_slice(&r.to_le_bytes());
                }
                (
                    if *linear {
                        opcode::LINEAR
                    } else {
                        opcode::CONV2D
                    },
                    a,
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
                let mut at = vec![mode, 0];
                at.extend(le16(&[a, b, 0]));
                (opcode::UPSAMPLE_BILINEAR, at)
            }
            OpKind::PixelShuffle(r) => (
                opcode::PIXEL_SHUFFLE,
                le16(&[u16_of("pixel_shuffle factor", *r)?, 0]),
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
                let mut a = le16(&[u16_of("n_bins", attrs.n_bins)?, 0]);
                a.extend_from_slice(&attrs.min_depth.to_le_bytes());
                a.extend_from_slice(&attrs.max_depth.to_le_bytes());
                let wr = bw.param(&wq.iter().map(|&v| v as u8).collect::<Vec<_>>());
                let br = bw.param(&bytes(&bq, i32::to_le_bytes));
                let sr = bw.param(&bytes(&sc, f32::to_le_bytes));
                for r in [wr, br, sr] {
                    a.extend_from_slice(&r.to_le_bytes());
                }
                (opcode::BINS_HEAD, a)
            }
            OpKind::Refine(attrs) => {
                let mut a = le16(&[u16_of("refine iterations", attrs.iterations)?, 0]);
                for s in attrs.sigma {
                    a.extend_from_slice(&s.to_le_bytes());
                }
                (opcode::REFINE, a)
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

    #[test]
    fn writer_layout_and_crc() {
        let mut bw = BlobWriter::new(4, 6);
        let q = QParams {
            scale: 0.5,
            zero_point: -3,
        };
        assert_eq!(bw.tensor(dtype::I8, 3, q), 0);
        bw.tensor(dtype::I8, 1, q);
        bw.tensor(dtype::F32, 1, q);
        assert_eq!(bw.param(&[1, 2, 3]), 0);
        assert_eq!(bw.param(&[4]), 16);
        bw.op(opcode::ADD, &[0, 1, 1], 2, &[]);
        bw.io(0, 1, 2);
        let b = bw.finish();
        assert_eq!(&b[0..4], b"DPTH");
        assert_eq!(u16::from_le_bytes([b[16], b[17]]), 4);
        assert_eq!(u16::from_le_bytes([b[18], b[19]]), 6);
        // 3 tensors × 16 + op record (8 + 3 ids padded to 8) = 64 bytes, then the data section
        // at blob offset 32 + 64 = 96 (16-aligned), 17 bytes of data.
        let payload_len = u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize;
        assert_eq!(payload_len, 64 + 17);
        assert_eq!(b[96..99], [1, 2, 3]);
        assert_eq!(b[112], 4);
        let crc = u32::from_le_bytes([b[12], b[13], b[14], b[15]]);
        assert_eq!(crc, crc32(&b[32..]));
        // Tensor 0's zero point.
        assert_eq!(i32::from_le_bytes([b[40], b[41], b[42], b[43]]), -3);
    }
}
