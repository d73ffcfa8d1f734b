//! Validating parser of the blob [`format`](super::format). Everything that does not depend on
//! the run size is checked here (magic, version, CRC, every table entry, arities, dtypes,
//! channel counts, parameter ranges); shapes are checked by the planner. The parser never
//! panics: every read is bounds-checked and reports [`BlobError::Bad`] with its offset.

use super::checksum::crc32;
use super::error::BlobError;
use super::format::*;
use crate::kernels::bins::BinsAttrs;
use crate::kernels::conv::{Activation, ConvGeometry, MAX_TAPS};
use crate::kernels::refine::RefineAttrs;
use crate::kernels::requant::QParams;
use crate::ops::{Kind, Types};
use heapless::Vec;

/// Element type of a tensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DType {
    /// int8 with [`QParams`].
    I8,
    /// f32.
    F32,
    /// int16 with [`QParams`] of zero point 0.
    I16,
}

/// One tensor-table entry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TensorInfo {
    /// Element type.
    pub dtype: DType,
    /// Channels.
    pub channels: usize,
    /// Quantisation (`scale 1, zero point 0` for f32).
    pub q: QParams,
}

/// A validated parameter: absolute byte range in the blob.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Param {
    /// Start, bytes from the blob start.
    pub offset: u32,
    /// Length in bytes.
    pub len: u32,
}

impl Param {
    /// The byte range in the blob.
    pub fn range(&self) -> core::ops::Range<usize> {
        self.offset as usize..self.offset as usize + self.len as usize
    }
}

/// Conv geometry as stored (u16 fields, to keep the op table small);
/// `[kh, kw, sh, sw, dh, dw, ph, pw, groups]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Geometry(pub [u16; 9]);

impl Geometry {
    /// The kernel-facing geometry.
    pub fn get(&self) -> ConvGeometry {
        let v = self.0.map(|x| x as usize);
        ConvGeometry {
            kernel: [v[0], v[1]],
            stride: [v[2], v[3]],
            dilation: [v[4], v[5]],
            padding: [v[6], v[7]],
            groups: v[8],
        }
    }
}

/// Parsed attributes of an op.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Attrs {
    /// `conv2d` / `linear`.
    Conv {
        /// Geometry.
        geometry: Geometry,
        /// Fused activation.
        act: Activation,
        /// int8 weights.
        weights: Param,
        /// int32 bias (absent = zeros).
        bias: Option<Param>,
        /// f32 per-output-channel weight scales.
        scales: Param,
    },
    /// Table ops: 256 bytes.
    Lut(Param),
    /// No attributes.
    Plain,
    /// `upsample_bilinear`.
    Upsample {
        /// [`upsample_mode`] code.
        mode: u8,
        /// First value (rows, row factor or tensor id).
        a: usize,
        /// Second value.
        b: usize,
    },
    /// `pixel_shuffle` factor.
    PixelShuffle(usize),
    /// `minmax_norm` eps.
    MinMax(f32),
    /// `bins_head`.
    Bins {
        /// Bin count and depth range.
        attrs: BinsAttrs,
        /// int8 weights `[N, C]`.
        weights: Param,
        /// int32 bias.
        bias: Option<Param>,
        /// f32 weight scales.
        scales: Param,
    },
    /// `refine`.
    Refine(RefineAttrs),
}

/// One op of the graph.
#[derive(Clone, Debug, PartialEq)]
pub struct OpInfo {
    /// [`opcode`] value.
    pub code: u8,
    /// Input tensor ids.
    pub inputs: Vec<u16, MAX_INPUTS>,
    /// Output tensor id.
    pub output: u16,
    /// Attributes.
    pub attrs: Attrs,
    /// Byte offset of the record (for error reports).
    pub offset: usize,
}

/// A validated graph referencing the blob's bytes.
#[derive(Clone, Debug)]
pub struct Graph<'a> {
    /// The whole blob.
    pub blob: &'a [u8],
    /// Native input rows.
    pub height: usize,
    /// Native input columns.
    pub width: usize,
    /// Tensor table.
    pub tensors: Vec<TensorInfo, MAX_TENSORS>,
    /// Ops in execution order.
    pub ops: Vec<OpInfo, MAX_OPS>,
    /// rgb input id.
    pub rgb: u16,
    /// sparse input id.
    pub sparse: u16,
    /// output id.
    pub output: u16,
}

