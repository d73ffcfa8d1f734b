//! [`Engine`]: prepare once (`new`), run many (`run`).

use super::cast::{view, view_mut, Pod};
use super::error::Error;
use super::plan::{plan_with, FusedRefine, Memory, Plan, ALIGN};
use crate::blob::format::{opcode, MAX_INPUTS};
use crate::blob::parse::{f32_at, i32_at, parse, Attrs, DType, Graph, OpInfo};
use crate::kernels::bins::{bin_centres, bins_head_i8, BinChannel, MAX_BINS};
use crate::kernels::conv::{
    conv2d_parts_with, conv2d_with, ChannelQuant, Conv2d, ConvQuant, OutRows,
};
use crate::kernels::elementwise::{self, AddQuant, MulQuant, Rescale};
use crate::kernels::isa::Isa;
use crate::kernels::pack::Parts;
use crate::kernels::pool::{self, MeanQuant};
use crate::kernels::refine::{
    refine_with, AffinityRows, ConvRows, DepthRows, Head, I8Map, MixConvRows, RefineAttrs, Sources,
    UpsampledDepth, WholeDepth, WholeMaps, WholeMix, KERNELS,
};
use crate::kernels::requant::QParams;
use crate::kernels::resize;
use crate::kernels::KernelError;
use core::ops::Range;

/// What one [`Engine::run`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunStats {
    /// Ops executed.
    pub ops: usize,
    /// Multiply-accumulates of the convs, linears and the bins head.
    pub macs: u64,
}

/// One op's output as [`Engine::run_observed`] shows it to its observer (a debugging aid: the
/// host quantizer compares every tensor with its float reference).
#[derive(Clone, Copy, Debug)]
pub enum Observed<'b> {
    /// An int8 tensor with its quantisation parameters (`real = scale · (q − zero_point)`).
    I8(&'b [i8], QParams),
    /// An f32 tensor (depth maps in metres).
    F32(&'b [f32]),
}

/// The callback [`Engine::run_observed`] calls after each op.
pub type Observer<'o> = dyn FnMut(usize, Observed<'_>) + 'o;

/// A prepared model: the parsed blob, its arena plan and the caller's arena holding the cached
/// constants. `Engine` itself holds the op and buffer tables (fixed capacity, no heap); its
/// size is `size_of::<Engine>()` (see the crate's engine tests), so on a microcontroller keep it
/// in a `static` rather than on a small stack.
pub struct Engine<'a> {
    graph: Graph<'a>,
    plan: Plan,
    arena: &'a mut [u8],
    rgb_lut: [i8; 256],
    isa: Isa,
}

/// Arena bytes `blob` needs at `height × width` (parses and plans; nothing runs), with the
/// default [`Memory::Streamed`] plan that [`Engine::new`] and [`Engine::with_size`] use.
pub fn required_arena_bytes(blob: &[u8], height: usize, width: usize) -> Result<usize, Error> {
    required_arena_bytes_with(blob, height, width, Memory::Streamed)
}

/// As [`required_arena_bytes`] for the plan `memory` ([`Engine::with_memory`]).
pub fn required_arena_bytes_with(
    blob: &[u8],
    height: usize,
    width: usize,
    memory: Memory,
) -> Result<usize, Error> {
    let g = parse(blob)?;
    Ok(plan_with(&g, height, width, memory)?.arena_bytes())
}

fn kerr(op: usize) -> impl Fn(KernelError) -> Error + Copy {
    move |error| Error::Kernel { op, error }
}

fn typed<T: Pod>(b: &[u8], op: usize) -> Result<&[T], Error> {
    view(b).ok_or(Error::Kernel {
        op,
        error: KernelError::Shape,
    })
}

fn typed_mut<T: Pod>(b: &mut [u8], op: usize) -> Result<&mut [T], Error> {
    view_mut(b).ok_or(Error::Kernel {
        op,
        error: KernelError::Shape,
    })
}

