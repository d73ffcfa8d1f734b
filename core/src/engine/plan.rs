//! The arena plan: a pure function of the graph and the run size, answering
//! [`Plan::arena_bytes`] before anything runs.
//!
//! Every tensor and every op's scratch is a [`BufferReq`] `{ bytes, first, last }` over *steps*
//! (step 0 writes the inputs, op `i` runs at step `i + 1`, the output lives to the end). The
//! greedy planner (as TFLite Micro's) places buffers in decreasing size at the lowest offset that
//! does not overlap any already-placed buffer whose lifetime intersects its own. Offsets and
//! sizes are multiples of [`ALIGN`]. Per-op constants (per-channel requantisation, add/mul/pool
//! multipliers) live in a persistent head written once by `Engine::new`:
//!
//! ```text
//!  arena (caller's &mut [u8])
//!  ┌─────┬──────────────────────────┬──────────────────────────────────────────────────┐
//!  │ pad │ persistent: per-op consts │ activations + scratch, reused by liveness        │
//!  │<16 B│ ChannelQuant × O per conv │  step:   0    1    2    3   …                    │
//!  │     │ BinChannel × N, Rescale…  │  ░░rgb░░░░░░░                                    │
//!  │     │                          │        ▒▒conv0 out▒▒▒▒▒▒▒▒                        │
//!  │     │                          │  ░░sparse░░░░░░░░░░░░  ▓scratch▓                  │
//!  │     │                          │          (freed bytes are reused by later tensors)│
//!  └─────┴──────────────────────────┴──────────────────────────────────────────────────┘
//!  arena_bytes = 15 (base alignment slack) + persistent_bytes + activation_bytes
//! ```

use crate::blob::format::{opcode, upsample_mode, MAX_OPS, MAX_TENSORS};
use crate::blob::parse::{Attrs, DType, Graph, OpInfo};
use crate::kernels::bins::BinChannel;
use crate::kernels::conv::{ChannelQuant, Conv2d};
use crate::kernels::elementwise::{AddQuant, MulQuant, Rescale};
use crate::kernels::float::Broadcast;
use crate::kernels::pool::MeanQuant;
use crate::kernels::Shape;
use core::mem::size_of;
use core::ops::Range;
use heapless::Vec;

/// Alignment of the arena base and of every planned offset.
pub const ALIGN: usize = 16;
/// Most buffers one plan holds (a tensor each plus a scratch per op).
pub const MAX_BUFFERS: usize = MAX_TENSORS + MAX_OPS;

/// One buffer the planner must place: `bytes`, alive from step `first` to step `last` inclusive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct BufferReq {
    /// Size in bytes (0 = no buffer).
    pub bytes: usize,
    /// First step that writes it.
    pub first: usize,
    /// Last step that reads it.
    pub last: usize,
}

/// Why a graph cannot be planned at a size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum PlanError {
    /// Shapes do not fit together at this size.
    Shape {
        /// Op index.
        op: usize,
        /// What failed.
        what: &'static str,
    },
    /// A size overflowed `usize`.
    TooLarge,
}

impl core::fmt::Display for PlanError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PlanError::Shape { op, what } => write!(f, "op {op}: {what}"),
            PlanError::TooLarge => f.write_str("buffer sizes overflow"),
        }
    }
}

/// The result of [`plan`]: shapes of all tensors and where every buffer lives.
#[derive(Clone, Debug)]
pub struct Plan {
    height: usize,
    width: usize,
    n_tensors: usize,
    shapes: Vec<Shape, MAX_TENSORS>,
    reqs: Vec<BufferReq, MAX_BUFFERS>,
    offsets: Vec<usize, MAX_BUFFERS>,
    consts: Vec<Range<usize>, MAX_OPS>,
    broadcast: Vec<Broadcast, MAX_OPS>,
    persistent_bytes: usize,
    activation_bytes: usize,
    macs: u64,
}

