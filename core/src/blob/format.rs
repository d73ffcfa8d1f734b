//! Byte format of the int8 model blob, version 1 (`DPTH` v1). The host quantizer writes it, the
//! core reads it in place (weights are never copied). All integers and floats are
//! little-endian; `f32` is IEEE-754 binary32. Offsets are in bytes.
//!
//! ```text
//! ┌ header, 32 bytes ───────────────────────────────────────────────────────────────────┐
//! │  0  [u8;4] magic "DPTH"          16 u16 height (native input rows H)                │
//! │  4  u16 version = 1              18 u16 width  (native input columns W)             │
//! │  6  u16 flags = 0 (reserved)     20 u16 n_tensors      22 u16 n_ops                 │
//! │  8  u32 payload_len              24 u16 rgb input id   26 u16 sparse input id       │
//! │ 12  u32 crc32(payload)           28 u16 output id      30 u16 reserved = 0          │
//! ├ payload = bytes 32 .. 32 + payload_len ─────────────────────────────────────────────┤
//! │ tensor table: n_tensors × 16 bytes                                                  │
//! │   0 u8 dtype (0 = int8, 1 = f32)   1 u8 reserved = 0   2 u16 channels (≥ 1)         │
//! │   4 f32 scale (int8: finite, > 0)  8 i32 zero_point (int8: −128..=127)              │
//! │  12 u32 reserved = 0                                                                │
//! │ op list: n_ops records, each starting 4-byte aligned (relative to the blob start)   │
//! │   0 u8 opcode   1 u8 n_inputs (1..=8)   2 u16 output tensor id                      │
//! │   4 u16 attr_len (multiple of 4)        6 u16 reserved = 0                          │
//! │   8 n_inputs × u16 input ids, zero-padded to a multiple of 4 bytes                  │
//! │   … attr_len bytes of attributes (layout per opcode below)                          │
//! │ data section: starts at the first 16-byte boundary after the op list; parameters    │
//! │   are referenced by a u32 offset relative to the data section start (NONE =         │
//! │   0xFFFF_FFFF for an absent bias); the writer aligns each parameter to 16 bytes     │
//! │   (the reader does not rely on it). Lengths follow from the shapes.                 │
//! └─────────────────────────────────────────────────────────────────────────────────────┘
//! ```
//!
//! The CRC is [`crc32`](super::checksum::crc32) over the payload only. The blob may be longer
//! than `32 + payload_len`; the tail is ignored. Tensor shapes are not stored: channels come
//! from the table, spatial sizes from shape inference for the run size `H×W` (the engine may run
//! the same weights at another size). Input tensors have shape `[3,H,W]` (rgb, values
//! `byte/255` quantised with the tensor's parameters) and `[1,H,W]` (sparse depth, metres);
//! the output is `[1,H,W]` metres. Every other tensor is the output of exactly one op, and ops
//! are in topological order (inputs produced before use).
//!
//! ## Ops (opcode: inputs → output; attributes)
//! Names are graph.md's. `batch_norm` is folded into the preceding conv by the quantizer; a conv
//! with `activation: "sigmoid"` is written as conv (`none`) followed by a `sigmoid` op.
//! Quantisation: activations int8 asymmetric per tensor, weights int8 symmetric per output
//! channel with f32 scales `s_w[o]`, bias int32 in units of `s_in · s_w[o]` (TFLite int8 spec).
//!
//! | code | op | attributes (bytes) |
//! |---|---|---|
//! | 1 | `conv2d` | u16 kh, kw, stride_h, stride_w, dil_h, dil_w, pad_h, pad_w, groups; u8 activation (0 none, 1 relu, 2 leaky_relu); u8 0; f32 alpha; u32 weight `[O, I/g, kh, kw]` i8; u32 bias `[O]` i32 or NONE; u32 w_scale `[O]` f32 — 36 bytes |
//! | 2 | `linear` | as `conv2d` with a 1×1 kernel, unit stride and dilation, no padding, groups 1; weight `[O, I]` |
//! | 3 | `relu` | `[u8; 256]` table, entry `q as u8` is the int8 output for input code `q` |
//! | 4 | `leaky_relu` | same table layout (slope baked in) |
//! | 5 | `sigmoid` | same table layout |
//! | 6 | `reciprocal` | same table layout (`1/(x + eps)` baked in) |
//! | 7 | `add` | none; two int8 inputs of one shape |
//! | 8 | `mul` | none; second input `[C,H,W]`, `[1,H,W]` (over channels) or `[C,1,1]` (over space) |
//! | 9 | `concat` | none; 1..=8 inputs with equal H, W; each requantised to the output |
//! | 10 | `upsample_bilinear` | u8 mode, u8 0, u16 a, u16 b, u16 0 — mode 0: size `a×b`; 1: scale `H·a × W·b`; 2: the size of tensor `a` (produced earlier); int8 in/out share parameters; f32 allowed |
//! | 11 | `pixel_shuffle` | u16 factor, u16 0; int8 in/out share parameters; f32 allowed |
//! | 12 | `global_avg_pool` | none |
//! | 13 | `global_max_pool` | none |
//! | 14 | `channel_mean` | none |
//! | 15 | `channel_max` | none |
//! | 16 | `minmax_norm` | f32 eps |
//! | 17 | `bins_head` | u16 n_bins, u16 0; f32 min_depth_m, max_depth_m; u32 weight `[N, C]` i8; u32 bias `[N]` i32 or NONE; u32 w_scale `[N]` f32 — inputs features (int8) and bin logits (`[N,1,1]`, int8 or f32); output f32 |
//! | 18 | `refine` | u16 iterations T (even), u16 0; f32 σ3, σ5, σ7 — inputs d0 (f32), aff3 (8 ch), aff5 (24), aff7 (48), kmix (3), tmix (3) (int8); output f32 |
//!
//! Lookup tables are stored rather than computed so the core needs no transcendental math for
//! element-wise activations; only `bins_head` and `refine` call `exp` (see their modules).