/// Splits `act` into two disjoint mutable ranges (`m1`, `m2`) and read-only `ins` (each of which
/// must lie outside both; the plan guarantees it, this checks it).
fn split<'b>(
    act: &'b mut [u8],
    m1: Range<usize>,
    m2: Range<usize>,
    ins: &[Range<usize>],
    out_ins: &mut [&'b [u8]; MAX_INPUTS],
    op: usize,
) -> Result<(&'b mut [u8], &'b mut [u8]), Error> {
    let bad = Error::Kernel {
        op,
        error: KernelError::Shape,
    };
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

impl<'a> Engine<'a> {
    /// Validates `blob` (format, CRC, every op), plans the arena for the blob's native input
    /// size and caches requantisation constants in `arena`.
    pub fn new(blob: &'a [u8], arena: &'a mut [u8]) -> Result<Engine<'a>, Error> {
        let g = parse(blob)?;
        let (h, w) = (g.height, g.width);
        Self::prepare(g, arena, h, w, Memory::Streamed)
    }

    /// As [`Engine::new`] for an input of `height × width` instead of the native size.
    pub fn with_size(
        blob: &'a [u8],
        arena: &'a mut [u8],
        height: usize,
        width: usize,
    ) -> Result<Engine<'a>, Error> {
        Self::prepare(parse(blob)?, arena, height, width, Memory::Streamed)
    }

    /// As [`Engine::with_size`] with the plan `memory`: [`Memory::Whole`] keeps every op's
    /// output whole, so that [`Engine::run_observed`] sees all of them (more arena).
    pub fn with_memory(
        blob: &'a [u8],
        arena: &'a mut [u8],
        height: usize,
        width: usize,
        memory: Memory,
    ) -> Result<Engine<'a>, Error> {
        Self::prepare(parse(blob)?, arena, height, width, memory)
    }

    fn prepare(
        graph: Graph<'a>,
        arena: &'a mut [u8],
        h: usize,
        w: usize,
        memory: Memory,
    ) -> Result<Engine<'a>, Error> {
        let plan = plan_with(&graph, h, w, memory)?;
        let have = arena.len();
        let need = plan.arena_bytes();
        let pad = arena.as_ptr().align_offset(ALIGN);
        let body = plan.persistent_bytes() + plan.activation_bytes();
        if pad >= ALIGN || have < pad + body {
            return Err(Error::ArenaTooSmall { need, have });
        }
        let arena = &mut arena[pad..pad + body];
        for (i, op) in graph.ops.iter().enumerate() {
            let r = plan.const_range(i).ok_or(Error::Kernel {
                op: i,
                error: KernelError::Shape,
            })?;
            let region = arena.get_mut(r).ok_or(Error::Kernel {
                op: i,
                error: KernelError::Shape,
            })?;
            write_consts(&graph, &plan, i, op, region)?;
        }
        let mut rgb_lut = [0i8; 256];
        let rq = graph.tensor(graph.rgb)?.q;
        for (v, q) in rgb_lut.iter_mut().enumerate() {
            *q = rq.quantize(v as f32 / 255.0);
        }
        Ok(Engine {
            graph,
            plan,
            arena,
            rgb_lut,
            isa: Isa::best(),
        })
    }

    /// The kernel set the convolutions run with (the fastest this CPU has, unless set).
    pub fn kernels(&self) -> Isa {
        self.isa
    }

    /// Runs the convolutions with kernel set `isa` (every set gives the same bits; this is for
    /// benchmarks and tests). `Err` if this CPU cannot run it.
    pub fn set_kernels(&mut self, isa: Isa) -> Result<(), Error> {
        if !isa.available() {
            return Err(Error::Kernel {
                op: 0,
                error: KernelError::Isa,
            });
        }
        self.isa = isa;
        Ok(())
    }

    /// Input size `(height, width)` this engine runs at.
    pub fn input_shape(&self) -> (usize, usize) {
        self.plan.size()
    }

    /// The arena plan.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// The parsed graph.
    pub fn graph(&self) -> &Graph<'a> {
        &self.graph
    }

    /// Runs one frame: `rgb` is RGB888 interleaved `H×W×3`, `sparse_m` the projected dToF depth
    /// `H×W` in metres (0 = no point), `out_depth_m` receives `H×W` metres (with the default
    /// [`Memory::Streamed`] plan the refinement accumulates straight into it, so the arena holds
    /// no output map).
    pub fn run(
        &mut self,
        rgb: &[u8],
        sparse_m: &[f32],
        out_depth_m: &mut [f32],
    ) -> Result<RunStats, Error> {
        self.run_with(rgb, Some(sparse_m), out_depth_m, None)
    }

    /// As [`Engine::run`] with one buffer for both depths: `depth_m` holds the sparse depth
    /// (metres, 0 = no point) when called and the dense depth when it returns (the sparse
    /// values are copied into the arena first). The least caller memory: `4·H·W` bytes.
    pub fn run_in_place(&mut self, rgb: &[u8], depth_m: &mut [f32]) -> Result<RunStats, Error> {
        self.run_with(rgb, None, depth_m, None)
    }

    /// As [`Engine::run`], calling `observer(op_index, output)` right after each op with that
    /// op's whole output tensor (before later ops may reuse its arena bytes). Ops fused into a
    /// streamed refinement ([`Memory::Streamed`]) run inside it and are not observed, nor is an
    /// output written straight into `out_depth_m`; build the engine with [`Memory::Whole`] to
    /// see every op.
    pub fn run_observed(
        &mut self,
        rgb: &[u8],
        sparse_m: &[f32],
        out_depth_m: &mut [f32],
        observer: &mut Observer<'_>,
    ) -> Result<RunStats, Error> {
        self.run_with(rgb, Some(sparse_m), out_depth_m, Some(observer))
    }

    /// `sparse`: the sparse depth, or `None` where `out` holds it.
    fn run_with(
        &mut self,
        rgb: &[u8],
        sparse: Option<&[f32]>,
        out: &mut [f32],
        observer: Option<&mut Observer<'_>>,
    ) -> Result<RunStats, Error> {
        let (h, w) = self.plan.size();
        let n = h * w;
        if let Some(s) = sparse {
            check_len("sparse_m", n, s.len())?;
        }
        check_len("out_depth_m", n, out.len())?;
        self.write_rgb(rgb)?;
        match sparse {
            Some(s) => self.write_sparse(|i| s[i])?,
            None => self.write_sparse(|i| out[i])?,
        }
        let stats = self.execute(observer, out)?;
        if self.plan.output_in_arena() {
            self.read_output(|i, v| out[i] = v)?;
        }
        Ok(stats)
    }

    fn act(&mut self) -> &mut [u8] {
        let p = self.plan.persistent_bytes();
        &mut self.arena[p..]
    }

    fn write_rgb(&mut self, rgb: &[u8]) -> Result<(), Error> {
        let (h, w) = self.plan.size();
        let n = h * w;
        check_len("rgb", 3 * n, rgb.len())?;
        let info = *self.graph.tensor(self.graph.rgb)?;
        let r = self
            .plan
            .tensor_range(self.graph.rgb)
            .ok_or(Error::Kernel {
                op: 0,
                error: KernelError::Shape,
            })?;
        let lut = self.rgb_lut;
        let buf = self.act().get_mut(r).ok_or(Error::Kernel {
            op: 0,
            error: KernelError::Shape,
        })?;
        match info.dtype {
            DType::I8 => {
                let t: &mut [i8] = typed_mut(buf, 0)?;
                for (i, px) in rgb.chunks_exact(3).enumerate().take(n) {
                    for c in 0..3 {
                        t[c * n + i] = lut[px[c] as usize];
                    }
                }
            }
            DType::F32 => {
                let t: &mut [f32] = typed_mut(buf, 0)?;
                for (i, px) in rgb.chunks_exact(3).enumerate().take(n) {
                    for c in 0..3 {
                        t[c * n + i] = px[c] as f32 / 255.0;
                    }
                }
            }
        }
        Ok(())
    }

    fn write_sparse(&mut self, get: impl Fn(usize) -> f32) -> Result<(), Error> {
        let (h, w) = self.plan.size();
        let info = *self.graph.tensor(self.graph.sparse)?;
        let r = self
            .plan
            .tensor_range(self.graph.sparse)
            .ok_or(Error::Kernel {
                op: 0,
                error: KernelError::Shape,
            })?;
        let buf = self.act().get_mut(r).ok_or(Error::Kernel {
            op: 0,
            error: KernelError::Shape,
        })?;
        match info.dtype {
            DType::I8 => {
                let t: &mut [i8] = typed_mut(buf, 0)?;
                for (i, v) in t.iter_mut().enumerate().take(h * w) {
                    *v = info.q.quantize(get(i));
                }
            }
            DType::F32 => {
                let t: &mut [f32] = typed_mut(buf, 0)?;
                for (i, v) in t.iter_mut().enumerate().take(h * w) {
                    *v = get(i);
                }
            }
        }
        Ok(())
    }

    fn read_output(&mut self, mut put: impl FnMut(usize, f32)) -> Result<(), Error> {
        let (h, w) = self.plan.size();
        let info = *self.graph.tensor(self.graph.output)?;
        let r = self
            .plan
            .tensor_range(self.graph.output)
            .ok_or(Error::Kernel {
                op: 0,
                error: KernelError::Shape,
            })?;
        let buf = self.act().get(r).ok_or(Error::Kernel {
            op: 0,
            error: KernelError::Shape,
        })?;
        match info.dtype {
            DType::I8 => {
                for (i, &q) in typed::<i8>(buf, 0)?.iter().enumerate().take(h * w) {
                    put(i, info.q.dequantize(q));
                }
            }
            DType::F32 => {
                for (i, &v) in typed::<f32>(buf, 0)?.iter().enumerate().take(h * w) {
                    put(i, v);
                }
            }
        }
        Ok(())
    }

    /// Runs every op; `ext` is the caller's f32 output (written by the graph's last op where the
    /// plan keeps the output out of the arena).
    fn execute(
        &mut self,
        mut observer: Option<&mut Observer<'_>>,
        ext: &mut [f32],
    ) -> Result<RunStats, Error> {
        let persistent = self.plan.persistent_bytes();
        let (consts, act) = self.arena.split_at_mut(persistent);
        for (i, op) in self.graph.ops.iter().enumerate() {
            if self.plan.fused_into(i).is_some() {
                continue; // runs row by row inside its refinement
            }
            exec(&self.graph, &self.plan, i, op, consts, act, ext, self.isa)?;
            if let Some(f) = observer.as_deref_mut() {
                observe(&self.graph, &self.plan, i, op, act, ext, f)?;
            }
        }
        Ok(RunStats {
            ops: self.graph.ops.len(),
            macs: self.plan.macs(),
        })
    }
}

