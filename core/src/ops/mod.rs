//! Graph ops (docs/graph.md), one file each, holding everything about the op: the attributes it
//! reads from the blob (`read_attrs`, with `ARITY`), its dtype and channel rules (`types_ok`),
//! its plan (output shape, scratch, persistent constants, MACs: `plan`), the constants written
//! once at prepare time (`write_consts`, where it has any) and its evaluation (`eval`). The blob
//! parser, the planner and the engine only dispatch here by opcode ([`Kind`]); the arithmetic
//! is in [`crate::kernels`].

pub(crate) mod add;
pub(crate) mod bins_head;
pub(crate) mod concat;
pub(crate) mod conv;
pub(crate) mod lut;
pub(crate) mod minmax_norm;
pub(crate) mod mul;
pub(crate) mod pixel_shuffle;
pub(crate) mod pool;
pub(crate) mod refine;
pub(crate) mod upsample;

use crate::blob::format::{opcode, MAX_INPUTS, MAX_TENSORS};
use crate::blob::parse::{bad, Attrs, DType, Graph, OpInfo, Reader, TensorInfo};
use crate::blob::BlobError;
use crate::engine::cast::{view, view_mut, Pod};
use crate::engine::plan::{OpPlan, Plan, PlanError};
use crate::engine::Error;
use crate::kernels::isa::Isa;
use crate::kernels::requant::QParams;
use crate::kernels::{KernelError, Shape};
use core::ops::Range;

/// The op files, by opcode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// `conv2d`, `linear` ([`conv`]).
    Conv,
    /// `relu`, `leaky_relu`, `sigmoid`, `reciprocal` ([`lut`]).
    Lut,
    /// `add` ([`add`]).
    Add,
    /// `mul` ([`mul`]).
    Mul,
    /// `concat` ([`concat`]).
    Concat,
    /// `upsample_bilinear` ([`upsample`]).
    Upsample,
    /// `pixel_shuffle` ([`pixel_shuffle`]).
    PixelShuffle,
    /// `global_avg_pool`, `global_max_pool`, `channel_mean`, `channel_max` ([`pool`]).
    Pool,
    /// `minmax_norm` ([`minmax_norm`]).
    MinMaxNorm,
    /// `bins_head` ([`bins_head`]).
    BinsHead,
    /// `refine` ([`refine`]).
    Refine,
}

impl Kind {
    /// The file of opcode `code`; `None` for an unknown opcode.
    pub(crate) fn of(code: u8) -> Option<Kind> {
        use opcode::*;
        Some(match code {
            CONV2D | LINEAR => Kind::Conv,
            RELU | LEAKY_RELU | SIGMOID | RECIPROCAL => Kind::Lut,
            ADD => Kind::Add,
            MUL => Kind::Mul,
            CONCAT => Kind::Concat,
            UPSAMPLE_BILINEAR => Kind::Upsample,
            PIXEL_SHUFFLE => Kind::PixelShuffle,
            GLOBAL_AVG_POOL | GLOBAL_MAX_POOL | CHANNEL_MEAN | CHANNEL_MAX => Kind::Pool,
            MINMAX_NORM => Kind::MinMaxNorm,
            BINS_HEAD => Kind::BinsHead,
            REFINE => Kind::Refine,
            _ => return None,
        })
    }

    /// Inputs the op takes: (min, max).
    pub(crate) fn arity(self) -> (usize, usize) {
        match self {
            Kind::Conv => conv::ARITY,
            Kind::Lut => lut::ARITY,
            Kind::Add => add::ARITY,
            Kind::Mul => mul::ARITY,
            Kind::Concat => concat::ARITY,
            Kind::Upsample => upsample::ARITY,
            Kind::PixelShuffle => pixel_shuffle::ARITY,
            Kind::Pool => pool::ARITY,
            Kind::MinMaxNorm => minmax_norm::ARITY,
            Kind::BinsHead => bins_head::ARITY,
            Kind::Refine => refine::ARITY,
        }
    }

