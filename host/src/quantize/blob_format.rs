//! The writer of the blob format (`docs/blob.md`), the inverse of the core's
//! `depthor_core::blob::parse`: a byte-level [`BlobWriter`] for the tensor table, op records and
//! the 16-byte aligned data section, and the encoders of each opcode's attributes. The
//! quantizers (the host's [`super::blob_writer`], and the miniature one of the core's tests,
//! which include this file by path: the core itself never allocates) decide the numbers and
//! write them through it. Only `depthor_core` paths are used, so the file compiles in both.

use depthor_core::blob::checksum::crc32;
use depthor_core::blob::format::{
    activation, DATA_ALIGN, HEADER_LEN, MAGIC, OP_HEADER_LEN, TENSOR_ENTRY_LEN, VERSION,
};
use depthor_core::kernels::conv::{Activation, ConvGeometry};
use depthor_core::kernels::requant::QParams;

/// Byte-level builder of a v1 blob.
#[derive(Clone, Debug, Default)]
pub struct BlobWriter {
    height: u16,
    width: u16,
    tensors: Vec<[u8; TENSOR_ENTRY_LEN]>,
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
        let mut e = [0u8; TENSOR_ENTRY_LEN];
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

    /// Appends the three parameters of a `conv2d`, `linear` or `bins_head` (int8 weights, int32
    /// bias, f32 per-channel weight scales); returns their references in that order.
    pub fn weights(&mut self, weight: &[i8], bias: &[i32], scales: &[f32]) -> [u32; 3] {
        let w: Vec<u8> = weight.iter().map(|&v| v as u8).collect();
        let b: Vec<u8> = bias.iter().flat_map(|v| v.to_le_bytes()).collect();
        let s: Vec<u8> = scales.iter().flat_map(|v| v.to_le_bytes()).collect();
        [self.param(&w), self.param(&b), self.param(&s)]
    }

    /// Appends an op record (`attrs.len()` must be a multiple of 4).
    pub fn op(&mut self, code: u8, inputs: &[u16], output: u16, attrs: &[u8]) {
        let mut r = Vec::with_capacity(OP_HEADER_LEN + 2 * inputs.len() + 2 + attrs.len());
        r.extend_from_slice(&[code, inputs.len() as u8]);
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

/// Little-endian bytes of `v`.
fn le16(v: &[u16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// `conv2d` / `linear` attributes: the geometry (kernel, stride, dilation, padding as rows then
/// columns, groups), the activation and its slope, and the weight, bias and scale references.
pub fn conv_attrs(g: &ConvGeometry, act: Activation, refs: [u32; 3]) -> Vec<u8> {
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
    let (code, alpha) = match act {
        Activation::None => (activation::NONE, 0.0f32),
        Activation::Relu => (activation::RELU, 0.0),
        Activation::LeakyRelu(a) => (activation::LEAKY_RELU, a),
    };
    a.extend_from_slice(&[code, 0]);
    a.extend_from_slice(&alpha.to_le_bytes());
    for r in refs {
        a.extend_from_slice(&r.to_le_bytes());
    }
    a
}

/// `bins_head` attributes: bin count, depth range in metres, weight, bias and scale references.
pub fn bins_head_attrs(n_bins: u16, min_depth: f32, max_depth: f32, refs: [u32; 3]) -> Vec<u8> {
    let mut a = le16(&[n_bins, 0]);
    a.extend_from_slice(&min_depth.to_le_bytes());
    a.extend_from_slice(&max_depth.to_le_bytes());
    for r in refs {
        a.extend_from_slice(&r.to_le_bytes());
    }
    a
}

/// `refine` attributes: iterations, the neighbourhood's code and the three kernels' σ.
pub fn refine_attrs(iterations: u16, neighbourhood: u16, sigma: [f32; 3]) -> Vec<u8> {
    let mut a = le16(&[iterations, neighbourhood]);
    for s in sigma {
        a.extend_from_slice(&s.to_le_bytes());
    }
    a
}

/// `upsample_bilinear` attributes: the mode (`format::upsample_mode`) and its two numbers (the
/// tensor to match, or rows and columns, or the two factors).
pub fn upsample_attrs(mode: u8, a: u16, b: u16) -> Vec<u8> {
    let mut at = Vec::from([mode, 0]);
    at.extend(le16(&[a, b, 0]));
    at
}

/// `pixel_shuffle` attributes: the factor.
pub fn pixel_shuffle_attrs(factor: u16) -> Vec<u8> {
    le16(&[factor, 0])
}