/// Hands op `i`'s output tensor to `f`.
fn observe(
    g: &Graph,
    plan: &Plan,
    i: usize,
    op: &OpInfo,
    act: &[u8],
    ext: &[f32],
    f: &mut Observer<'_>,
) -> Result<(), Error> {
    let bad = Error::Kernel {
        op: i,
        error: KernelError::Shape,
    };
    let info = g.tensor(op.output)?;
    let n = plan.shape(op.output).and_then(|s| s.len()).ok_or(bad)?;
    if op.output == g.output && !plan.output_in_arena() {
        f(i, Observed::F32(ext.get(..n).ok_or(bad)?));
        return Ok(());
    }
    let buf = act
        .get(plan.tensor_range(op.output).ok_or(bad)?)
        .ok_or(bad)?;
    match info.dtype {
        DType::I8 => f(
            i,
            Observed::I8(typed::<i8>(buf, i)?.get(..n).ok_or(bad)?, info.q),
        ),
        DType::F32 => f(i, Observed::F32(typed::<f32>(buf, i)?.get(..n).ok_or(bad)?)),
    }
    Ok(())
}

fn check_len(what: &'static str, expected: usize, found: usize) -> Result<(), Error> {
    if expected != found {
        return Err(Error::ShapeMismatch {
            what,
            expected,
            found,
        });
    }
    Ok(())
}