    /// Reads opcode `code`'s attribute record; returns the attributes and its raw parameter
    /// references (weights, bias, scales; [`crate::blob::format::NONE`] where unused).
    pub(crate) fn read_attrs(
        self,
        code: u8,
        a: &mut Reader,
    ) -> Result<(Attrs, [u32; 3]), BlobError> {
        match self {
            Kind::Conv => conv::read_attrs(code, a),
            Kind::Lut => lut::read_attrs(a),
            Kind::Add | Kind::Mul | Kind::Concat | Kind::Pool => Ok(plain()),
            Kind::Upsample => upsample::read_attrs(a),
            Kind::PixelShuffle => pixel_shuffle::read_attrs(a),
            Kind::MinMaxNorm => minmax_norm::read_attrs(a),
            Kind::BinsHead => bins_head::read_attrs(a),
            Kind::Refine => refine::read_attrs(a),
        }
    }

    /// Whether the op's input and output dtypes and channel counts fit it.
    pub(crate) fn types_ok(self, k: &Types) -> Result<bool, BlobError> {
        match self {
            Kind::Conv => conv::types_ok(k),
            Kind::Lut => lut::types_ok(k),
            Kind::Add => add::types_ok(k),
            Kind::Mul => mul::types_ok(k),
            Kind::Concat => concat::types_ok(k),
            Kind::Upsample => upsample::types_ok(k),
            Kind::PixelShuffle => pixel_shuffle::types_ok(k),
            Kind::Pool => pool::types_ok(k),
            Kind::MinMaxNorm => minmax_norm::types_ok(k),
            Kind::BinsHead => bins_head::types_ok(k),
            Kind::Refine => refine::types_ok(k),
        }
    }

    /// Fills `p` (preset to the input's spatial size, the output's channels, nothing else).
    pub(crate) fn plan(self, c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
        match self {
            Kind::Conv => conv::plan(c, p),
            Kind::Lut | Kind::MinMaxNorm => Ok(()),
            Kind::Add => add::plan(c, p),
            Kind::Mul => mul::plan(c, p),
            Kind::Concat => concat::plan(c, p),
            Kind::Upsample => upsample::plan(c, p),
            Kind::PixelShuffle => pixel_shuffle::plan(c, p),
            Kind::Pool => pool::plan(c, p),
            Kind::BinsHead => bins_head::plan(c, p),
            Kind::Refine => refine::plan(c, p),
        }
    }

    /// Writes the op's persistent constants into `region` (prepare time).
    pub(crate) fn write_consts(self, c: &ConstCtx, region: &mut [u8]) -> Result<(), Error> {
        match self {
            Kind::Conv => conv::write_consts(c, region),
            Kind::Add => add::write_consts(c, region),
            Kind::Mul => mul::write_consts(c, region),
            Kind::Concat => concat::write_consts(c, region),
            Kind::Pool => pool::write_consts(c, region),
            Kind::BinsHead => bins_head::write_consts(c, region),
            Kind::Upsample => upsample::write_consts(c, region),
            Kind::Lut | Kind::PixelShuffle | Kind::MinMaxNorm | Kind::Refine => Ok(()),
        }
    }

    /// Runs the op on its operands.
    pub(crate) fn eval(self, e: Eval) -> Result<(), Error> {
        match self {
            Kind::Conv => conv::eval(e),
            Kind::Lut => lut::eval(e),
            Kind::Add => add::eval(e),
            Kind::Mul => mul::eval(e),
            Kind::Concat => concat::eval(e),
            Kind::Upsample => upsample::eval(e),
            Kind::PixelShuffle => pixel_shuffle::eval(e),
            Kind::Pool => pool::eval(e),
            Kind::MinMaxNorm => minmax_norm::eval(e),
            Kind::BinsHead => bins_head::eval(e),
            Kind::Refine => refine::eval(e),
        }
    }
}

/// The attributes of an op without any.
fn plain() -> (Attrs, [u32; 3]) {
    (Attrs::Plain, [crate::blob::format::NONE; 3])
}