impl Plan {
    /// Total arena bytes the caller must provide (includes up to 15 bytes of base alignment).
    pub fn arena_bytes(&self) -> usize {
        ALIGN - 1 + self.persistent_bytes + self.activation_bytes
    }
    /// Bytes of per-op constants at the arena head.
    pub fn persistent_bytes(&self) -> usize {
        self.persistent_bytes
    }
    /// Bytes of the activation/scratch region.
    pub fn activation_bytes(&self) -> usize {
        self.activation_bytes
    }
    /// Run size `(height, width)`.
    pub fn size(&self) -> (usize, usize) {
        (self.height, self.width)
    }
    /// Multiply-accumulates of one run (convs, linears, bins head).
    pub fn macs(&self) -> u64 {
        self.macs
    }
    /// Multiply-accumulates of op `op` of the planned `graph` (0 for ops without a reduction,
    /// or past the last op); recomputed, so the plan stays small.
    pub fn op_macs(&self, graph: &Graph, op: usize) -> u64 {
        graph
            .ops
            .get(op)
            .and_then(|o| plan_op(op, o, graph, &self.shapes).ok())
            .map_or(0, |p| p.macs)
    }
    /// Shape of tensor `id`.
    pub fn shape(&self, id: u16) -> Option<Shape> {
        self.shapes.get(id as usize).copied()
    }
    /// All placed buffers with their offsets in the activation region (tensors first, then
    /// one scratch per op).
    pub fn buffers(&self) -> impl Iterator<Item = (BufferReq, usize)> + '_ {
        self.reqs.iter().copied().zip(self.offsets.iter().copied())
    }
    /// Byte range of tensor `id` in the activation region.
    pub fn tensor_range(&self, id: u16) -> Option<Range<usize>> {
        let i = id as usize;
        if i >= self.n_tensors {
            return None;
        }
        let (r, o) = (self.reqs.get(i)?, self.offsets.get(i)?);
        Some(*o..*o + r.bytes)
    }
    /// Byte range of op `op`'s scratch in the activation region.
    pub fn scratch_range(&self, op: usize) -> Option<Range<usize>> {
        let i = self.n_tensors + op;
        let (r, o) = (self.reqs.get(i)?, self.offsets.get(i)?);
        Some(*o..*o + r.bytes)
    }
    /// Byte range of op `op`'s constants in the persistent region.
    pub fn const_range(&self, op: usize) -> Option<Range<usize>> {
        self.consts.get(op).cloned()
    }
    /// How the second input of op `op` broadcasts (meaningful for `mul`).
    pub fn broadcast(&self, op: usize) -> Broadcast {
        self.broadcast.get(op).copied().unwrap_or(Broadcast::None)
    }
}

fn round_up(n: usize) -> Result<usize, PlanError> {
    n.checked_add(ALIGN - 1)
        .map(|v| v / ALIGN * ALIGN)
        .ok_or(PlanError::TooLarge)
}

/// Places buffers greedily (largest first, lowest non-conflicting offset); writes one offset
/// per request and returns the total bytes. Offsets are multiples of [`ALIGN`] when the sizes
/// are.
pub fn place(reqs: &[BufferReq], offsets: &mut [usize]) -> Result<usize, PlanError> {
    if reqs.len() > MAX_BUFFERS || offsets.len() < reqs.len() {
        return Err(PlanError::TooLarge);
    }
    let mut order: Vec<u16, MAX_BUFFERS> = Vec::new();
    for i in 0..reqs.len() {
        order.push(i as u16).map_err(|_| PlanError::TooLarge)?;
    }
    // Decreasing size, then earlier first use, then index: deterministic.
    order.sort_unstable_by(|&a, &b| {
        let (ra, rb) = (&reqs[a as usize], &reqs[b as usize]);
        rb.bytes
            .cmp(&ra.bytes)
            .then(ra.first.cmp(&rb.first))
            .then(a.cmp(&b))
    });
    let mut placed: Vec<u16, MAX_BUFFERS> = Vec::new();
    let mut total = 0usize;
    for &i in &order {
        let r = reqs[i as usize];
        let mut conflicts: Vec<(usize, usize), MAX_BUFFERS> = Vec::new();
        for &j in &placed {
            let q = reqs[j as usize];
            if q.bytes > 0 && q.first <= r.last && r.first <= q.last {
                let o = offsets[j as usize];
                conflicts
                    .push((o, o + q.bytes))
                    .map_err(|_| PlanError::TooLarge)?;
            }
        }
        conflicts.sort_unstable();
        let mut at = 0usize;
        for &(s, e) in &conflicts {
            if at.checked_add(r.bytes).ok_or(PlanError::TooLarge)? <= s {
                break;
            }
            at = at.max(e);
        }
        offsets[i as usize] = at;
        total = total.max(at.checked_add(r.bytes).ok_or(PlanError::TooLarge)?);
        placed.push(i).map_err(|_| PlanError::TooLarge)?;
    }
    Ok(total)
}

/// Output shape, scratch bytes, constant bytes, broadcast and MACs of one op.
struct OpPlan {
    out: Shape,
    scratch: usize,
    consts: usize,
    broadcast: Broadcast,
    macs: u64,
}