/// Computes and stores op `i`'s constants (prepare time).
fn write_consts(
    g: &Graph,
    plan: &Plan,
    i: usize,
    op: &OpInfo,
    region: &mut [u8],
) -> Result<(), Error> {
    let q = |id: u16| g.tensor(id).map(|t| t.q);
    let out_q = q(op.output)?;
    let in_q = q(op.inputs[0])?;
    let shape = |id: u16| {
        plan.shape(id).ok_or(Error::Kernel {
            op: i,
            error: KernelError::Shape,
        })
    };
    match (op.code, &op.attrs) {
        (
            opcode::CONV2D | opcode::LINEAR,
            Attrs::Conv {
                act, bias, scales, ..
            },
        ) => {
            let _ = (act, bias, scales);
            fill_channel_quants(g, i, typed_mut(region, i)?)?;
        }
        (opcode::BINS_HEAD, Attrs::Bins { bias, scales, .. }) => {
            let dst: &mut [BinChannel] = typed_mut(region, i)?;
            let sb = g.bytes(*scales);
            for (o, bc) in dst.iter_mut().enumerate() {
                let b = bias.map_or(0, |p| i32_at(g.bytes(p), o));
                *bc = BinChannel {
                    bias: b,
                    scale: in_q.scale * f32_at(sb, o),
                };
            }
        }
        (opcode::ADD, _) => {
            let dst: &mut [AddQuant] = typed_mut(region, i)?;
            if let Some(d) = dst.first_mut() {
                *d = AddQuant::new(in_q, q(op.inputs[1])?, out_q);
            }
        }
        (opcode::MUL, _) => {
            let dst: &mut [MulQuant] = typed_mut(region, i)?;
            if let Some(d) = dst.first_mut() {
                *d = MulQuant::new(in_q, q(op.inputs[1])?, out_q);
            }
        }
        (opcode::CONCAT, _) => {
            let dst: &mut [Rescale] = typed_mut(region, i)?;
            for (d, &id) in dst.iter_mut().zip(&op.inputs) {
                *d = Rescale::new(q(id)?, out_q);
            }
        }
        (opcode::GLOBAL_AVG_POOL | opcode::CHANNEL_MEAN, _) => {
            let s = shape(op.inputs[0])?;
            let n = if op.code == opcode::CHANNEL_MEAN {
                s.c
            } else {
                s.h * s.w
            };
            let dst: &mut [MeanQuant] = typed_mut(region, i)?;
            if let Some(d) = dst.first_mut() {
                *d = MeanQuant::new(in_q, out_q, n);
            }
        }
        (opcode::GLOBAL_MAX_POOL | opcode::CHANNEL_MAX, _) => {
            let dst: &mut [Rescale] = typed_mut(region, i)?;
            if let Some(d) = dst.first_mut() {
                *d = Rescale::new(in_q, out_q);
            }
        }
        _ => {}
    }
    Ok(())
}

/// Writes conv op `i`'s per-channel requantisation constants into `dst` (one per output
/// channel that `dst` holds).
fn fill_channel_quants(g: &Graph, i: usize, dst: &mut [ChannelQuant]) -> Result<(), Error> {
    let bad = Error::Kernel {
        op: i,
        error: KernelError::Shape,
    };
    let op = g.ops.get(i).ok_or(bad)?;
    let Attrs::Conv {
        act, bias, scales, ..
    } = &op.attrs
    else {
        return Err(bad);
    };
    let (in_q, out_q) = (g.tensor(op.inputs[0])?.q, g.tensor(op.output)?.q);
    let sb = g.bytes(*scales);
    for (o, cq) in dst.iter_mut().enumerate() {
        let b = bias.map_or(0, |p| i32_at(g.bytes(p), o));
        *cq = ChannelQuant::new(b, in_q.scale, f32_at(sb, o), out_q.scale, *act);
    }
    Ok(())
}

/// Conv op `j`'s per-channel constants and the scratch its kernel may use: from the
/// persistent region, or computed now at the head of `scratch` ([`Plan::channel_bytes`]).
fn channel_quants<'s>(
    g: &Graph,
    plan: &Plan,
    j: usize,
    consts: &'s [u8],
    scratch: &'s mut [u8],
) -> Result<(&'s [ChannelQuant], &'s mut [u8]), Error> {
    let bad = Error::Kernel {
        op: j,
        error: KernelError::Shape,
    };
    let bytes = plan.channel_bytes(g, j);
    if bytes == 0 {
        let cb = consts.get(plan.const_range(j).ok_or(bad)?).ok_or(bad)?;
        return Ok((typed(cb, j)?, scratch));
    }
    if scratch.len() < bytes {
        return Err(bad);
    }
    let (head, rest) = scratch.split_at_mut(bytes);
    let out_c = g.tensor(g.ops.get(j).ok_or(bad)?.output)?.channels;
    let cq: &mut [ChannelQuant] = typed_mut(head, j)?;
    let cq = cq.get_mut(..out_c).ok_or(bad)?;
    fill_channel_quants(g, j, cq)?;
    Ok((cq, rest))
}

fn first<T: Pod + Default>(b: &[u8], op: usize) -> Result<T, Error> {
    typed::<T>(b, op)?.first().copied().ok_or(Error::Kernel {
        op,
        error: KernelError::Shape,
    })
}

