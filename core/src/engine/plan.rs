//! The arena plan: a pure function of the graph and the run size, answering
//! [`Plan::arena_bytes`] before anything runs.
//!
//! Every tensor and every op's scratch is a [`BufferReq`] `{ bytes, first, last }` over *steps*
//! (step 0 writes the inputs, op `i` runs at step `i + 1`, the output lives to the end). The
//! greedy planner (as TFLite Micro's) places buffers in decreasing size at the lowest offset that
//! does not overlap any already-placed buffer whose lifetime intersects its own. Offsets and
//! sizes are multiples of [`ALIGN`]. Per-op constants (per-channel requantisation, add/mul/pool/
//! rescaling-upsample multipliers) live in a persistent head written once by `Engine::new`:
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

use crate::blob::format::{opcode, MAX_OPS, MAX_TENSORS};
use crate::blob::parse::{Attrs, DType, Graph, OpInfo};
use crate::kernels::broadcast::Broadcast;
use crate::kernels::conv::ChannelQuant;
use crate::kernels::pack::MAX_PARTS;
use crate::kernels::refine;
use crate::kernels::Shape;
use crate::ops::{Kind, PlanCtx};
use core::mem::size_of;
use core::ops::Range;
use heapless::Vec;

/// Alignment of the arena base and of every planned offset.
pub const ALIGN: usize = 16;
/// Most buffers one plan holds (a tensor each plus a scratch per op, and the two input staging
/// areas of [`Io::Arena`], which a graph with both tables full cannot have).
pub const MAX_BUFFERS: usize = MAX_TENSORS + MAX_OPS;
// `Plan::order` holds op indices as `u8`.
const _: () = assert!(MAX_OPS <= 256);

/// Most refinements per graph whose heads are fused ([`Memory::Streamed`]); others keep
/// whole maps.
pub const MAX_FUSED: usize = 2;
/// Most `mul` ops per graph that write their output over their first operand
/// ([`Plan::in_place_of`]); others get their own buffer.
pub const MAX_ALIASES: usize = 8;
/// Most concats per graph read in place by their conv ([`Memory::Streamed`]); others are
/// copied.
pub const MAX_IN_PLACE: usize = 32;

/// How the plan trades arena bytes against what a run exposes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Memory {
    /// Least memory: where a `refine` op's three affinity inputs each come from a `conv2d`
    /// read by nothing else, those convs are fused into the refinement and run one output row
    /// at a time into a ring ([`crate::kernels::refine::ConvRows`]); so are its kmix and tmix
    /// convs ([`crate::kernels::refine::MixConvRows`]) and a one-channel f32
    /// `upsample_bilinear` giving its `D_0` ([`crate::kernels::refine::UpsampledDepth`]).
    /// Their outputs are never stored whole (nor shown to `Engine::run_observed`). A refine
    /// whose output is the graph's writes it straight into the caller's f32 output
    /// ([`Plan::output_in_arena`] is false). A concat read only by one conv is read in place
    /// by it. Convs compute their per-channel requantisation constants per run in their
    /// scratch rather than holding them in the persistent region. The bits do not change.
    #[default]
    Streamed,
    /// The fastest streamed plan within this many arena bytes: the least [`Fusion`] (fusing
    /// the kmix/tmix heads recomputes them per refinement branch) whose arena fits, else the
    /// smallest ([`Memory::Streamed`]); [`Plan::arena_bytes`] says whether it fits.
    Budget(usize),
    /// Every op's output stored whole (for observers that compare every tensor).
    Whole,
}

/// Where a run's inputs and output live.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Io {
    /// In the caller's buffers: `Engine::run` copies the inputs into the arena and the output
    /// out of it (or the refinement writes the caller's output directly).
    #[default]
    Caller,
    /// In the arena: the caller writes the RGB frame (`3·H·W` bytes) and the sparse depth
    /// (`H·W` f32) into two staging areas of the arena (`Engine::staging`), placed at step 0
    /// beside the int8 inputs they are converted into (free bytes wherever the arena peaks
    /// later, which it does for the shipped networks), and reads the dense depth from the
    /// arena after the run (`Engine::output_m`, or as millimetres `Engine::output_mm`). Where
    /// the refinement would write the caller's output ([`Plan::output_in_arena`] false), an
    /// f32 output area of `4·H·W` bytes follows the activations ([`Plan::output_tail_bytes`]).
    /// The caller holds no frame-sized buffer at all; the bits are those of [`Io::Caller`].
    Arena,
}

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

/// A refinement that runs producers of its inputs row by row ([`Memory::Streamed`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FusedRefine {
    /// The refine op.
    pub refine: u16,
    /// The conv heads of the affinities of kernels 3, 5 and 7.
    pub aff: [u16; 3],
    /// The kmix and tmix conv heads, where they are fused too.
    pub mix: Option<[u16; 2]>,
    /// The `upsample_bilinear` giving `D_0`, where it is fused too.
    pub depth: Option<u16>,
    /// How the refine's scratch is laid out.
    pub scratch: RefineScratch,
}

