//! The deployable network: graph.json after batch-norm folding, in the blob's op vocabulary
//! (one [`Op`] per blob op, one [`Value`] per blob tensor), and its f32 execution with the
//! core's [`kernels::float`](depthor_core::kernels::float) references — the ground truth the
//! quantizer calibrates on and compares the int8 engine with.

use depthor_core::kernels::bins::BinsAttrs;
use depthor_core::kernels::conv::{Activation, ConvGeometry};
use depthor_core::kernels::float::{self, Broadcast};
use depthor_core::kernels::refine::{self, RefineAttrs};
use depthor_core::kernels::{KernelError, Shape};

/// Value index of the `rgb` input (`[3,H,W]`, `byte/255`).
pub const RGB: usize = 0;
/// Value index of the `sparse` input (`[1,H,W]` metres, 0 = no point).
pub const SPARSE: usize = 1;

/// Element type a value has in the blob.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    /// int8, per-tensor asymmetric.
    I8,
    /// f32 (depth maps in metres: the bins head, its upsampling and refine).
    F32,
    /// int16, per-tensor symmetric: a conv or concat output read only by convs and concats,
    /// chosen with `depthor quantize --int16` ([`super::widen`]).
    I16,
}

/// One tensor of the network.
#[derive(Clone, Debug, PartialEq)]
pub struct Value {
    /// graph.json value name (folded convs carry their activation's name).
    pub name: String,
    /// Shape at the native input size.
    pub shape: Shape,
    /// Blob element type.
    pub storage: Storage,
    /// Quantised with this other value's parameters instead of its own (an upsample written at
    /// the scale of the concat that reads it: [`super::upsample_scale`]).
    pub params_of: Option<usize>,
}

/// How `upsample_bilinear` sizes its output in the blob.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpsampleSize {
    /// The spatial size of an earlier value (follows the run size).
    Like(usize),
    /// A fixed size `h × w`.
    Fixed(usize, usize),
}

/// A blob op with f32 parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum OpKind {
    /// `conv2d` (or `linear` when `linear`), batch norm folded in, weights `[O, I/g, kh, kw]`.
    Conv {
        /// Geometry.
        geometry: ConvGeometry,
        /// Fused activation (sigmoid is split off into its own op).
        act: Activation,
        /// Weights.
        weight: Vec<f32>,
        /// Bias `[O]`.
        bias: Vec<f32>,
        /// Written as the `linear` opcode.
        linear: bool,
    },
    /// `relu`.
    Relu,
    /// `leaky_relu`.
    LeakyRelu(f32),
    /// `sigmoid`.
    Sigmoid,
    /// `reciprocal` with eps.
    Reciprocal(f32),
    /// `add`.
    Add,
    /// `mul` with the second input's broadcast.
    Mul(Broadcast),
    /// `concat`.
    Concat,
    /// `upsample_bilinear`.
    Upsample(UpsampleSize),
    /// `pixel_shuffle`.
    PixelShuffle(usize),
    /// `global_avg_pool`.
    GlobalAvgPool,
    /// `global_max_pool`.
    GlobalMaxPool,
    /// `channel_mean`.
    ChannelMean,
    /// `channel_max`.
    ChannelMax,
    /// `minmax_norm` with eps.
    MinMaxNorm(f32),
    /// `bins_head`, weights `[N, C]`.
    BinsHead {
        /// Bins and depth range.
        attrs: BinsAttrs,
        /// Weights.
        weight: Vec<f32>,
        /// Bias `[N]`.
        bias: Vec<f32>,
    },
    /// `refine`.
    Refine(RefineAttrs),
}

/// One op: inputs and output are value indices.
#[derive(Clone, Debug, PartialEq)]
pub struct Op {
    /// What it computes.
    pub kind: OpKind,
    /// Input values.
    pub inputs: Vec<usize>,
    /// Output value (always `2 + op index`).
    pub output: usize,
}

/// The folded network. Values 0 and 1 are the inputs; op `k` produces value `k + 2`.
#[derive(Clone, Debug, PartialEq)]
pub struct Net {
    /// Variant name.
    pub variant: String,
    /// Native input rows.
    pub height: usize,
    /// Native input columns.
    pub width: usize,
    /// Every tensor.
    pub values: Vec<Value>,
    /// Ops in topological order.
    pub ops: Vec<Op>,
    /// The output value (`depth`).
    pub output: usize,
}

/// Why the float run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// An input slice has the wrong length.
    #[error("input {what}: expected {expected} values, got {got}")]
    Input {
        /// Which input.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// A kernel refused its operands.
    #[error("op {op} ({name}): {error}")]
    Kernel {
        /// Op index.
        op: usize,
        /// Output value name.
        name: String,
        /// Kernel error.
        error: KernelError,
    },
}