/// Runs op `i` on the arena (run time; nothing is validated twice except cheap slice bounds);
/// `ext` is the caller's f32 output ([`Plan::output_in_arena`]).
#[allow(clippy::too_many_arguments)]
fn exec(
    g: &Graph,
    plan: &Plan,
    i: usize,
    op: &OpInfo,
    consts: &[u8],
    act: &mut [u8],
    ext: &mut [f32],
    isa: Isa,
) -> Result<(), Error> {
    if let Some(c) = plan.concat_in_place(i) {
        return exec_conv_on_parts(g, plan, i, c, consts, act, isa);
    }
    let e = kerr(i);
    let bad = Error::Kernel {
        op: i,
        error: KernelError::Shape,
    };
    let out_r = plan.tensor_range(op.output).ok_or(bad)?;
    let scr_r = plan.scratch_range(i).ok_or(bad)?;
    let mut in_r: [Range<usize>; MAX_INPUTS] = Default::default();
    for (r, &id) in in_r.iter_mut().zip(&op.inputs) {
        *r = plan.tensor_range(id).ok_or(bad)?;
    }
    let n_in = op.inputs.len();
    let mut ins: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
    let (out_b, scr_b) = split(act, out_r, scr_r, &in_r[..n_in], &mut ins, i)?;
    let cb = consts.get(plan.const_range(i).ok_or(bad)?).ok_or(bad)?;
    let shape = |id: u16| plan.shape(id).ok_or(bad);
    let tq = |id: u16| g.tensor(id).map(|t| t.q);
    let x_shape = shape(op.inputs[0])?;
    let out_shape = shape(op.output)?;
    let out_dtype = g.tensor(op.output)?.dtype;
    match (op.code, &op.attrs) {
        (
            opcode::CONV2D | opcode::LINEAR,
            Attrs::Conv {
                geometry,
                act,
                weights,
                ..
            },
        ) => {
            let (channels, scr_b) = channel_quants(g, plan, i, consts, scr_b)?;
            let conv = Conv2d {
                geometry: geometry.get(),
                quant: ConvQuant::new(
                    tq(op.inputs[0])?.zero_point,
                    tq(op.output)?.zero_point,
                    *act,
                ),
                weights: typed(g.bytes(*weights), i)?,
                channels,
            };
            conv2d_with(
                isa,
                &conv,
                typed(ins[0], i)?,
                x_shape,
                typed_mut(out_b, i)?,
                typed_mut(scr_b, i)?,
            )
            .map_err(e)?;
        }
        (
            opcode::RELU | opcode::LEAKY_RELU | opcode::SIGMOID | opcode::RECIPROCAL,
            Attrs::Lut(p),
        ) => {
            let t: &[i8; 256] = typed::<i8>(g.bytes(*p), i)?.try_into().map_err(|_| bad)?;
            elementwise::lut(typed(ins[0], i)?, t, typed_mut(out_b, i)?).map_err(e)?;
        }
        (opcode::ADD, _) => {
            let q: AddQuant = first(cb, i)?;
            let n = x_shape.len().ok_or(bad)?;
            let (a, b): (&[i8], &[i8]) = (typed(ins[0], i)?, typed(ins[1], i)?);
            let (a, b) = (a.get(..n).ok_or(bad)?, b.get(..n).ok_or(bad)?);
            elementwise::add(&q, a, b, typed_mut(out_b, i)?).map_err(e)?;
        }
        (opcode::MUL, _) => {
            let q: MulQuant = first(cb, i)?;
            let b: &[i8] = typed(ins[1], i)?;
            let b = b.get(..shape(op.inputs[1])?.len().ok_or(bad)?).ok_or(bad)?;
            elementwise::mul(
                &q,
                typed(ins[0], i)?,
                x_shape,
                b,
                plan.broadcast(i),
                typed_mut(out_b, i)?,
            )
            .map_err(e)?;
        }
        (opcode::CONCAT, _) => {
            let rs: &[Rescale] = typed(cb, i)?;
            let out: &mut [i8] = typed_mut(out_b, i)?;
            let mut c0 = 0;
            for ((&id, r), b) in op.inputs.iter().zip(rs).zip(&ins) {
                let s = shape(id)?;
                elementwise::concat_part(typed(b, i)?, s, r, out, out_shape, c0).map_err(e)?;
                c0 += s.c;
            }
        }
        (opcode::UPSAMPLE_BILINEAR, _) => match out_dtype {
            DType::I8 => resize::upsample_bilinear(
                typed(ins[0], i)?,
                x_shape,
                typed_mut(out_b, i)?,
                out_shape,
            )
            .map_err(e)?,
            DType::F32 => resize::upsample_bilinear_f32(
                typed(ins[0], i)?,
                x_shape,
                typed_mut(out_b, i)?,
                out_shape,
            )
            .map_err(e)?,
        },
        (opcode::PIXEL_SHUFFLE, Attrs::PixelShuffle(r)) => {
            match out_dtype {
                DType::I8 => elementwise::pixel_shuffle::<i8>(
                    typed(ins[0], i)?,
                    x_shape,
                    *r,
                    typed_mut(out_b, i)?,
                ),
                DType::F32 => elementwise::pixel_shuffle::<f32>(
                    typed(ins[0], i)?,
                    x_shape,
                    *r,
                    typed_mut(out_b, i)?,
                ),
            }
            .map_err(e)?;
        }
        (opcode::GLOBAL_AVG_POOL, _) => pool::global_avg_pool(
            &first(cb, i)?,
            typed(ins[0], i)?,
            x_shape,
            typed_mut(out_b, i)?,
        )
        .map_err(e)?,
        (opcode::GLOBAL_MAX_POOL, _) => pool::global_max_pool(
            &first(cb, i)?,
            typed(ins[0], i)?,
            x_shape,
            typed_mut(out_b, i)?,
        )
        .map_err(e)?,
        (opcode::CHANNEL_MEAN, _) => pool::channel_mean(
            &first(cb, i)?,
            typed(ins[0], i)?,
            x_shape,
            typed_mut(out_b, i)?,
        )
        .map_err(e)?,
        (opcode::CHANNEL_MAX, _) => pool::channel_max(
            &first(cb, i)?,
            typed(ins[0], i)?,
            x_shape,
            typed_mut(out_b, i)?,
        )
        .map_err(e)?,
        (opcode::MINMAX_NORM, Attrs::MinMax(eps)) => {
            let n = x_shape.len().ok_or(bad)?;
            let x: &[i8] = typed(ins[0], i)?;
            elementwise::minmax_norm(
                x.get(..n).ok_or(bad)?,
                tq(op.inputs[0])?,
                *eps,
                tq(op.output)?,
                typed_mut(out_b, i)?,
            )
            .map_err(e)?;
        }
        (opcode::BINS_HEAD, Attrs::Bins { attrs, weights, .. }) => {
            let li = g.tensor(op.inputs[1])?;
            let mut logits = [0f32; MAX_BINS];
            let nb = attrs.n_bins.min(MAX_BINS);
            match li.dtype {
                DType::I8 => {
                    for (l, &q) in logits[..nb].iter_mut().zip(typed::<i8>(ins[1], i)?) {
                        *l = li.q.dequantize(q);
                    }
                }
                DType::F32 => {
                    for (l, &v) in logits[..nb].iter_mut().zip(typed::<f32>(ins[1], i)?) {
                        *l = v;
                    }
                }
            }
            let mut centres = [0f32; MAX_BINS];
            bin_centres(&logits[..nb], attrs, &mut centres).map_err(e)?;
            let fz = tq(op.inputs[0])?.zero_point;
            bins_head_i8(
                isa,
                typed(ins[0], i)?,
                x_shape,
                fz,
                typed(g.bytes(*weights), i)?,
                typed(cb, i)?,
                &centres[..nb],
                typed_mut(out_b, i)?,
            )
            .map_err(e)?;
        }
        (opcode::REFINE, Attrs::Refine(attrs)) if plan.fused_heads(i).is_some() => {
            return exec_refine_streamed(g, plan, i, op, attrs, consts, act, ext, isa);
        }
        (opcode::REFINE, Attrs::Refine(attrs)) => {
            let p = x_shape.plane().ok_or(bad)?;
            let m = |k: usize, c: usize| -> Result<I8Map<'_>, Error> {
                I8Map::new(typed(ins[k], i)?, tq(op.inputs[k])?, c, p).map_err(e)
            };
            let aff = [
                m(1, KERNELS[0] * KERNELS[0] - 1)?,
                m(2, KERNELS[1] * KERNELS[1] - 1)?,
                m(3, KERNELS[2] * KERNELS[2] - 1)?,
            ];
            let (km, tm) = (m(4, 3)?, m(5, 3)?);
            let (h, w) = (x_shape.h, x_shape.w);
            let d0: &[f32] = typed(ins[0], i)?;
            if d0.len() < p {
                return Err(bad);
            }
            let sources = Sources {
                depth: &mut WholeDepth::new(d0, w),
                aff: &mut WholeMaps::new([&aff[0], &aff[1], &aff[2]], w),
                mix: &mut WholeMix::new(&km, &tm, w),
            };
            let (out, scratch) = (typed_mut(out_b, i)?, typed_mut(scr_b, i)?);
            refine_with(isa, sources, h, w, attrs, out, scratch).map_err(e)?;
        }
        _ => return Err(bad),
    }
    Ok(())
}