impl FusedRefine {
    /// Every fused op.
    fn ops(&self) -> impl Iterator<Item = u16> + '_ {
        let mix = self.mix.into_iter().flatten();
        self.aff.iter().copied().chain(mix).chain(self.depth)
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
    /// Refinements with fused producers.
    fused: Vec<FusedRefine, MAX_FUSED>,
    /// Whether the graph's output is a tensor of the arena (else the caller's f32 buffer).
    output_in_arena: bool,
    /// What the plan fuses into refinements.
    fusion: Fusion,
    /// Concats read in place: (concat op, the conv that reads its parts).
    in_place: Vec<(u16, u16), MAX_IN_PLACE>,
    /// Whether convs compute their per-channel constants per run in their scratch.
    per_run_consts: bool,
    /// [`Io::Arena`]: the staging areas are the last two requests.
    io: Io,
    /// Tensors written over another tensor's bytes: (output of a `mul`, its first operand).
    aliases: Vec<(u16, u16), MAX_ALIASES>,
    /// The order the ops run in (op indices; a topological order of the graph: the blob's,
    /// with some ops deferred, see [`Plan::order`]).
    order: Vec<u8, MAX_OPS>,
    persistent_bytes: usize,
    activation_bytes: usize,
    macs: u64,
}

impl Plan {
    /// A plan of nothing (every table empty), to be filled by [`plan_with_into`].
    pub const fn empty() -> Plan {
        Plan {
            height: 0,
            width: 0,
            n_tensors: 0,
            shapes: Vec::new(),
            reqs: Vec::new(),
            offsets: Vec::new(),
            consts: Vec::new(),
            broadcast: Vec::new(),
            fused: Vec::new(),
            output_in_arena: true,
            fusion: Fusion::None,
            in_place: Vec::new(),
            per_run_consts: false,
            io: Io::Caller,
            order: Vec::new(),
            aliases: Vec::new(),
            persistent_bytes: 0,
            activation_bytes: 0,
            macs: 0,
        }
    }

