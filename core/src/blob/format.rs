//! Constants of the int8 model blob, version 1 (`DPTH` v1): magic, header and record sizes,
//! dtype, opcode, activation and upsample-mode codes, and the reader's limits. The byte layout and
//! each opcode's attributes are specified in `docs/blob.md`; the host quantizer writes it, the
//! core reads it in place (weights are never copied).

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
/// Most tensors in a blob (120 with the `small-tables` feature).
#[cfg(not(feature = "small-tables"))]
pub const MAX_TENSORS: usize = 256;
/// Most ops in a blob (120 with the `small-tables` feature).
#[cfg(not(feature = "small-tables"))]
pub const MAX_OPS: usize = 192;
/// Most tensors in a blob: the `small-tables` build (a microcontroller's engine tables sized for
/// the shipped networks, at most 119 tensors and 117 ops; a larger blob is refused by the parser).
#[cfg(feature = "small-tables")]
pub const MAX_TENSORS: usize = 120;
/// Most ops in a blob: the `small-tables` build (see [`MAX_TENSORS`]).
#[cfg(feature = "small-tables")]
pub const MAX_OPS: usize = 120;

/// Tensor element type codes.
pub mod dtype {
    /// int8 with per-tensor scale and zero point.
    pub const I8: u8 = 0;
    /// IEEE f32 (depth maps in metres).
    pub const F32: u8 = 1;
    /// int16, symmetric per tensor (zero point 0): `conv2d` / `linear` / `concat` outputs and
    /// `conv2d` / `linear` inputs and `concat` parts only (TFLite's 16×8 scheme,
    /// `crate::kernels::wide`).
    pub const I16: u8 = 2;
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

/// The `docs/graph.md` name of an opcode (`None` for unknown codes).
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