/// The conv op `j` as a kernel [`Conv2d`] (weights in the blob, constants in `consts`).
fn conv_of<'g>(g: &'g Graph, j: usize, channels: &'g [ChannelQuant]) -> Result<Conv2d<'g>, Error> {
    let bad = Error::Kernel {
        op: j,
        error: KernelError::Shape,
    };
    let op = g.ops.get(j).ok_or(bad)?;
    let Attrs::Conv {
        geometry,
        act,
        weights,
        ..
    } = &op.attrs
    else {
        return Err(bad);
    };
    Ok(Conv2d {
        geometry: geometry.get(),
        quant: ConvQuant::new(
            g.tensor(op.inputs[0])?.q.zero_point,
            g.tensor(op.output)?.q.zero_point,
            *act,
        ),
        weights: typed(g.bytes(*weights), j)?,
        channels,
    })
}

/// Conv op `i` reading the parts of concat op `c` in place, each mapped by a 256-entry table of
/// the concat's rescale (the codes the concat would have written).
fn exec_conv_on_parts(
    g: &Graph,
    plan: &Plan,
    i: usize,
    c: usize,
    consts: &[u8],
    act: &mut [u8],
    isa: Isa,
) -> Result<(), Error> {
    let bad = Error::Kernel {
        op: i,
        error: KernelError::Shape,
    };
    let op = g.ops.get(i).ok_or(bad)?;
    let concat = g.ops.get(c).ok_or(bad)?;
    let n = concat.inputs.len();
    let mut in_r: [Range<usize>; MAX_INPUTS] = Default::default();
    for (r, &id) in in_r.iter_mut().zip(&concat.inputs) {
        *r = plan.tensor_range(id).ok_or(bad)?;
    }
    let mut ins: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
    let out_r = plan.tensor_range(op.output).ok_or(bad)?;
    let scr_r = plan.scratch_range(i).ok_or(bad)?;
    let (out_b, scr_b) = split(act, out_r, scr_r, &in_r[..n], &mut ins, i)?;
    let rescales: &[Rescale] = typed(consts.get(plan.const_range(c).ok_or(bad)?).ok_or(bad)?, c)?;
    let x = plan.shape(op.inputs[0]).ok_or(bad)?;
    let mut tables = [[0i8; 256]; MAX_INPUTS];
    let mut parts = Parts::new(x.plane().ok_or(bad)?);
    for (k, t) in tables.iter_mut().enumerate().take(n) {
        let r = rescales.get(k).ok_or(bad)?;
        for (code, v) in t.iter_mut().enumerate() {
            *v = r.apply(code as u8 as i8);
        }
    }
    for (k, &id) in concat.inputs.iter().enumerate() {
        let r = rescales.get(k).ok_or(bad)?;
        let table = (!r.is_identity()).then_some(&tables[k]);
        let ch = plan.shape(id).ok_or(bad)?.c;
        if !parts.push(typed(ins[k], i)?, ch, table) {
            return Err(bad);
        }
    }
    let (channels, scr_b) = channel_quants(g, plan, i, consts, scr_b)?;
    let conv = conv_of(g, i, channels)?;
    let out = plan.shape(op.output).ok_or(bad)?;
    let dst = OutRows {
        rows: 0..out.h,
        stride: out.plane().ok_or(bad)?,
    };
    conv2d_parts_with(
        isa,
        &conv,
        &parts,
        x,
        &dst,
        typed_mut(out_b, i)?,
        typed_mut(scr_b, i)?,
    )
    .map_err(kerr(i))?;
    Ok(())
}