/// What the type rules of one op see (at parse time).
pub(crate) struct Types<'a> {
    /// The op.
    pub op: &'a OpInfo,
    /// The tensor table.
    pub tensors: &'a [TensorInfo],
    /// Tensors produced by earlier ops or given as inputs.
    pub produced: &'a [bool; MAX_TENSORS],
    /// The first input.
    pub x: TensorInfo,
    /// The output.
    pub out: TensorInfo,
}

impl Types<'_> {
    /// Tensor `id`.
    pub fn t(&self, id: u16) -> Result<TensorInfo, BlobError> {
        self.tensors
            .get(id as usize)
            .copied()
            .ok_or(bad(self.op.offset, "tensor id out of range"))
    }

    /// `Err` unless every input and the output are int8.
    pub fn all_i8(&self) -> Result<(), BlobError> {
        let ok = self
            .op
            .inputs
            .iter()
            .all(|&i| self.t(i).is_ok_and(|ti| ti.dtype == DType::I8))
            && self.out.dtype == DType::I8;
        if ok {
            Ok(())
        } else {
            Err(bad(self.op.offset, "op: inputs and output must be int8"))
        }
    }

    /// Whether tensor `id` holds int8 or int16 codes.
    pub fn int(&self, id: u16) -> Result<bool, BlobError> {
        Ok(matches!(self.t(id)?.dtype, DType::I8 | DType::I16))
    }
}

/// What planning one op sees.
pub(crate) struct PlanCtx<'a> {
    /// The graph (tensor types and quantisation).
    pub g: &'a Graph<'a>,
    /// Op index.
    pub i: usize,
    /// The op.
    pub op: &'a OpInfo,
    /// Shapes known so far, by tensor id.
    pub shapes: &'a [Shape],
    /// The first input's shape.
    pub x: Shape,
    /// The output's channels.
    pub out_c: usize,
}

impl PlanCtx<'_> {
    /// A shape error of this op.
    pub fn err(&self, what: &'static str) -> PlanError {
        PlanError::Shape { op: self.i, what }
    }

    /// The shape of tensor `id`.
    pub fn shape(&self, id: u16) -> Result<Shape, PlanError> {
        self.shapes
            .get(id as usize)
            .copied()
            .ok_or(self.err("input shape unknown"))
    }
}

/// What writing one op's constants sees (prepare time).
pub(crate) struct ConstCtx<'a, 'g> {
    /// The graph.
    pub g: &'a Graph<'g>,
    /// The plan.
    pub plan: &'a Plan,
    /// Op index.
    pub i: usize,
    /// The op.
    pub op: &'a OpInfo,
}

impl ConstCtx<'_, '_> {
    /// Quantisation of tensor `id`.
    pub fn q(&self, id: u16) -> Result<QParams, Error> {
        Ok(self.g.tensor(id)?.q)
    }
}

/// One op's operands at run time: its inputs, output, scratch and constants, cut from the arena.
pub(crate) struct Eval<'r, 'g> {
    /// The graph.
    pub g: &'r Graph<'g>,
    /// The plan.
    pub plan: &'r Plan,
    /// Op index.
    pub i: usize,
    /// The op.
    pub op: &'r OpInfo,
    /// Input bytes, in input order.
    pub ins: [&'r [u8]; MAX_INPUTS],
    /// Output bytes.
    pub out: &'r mut [u8],
    /// Scratch bytes.
    pub scratch: &'r mut [u8],
    /// The op's persistent constants.
    pub consts: &'r [u8],
    /// Every op's persistent constants (the region `consts` is part of).
    pub all_consts: &'r [u8],
    /// Kernel set.
    pub isa: Isa,
    /// The first input's shape.
    pub x: Shape,
    /// The output's shape.
    pub out_shape: Shape,
}

impl Eval<'_, '_> {
    /// A shape error of this op.
    pub fn bad(&self) -> Error {
        bad_op(self.i)
    }