impl Graph<'_> {
    /// Tensor info by id (ids are validated by [`parse`]).
    pub fn tensor(&self, id: u16) -> Result<&TensorInfo, BlobError> {
        self.tensors.get(id as usize).ok_or(BlobError::Bad {
            offset: 0,
            what: "tensor id out of range",
        })
    }

    /// Bytes of a validated parameter.
    pub fn bytes(&self, p: Param) -> &[u8] {
        self.blob.get(p.range()).unwrap_or(&[])
    }

    /// Bytes of the int8 weights of every conv, linear and bins head (one byte per weight; the
    /// int32 biases, f32 scales and tables are counted in the blob size, not here).
    pub fn int8_weight_bytes(&self) -> usize {
        self.ops
            .iter()
            .map(|op| match op.attrs {
                Attrs::Conv { weights, .. } | Attrs::Bins { weights, .. } => weights.len as usize,
                _ => 0,
            })
            .sum()
    }
}

pub(crate) struct Reader<'a> {
    b: &'a [u8],
    /// Next byte to read.
    pub(crate) pos: usize,
    end: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], BlobError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.end);
        let s = end
            .and_then(|e| self.b.get(self.pos..e))
            .ok_or(BlobError::Bad {
                offset: self.pos,
                what,
            })?;
        self.pos += n;
        Ok(s)
    }
    pub(crate) fn arr<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], BlobError> {
        let s = self.take(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }
    pub(crate) fn u8(&mut self, what: &'static str) -> Result<u8, BlobError> {
        Ok(self.arr::<1>(what)?[0])
    }
    pub(crate) fn u16(&mut self, what: &'static str) -> Result<u16, BlobError> {
        Ok(u16::from_le_bytes(self.arr(what)?))
    }
    pub(crate) fn u32(&mut self, what: &'static str) -> Result<u32, BlobError> {
        Ok(u32::from_le_bytes(self.arr(what)?))
    }
    pub(crate) fn i32(&mut self, what: &'static str) -> Result<i32, BlobError> {
        Ok(i32::from_le_bytes(self.arr(what)?))
    }
    pub(crate) fn f32(&mut self, what: &'static str) -> Result<f32, BlobError> {
        Ok(f32::from_le_bytes(self.arr(what)?))
    }
    pub(crate) fn zero16(&mut self, what: &'static str) -> Result<(), BlobError> {
        let at = self.pos;
        if self.u16(what)? != 0 {
            return Err(BlobError::Bad { offset: at, what });
        }
        Ok(())
    }
    pub(crate) fn align(&mut self, a: usize, what: &'static str) -> Result<(), BlobError> {
        let pad = (a - self.pos % a) % a;
        self.take(pad, what).map(|_| ())
    }
}

pub(crate) fn bad(offset: usize, what: &'static str) -> BlobError {
    BlobError::Bad { offset, what }
}