/// Magic bytes at offset 0.
pub const MAGIC: [u8; 4] = *b"DPTH";
/// The format version this core reads.
pub const VERSION: u16 = 1;
/// Header length in bytes.
pub const HEADER_LEN: usize = 32;
/// Bytes per tensor-table entry.
pub const TENSOR_ENTRY_LEN: usize = 16;
/// Bytes of an op record before its input ids.
pub const OP_HEADER_LEN: usize = 8;
/// Alignment of the data section (relative to the blob start).
pub const DATA_ALIGN: usize = 16;
/// Parameter reference meaning "absent".
pub const NONE: u32 = 0xFFFF_FFFF;
/// Most inputs of one op.
pub const MAX_INPUTS: usize = 8;
/// Most tensors in a blob.
pub const MAX_TENSORS: usize = 256;
/// Most ops in a blob.
pub const MAX_OPS: usize = 192;

/// Tensor element type codes.
pub mod dtype {
    /// int8 with per-tensor scale and zero point.
    pub const I8: u8 = 0;
    /// IEEE f32 (depth maps in metres).
    pub const F32: u8 = 1;
}

/// Opcodes.
pub mod opcode {
    /// `conv2d`.
    pub const CONV2D: u8 = 1;
    /// `linear`.
    pub const LINEAR: u8 = 2;
    /// `relu` (table).
    pub const RELU: u8 = 3;
    /// `leaky_relu` (table).
    pub const LEAKY_RELU: u8 = 4;
    /// `sigmoid` (table).
    pub const SIGMOID: u8 = 5;
    /// `reciprocal` (table).
    pub const RECIPROCAL: u8 = 6;
    /// `add`.
    pub const ADD: u8 = 7;
    /// `mul`.
    pub const MUL: u8 = 8;
    /// `concat`.
    pub const CONCAT: u8 = 9;
    /// `upsample_bilinear`.
    pub const UPSAMPLE_BILINEAR: u8 = 10;
    /// `pixel_shuffle`.
    pub const PIXEL_SHUFFLE: u8 = 11;
    /// `global_avg_pool`.
    pub const GLOBAL_AVG_POOL: u8 = 12;
    /// `global_max_pool`.
    pub const GLOBAL_MAX_POOL: u8 = 13;
    /// `channel_mean`.
    pub const CHANNEL_MEAN: u8 = 14;
    /// `channel_max`.
    pub const CHANNEL_MAX: u8 = 15;
    /// `minmax_norm`.
    pub const MINMAX_NORM: u8 = 16;
    /// `bins_head`.
    pub const BINS_HEAD: u8 = 17;
    /// `refine`.
    pub const REFINE: u8 = 18;
}

/// Activation codes of `conv2d` / `linear`.
pub mod activation {
    /// Identity.
    pub const NONE: u8 = 0;
    /// ReLU.
    pub const RELU: u8 = 1;
    /// LeakyReLU with the record's `alpha`.
    pub const LEAKY_RELU: u8 = 2;
}

/// `upsample_bilinear` size modes.
pub mod upsample_mode {
    /// Fixed output size `a × b`.
    pub const FIXED: u8 = 0;
    /// Integer scale factors `a`, `b`.
    pub const SCALE: u8 = 1;
    /// Same spatial size as tensor `a`.
    pub const LIKE: u8 = 2;
}

/// The graph.md name of an opcode (`None` for unknown codes).
pub fn op_name(code: u8) -> Option<&'static str> {
    use opcode::*;
    Some(match code {
        CONV2D => "conv2d",
        LINEAR => "linear",
        RELU => "relu",
        LEAKY_RELU => "leaky_relu",
        SIGMOID => "sigmoid",
        RECIPROCAL => "reciprocal",
        ADD => "add",
        MUL => "mul",
        CONCAT => "concat",
        UPSAMPLE_BILINEAR => "upsample_bilinear",
        PIXEL_SHUFFLE => "pixel_shuffle",
        GLOBAL_AVG_POOL => "global_avg_pool",
        GLOBAL_MAX_POOL => "global_max_pool",
        CHANNEL_MEAN => "channel_mean",
        CHANNEL_MAX => "channel_max",
        MINMAX_NORM => "minmax_norm",
        BINS_HEAD => "bins_head",
        REFINE => "refine",
        _ => return None,
    })
}