    /// Quantisation of tensor `id`.
    pub fn q(&self, id: u16) -> Result<QParams, Error> {
        Ok(self.g.tensor(id)?.q)
    }

    /// The shape of tensor `id`.
    pub fn shape(&self, id: u16) -> Result<Shape, Error> {
        self.plan.shape(id).ok_or(self.bad())
    }

    /// Maps a kernel error to this op's.
    pub fn kerr(&self) -> impl Fn(KernelError) -> Error + Copy {
        kerr(self.i)
    }
}

/// A shape error of op `op`.
pub(crate) fn bad_op(op: usize) -> Error {
    Error::Kernel {
        op,
        error: KernelError::Shape,
    }
}

/// Maps a kernel error to op `op`'s.
pub(crate) fn kerr(op: usize) -> impl Fn(KernelError) -> Error + Copy {
    move |error| Error::Kernel { op, error }
}

/// `b` as a slice of `T` (op `op`'s error where it is misaligned).
pub(crate) fn typed<T: Pod>(b: &[u8], op: usize) -> Result<&[T], Error> {
    view(b).ok_or(bad_op(op))
}

/// `b` as a mutable slice of `T`.
pub(crate) fn typed_mut<T: Pod>(b: &mut [u8], op: usize) -> Result<&mut [T], Error> {
    view_mut(b).ok_or(bad_op(op))
}

/// The first `T` of `b`.
pub(crate) fn first<T: Pod + Default>(b: &[u8], op: usize) -> Result<T, Error> {
    typed::<T>(b, op)?.first().copied().ok_or(bad_op(op))
}

/// Writes `v` as the first `T` of `region` (an op's one persistent constant; nothing where the
/// region holds none).
pub(crate) fn write_first<T: Pod>(region: &mut [u8], op: usize, v: T) -> Result<(), Error> {
    if let Some(d) = typed_mut::<T>(region, op)?.first_mut() {
        *d = v;
    }
    Ok(())
}

/// Splits `act` into two disjoint mutable ranges (`m1`, `m2`) and read-only `ins` (each of which
/// must lie outside both; the plan guarantees it, this checks it).
pub(crate) fn split<'b>(
    act: &'b mut [u8],
    m1: Range<usize>,
    m2: Range<usize>,
    ins: &[Range<usize>],
    out_ins: &mut [&'b [u8]; MAX_INPUTS],
    op: usize,
) -> Result<(&'b mut [u8], &'b mut [u8]), Error> {
    let bad = bad_op(op);
    // An empty range may sit anywhere; move it next to the other so ordering is well defined.
    let m2 = if m2.is_empty() { m1.end..m1.end } else { m2 };
    let swapped = m2.start < m1.start;
    let (a, b) = if swapped { (m2, m1) } else { (m1, m2) };
    if a.start > a.end || b.start > b.end || a.end > b.start || b.end > act.len() {
        return Err(bad);
    }
    let (p0, rest) = act.split_at_mut(a.start);
    let (ma, rest) = rest.split_at_mut(a.end - a.start);
    let (p1, rest) = rest.split_at_mut(b.start - a.end);
    let (mb, p2) = rest.split_at_mut(b.end - b.start);
    let pieces: [(usize, &'b [u8]); 3] = [(0, p0), (a.end, p1), (b.end, p2)];
    for (slot, r) in out_ins.iter_mut().zip(ins) {
        *slot = pieces
            .iter()
            .find(|(base, p)| r.start >= *base && r.end <= base + p.len())
            .and_then(|(base, p)| p.get(r.start - base..r.end - base))
            .ok_or(bad)?;
    }
    Ok(if swapped { (mb, ma) } else { (ma, mb) })
}

/// Splits `n` bytes off the front of `b` (`Err` where it is shorter).
pub(crate) fn take(b: &mut [u8], n: usize, op: usize) -> Result<(&mut [u8], &mut [u8]), Error> {
    if b.len() < n {
        return Err(Error::Kernel {
            op,
            error: KernelError::Scratch,
        });
    }
    Ok(b.split_at_mut(n))
}