    /// Total arena bytes the caller must provide (includes up to 15 bytes of base alignment).
    pub fn arena_bytes(&self) -> usize {
        ALIGN - 1 + self.persistent_bytes + self.activation_bytes + self.output_tail_bytes()
    }
    /// The op indices in the order they run: the blob's order, except that an op whose output
    /// is larger than its inputs and is first read much later may run just before that reader
    /// ([`Memory::Streamed`] and [`Memory::Budget`], where that lowers the arena; the bits do not
    /// change: every op computes the same values from the same inputs).
    pub fn order(&self) -> impl Iterator<Item = usize> + '_ {
        self.order.iter().map(|&i| usize::from(i))
    }
    /// Where the inputs and the output live ([`Io`]).
    pub fn io(&self) -> Io {
        self.io
    }
    /// [`Io::Arena`]: byte ranges in the activation region of the RGB staging area (`3·H·W`
    /// bytes) and of the sparse-depth staging area (`4·H·W` bytes, f32); `None` otherwise.
    pub fn staging(&self) -> Option<(Range<usize>, Range<usize>)> {
        if self.io != Io::Arena {
            return None;
        }
        let n = self.reqs.len();
        let range = |i: usize| {
            let (r, o) = (self.reqs.get(i)?, self.offsets.get(i)?);
            Some(*o..*o + r.bytes)
        };
        Some((range(n.checked_sub(2)?)?, range(n - 1)?))
    }
    /// [`Io::Arena`] where the output is not a tensor of the arena: bytes of the f32 output
    /// area after the activations (0 otherwise).
    pub fn output_tail_bytes(&self) -> usize {
        if self.io == Io::Arena && !self.output_in_arena {
            round_up(self.height * self.width * 4).unwrap_or(usize::MAX)
        } else {
            0
        }
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
    /// All tensor shapes, by tensor id.
    pub(crate) fn shapes(&self) -> &[Shape] {
        &self.shapes
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
        let mut id = id;
        // An in-place output has its operand's bytes (chains end within MAX_ALIASES steps).
        for _ in 0..MAX_ALIASES {
            match self.in_place_of(id) {
                Some(src) => id = src,
                None => break,
            }
        }
        let i = id as usize;
        if i >= self.n_tensors {
            return None;
        }
        let (r, o) = (self.reqs.get(i)?, self.offsets.get(i)?);
        Some(*o..*o + r.bytes)
    }
    /// For a tensor that a `mul` writes over its first operand ([`Memory::Streamed`] and
    /// [`Memory::Budget`], where that operand is read by nothing later): that operand.
    pub fn in_place_of(&self, id: u16) -> Option<u16> {
        self.aliases
            .iter()
            .find(|&&(out, _)| out == id)
            .map(|&(_, src)| src)
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
    /// The op that runs op `op` inside itself: the refine that runs it row by row, or the conv
    /// that reads a concat's parts in place (`None`: it runs on its own).
    pub fn fused_into(&self, op: usize) -> Option<usize> {
        let head = self
            .fused
            .iter()
            .find(|f| f.ops().any(|j| usize::from(j) == op))
            .map(|f| usize::from(f.refine));
        head.or_else(|| {
            self.in_place
                .iter()
                .find(|&&(c, _)| usize::from(c) == op)
                .map(|&(_, j)| usize::from(j))
        })
    }
    /// Bytes at the head of conv op `op`'s scratch that hold its per-channel constants, computed
    /// per run ([`Memory::Streamed`]; 0 where they sit in the persistent region).
    pub fn channel_bytes(&self, graph: &Graph, op: usize) -> usize {
        let Some(o) = graph.ops.get(op) else {
            return 0;
        };
        if !self.per_run_consts || !matches!(o.code, opcode::CONV2D | opcode::LINEAR) {
            return 0;
        }
        let out_c = graph
            .tensors
            .get(o.output as usize)
            .map_or(0, |t| t.channels);
        round_up(out_c * size_of::<ChannelQuant>()).unwrap_or(0)
    }
    /// For a conv that reads a concat's parts in place, the concat op.
    pub fn concat_in_place(&self, conv: usize) -> Option<usize> {
        self.in_place
            .iter()
            .find(|&&(_, j)| usize::from(j) == conv)
            .map(|&(c, _)| usize::from(c))
    }
    /// For a refine op with fused affinity heads, the head ops of kernels 3, 5 and 7.
    pub fn fused_heads(&self, op: usize) -> Option<[usize; 3]> {
        self.fused_refine(op).map(|f| f.aff.map(usize::from))
    }
    /// For a refine op with fused producers, what is fused into it.
    pub fn fused_refine(&self, op: usize) -> Option<FusedRefine> {
        self.fused
            .iter()
            .find(|f| usize::from(f.refine) == op)
            .copied()
    }
    /// What the plan fuses into refinements (the level [`plan_with`] chose).
    pub fn fusion(&self) -> Fusion {
        self.fusion
    }
    /// Whether the graph's output lives in the arena ([`Memory::Whole`]) or is written by its
    /// producer straight into the caller's f32 output ([`Memory::Streamed`]).
    pub fn output_in_arena(&self) -> bool {
        self.output_in_arena
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

/// Most rounds of [`place`]'s search, per starting order.
pub const PLACE_ROUNDS: usize = 64;
/// Starting orders [`place`] tries (decreasing size × lifetime; earliest first use; earliest
/// last use).
pub const PLACE_STARTS: usize = 3;

/// Places buffers: each in turn at the lowest offset that does not overlap a placed buffer
/// alive at the same time (TFLite Micro's greedy planner), starting from the order largest
/// first by bytes × lifetime (then, unless that reached the bound below, by first use and by
/// last use); then,
/// for up to [`PLACE_ROUNDS`] rounds or until the total equals the bytes live at the busiest
/// step (no placement needs fewer), the buffer that reaches the top is moved to the
/// front of the order and everything placed again. Keeps the order with the smallest total (the
/// first such). Buffers alive at step 0 alone (the staging areas of [`Io::Arena`]) are placed
/// after all others, into the gaps at step 0. Writes one offset per request and returns the
/// total bytes; deterministic. Offsets are multiples of [`ALIGN`] when the sizes are.
pub fn place(reqs: &[BufferReq], offsets: &mut [usize]) -> Result<usize, PlanError> {
    if reqs.len() > MAX_BUFFERS || offsets.len() < reqs.len() {
        return Err(PlanError::TooLarge);
    }
    let mut order: Vec<u16, MAX_BUFFERS> = Vec::new();
    // Buffers of step 0 alone (the staging areas of `Io::Arena`) are placed last, into the
    // gaps at step 0, so that they never change where the others go.
    let first_only = |r: &BufferReq| r.first == 0 && r.last == 0;
    for (i, r) in reqs.iter().enumerate() {
        offsets[i] = 0;
        if r.bytes > 0 && !first_only(r) {
            order.push(i as u16).map_err(|_| PlanError::TooLarge)?;
        }
    }
    // No placement needs fewer bytes than are live at the busiest step: stop there.
    let bound = live_bound(reqs);
    let life = |r: &BufferReq| r.last - r.first.min(r.last) + 1;
    let mut best = (usize::MAX, order.clone());
    // Starting orders, each improved by the rounds below: decreasing size × lifetime (bytes ·
    // steps), earliest first use, earliest last use; ties by size, earlier first use, index. The
    // smallest total is kept; the search stops at the bound (nothing is smaller).
    for start in 0..PLACE_STARTS {
        order.sort_unstable_by(|&a, &b| {
            let (ra, rb) = (&reqs[a as usize], &reqs[b as usize]);
            let key = |r: &BufferReq| match start {
                0 => r.bytes.saturating_mul(life(r)),
                1 => usize::MAX - r.first,
                _ => usize::MAX - r.last,
            };
            key(rb)
                .cmp(&key(ra))
                .then(rb.bytes.cmp(&ra.bytes))
                .then(ra.first.cmp(&rb.first))
                .then(a.cmp(&b))
        });
        for _ in 0..PLACE_ROUNDS {
            let total = place_in(reqs, offsets, &order)?;
            if total < best.0 {
                best = (total, order.clone());
            }
            if total <= bound {
                break;
            }
            let end = |i: u16| offsets[i as usize] + reqs[i as usize].bytes;
            let Some(top) = order.iter().position(|&i| end(i) == total) else {
                break;
            };
            if top == 0 {
                break;
            }
            let i = order.remove(top);
            order.insert(0, i).map_err(|_| PlanError::TooLarge)?;
        }
        if best.0 <= bound {
            break;
        }
    }
    let mut order = best.1;
    for (i, r) in reqs.iter().enumerate() {
        if r.bytes > 0 && first_only(r) {
            order.push(i as u16).map_err(|_| PlanError::TooLarge)?;
        }
    }
    place_in(reqs, offsets, &order)
}

/// The bytes live at the busiest step: no placement of `reqs` needs fewer.
fn live_bound(reqs: &[BufferReq]) -> usize {
    let steps = reqs
        .iter()
        .map(|r| r.last.saturating_add(1))
        .max()
        .unwrap_or(0);
    (0..steps)
        .map(|t| {
            reqs.iter()
                .filter(|r| r.first <= t && t <= r.last)
                .map(|r| r.bytes)
                .sum::<usize>()
        })
        .max()
        .unwrap_or(0)
}

/// Places the buffers of `order` one by one at the lowest offset that does not overlap an
/// already-placed buffer alive at the same time; returns the total.
fn place_in(reqs: &[BufferReq], offsets: &mut [usize], order: &[u16]) -> Result<usize, PlanError> {
    let mut total = 0usize;
    for (k, &i) in order.iter().enumerate() {
        let r = reqs[i as usize];
        let mut conflicts: Vec<(usize, usize), MAX_BUFFERS> = Vec::new();
        // The buffers placed so far are the order's first k.
        for &j in &order[..k] {
            let q = reqs[j as usize];
            if q.first <= r.last && r.first <= q.last {
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
    }
    Ok(total)
}

/// Output shape, scratch bytes, constant bytes, broadcast and MACs of one op (each op's
/// file in `crate::ops` fills it).
pub(crate) struct OpPlan {
    /// Output shape.
    pub out: Shape,
    /// Scratch bytes.
    pub scratch: usize,
    /// Persistent constant bytes.
    pub consts: usize,
    /// How a `mul`'s second operand broadcasts.
    pub broadcast: Broadcast,
    /// Multiply-accumulates.
    pub macs: u64,
}

fn plan_op(i: usize, op: &OpInfo, g: &Graph, shapes: &[Shape]) -> Result<OpPlan, PlanError> {
    let err = |what| PlanError::Shape { op: i, what };
    let x = shapes
        .get(op.inputs[0] as usize)
        .copied()
        .ok_or(err("input shape unknown"))?;
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
    let kind = Kind::of(op.code).ok_or(err("op attributes do not match the opcode"))?;
    let c = PlanCtx {
        g,
        i,
        op,
        shapes,
        x,
        out_c,
    };
    kind.plan(&c, &mut p)?;
    if p.out.len().is_none_or(|n| n == 0) {
        return Err(err("empty or overflowing output"));
    }
    Ok(p)
}

/// Byte layout of a fused refinement's scratch, in this order: the f32 windows, the
/// affinity ring, the affinity heads' per-channel constants, the affinity heads' conv scratch,
/// then (where the mixing heads are fused) for kmix and tmix each: ring, constants, conv
/// scratch. Every part is a multiple of [`ALIGN`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RefineScratch {
    /// f32 windows ([`refine::scratch_len`]).
    pub windows: usize,
    /// The affinity ring ([`refine::ring_bytes`]).
    pub ring: usize,
    /// Per-channel constants of the affinity heads of kernels 3, 5, 7.
    pub aff_consts: [usize; 3],
    /// Conv scratch shared by the affinity heads.
    pub aff_conv: usize,
    /// Per mixing head (kmix, tmix): ring, per-channel constants, conv scratch (0 unfused).
    pub mix: [[usize; 3]; 2],
}

impl RefineScratch {
    /// All bytes.
    pub fn total(&self) -> Result<usize, PlanError> {
        let mut parts = [self.windows, self.ring, self.aff_conv]
            .into_iter()
            .chain(self.aff_consts)
            .chain(self.mix.iter().flatten().copied());
        parts.try_fold(0usize, |a, b| a.checked_add(b).ok_or(PlanError::TooLarge))
    }
}

fn refine_scratch(
    f: &FusedRefine,
    (h, w): (usize, usize),
    attrs: &refine::RefineAttrs,
    head_scratch: &[usize],
    head_consts: &[usize],
) -> Result<RefineScratch, PlanError> {
    let at = |v: &[usize], j: u16| v.get(usize::from(j)).copied().unwrap_or(0);
    let bytes = |n: usize| {
        n.checked_mul(4)
            .ok_or(PlanError::TooLarge)
            .and_then(round_up)
    };
    let mut s = RefineScratch {
        windows: bytes(refine::scratch_len(w, attrs.iterations))?,
        ring: round_up(refine::ring_bytes(h, w, attrs))?,
        aff_consts: f.aff.map(|j| at(head_consts, j)),
        aff_conv: round_up(
            f.aff
                .iter()
                .map(|&j| at(head_scratch, j))
                .max()
                .unwrap_or(0),
        )?,
        mix: [[0; 3]; 2],
    };
    if let Some(mix) = f.mix {
        let ring = round_up(refine::MixConvRows::ring_bytes(h, w, attrs.iterations))?;
        for (m, &j) in s.mix.iter_mut().zip(&mix) {
            *m = [ring, at(head_consts, j), round_up(at(head_scratch, j))?];
        }
    }
    Ok(s)
}

/// Plans `graph` for an input of `h × w` with [`Memory::Streamed`] (see the module doc).
pub fn plan(graph: &Graph, h: usize, w: usize) -> Result<Plan, PlanError> {
    plan_with(graph, h, w, Memory::Streamed)
}

/// Per op, the op it can be fused into: a `conv2d` whose output is one of the three affinity
/// inputs of a `refine` and read by nothing else, where all three are such convs, goes into the
/// refine; a `concat` read only by a `conv2d` with one group (not itself fused) goes into that
/// conv, which reads its parts in place. Only int8 convs and int8 concat outputs fuse (int16
/// values run unfused, `crate::kernels::wide`); an int16 part of such a concat is requantised into
/// the conv's scratch first ([`wide_parts_bytes`]).
fn fusable(graph: &Graph, fusion: Fusion) -> Result<Vec<Option<u16>, MAX_OPS>, PlanError> {
    let n_ops = graph.ops.len();
    let mut fused: Vec<Option<u16>, MAX_OPS> = Vec::new();
    fused.resize(n_ops, None).map_err(|_| PlanError::TooLarge)?;
    let mut readers: Vec<u16, MAX_TENSORS> = Vec::new();
    readers
        .resize(graph.tensors.len(), 0)
        .map_err(|_| PlanError::TooLarge)?;
    let mut producer: Vec<Option<u16>, MAX_TENSORS> = Vec::new();
    producer
        .resize(graph.tensors.len(), None)
        .map_err(|_| PlanError::TooLarge)?;
    for (i, op) in graph.ops.iter().enumerate() {
        for &id in &op.inputs {
            if let Some(r) = readers.get_mut(id as usize) {
                *r = r.saturating_add(1);
            }
        }
        if let Some(p) = producer.get_mut(op.output as usize) {
            *p = Some(i as u16);
        }
    }
    // Fused heads and in-place reads run the int8 kernels only.
    let int8 = |id: u16| {
        graph
            .tensors
            .get(id as usize)
            .is_some_and(|x| x.dtype == DType::I8)
    };
    let mut count = 0;
    for (i, op) in graph.ops.iter().enumerate() {
        if op.code != opcode::REFINE || op.inputs.len() != 6 {
            continue;
        }
        let mut heads = [0u16; 3];
        let ok = op.inputs[1..4].iter().zip(&mut heads).all(|(&t, head)| {
            let Some(Some(p)) = producer.get(t as usize).copied() else {
                return false;
            };
            *head = p;
            let conv = &graph.ops[p as usize];
            conv.code == opcode::CONV2D
                && readers.get(t as usize) == Some(&1)
                && t != graph.output
                && int8(t)
                && int8(conv.inputs[0])
        });
        if !ok || count == MAX_FUSED || fusion == Fusion::None {
            continue;
        }
        count += 1;
        for h in heads {
            fused[h as usize] = Some(i as u16);
        }
        if fusion != Fusion::All {
            continue;
        }
        // kmix and tmix: 3-channel int8 convs read only here.
        let only_here = |t: u16| readers.get(t as usize) == Some(&1) && t != graph.output;
        let tensor = |t: u16| graph.tensors.get(t as usize);
        let producer_of = |t: u16| producer.get(t as usize).copied().flatten();
        let mix = op.inputs[4..6].iter().map(|&t| {
            let p = producer_of(t)?;
            let conv = &graph.ops[p as usize];
            let conv = conv.code == opcode::CONV2D && int8(conv.inputs[0]);
            let ok = tensor(t).is_some_and(|x| x.dtype == DType::I8 && x.channels == 3);
            (conv && ok && only_here(t)).then_some(p)
        });
        let mix: Vec<u16, 2> = mix.flatten().collect();
        if mix.len() == 2 {
            for &h in &mix {
                fused[h as usize] = Some(i as u16);
            }
        }
        // D_0: a one-channel f32 upsample of a one-channel f32 tensor, read only here.
        let d0 = op.inputs[0];
        if let Some(p) = producer_of(d0) {
            let up = &graph.ops[p as usize];
            let f32_1 =
                |t: u16| tensor(t).is_some_and(|x| x.dtype == DType::F32 && x.channels == 1);
            if up.code == opcode::UPSAMPLE_BILINEAR
                && f32_1(d0)
                && f32_1(up.inputs[0])
                && only_here(d0)
            {
                fused[p as usize] = Some(i as u16);
            }
        }
    }
    // An int16 part is requantised into the conv's scratch first (`wide_parts_bytes`).
    let int8_or_16 = |id: u16| {
        graph
            .tensors
            .get(id as usize)
            .is_some_and(|x| matches!(x.dtype, DType::I8 | DType::I16))
    };
    let mut count = 0;
    for op in graph.ops.iter() {
        let t = op.output as usize;
        if op.code != opcode::CONCAT
            || readers.get(t) != Some(&1)
            || op.output == graph.output
            || !int8(op.output)
            || !op.inputs.iter().all(|&id| int8_or_16(id))
            || op.inputs.len() > MAX_PARTS
            || count == MAX_IN_PLACE
        {
            continue;
        }
        let Some(j) = graph.ops.iter().position(|o| o.inputs.contains(&op.output)) else {
            continue;
        };
        let reader = &graph.ops[j];
        let one_group =
            matches!(&reader.attrs, Attrs::Conv { geometry, .. } if geometry.get().groups == 1);
        if reader.code == opcode::CONV2D
            && reader.inputs[0] == op.output
            && int8(reader.output)
            && one_group
            && fused[j].is_none()
        {
            let Some(c) = producer.get(t).copied().flatten() else {
                continue;
            };
            fused[c as usize] = Some(j as u16);
            count += 1;
        }
    }
    Ok(fused)
}

/// Plans `graph` for an input of `h × w` with the given [`Memory`] choice. Pure: reads only its
/// arguments.
///
/// [`Memory::Streamed`] plans every [`Fusion`] level and keeps the one needing the fewest arena
/// bytes (the most fused where they tie): on small images a ring can hold more than the map it
/// replaces.
pub fn plan_with(graph: &Graph, h: usize, w: usize, memory: Memory) -> Result<Plan, PlanError> {
    let mut p = Plan::empty();
    plan_with_into(&mut p, graph, (h, w), memory, Io::Caller)?;
    Ok(p)
}

/// As [`plan_with`] at `(h, w)` with the inputs and output `io`, into the caller's `plan` (its
/// tables are reused, so no plan-sized value sits on the stack: for an engine built in place).
/// On an error `plan` holds a partial plan: do not use it.
#[inline(never)]
pub fn plan_with_into(
    plan: &mut Plan,
    graph: &Graph,
    (h, w): (usize, usize),
    memory: Memory,
    io: Io,
) -> Result<(), PlanError> {
    plan.io = io;
    let budget = match memory {
        Memory::Whole => {
            let search = Placement::Search;
            return plan_fused(plan, graph, (h, w), memory, Fusion::None, false, search);
        }
        Memory::Streamed => 0,
        Memory::Budget(bytes) => bytes,
    };
    let mut best: Option<(usize, Fusion, bool)> = None;
    let mut last = None;
    for fusion in [Fusion::All, Fusion::Affinities, Fusion::None] {
        // Each level with ops deferred and in the blob's op order, the latter where smaller; it
        // is placed only where its lower bound (the bytes live at its busiest step) is.
        plan_fused(plan, graph, (h, w), memory, fusion, true, Placement::Search)?;
        let mut level = (plan.arena_bytes(), true);
        plan_fused(plan, graph, (h, w), memory, fusion, false, Placement::Bound)?;
        last = None; // a bound only: not a usable plan
        if plan.arena_bytes() < level.0 {
            plan_fused(
                plan,
                graph,
                (h, w),
                memory,
                fusion,
                false,
                Placement::Search,
            )?;
            last = Some((fusion, false));
            if plan.arena_bytes() < level.0 {
                level = (plan.arena_bytes(), false);
            }
        }
        let (bytes, defer) = level;
        let fits = bytes <= budget;
        // Smallest first; within the budget, the least fused (the last that fits).
        if best.is_none_or(|(b, ..)| bytes < b || (fits && b <= budget)) {
            best = Some((bytes, fusion, defer));
        }
    }
    let (_, fusion, defer) = best.ok_or(PlanError::TooLarge)?;
    if last != Some((fusion, defer)) {
        plan_fused(
            plan,
            graph,
            (h, w),
            memory,
            fusion,
            defer,
            Placement::Search,
        )?;
    }
    Ok(())
}

/// What a [`Memory::Streamed`] plan fuses into a refinement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fusion {
    /// Its affinity heads, kmix/tmix heads and `D_0`'s upsample, where they qualify.
    All,
    /// Its affinity heads only.
    Affinities,
    /// Nothing.
    None,
}

/// Bytes a conv reading concat op `concat`'s parts in place needs at the end of its scratch for
/// the int16 parts, each requantised to the concat's int8 codes there before the conv runs (as the
/// concat would write them): `C·H·W` bytes per int16 part, each rounded to [`ALIGN`].
pub(crate) fn wide_parts_bytes(
    graph: &Graph,
    shapes: &[Shape],
    concat: usize,
) -> Result<usize, PlanError> {
    let Some(op) = graph.ops.get(concat) else {
        return Ok(0);
    };
    let mut total = 0usize;
    for &id in &op.inputs {
        if graph.tensors.get(usize::from(id)).map(|t| t.dtype) != Some(DType::I16) {
            continue;
        }
        let n = shapes
            .get(usize::from(id))
            .and_then(|s| s.len())
            .ok_or(PlanError::TooLarge)?;
        total = total.checked_add(round_up(n)?).ok_or(PlanError::TooLarge)?;
    }
    Ok(total)
}

/// Writes the order the ops run in: the blob's, and with `defer`, each op that runs on its own,
/// whose output has more bytes than all its inputs together and is first read more than one op
/// later, moved to run just before that first reader (its output then lives for a step instead
/// of the whole gap, its inputs a little longer). Topological: an op only moves later, never past
/// a reader of its output.
fn run_order(
    graph: &Graph,
    shapes: &[Shape],
    fused_into: &[Option<u16>],
    defer: bool,
    order: &mut Vec<u8, MAX_OPS>,
) -> Result<(), PlanError> {
    let n_ops = graph.ops.len();
    order.clear();
    for i in 0..n_ops {
        order
            .push(u8::try_from(i).map_err(|_| PlanError::TooLarge)?)
            .map_err(|_| PlanError::TooLarge)?;
    }
    if !defer {
        return Ok(());
    }
    let bytes = |t: u16| -> usize {
        let elem = graph
            .tensors
            .get(usize::from(t))
            .map_or(4, |x| match x.dtype {
                DType::I8 => 1,
                DType::I16 => 2,
                DType::F32 => 4,
            });
        shapes
            .get(usize::from(t))
            .and_then(|s| s.len())
            .map_or(usize::MAX, |n| n.saturating_mul(elem))
    };
    for (x, op) in graph.ops.iter().enumerate() {
        if fused_into.get(x).copied().flatten().is_some()
            || op.code == opcode::REFINE
            || op.output == graph.output
        {
            continue;
        }
        let Some(reader) = (x + 1..n_ops).find(|&j| graph.ops[j].inputs.contains(&op.output))
        else {
            continue;
        };
        let ins: usize = op
            .inputs
            .iter()
            .map(|&t| bytes(t))
            .fold(0, usize::saturating_add);
        if reader <= x + 1 || bytes(op.output) <= ins {
            continue;
        }
        let Some(from) = order.iter().position(|&k| usize::from(k) == x) else {
            continue;
        };
        let moved = order.remove(from);
        let Some(to) = order.iter().position(|&k| usize::from(k) == reader) else {
            return Err(PlanError::TooLarge);
        };
        order.insert(to, moved).map_err(|_| PlanError::TooLarge)?;
    }
    Ok(())
}

/// Whether [`plan_fused`] places the buffers or only bounds the activation bytes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Placement {
    /// [`place`]: offsets and the total.
    Search,
    /// The bytes live at the busiest step (a lower bound of the total; the offsets are unset
    /// and the plan is not usable).
    Bound,
}

/// [`plan_with`] at one [`Fusion`] level. Out of line: its tables (≈ 12 KiB on 32-bit Arm) live
/// in its own frame only while it runs, not in every caller's.
#[inline(never)]
fn plan_fused(
    plan: &mut Plan,
    graph: &Graph,
    (h, w): (usize, usize),
    memory: Memory,
    fusion: Fusion,
    defer: bool,
    placement: Placement,
) -> Result<(), PlanError> {
    let Plan {
        shapes,
        reqs,
        offsets,
        consts,
        broadcast,
        fused,
        in_place,
        order,
        aliases,
        ..
    } = plan;
    order.clear();
    aliases.clear();
    reqs.clear();
    offsets.clear();
    shapes.clear();
    consts.clear();
    broadcast.clear();
    fused.clear();
    in_place.clear();
    let n_t = graph.tensors.len();
    let n_ops = graph.ops.len();
    let fused_into = match memory {
        Memory::Streamed | Memory::Budget(_) => fusable(graph, fusion)?,
        Memory::Whole => {
            let mut v: Vec<Option<u16>, MAX_OPS> = Vec::new();
            v.resize(n_ops, None).map_err(|_| PlanError::TooLarge)?;
            v
        }
    };
    // Scratch bytes of each fused head (run inside its refinement, which holds it).
    let per_run_consts = memory != Memory::Whole;
    let mut head_consts: Vec<usize, MAX_OPS> = Vec::new();
    head_consts
        .resize(n_ops, 0)
        .map_err(|_| PlanError::TooLarge)?;
    let mut head_scratch: Vec<usize, MAX_OPS> = Vec::new();
    head_scratch
        .resize(n_ops, 0)
        .map_err(|_| PlanError::TooLarge)?;
    let zero = Shape::default();
    shapes.resize(n_t, zero).map_err(|_| PlanError::TooLarge)?;
    shapes[graph.rgb as usize] = Shape::new(3, h, w);
    shapes[graph.sparse as usize] = Shape::new(1, h, w);
    let staged = plan.io == Io::Arena;
    let n_reqs = n_t + n_ops + if staged { 2 } else { 0 };
    reqs.resize(n_reqs, BufferReq::default())
        .map_err(|_| PlanError::TooLarge)?;
    let last_step = n_ops + 1;
    let mut persistent = 0usize;
    let mut macs = 0u64;
    // Shapes first (in the blob's order, which is topological), then the run order.
    for (i, op) in graph.ops.iter().enumerate() {
        shapes[op.output as usize] = plan_op(i, op, graph, shapes)?.out;
    }
    run_order(graph, shapes, &fused_into, defer, order)?;
    consts
        .resize(n_ops, 0..0)
        .map_err(|_| PlanError::TooLarge)?;
    broadcast
        .resize(n_ops, Broadcast::None)
        .map_err(|_| PlanError::TooLarge)?;
    for (pos, &i) in order.iter().enumerate() {
        let i = usize::from(i);
        let op = &graph.ops[i];
        let mut p = plan_op(i, op, graph, shapes)?;
        let step = pos + 1;
        let conv = matches!(op.code, opcode::CONV2D | opcode::LINEAR);
        // Streamed: a conv's per-channel constants are computed per run at the head of its
        // scratch instead of being held in the persistent region.
        let channel_bytes = if conv && per_run_consts {
            round_up(core::mem::take(&mut p.consts))?
        } else {
            0
        };
        if fused_into[i].is_some() {
            head_scratch[i] = core::mem::take(&mut p.scratch);
            head_consts[i] = channel_bytes;
        } else if channel_bytes > 0 {
            p.scratch = round_up(p.scratch)?
                .checked_add(channel_bytes)
                .ok_or(PlanError::TooLarge)?;
        }
        if op.code == opcode::CONV2D {
            if let Some(c) = (0..i)
                .find(|&c| graph.ops[c].code == opcode::CONCAT && fused_into[c] == Some(i as u16))
            {
                in_place
                    .push((c as u16, i as u16))
                    .map_err(|_| PlanError::TooLarge)?;
                // Its int16 parts, requantised to int8 at the end of the conv's scratch.
                let wide = wide_parts_bytes(graph, shapes, c)?;
                if wide > 0 {
                    p.scratch = round_up(p.scratch)?
                        .checked_add(wide)
                        .ok_or(PlanError::TooLarge)?;
                }
                // The parts are read while the conv runs.
                for &id in &graph.ops[c].inputs {
                    reqs[id as usize].last = reqs[id as usize].last.max(step);
                }
            }
        }
        if let Attrs::Refine(attrs) = &op.attrs {
            let mine = |input: usize| -> Option<u16> {
                let t = *op.inputs.get(input)?;
                (0..i)
                    .find(|&j| graph.ops[j].output == t && fused_into[j] == Some(i as u16))
                    .map(|j| j as u16)
            };
            if let [Some(a), Some(b), Some(c)] = [mine(1), mine(2), mine(3)] {
                let mix = match [mine(4), mine(5)] {
                    [Some(k), Some(t)] => Some([k, t]),
                    _ => None,
                };
                let mut f = FusedRefine {
                    refine: i as u16,
                    aff: [a, b, c],
                    mix,
                    depth: mine(0),
                    scratch: RefineScratch::default(),
                };
                let hw = (p.out.h, p.out.w);
                f.scratch = refine_scratch(&f, hw, attrs, &head_scratch, &head_consts)?;
                p.scratch = f.scratch.total()?;
                fused.push(f).map_err(|_| PlanError::TooLarge)?;
                // The fused ops' inputs are read while the refinement runs.
                for j in f.ops() {
                    let input = graph.ops[j as usize].inputs[0] as usize;
                    reqs[input].last = reqs[input].last.max(step);
                }
            }
        }
        let cb = round_up(p.consts)?;
        consts[i] = persistent..persistent + p.consts;
        persistent = persistent.checked_add(cb).ok_or(PlanError::TooLarge)?;
        broadcast[i] = p.broadcast;
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
    // Streamed: a fused refinement producing the graph's output writes the caller's buffer.
    let output_in_arena = !fused.iter().any(|f| {
        graph
            .ops
            .get(usize::from(f.refine))
            .is_some_and(|o| o.output == graph.output)
    });
    for (t, info) in graph.tensors.iter().enumerate() {
        let elem = match info.dtype {
            DType::I8 => 1,
            DType::I16 => 2,
            DType::F32 => 4,
        };
        let n = shapes[t]
            .len()
            .and_then(|n| n.checked_mul(elem))
            .ok_or(PlanError::TooLarge)?;
        reqs[t].bytes = round_up(n)?;
    }
    for (op, f) in graph.ops.iter().zip(&fused_into) {
        if f.is_some() {
            reqs[op.output as usize].bytes = 0;
        }
    }
    if !output_in_arena {
        reqs[graph.output as usize].bytes = 0;
    }
    // A `mul` whose first operand nobody reads later writes over it (elementwise: each code is
    // read before it is written; `ops::mul::eval_in_place`).
    if memory != Memory::Whole {
        for (pos, &i) in order.iter().enumerate() {
            let op = &graph.ops[usize::from(i)];
            if op.code != opcode::MUL
                || fused_into[usize::from(i)].is_some()
                || op.output == graph.output
                || aliases.is_full()
            {
                continue;
            }
            let root = |mut t: u16| {
                while let Some(&(_, src)) = aliases.iter().find(|&&(o, _)| o == t) {
                    t = src;
                }
                t
            };
            let (a, b) = (op.inputs[0], op.inputs[1]);
            let src = root(a);
            let step = pos + 1;
            if src == graph.rgb
                || src == graph.sparse
                || root(b) == src
                || reqs[usize::from(src)].bytes == 0
                || reqs[usize::from(src)].last != step
                || reqs[usize::from(op.output)].bytes != reqs[usize::from(src)].bytes
            {
                continue;
            }
            let out = usize::from(op.output);
            reqs[usize::from(src)].last = reqs[out].last;
            reqs[out].bytes = 0;
            aliases
                .push((op.output, a))
                .map_err(|_| PlanError::TooLarge)?;
        }
    }
    // Io::Arena: the staging areas live at step 0 only (converted into the int8 inputs there);
    // an output outside the activations gets an area after them (`Plan::output_tail_bytes`).
    if staged {
        let pixels = h.checked_mul(w).ok_or(PlanError::TooLarge)?;
        for (k, elem) in [3usize, 4].into_iter().enumerate() {
            let bytes = pixels.checked_mul(elem).ok_or(PlanError::TooLarge)?;
            reqs[n_t + n_ops + k] = BufferReq {
                bytes: round_up(bytes)?,
                first: 0,
                last: 0,
            };
        }
    }
    offsets
        .resize(reqs.len(), 0)
        .map_err(|_| PlanError::TooLarge)?;
    let activation_bytes = match placement {
        Placement::Search => place(reqs, offsets)?,
        Placement::Bound => live_bound(reqs),
    };
    plan.height = h;
    plan.width = w;
    plan.n_tensors = n_t;
    plan.output_in_arena = output_in_arena;
    plan.fusion = fusion;
    plan.per_run_consts = per_run_consts;
    plan.persistent_bytes = persistent;
    plan.activation_bytes = activation_bytes;
    plan.macs = macs;
    Ok(())
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