fn plan_op(i: usize, op: &OpInfo, g: &Graph, shapes: &[Shape]) -> Result<OpPlan, PlanError> {
    use opcode::*;
    let err = |what| PlanError::Shape { op: i, what };
    let shape = |id: u16| {
        shapes
            .get(id as usize)
            .copied()
            .ok_or(err("input shape unknown"))
    };
    let x = shape(op.inputs[0])?;
    let out_c = g
        .tensors
        .get(op.output as usize)
        .ok_or(err("output id"))?
        .channels;
    let mut p = OpPlan {
        out: Shape::new(out_c, x.h, x.w),
        scratch: 0,
        consts: 0,
        broadcast: Broadcast::None,
        macs: 0,
    };
    match (op.code, &op.attrs) {
        (CONV2D | LINEAR, Attrs::Conv { geometry, .. }) => {
            let geometry = geometry.get();
            p.out = geometry
                .output_shape(x, out_c)
                .ok_or(err("conv: no output for this input size"))?;
            p.scratch = Conv2d::scratch_len(&geometry, x, p.out)
                .checked_mul(4)
                .ok_or(PlanError::TooLarge)?;
            p.consts = out_c * size_of::<ChannelQuant>();
            let taps = geometry.weight_len(x.c, out_c).ok_or(PlanError::TooLarge)? / out_c;
            p.macs = (p.out.len().ok_or(PlanError::TooLarge)? as u64).saturating_mul(taps as u64);
        }
        (ADD, _) => {
            if shape(op.inputs[1])? != x {
                return Err(err("add: operand shapes differ"));
            }
            p.consts = size_of::<AddQuant>();
        }
        (MUL, _) => {
            let y = shape(op.inputs[1])?;
            p.broadcast = if y == x {
                Broadcast::None
            } else if y == Shape::new(1, x.h, x.w) {
                Broadcast::OverChannels
            } else if y == Shape::new(x.c, 1, 1) {
                Broadcast::OverSpace
            } else {
                return Err(err(
                    "mul: second operand neither equal, [1,H,W] nor [C,1,1]",
                ));
            };
            p.consts = size_of::<MulQuant>();
        }
        (CONCAT, _) => {
            for &id in &op.inputs {
                let s = shape(id)?;
                if (s.h, s.w) != (x.h, x.w) {
                    return Err(err("concat: inputs differ in H or W"));
                }
            }
            p.consts = op.inputs.len() * size_of::<Rescale>();
        }
        (UPSAMPLE_BILINEAR, Attrs::Upsample { mode, a, b }) => {
            let (h, w) = match *mode {
                upsample_mode::FIXED => (*a, *b),
                upsample_mode::SCALE => (
                    x.h.checked_mul(*a).ok_or(PlanError::TooLarge)?,
                    x.w.checked_mul(*b).ok_or(PlanError::TooLarge)?,
                ),
                _ => {
                    let s = shapes
                        .get(*a)
                        .copied()
                        .filter(|s| s.c > 0)
                        .ok_or(err("upsample: size tensor unknown"))?;
                    (s.h, s.w)
                }
            };
            p.out = Shape::new(out_c, h, w);
        }
        (PIXEL_SHUFFLE, Attrs::PixelShuffle(r)) => {
            p.out = Shape::new(
                out_c,
                x.h.checked_mul(*r).ok_or(PlanError::TooLarge)?,
                x.w.checked_mul(*r).ok_or(PlanError::TooLarge)?,
            );
        }
        (GLOBAL_AVG_POOL, _) => {
            p.out = Shape::new(out_c, 1, 1);
            p.consts = size_of::<MeanQuant>();
        }
        (GLOBAL_MAX_POOL, _) => {
            p.out = Shape::new(out_c, 1, 1);
            p.consts = size_of::<Rescale>();
        }
        (CHANNEL_MEAN, _) => p.consts = size_of::<MeanQuant>(),
        (CHANNEL_MAX, _) => p.consts = size_of::<Rescale>(),
        (RELU | LEAKY_RELU | SIGMOID | RECIPROCAL | MINMAX_NORM, _) => {}
        (BINS_HEAD, Attrs::Bins { attrs, .. }) => {
            if shape(op.inputs[1])? != Shape::new(attrs.n_bins, 1, 1) {
                return Err(err("bins_head: bin logits must be [N,1,1]"));
            }
            p.consts = attrs.n_bins * size_of::<BinChannel>();
            p.macs = (x.plane().ok_or(PlanError::TooLarge)? as u64)
                .saturating_mul((x.c * attrs.n_bins) as u64);
        }
        (REFINE, _) => {
            for &id in &op.inputs {
                let s = shape(id)?;
                if (s.h, s.w) != (x.h, x.w) {
                    return Err(err("refine: inputs differ in H or W"));
                }
            }
            p.scratch = x
                .plane()
                .and_then(|n| n.checked_mul(8))
                .ok_or(PlanError::TooLarge)?;
        }
        _ => return Err(err("op attributes do not match the opcode")),
    }
    if p.out.len().is_none_or(|n| n == 0) {
        return Err(err("empty or overflowing output"));
    }
    Ok(p)
}