/// Splits `n` bytes off the front of `b` (`Err` where it is shorter).
fn take(b: &mut [u8], n: usize, op: usize) -> Result<(&mut [u8], &mut [u8]), Error> {
    if b.len() < n {
        return Err(Error::Kernel {
            op,
            error: KernelError::Scratch,
        });
    }
    Ok(b.split_at_mut(n))
}

/// `refine` op `i` with the producers the plan fused into it run row by row: the three
/// affinity heads ([`ConvRows`]), kmix and tmix where fused ([`MixConvRows`]), `D_0`'s upsample
/// where fused ([`UpsampledDepth`]); the output into the caller's `ext` where the plan keeps
/// it out of the arena. Scratch as [`crate::engine::RefineScratch`] lays it out.
#[allow(clippy::too_many_arguments)]
fn exec_refine_streamed<'a>(
    g: &'a Graph,
    plan: &Plan,
    i: usize,
    op: &OpInfo,
    attrs: &RefineAttrs,
    consts: &'a [u8],
    act: &'a mut [u8],
    ext: &mut [f32],
    isa: Isa,
) -> Result<(), Error> {
    let e = kerr(i);
    let bad = Error::Kernel {
        op: i,
        error: KernelError::Shape,
    };
    let f = plan.fused_refine(i).ok_or(bad)?;
    let range = |id: u16| plan.tensor_range(id).ok_or(bad);
    let input_of = |j: u16| g.ops.get(usize::from(j)).map(|o| o.inputs[0]).ok_or(bad);
    // What the refinement reads from the arena: D_0 (or its upsample's input), the mixing maps
    // (or their heads' input), the affinity heads' inputs.
    let d0_id = match f.depth {
        Some(j) => input_of(j)?,
        None => op.inputs[0],
    };
    let (km_id, tm_id) = match f.mix {
        Some([k, t]) => (input_of(k)?, input_of(t)?),
        None => (op.inputs[4], op.inputs[5]),
    };
    let ids = [
        d0_id,
        km_id,
        tm_id,
        input_of(f.aff[0])?,
        input_of(f.aff[1])?,
        input_of(f.aff[2])?,
    ];
    let mut in_r: [Range<usize>; 6] = Default::default();
    for (r, &id) in in_r.iter_mut().zip(&ids) {
        *r = range(id)?;
    }
    let mut ins: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
    let out_r = if plan.output_in_arena() {
        range(op.output)?
    } else {
        0..0
    };
    let scr_r = plan.scratch_range(i).ok_or(bad)?;
    let (out_b, scr_b) = split(act, out_r, scr_r, &in_r, &mut ins, i)?;
    let out: &mut [f32] = if plan.output_in_arena() {
        typed_mut(out_b, i)?
    } else {
        ext
    };
    let shape = plan.shape(op.output).ok_or(bad)?;
    let (h, w) = (shape.h, shape.w);
    let p = shape.plane().ok_or(bad)?;
    let t = attrs.iterations;
    let sz = f.scratch;
    let (win_b, rest) = take(scr_b, sz.windows, i)?;
    let (ring_b, rest) = take(rest, sz.ring, i)?;
    let (c0, rest) = channel_quants(g, plan, usize::from(f.aff[0]), consts, rest)?;
    let (c1, rest) = channel_quants(g, plan, usize::from(f.aff[1]), consts, rest)?;
    let (c2, rest) = channel_quants(g, plan, usize::from(f.aff[2]), consts, rest)?;
    let (conv_b, rest) = take(rest, sz.aff_conv, i)?;
    let head =
        |j: u16, ch: &'a [ChannelQuant], k: usize| fused_head(g, plan, i, j, ch, ins[k], ids[k]);
    let hs = [
        head(f.aff[0], c0, 3)?,
        head(f.aff[1], c1, 4)?,
        head(f.aff[2], c2, 5)?,
    ];
    let mut aff = ConvRows::new(
        isa,
        hs,
        h,
        w,
        t,
        typed_mut(ring_b, i)?,
        typed_mut(conv_b, i)?,
    )
    .map_err(e)?;
    let scratch: &mut [f32] = typed_mut(win_b, i)?;
    let mut depth = match f.depth {
        Some(_) => {
            let d_in = plan.shape(d0_id).ok_or(bad)?;
            Depth::Upsampled(UpsampledDepth::new(typed(ins[0], i)?, d_in, h, w))
        }
        None => {
            let d0: &[f32] = typed(ins[0], i)?;
            if d0.len() < p {
                return Err(bad);
            }
            Depth::Whole(WholeDepth::new(d0, w))
        }
    };
    let arena = (consts, rest);
    refine_mixed(
        g, plan, i, &f, &ins, &ids, arena, isa, &mut depth, &mut aff, attrs, out, scratch,
    )
}