impl Net {
    /// Index of the value called `name`.
    pub fn value(&self, name: &str) -> Option<usize> {
        self.values.iter().position(|v| v.name == name)
    }

    /// Int8 weight bytes the blob will hold (conv, linear and bins-head weights).
    pub fn weight_count(&self) -> usize {
        self.ops
            .iter()
            .map(|o| match &o.kind {
                OpKind::Conv { weight, .. } | OpKind::BinsHead { weight, .. } => weight.len(),
                _ => 0,
            })
            .sum()
    }

    /// Runs the network in f32 at the native size. `rgb` is `[3,H,W]` planar in [0, 1],
    /// `sparse` `[1,H,W]` metres. Returns every value (index = value index).
    pub fn run_f32(&self, rgb: &[f32], sparse: &[f32]) -> Result<Vec<Vec<f32>>, RunError> {
        let n = self.height * self.width;
        for (what, x, e) in [("rgb", rgb, 3 * n), ("sparse", sparse, n)] {
            if x.len() != e {
                return Err(RunError::Input {
                    what,
                    expected: e,
                    got: x.len(),
                });
            }
        }
        let mut vals: Vec<Vec<f32>> = vec![rgb.to_vec(), sparse.to_vec()];
        for (k, op) in self.ops.iter().enumerate() {
            let out = self.eval(op, &vals).map_err(|error| RunError::Kernel {
                op: k,
                name: self.values[op.output].name.clone(),
                error,
            })?;
            vals.push(out);
        }
        Ok(vals)
    }

    /// Runs one op in f32 on `vals` (every earlier value, indexed by value).
    pub(crate) fn eval(&self, op: &Op, vals: &[Vec<f32>]) -> Result<Vec<f32>, KernelError> {
        let x = vals.get(op.inputs[0]).ok_or(KernelError::Shape)?;
        let xs = self.values[op.inputs[0]].shape;
        let os = self.values[op.output].shape;
        let mut out = vec![0f32; os.len().ok_or(KernelError::Shape)?];
        let arg = |i: usize| vals.get(op.inputs[i]).ok_or(KernelError::Shape);
        match &op.kind {
            OpKind::Conv {
                geometry,
                act,
                weight,
                bias,
                ..
            } => float::conv2d(geometry, x, xs, weight, Some(bias), *act, &mut out, os)?,
            OpKind::Relu => map(x, &mut out, float::relu),
            OpKind::LeakyRelu(a) => map(x, &mut out, |v| float::leaky_relu(v, *a)),
            OpKind::Sigmoid => map(x, &mut out, float::sigmoid),
            OpKind::Reciprocal(e) => map(x, &mut out, |v| float::reciprocal(v, *e)),
            OpKind::Add => float::add(x, arg(1)?, &mut out)?,
            OpKind::Mul(b) => float::mul(x, xs, arg(1)?, *b, &mut out)?,
            OpKind::Concat => {
                let mut at = 0;
                for &i in &op.inputs {
                    let v = vals.get(i).ok_or(KernelError::Shape)?;
                    out.get_mut(at..at + v.len())
                        .ok_or(KernelError::Shape)?
                        .copy_from_slice(v);
                    at += v.len();
                }
            }
            OpKind::Upsample(_) => float::upsample_bilinear(x, xs, &mut out, os)?,
            OpKind::PixelShuffle(r) => {
                float::pixel_shuffle(x, xs, *r, &mut out)?;
            }
            OpKind::GlobalAvgPool => float::global_avg_pool(x, xs, &mut out)?,
            OpKind::GlobalMaxPool => float::global_max_pool(x, xs, &mut out)?,
            OpKind::ChannelMean => float::channel_mean(x, xs, &mut out)?,
            OpKind::ChannelMax => float::channel_max(x, xs, &mut out)?,
            OpKind::MinMaxNorm(e) => float::minmax_norm(x, *e, &mut out)?,
            OpKind::BinsHead {
                attrs,
                weight,
                bias,
            } => float::bins_head(x, xs, arg(1)?, weight, bias, attrs, &mut out)?,
            OpKind::Refine(attrs) => {
                let mut scratch = vec![0f32; refine::scratch_len(xs.w, attrs.iterations)];
                float::refine(
                    x,
                    xs.h,
                    xs.w,
                    [arg(1)?, arg(2)?, arg(3)?],
                    arg(4)?,
                    arg(5)?,
                    attrs,
                    &mut out,
                    &mut scratch,
                )?;
            }
        }
        Ok(out)
    }
}

fn map(x: &[f32], out: &mut [f32], f: impl Fn(f32) -> f32) {
    for (o, &v) in out.iter_mut().zip(x) {
        *o = f(v);
    }
}