/// Reads a little-endian f32 array element from validated bytes.
pub fn f32_at(bytes: &[u8], i: usize) -> f32 {
    bytes
        .get(i * 4..i * 4 + 4)
        .map_or(0.0, |s| f32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// Reads a little-endian i32 array element from validated bytes.
pub fn i32_at(bytes: &[u8], i: usize) -> i32 {
    bytes
        .get(i * 4..i * 4 + 4)
        .map_or(0, |s| i32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// The header fields the rest of the parse needs.
struct Header {
    height: usize,
    width: usize,
    n_tensors: usize,
    n_ops: usize,
    rgb: u16,
    sparse: u16,
    output: u16,
    /// End of the payload (the CRC covers `HEADER_LEN..end`).
    end: usize,
}

/// Parses and validates a blob (see the module doc).
pub fn parse(blob: &[u8]) -> Result<Graph<'_>, BlobError> {
    let mut g = Graph {
        blob,
        height: 0,
        width: 0,
        tensors: Vec::new(),
        ops: Vec::new(),
        rgb: 0,
        sparse: 0,
        output: 0,
    };
    parse_into(&mut g, blob)?;
    Ok(g)
}

/// As [`parse`], into the caller's `graph` (its tables are reused, so nothing of the graph's
/// size sits on the stack: for an engine built in place, `Engine::init_in`). On an error the
/// graph holds a partial parse: do not use it.
#[inline(never)]
pub fn parse_into<'a>(graph: &mut Graph<'a>, blob: &'a [u8]) -> Result<(), BlobError> {
    let mut r = Reader {
        b: blob,
        pos: 0,
        end: blob.len(),
    };
    let h = read_header(&mut r)?;
    graph.blob = blob;
    graph.height = h.height;
    graph.width = h.width;
    graph.rgb = h.rgb;
    graph.sparse = h.sparse;
    graph.output = h.output;
    let tensors = &mut graph.tensors;
    tensors.clear();
    for _ in 0..h.n_tensors {
        let at = r.pos;
        tensors
            .push(read_tensor(&mut r)?)
            .map_err(|_| bad(at, "tensor: table full"))?;
    }
    check_io(tensors, &h)?;

    // First pass over ops: record layout; parameters are resolved after the data start is known.
    let mut produced = [false; MAX_TENSORS];
    produced[h.rgb as usize] = true;
    produced[h.sparse as usize] = true;
    let ops = &mut graph.ops;
    ops.clear();
    // Raw parameter offsets per op (weights, bias, scales), relative to the data section.
    let mut raw: Vec<[u32; 3], MAX_OPS> = Vec::new();
    for _ in 0..h.n_ops {
        let (op, refs) = read_op(&mut r, tensors, &mut produced)?;
        let at = op.offset;
        ops.push(op).map_err(|_| bad(at, "too many ops"))?;
        raw.push(refs).map_err(|_| bad(at, "too many ops"))?;
    }
    if !produced[h.output as usize] || h.output == h.rgb || h.output == h.sparse {
        return Err(bad(28, "header: output is not produced by any op"));
    }
    r.align(DATA_ALIGN, "data: alignment padding")?;
    let data = r.pos;

    // Resolve parameter references now that the data start is known.
    for (op, refs) in ops.iter_mut().zip(raw.iter()) {
        resolve_params(blob, op, *refs, tensors, data, h.end)?;
    }
    Ok(())
}

/// Reads and checks the header: magic, version, flags, the payload's length and CRC (the
/// reader's end becomes the payload's), the input size and the table sizes.
fn read_header(r: &mut Reader<'_>) -> Result<Header, BlobError> {
    let blob = r.b;
    if r.arr::<4>("header: magic")? != MAGIC {
        return Err(bad(0, "header: magic is not \"DPTH\""));
    }
    let version = r.u16("header: version")?;
    if version != VERSION {
        return Err(BlobError::UnsupportedVersion { found: version });
    }
    if r.u16("header: flags")? != 0 {
        return Err(bad(6, "header: unknown flags"));
    }
    let payload_len = r.u32("header: payload_len")? as usize;
    let stored = r.u32("header: crc32")?;
    let height = r.u16("header: height")? as usize;
    let width = r.u16("header: width")? as usize;
    let n_tensors = r.u16("header: n_tensors")? as usize;
    let n_ops = r.u16("header: n_ops")? as usize;
    let rgb = r.u16("header: rgb id")?;
    let sparse = r.u16("header: sparse id")?;
    let output = r.u16("header: output id")?;
    r.zero16("header: reserved")?;
    let end = HEADER_LEN
        .checked_add(payload_len)
        .filter(|&e| e <= blob.len())
        .ok_or(bad(8, "header: payload_len beyond the blob"))?;
    let computed = crc32(&blob[HEADER_LEN..end]);
    if computed != stored {
        return Err(BlobError::BadChecksum { stored, computed });
    }
    r.end = end;
    if height == 0 || width == 0 {
        return Err(bad(16, "header: zero input size"));
    }
    if n_tensors > MAX_TENSORS {
        return Err(bad(20, "header: more tensors than MAX_TENSORS"));
    }
    if n_ops == 0 || n_ops > MAX_OPS {
        return Err(bad(22, "header: op count 0 or above MAX_OPS"));
    }
    Ok(Header {
        height,
        width,
        n_tensors,
        n_ops,
        rgb,
        sparse,
        output,
        end,
    })
}

/// Reads one tensor-table entry: dtype, channels, quantisation (checked for int8).
fn read_tensor(r: &mut Reader<'_>) -> Result<TensorInfo, BlobError> {
    let at = r.pos;
    let dt = r.u8("tensor: dtype")?;
    if r.u8("tensor: reserved")? != 0 {
        return Err(bad(at + 1, "tensor: reserved byte not zero"));
    }
    let channels = r.u16("tensor: channels")? as usize;
    let scale = r.f32("tensor: scale")?;
    let zero_point = r.i32("tensor: zero_point")?;
    if r.u32("tensor: reserved")? != 0 {
        return Err(bad(at + 12, "tensor: reserved word not zero"));
    }
    let (dtype, q) = match dt {
        dtype::I8 => {
            if !(scale.is_finite() && scale > 0.0 && (-128..=127).contains(&zero_point)) {
                return Err(bad(
                    at + 4,
                    "tensor: int8 scale must be finite and > 0, zero point in -128..=127",
                ));
            }
            (DType::I8, QParams { scale, zero_point })
        }
        dtype::I16 => {
            if !(scale.is_finite() && scale > 0.0 && zero_point == 0) {
                return Err(bad(
                    at + 4,
                    "tensor: int16 scale must be finite and > 0, zero point 0",
                ));
            }
            (DType::I16, QParams { scale, zero_point })
        }
        dtype::F32 => (
            DType::F32,
            QParams {
                scale: 1.0,
                zero_point: 0,
            },
        ),
        _ => return Err(bad(at, "tensor: unknown dtype")),
    };
    if channels == 0 {
        return Err(bad(at + 2, "tensor: zero channels"));
    }
    Ok(TensorInfo { dtype, channels, q })
}

/// Tensor `id` of the table; `at` is the offset reported when it is out of range.
fn tensor_at(tensors: &[TensorInfo], id: u16, at: usize) -> Result<TensorInfo, BlobError> {
    tensors
        .get(id as usize)
        .copied()
        .ok_or(bad(at, "tensor id out of range"))
}

/// The header's inputs and output exist and have the contract's channels (rgb 3, sparse 1,
/// output 1) and int8 or f32 codes, and the two inputs differ.
fn check_io(tensors: &[TensorInfo], h: &Header) -> Result<(), BlobError> {
    let ti_rgb = tensor_at(tensors, h.rgb, 24)?;
    let ti_sparse = tensor_at(tensors, h.sparse, 26)?;
    let ti_out = tensor_at(tensors, h.output, 28)?;
    if ti_rgb.channels != 3 || ti_sparse.channels != 1 || ti_out.channels != 1 || h.rgb == h.sparse
    {
        return Err(bad(
            24,
            "header: inputs must be distinct [3,H,W] rgb and [1,H,W] sparse, output [1,H,W]",
        ));
    }
    if [ti_rgb, ti_sparse, ti_out]
        .iter()
        .any(|t| t.dtype == DType::I16)
    {
        return Err(bad(24, "header: inputs and output must be int8 or f32"));
    }
    Ok(())
}

/// Reads one op record (opcode, inputs produced before it, an output produced once, its
/// attributes) and checks its types; returns it with its raw parameter references.
fn read_op(
    r: &mut Reader<'_>,
    tensors: &[TensorInfo],
    produced: &mut [bool; MAX_TENSORS],
) -> Result<(OpInfo, [u32; 3]), BlobError> {
    r.align(4, "op: alignment padding")?;
    let at = r.pos;
    let code = r.u8("op: opcode")?;
    let n_in = r.u8("op: n_inputs")? as usize;
    let out_id = r.u16("op: output id")?;
    let attr_len = r.u16("op: attr_len")? as usize;
    r.zero16("op: reserved")?;
    let kind = Kind::of(code).ok_or(bad(at, "op: unknown opcode"))?;
    let (lo, hi) = kind.arity();
    if n_in < lo || n_in > hi {
        return Err(bad(at + 1, "op: wrong number of inputs"));
    }
    let mut inputs: Vec<u16, MAX_INPUTS> = Vec::new();
    for _ in 0..n_in {
        let ip = r.pos;
        let id = r.u16("op: input id")?;
        tensor_at(tensors, id, ip)?;
        if !produced[id as usize] {
            return Err(bad(ip, "op: input used before it is produced"));
        }
        inputs
            .push(id)
            .map_err(|_| bad(ip, "op: too many inputs"))?;
    }
    r.align(4, "op: input padding")?;
    tensor_at(tensors, out_id, at + 2)?;
    if produced[out_id as usize] {
        return Err(bad(at + 2, "op: output tensor produced twice"));
    }
    produced[out_id as usize] = true;
    if !attr_len.is_multiple_of(4) {
        return Err(bad(at + 4, "op: attr_len not a multiple of 4"));
    }
    let attr_start = r.pos;
    let mut a = Reader {
        b: r.b,
        pos: attr_start,
        end: attr_start
            .checked_add(attr_len)
            .ok_or(bad(at, "op: attr_len"))?,
    };
    if a.end > r.end {
        return Err(bad(at + 4, "op: attributes beyond the payload"));
    }
    let (attrs, refs) = kind.read_attrs(code, &mut a)?;
    if a.pos != a.end {
        return Err(bad(
            a.pos,
            "op: attr_len does not match the opcode's attributes",
        ));
    }
    r.pos = a.end;
    let op = OpInfo {
        code,
        inputs,
        output: out_id,
        attrs,
        offset: at,
    };
    check_types(kind, &op, tensors, produced)?;
    Ok((op, refs))
}

/// Turns a conv's or bins head's raw references (relative to the data section at `data`) into
/// parameters inside the payload (which ends at `end`) of the sizes its shapes need, and checks
/// its weight scales.
fn resolve_params(
    blob: &[u8],
    op: &mut OpInfo,
    refs: [u32; 3],
    tensors: &[TensorInfo],
    data: usize,
    end: usize,
) -> Result<(), BlobError> {
    let at = op.offset;
    let in_c = tensor_at(tensors, op.inputs[0], at)?.channels;
    let out_c = tensor_at(tensors, op.output, at)?.channels;
    let param = |rel: u32, len: usize, what: &'static str| -> Result<Param, BlobError> {
        let offset = data.checked_add(rel as usize).ok_or(bad(at, what))?;
        match offset.checked_add(len) {
            Some(e) if rel != NONE && e <= end => Ok(Param {
                offset: u32::try_from(offset).map_err(|_| bad(at, what))?,
                len: u32::try_from(len).map_err(|_| bad(at, what))?,
            }),
            _ => Err(bad(at, what)),
        }
    };
    match &mut op.attrs {
        Attrs::Conv {
            geometry,
            weights,
            bias,
            scales,
            ..
        } => {
            let n = geometry
                .get()
                .weight_len(in_c, out_c)
                .filter(|&n| n / out_c <= MAX_TAPS);
            let n = n.ok_or(bad(at, "conv: weight shape too large"))?;
            *weights = param(refs[0], n, "conv: weights outside the data section")?;
            *bias = if refs[1] == NONE {
                None
            } else {
                Some(param(
                    refs[1],
                    out_c * 4,
                    "conv: bias outside the data section",
                )?)
            };
            *scales = param(refs[2], out_c * 4, "conv: scales outside the data section")?;
            check_scales(blob, *scales, out_c, at)?;
        }
        Attrs::Bins {
            attrs,
            weights,
            bias,
            scales,
        } => {
            let nb = attrs.n_bins;
            *weights = param(
                refs[0],
                nb * in_c,
                "bins_head: weights outside the data section",
            )?;
            *bias = if refs[1] == NONE {
                None
            } else {
                Some(param(
                    refs[1],
                    nb * 4,
                    "bins_head: bias outside the data section",
                )?)
            };
            *scales = param(
                refs[2],
                nb * 4,
                "bins_head: scales outside the data section",
            )?;
            check_scales(blob, *scales, nb, at)?;
        }
        _ => {}
    }
    Ok(())
}

fn check_scales(blob: &[u8], p: Param, n: usize, at: usize) -> Result<(), BlobError> {
    let bytes = blob.get(p.range()).ok_or(bad(at, "scales"))?;
    for i in 0..n {
        let s = f32_at(bytes, i);
        if !(s.is_finite() && s > 0.0) {
            return Err(bad(
                p.offset as usize + 4 * i,
                "weight scale must be finite and > 0",
            ));
        }
    }
    Ok(())
}

/// A parameter not yet resolved (attributes before [`parse`] resolves references).
pub(crate) const NO_PARAM: Param = Param { offset: 0, len: 0 };

/// Static dtype / channel rules per op (spatial sizes are the planner's job): the op's file in
/// `crate::ops` says what fits it.
fn check_types(
    kind: Kind,
    op: &OpInfo,
    tensors: &[TensorInfo],
    produced: &[bool; MAX_TENSORS],
) -> Result<(), BlobError> {
    let at = op.offset;
    let t = |id: u16| {
        tensors
            .get(id as usize)
            .copied()
            .ok_or(bad(at, "tensor id out of range"))
    };
    let k = Types {
        op,
        tensors,
        produced,
        x: t(op.inputs[0])?,
        out: t(op.output)?,
    };
    if kind.types_ok(&k)? {
        Ok(())
    } else {
        Err(bad(
            at,
            "op: input/output dtypes or channel counts do not fit the op",
        ))
    }
}

#[cfg(test)]
mod tests {
    //! Small parser checks on [`crate::blob::TEST_BLOB`], sized for Miri
    //! (`cargo +nightly miri test -p depthor-core --lib blob::`); the exhaustive corruption
    //! suites are `core/tests/blob.rs` and the `parse_blob` fuzz target.
    use super::*;
    use crate::blob::checksum::crc32;
    use crate::blob::format::HEADER_LEN;
    use crate::blob::TEST_BLOB;
    use std::vec;
    use std::vec::Vec;

    fn payload_end(b: &[u8]) -> usize {
        HEADER_LEN + u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize
    }

    fn fix_crc(b: &mut [u8]) {
        let end = payload_end(b).min(b.len());
        let c = crc32(&b[HEADER_LEN..end]);
        b[12..16].copy_from_slice(&c.to_le_bytes());
    }

    #[test]
    fn test_blob_parses() {
        let g = parse(TEST_BLOB).unwrap();
        assert_eq!((g.height, g.width), (12, 16));
        assert!(g.ops.len() >= 30 && g.tensors.len() == g.ops.len() + 2);
        assert_eq!(g.blob.len(), TEST_BLOB.len());
    }

    #[test]
    fn truncations_are_errors() {
        let end = payload_end(TEST_BLOB);
        assert!(end <= TEST_BLOB.len());
        // Under Miri every parse is slow (a CRC over 15 KB): a few lengths only.
        let step = if cfg!(miri) { 3001 } else { 61 };
        for len in (0..end).step_by(step).chain([end - 1]) {
            assert!(parse(&TEST_BLOB[..len]).is_err(), "{len} bytes parsed");
        }
    }

    #[test]
    fn corruptions_with_a_repaired_crc_are_errors_or_graphs() {
        // The header and the tables byte by byte, the rest sparsely; no panic, and the header
        // fields the reader must refuse are refused.
        let (mut refused, mut tried) = (0, 0);
        // Under Miri (slow: each parse runs the CRC over 15 KB) a few header, table and
        // op bytes with one value; natively every header and table byte and every 211th other.
        let first_op = parse(TEST_BLOB).unwrap().ops[0].offset;
        let (picks, values): (Vec<usize>, &[u8]) = if cfg!(miri) {
            (vec![4, 17, 21, 40, first_op + 1, first_op + 9], &[0xff])
        } else {
            let head = 0..first_op + 32;
            let tail = (first_op + 32..TEST_BLOB.len()).step_by(211);
            (head.chain(tail).collect(), &[0, 0x7f, 0xff])
        };
        for i in picks {
            for &v in values {
                let mut b = TEST_BLOB.to_vec();
                if b[i] == v {
                    continue;
                }
                b[i] = v;
                fix_crc(&mut b);
                tried += 1;
                let r = parse(&b);
                if i < 8 {
                    assert!(r.is_err(), "magic/version byte {i} = {v:#x} accepted");
                }
                refused += usize::from(r.is_err());
            }
        }
        assert!(refused * 4 > tried, "{refused} of {tried} refused");
    }

    #[test]
    fn a_bad_crc_is_refused() {
        let mut b: Vec<u8> = TEST_BLOB.to_vec();
        let last = payload_end(&b) - 1;
        b[last] ^= 1;
        assert!(matches!(parse(&b), Err(BlobError::BadChecksum { .. })));
    }
}