/// The conv op `j` fused into refine op `i` as a [`Head`]: per-channel constants `ch`, its
/// input tensor `input_id` read from `input`.
fn fused_head<'a>(
    g: &'a Graph,
    plan: &Plan,
    i: usize,
    j: u16,
    ch: &'a [ChannelQuant],
    input: &'a [u8],
    input_id: u16,
) -> Result<Head<'a>, Error> {
    let bad = Error::Kernel {
        op: i,
        error: KernelError::Shape,
    };
    let out_id = g.ops.get(usize::from(j)).ok_or(bad)?.output;
    Ok(Head {
        conv: conv_of(g, usize::from(j), ch)?,
        input: typed(input, i)?,
        in_shape: plan.shape(input_id).ok_or(bad)?,
        out_q: g.tensor(out_id)?.q,
    })
}

/// `D_0` of a fused refinement: whole in the arena, or upsampled row by row.
enum Depth<'a> {
    Whole(WholeDepth<'a>),
    Upsampled(UpsampledDepth<'a>),
}

impl DepthRows for Depth<'_> {
    fn row(&mut self, y: usize, dst: &mut [f32]) -> Result<(), KernelError> {
        match self {
            Depth::Whole(d) => d.row(y, dst),
            Depth::Upsampled(d) => d.row(y, dst),
        }
    }
}

/// The rest of [`exec_refine_streamed`]: the mixing maps, streamed by their heads or whole,
/// then the refinement.
#[allow(clippy::too_many_arguments)]
fn refine_mixed<D: DepthRows, R: AffinityRows>(
    g: &Graph,
    plan: &Plan,
    i: usize,
    f: &FusedRefine,
    ins: &[&[u8]],
    ids: &[u16; 6],
    (consts, rest): (&[u8], &mut [u8]),
    isa: Isa,
    depth: &mut D,
    aff: &mut R,
    attrs: &RefineAttrs,
    out: &mut [f32],
    scratch: &mut [f32],
) -> Result<(), Error> {
    let e = kerr(i);
    let bad = Error::Kernel {
        op: i,
        error: KernelError::Shape,
    };
    let shape = plan.shape(g.ops.get(i).ok_or(bad)?.output).ok_or(bad)?;
    let (h, w) = (shape.h, shape.w);
    let Some(mix) = f.mix else {
        let p = shape.plane().ok_or(bad)?;
        let map = |k: usize| I8Map::new(typed(ins[k], i)?, g.tensor(ids[k])?.q, 3, p).map_err(e);
        let (km, tm) = (map(1)?, map(2)?);
        let sources = Sources {
            depth,
            aff,
            mix: &mut WholeMix::new(&km, &tm, w),
        };
        return refine_with(isa, sources, h, w, attrs, out, scratch).map_err(e);
    };
    let [[kr, _, kc], [tr, _, tc]] = f.scratch.mix;
    let (k_ring, rest) = take(rest, kr, i)?;
    let (k_ch, rest) = channel_quants(g, plan, usize::from(mix[0]), consts, rest)?;
    let (k_conv, rest) = take(rest, kc, i)?;
    let (t_ring, rest) = take(rest, tr, i)?;
    let (t_ch, rest) = channel_quants(g, plan, usize::from(mix[1]), consts, rest)?;
    let (t_conv, _) = take(rest, tc, i)?;
    let head = |j: u16, ch, k: usize| fused_head(g, plan, i, j, ch, ins[k], ids[k]);
    let heads = [head(mix[0], k_ch, 1)?, head(mix[1], t_ch, 2)?];
    let rings = [typed_mut(k_ring, i)?, typed_mut(t_ring, i)?];
    let convs = [typed_mut(k_conv, i)?, typed_mut(t_conv, i)?];
    let attrs_t = attrs.iterations;
    let mut mix = MixConvRows::new(isa, heads, h, w, attrs_t, rings, convs).map_err(e)?;
    let sources = Sources {
        depth,
        aff,
        mix: &mut mix,
    };
    refine_with(isa, sources, h, w, attrs, out, scratch).map_err(e)
}

impl core::fmt::Debug for Engine<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Engine")
            .field("input_shape", &self.plan.size())
            .field("ops", &self.graph.ops.len())
            .field("arena_bytes", &self.plan.arena_bytes())
            .finish()
    }
}