/// Plans `graph` for an input of `h × w` (see the module doc). Pure: reads only its arguments.
pub fn plan(graph: &Graph, h: usize, w: usize) -> Result<Plan, PlanError> {
    let n_t = graph.tensors.len();
    let n_ops = graph.ops.len();
    let zero = Shape::default();
    let mut shapes: Vec<Shape, MAX_TENSORS> = Vec::new();
    shapes.resize(n_t, zero).map_err(|_| PlanError::TooLarge)?;
    shapes[graph.rgb as usize] = Shape::new(3, h, w);
    shapes[graph.sparse as usize] = Shape::new(1, h, w);
    let mut reqs: Vec<BufferReq, MAX_BUFFERS> = Vec::new();
    reqs.resize(n_t + n_ops, BufferReq::default())
        .map_err(|_| PlanError::TooLarge)?;
    let last_step = n_ops + 1;
    let mut consts: Vec<Range<usize>, MAX_OPS> = Vec::new();
    let mut broadcast: Vec<Broadcast, MAX_OPS> = Vec::new();
    let mut persistent = 0usize;
    let mut macs = 0u64;
    for (i, op) in graph.ops.iter().enumerate() {
        let p = plan_op(i, op, graph, &shapes)?;
        shapes[op.output as usize] = p.out;
        let step = i + 1;
        let cb = round_up(p.consts)?;
        consts
            .push(persistent..persistent + p.consts)
            .map_err(|_| PlanError::TooLarge)?;
        persistent = persistent.checked_add(cb).ok_or(PlanError::TooLarge)?;
        broadcast
            .push(p.broadcast)
            .map_err(|_| PlanError::TooLarge)?;
        reqs[n_t + i] = BufferReq {
            bytes: round_up(p.scratch)?,
            first: step,
            last: step,
        };
        reqs[op.output as usize].first = step;
        reqs[op.output as usize].last = step;
        for &id in &op.inputs {
            reqs[id as usize].last = reqs[id as usize].last.max(step);
        }
        macs = macs.saturating_add(p.macs);
    }
    if shapes[graph.output as usize] != Shape::new(1, h, w) {
        return Err(PlanError::Shape {
            op: n_ops.saturating_sub(1),
            what: "output is not [1,H,W]",
        });
    }
    reqs[graph.output as usize].last = last_step;
    for (t, info) in graph.tensors.iter().enumerate() {
        let elem = if info.dtype == DType::F32 { 4 } else { 1 };
        let n = shapes[t]
            .len()
            .and_then(|n| n.checked_mul(elem))
            .ok_or(PlanError::TooLarge)?;
        reqs[t].bytes = round_up(n)?;
    }
    let mut offsets: Vec<usize, MAX_BUFFERS> = Vec::new();
    offsets
        .resize(reqs.len(), 0)
        .map_err(|_| PlanError::TooLarge)?;
    let activation_bytes = place(&reqs, &mut offsets)?;
    Ok(Plan {
        height: h,
        width: w,
        n_tensors: n_t,
        shapes,
        reqs,
        offsets,
        consts,
        broadcast,
        persistent_bytes: persistent,
        activation_bytes,
        macs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn place_reuses_freed_memory() {
        // a (0..1) and c (2..3) never live together: c reuses a's bytes; b overlaps both.
        let reqs = [
            BufferReq {
                bytes: 32,
                first: 0,
                last: 1,
            },
            BufferReq {
                bytes: 16,
                first: 1,
                last: 2,
            },
            BufferReq {
                bytes: 32,
                first: 2,
                last: 3,
            },
        ];
        let mut off = [0; 3];
        let total = place(&reqs, &mut off).unwrap();
        assert_eq!(total, 48);
        assert_eq!(off[0], off[2]);
        assert_eq!(off[1], 32);
    }

    #[test]
    fn place_never_overlaps_live_buffers() {
        let mut reqs = [BufferReq::default(); 40];
        for (i, r) in reqs.iter_mut().enumerate() {
            *r = BufferReq {
                bytes: 16 * (1 + (i * 7) % 5),
                first: i % 9,
                last: i % 9 + (i * 3) % 4,
            };
        }
        let mut off = [0; 40];
        let total = place(&reqs, &mut off).unwrap();
        for i in 0..40 {
            assert!(off[i] + reqs[i].bytes <= total);
            for j in 0..i {
                let (a, b) = (reqs[i], reqs[j]);
                if a.first <= b.last && b.first <= a.last {
                    assert!(
                        off[i] + a.bytes <= off[j] || off[j] + b.bytes <= off[i],
                        "{i} {j}"
                    );
                }
            }
        }
    }
}
