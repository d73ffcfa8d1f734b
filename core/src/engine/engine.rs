//! [`Engine`]: prepare once (`new`), run many (`run`).

use super::error::Error;
use super::plan::{plan_with, plan_with_into, Io, Memory, Plan, ALIGN};
use crate::blob::format::MAX_INPUTS;
use crate::blob::parse::{parse, parse_into, DType, Graph, OpInfo};
use crate::kernels::isa::Isa;
use crate::kernels::requant::QParams;
use crate::kernels::KernelError;
use crate::ops::{self, bad_op, split, typed, typed_mut, ConstCtx, Eval, Kind};
use crate::pipeline::metres_to_mm;
use core::mem::MaybeUninit;
use core::ops::Range;
use core::ptr::addr_of_mut;

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
    /// An int16 tensor with its quantisation parameters (zero point 0; `crate::kernels::wide`).
    I16(&'b [i16], QParams),
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

/// As [`required_arena_bytes`] for the plan `memory` and the inputs and output `io`
/// ([`Engine::init_in`]).
pub fn required_arena_bytes_io(
    blob: &[u8],
    height: usize,
    width: usize,
    memory: Memory,
    io: Io,
) -> Result<usize, Error> {
    let g = parse(blob)?;
    let mut plan = Plan::empty();
    plan_with_into(&mut plan, &g, (height, width), memory, io)?;
    Ok(plan.arena_bytes())
}

/// The caller's input areas inside the arena of an [`Io::Arena`] engine ([`Engine::staging`]).
#[derive(Debug)]
pub struct Staging<'e> {
    /// RGB888 interleaved, `3·H·W` bytes.
    pub rgb: &'e mut [u8],
    /// Sparse depth in metres (0 = no point), `H·W` values.
    pub sparse_m: &'e mut [f32],
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

    /// As [`Engine::with_memory`] with the inputs and output `io` ([`Io::Arena`]: the caller
    /// holds no frame buffer, see [`Engine::staging`]), building the engine in the caller's `slot` (a `static` on a
    /// microcontroller) instead of returning it by value: the ≈ 32 KiB value (on 32-bit Arm;
    /// [`core::mem::size_of`]) never sits on the stack, only the parser's and the planner's
    /// temporaries do while this runs. On an error the slot stays uninitialised (nothing in it
    /// needs dropping).
    #[inline(never)]
    pub fn init_in<'s>(
        slot: &'s mut MaybeUninit<Engine<'a>>,
        blob: &'a [u8],
        arena: &'a mut [u8],
        height: usize,
        width: usize,
        memory: Memory,
        io: Io,
    ) -> Result<&'s mut Engine<'a>, Error> {
        let p = slot.as_mut_ptr();
        // SAFETY: `p` points to the slot's memory: valid for writes and aligned for `Engine`;
        // `addr_of_mut!` makes no reference to the uninitialised value. Each table starts
        // empty (field by field, so no engine-sized value is built on the stack) and the
        // parser and planner fill them in place.
        unsafe {
            addr_of_mut!((*p).graph).write(Graph {
                blob,
                height: 0,
                width: 0,
                tensors: heapless::Vec::new(),
                ops: heapless::Vec::new(),
                rgb: 0,
                sparse: 0,
                output: 0,
            });
            addr_of_mut!((*p).plan).write(Plan::empty());
        }
        // SAFETY: both fields were initialised just above and do not overlap; nothing else
        // refers to the slot while these references live (the fields written below are
        // others, through `p`).
        let (graph, plan) = unsafe {
            (
                &mut *addr_of_mut!((*p).graph),
                &mut *addr_of_mut!((*p).plan),
            )
        };
        parse_into(graph, blob)?;
        plan_with_into(plan, graph, (height, width), memory, io)?;
        let (arena, rgb_lut) = Self::fill_arena(graph, plan, arena)?;
        // SAFETY: the remaining fields, written once each into the slot.
        unsafe {
            addr_of_mut!((*p).arena).write(arena);
            addr_of_mut!((*p).rgb_lut).write(rgb_lut);
            addr_of_mut!((*p).isa).write(Isa::best());
        }
        // SAFETY: every field of the `Engine` has been written above.
        Ok(unsafe { slot.assume_init_mut() })
    }

    fn prepare(
        graph: Graph<'a>,
        arena: &'a mut [u8],
        h: usize,
        w: usize,
        memory: Memory,
    ) -> Result<Engine<'a>, Error> {
        let plan = plan_with(&graph, h, w, memory)?;
        let (arena, rgb_lut) = Self::fill_arena(&graph, &plan, arena)?;
        Ok(Engine {
            graph,
            plan,
            arena,
            rgb_lut,
            isa: Isa::best(),
        })
    }

    /// Checks `arena` against `plan`, writes every op's constants into it and builds the RGB
    /// table; returns the aligned part of the arena the engine uses and the table.
    fn fill_arena(
        graph: &Graph<'a>,
        plan: &Plan,
        arena: &'a mut [u8],
    ) -> Result<(&'a mut [u8], [i8; 256]), Error> {
        let have = arena.len();
        let need = plan.arena_bytes();
        let pad = arena.as_ptr().align_offset(ALIGN);
        let body = plan.persistent_bytes() + plan.activation_bytes() + plan.output_tail_bytes();
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
            write_consts(graph, plan, i, op, region)?;
        }
        let mut rgb_lut = [0i8; 256];
        let rq = graph.tensor(graph.rgb)?.q;
        for (v, q) in rgb_lut.iter_mut().enumerate() {
            *q = rq.quantize(v as f32 / 255.0);
        }
        Ok((arena, rgb_lut))
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

    /// [`Io::Arena`]: the staging areas inside the arena where the caller writes the next
    /// frame's RGB (`3·H·W` bytes) and sparse depth (`H·W` metres, 0 = no point) before
    /// [`Engine::run_staged`]. They share bytes with the previous run's activations and output:
    /// read the output ([`Engine::output_m`], [`Engine::output_mm`]) first. Their contents are
    /// whatever was there: write every value (`project_to_sparse` clears the map it writes).
    /// [`Error::NotStaged`] for an [`Io::Caller`] engine.
    pub fn staging(&mut self) -> Result<Staging<'_>, Error> {
        let (rgb_r, sparse_r) = self.plan.staging().ok_or(Error::NotStaged)?;
        let n = {
            let (h, w) = self.plan.size();
            h * w
        };
        let act = self.act_mut();
        let mut none: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
        let (rgb, sparse) = split(act, rgb_r, sparse_r, &[], &mut none, 0)?;
        let bad = Error::Kernel {
            op: 0,
            error: KernelError::Shape,
        };
        Ok(Staging {
            rgb: rgb.get_mut(..3 * n).ok_or(bad)?,
            sparse_m: typed_mut::<f32>(sparse, 0)?.get_mut(..n).ok_or(bad)?,
        })
    }

    /// [`Io::Arena`]: runs one frame on the inputs the caller wrote into [`Engine::staging`]; the
    /// dense depth is then in the arena ([`Engine::output_m`]) until the staging areas are
    /// written again. The same bits as [`Engine::run`] on the same inputs.
    pub fn run_staged(&mut self) -> Result<RunStats, Error> {
        let (rgb_r, sparse_r) = self.plan.staging().ok_or(Error::NotStaged)?;
        let (h, w) = self.plan.size();
        let n = h * w;
        let (graph, lut) = (&self.graph, &self.rgb_lut);
        let mut ins: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
        let srcs = [rgb_r, sparse_r];
        let (rgb_t, sparse_t) = input_tensors(graph, &self.plan, self.arena, &srcs, &mut ins)?;
        let bad = Error::Kernel {
            op: 0,
            error: KernelError::Shape,
        };
        write_rgb(
            self.isa,
            graph,
            n,
            lut,
            ins[0].get(..3 * n).ok_or(bad)?,
            rgb_t,
        )?;
        let sparse = typed::<f32>(ins[1], 0)?.get(..n).ok_or(bad)?;
        write_sparse(graph, n, |i| sparse[i], sparse_t)?;
        self.execute(None, None)
    }

    /// [`Io::Arena`]: the dense depth in metres (`H·W`) the last [`Engine::run_staged`] left in
    /// the arena. [`Error::NotStaged`] for an [`Io::Caller`] engine or an int8 output.
    pub fn output_m(&self) -> Result<&[f32], Error> {
        let bytes = self.output_bytes()?;
        let n = {
            let (h, w) = self.plan.size();
            h * w
        };
        let out = typed::<f32>(bytes, 0)?;
        out.get(..n).ok_or(Error::NotStaged)
    }

    /// [`Io::Arena`]: converts the dense depth the last [`Engine::run_staged`] left in the arena
    /// to millimetres in place (rounded, clamped to `0..=65535`, as
    /// [`crate::pipeline::DepthOut::Millimetres`]) and returns them (`H·W` values in the first
    /// half of the f32 output's bytes; [`Engine::output_m`] is no longer meaningful after this).
    pub fn output_mm(&mut self) -> Result<&[u16], Error> {
        let n = {
            let (h, w) = self.plan.size();
            h * w
        };
        let r = self.output_range()?;
        let bytes = self.arena.get_mut(r).ok_or(Error::NotStaged)?;
        if bytes.len() < 4 * n {
            return Err(Error::NotStaged);
        }
        // Front to back: value i is read (bytes 4i..4i+4) before its millimetres are written
        // (bytes 2i..2i+2), and a write never reaches a value not read yet (2i + 2 <= 4(i + 1)).
        for i in 0..n {
            let mut f = [0u8; 4];
            f.copy_from_slice(&bytes[4 * i..4 * i + 4]);
            let mm = metres_to_mm(f32::from_ne_bytes(f));
            bytes[2 * i..2 * i + 2].copy_from_slice(&mm.to_ne_bytes());
        }
        let mm = typed::<u16>(bytes, 0)?;
        mm.get(..n).ok_or(Error::NotStaged)
    }

    /// Byte range in the arena of the f32 output of an [`Io::Arena`] engine.
    fn output_range(&self) -> Result<Range<usize>, Error> {
        if self.plan.io() != Io::Arena || self.graph.tensor(self.graph.output)?.dtype != DType::F32
        {
            return Err(Error::NotStaged);
        }
        let p = self.plan.persistent_bytes();
        if self.plan.output_in_arena() {
            let r = self
                .plan
                .tensor_range(self.graph.output)
                .ok_or(Error::NotStaged)?;
            Ok(p + r.start..p + r.end)
        } else {
            let start = p + self.plan.activation_bytes();
            Ok(start..start + self.plan.output_tail_bytes())
        }
    }

    fn output_bytes(&self) -> Result<&[u8], Error> {
        let r = self.output_range()?;
        self.arena.get(r).ok_or(Error::NotStaged)
    }

    fn act_mut(&mut self) -> &mut [u8] {
        let p = self.plan.persistent_bytes();
        self.arena.get_mut(p..).unwrap_or(&mut [])
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
        check_len("rgb", 3 * n, rgb.len())?;
        let (graph, lut) = (&self.graph, &self.rgb_lut);
        let mut none: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
        let (rgb_t, sparse_t) = input_tensors(graph, &self.plan, self.arena, &[], &mut none)?;
        write_rgb(self.isa, graph, n, lut, rgb, rgb_t)?;
        match sparse {
            Some(s) => write_sparse(graph, n, |i| s[i], sparse_t)?,
            None => write_sparse(graph, n, |i| out[i], sparse_t)?,
        }
        let stats = self.execute(observer, Some(out))?;
        if self.plan.output_in_arena() {
            self.read_output(|i, v| out[i] = v)?;
        }
        Ok(stats)
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
        let act = self
            .arena
            .get(self.plan.persistent_bytes()..)
            .unwrap_or(&[]);
        let buf = act.get(r).ok_or(Error::Kernel {
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
            // The parser admits int8 or f32 only for the inputs and the output.
            DType::I16 => {
                return Err(Error::Kernel {
                    op: 0,
                    error: KernelError::Shape,
                })
            }
        }
        Ok(())
    }

    /// Runs every op; `ext` is the caller's f32 output (written by the graph's last op where the
    /// plan keeps the output out of the arena).
    /// `ext` `None`: the plan's output area after the activations ([`Io::Arena`]).
    fn execute(
        &mut self,
        mut observer: Option<&mut Observer<'_>>,
        ext: Option<&mut [f32]>,
    ) -> Result<RunStats, Error> {
        let persistent = self.plan.persistent_bytes();
        let (consts, act) = self.arena.split_at_mut(persistent);
        let at = self.plan.activation_bytes().min(act.len());
        let (act, tail) = act.split_at_mut(at);
        let ext = match ext {
            Some(ext) => ext,
            None => typed_mut::<f32>(tail, 0)?,
        };
        for i in self.plan.order() {
            let op = self.graph.ops.get(i).ok_or(bad_op(i))?;
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

/// Converts the RGB888 frame `rgb` (`3·n` bytes, interleaved) into the graph's RGB input tensor
/// `t` (planar, int8 through `lut`, or f32 in `[0, 1]`).
fn write_rgb(
    isa: Isa,
    g: &Graph,
    n: usize,
    lut: &[i8; 256],
    rgb: &[u8],
    t: &mut [u8],
) -> Result<(), Error> {
    #[cfg(not(target_arch = "aarch64"))]
    let _ = isa;
    check_len("rgb", 3 * n, rgb.len())?;
    let info = *g.tensor(g.rgb)?;
    match info.dtype {
        DType::I8 => {
            let t: &mut [i8] = typed_mut(t, 0)?;
            // The three planes side by side: one pass, no index arithmetic per code.
            let short = Error::Kernel {
                op: 0,
                error: KernelError::Shape,
            };
            let (r, rest) = t.get_mut(..3 * n).ok_or(short)?.split_at_mut(n);
            let (gr, b) = rest.split_at_mut(n);
            // 16 pixels per pass with `LD3` and `TBL` on `neon`/`neon-dot` (the same table).
            #[cfg(target_arch = "aarch64")]
            let (rgb, r, gr, b) = if matches!(isa, Isa::Neon | Isa::NeonDot) {
                let done = crate::kernels::aarch64::elementwise::lookup_rgb(lut, rgb, r, gr, b);
                let rgb = rgb.get(3 * done..).unwrap_or_default();
                (rgb, &mut r[done..], &mut gr[done..], &mut b[done..])
            } else {
                (rgb, r, gr, b)
            };
            for (((px, r), gr), b) in rgb.chunks_exact(3).zip(r).zip(gr).zip(b) {
                *r = lut[px[0] as usize];
                *gr = lut[px[1] as usize];
                *b = lut[px[2] as usize];
            }
        }
        DType::F32 => {
            let t: &mut [f32] = typed_mut(t, 0)?;
            for (i, px) in rgb.chunks_exact(3).enumerate().take(n) {
                for c in 0..3 {
                    t[c * n + i] = px[c] as f32 / 255.0;
                }
            }
        }
        // The parser admits int8 or f32 only for the inputs and the output.
        DType::I16 => {
            return Err(Error::Kernel {
                op: 0,
                error: KernelError::Shape,
            })
        }
    }
    Ok(())
}

/// The arena bytes of the network's two inputs (RGB, sparse), and in `ins` the arena ranges
/// `srcs` read alongside them (the staging areas of [`Io::Arena`]).
fn input_tensors<'b>(
    g: &Graph,
    plan: &Plan,
    arena: &'b mut [u8],
    srcs: &[Range<usize>],
    ins: &mut [&'b [u8]; MAX_INPUTS],
) -> Result<(&'b mut [u8], &'b mut [u8]), Error> {
    let act = arena.get_mut(plan.persistent_bytes()..).unwrap_or(&mut []);
    let t = |id: u16| {
        plan.tensor_range(id).ok_or(Error::Kernel {
            op: 0,
            error: KernelError::Shape,
        })
    };
    split(act, t(g.rgb)?, t(g.sparse)?, srcs, ins, 0)
}

/// Writes the sparse depth `get(i)` (metres, `i < n`) into the graph's sparse input tensor `t`.
fn write_sparse(
    g: &Graph,
    n: usize,
    get: impl Fn(usize) -> f32,
    t: &mut [u8],
) -> Result<(), Error> {
    let info = *g.tensor(g.sparse)?;
    match info.dtype {
        DType::I8 => {
            let t: &mut [i8] = typed_mut(t, 0)?;
            // Most pixels have no depth: 0.0 (and −0.0, the same arithmetic) quantises to one
            // code, computed once; the same bits.
            let zero = info.q.quantize(0.0);
            let one = |i: usize| {
                let x = get(i);
                if x == 0.0 {
                    zero
                } else {
                    info.q.quantize(x)
                }
            };
            // 16 pixels at a time: a run with no depth at all (every value compared, no early
            // exit, so the comparison vectorises) is one fill.
            let m = n.min(t.len());
            let t = &mut t[..m];
            let mut runs = t.chunks_exact_mut(16);
            for (k, run) in (&mut runs).enumerate() {
                let at = 16 * k;
                let empty = (0..16).fold(true, |e, j| e & (get(at + j) == 0.0));
                if empty {
                    run.fill(zero);
                } else {
                    for (j, v) in run.iter_mut().enumerate() {
                        *v = one(at + j);
                    }
                }
            }
            let done = m - runs.into_remainder().len();
            for (i, v) in t.iter_mut().enumerate().skip(done) {
                *v = one(i);
            }
        }
        DType::F32 => {
            let t: &mut [f32] = typed_mut(t, 0)?;
            for (i, v) in t.iter_mut().enumerate().take(n) {
                *v = get(i);
            }
        }
        // The parser admits int8 or f32 only for the inputs and the output.
        DType::I16 => {
            return Err(Error::Kernel {
                op: 0,
                error: KernelError::Shape,
            })
        }
    }
    Ok(())
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
        DType::I16 => f(
            i,
            Observed::I16(typed::<i16>(buf, i)?.get(..n).ok_or(bad)?, info.q),
        ),
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
    let kind = Kind::of(op.code).ok_or(bad_op(i))?;
    kind.write_consts(&ConstCtx { g, plan, i, op }, region)
}

/// Runs op `i` on the arena (run time; nothing is validated twice except cheap slice bounds);
/// `ext` is the caller's f32 output ([`Plan::output_in_arena`]).
#[allow(clippy::too_many_arguments)]
#[inline(never)]
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
    let bad = bad_op(i);
    if let Some(c) = plan.concat_in_place(i) {
        return ops::conv::eval_on_parts(g, plan, (i, c), consts, act, isa);
    }
    let kind = Kind::of(op.code).ok_or(bad)?;
    if kind == Kind::Refine && plan.fused_heads(i).is_some() {
        return ops::refine::eval_streamed((g, plan), (i, op), consts, act, ext, isa);
    }
    if kind == Kind::Mul && plan.in_place_of(op.output).is_some() {
        let op_consts = consts.get(plan.const_range(i).ok_or(bad)?).ok_or(bad)?;
        return ops::mul::eval_in_place(plan, (i, op), op_consts, act, isa);
    }
    let out_r = plan.tensor_range(op.output).ok_or(bad)?;
    let scr_r = plan.scratch_range(i).ok_or(bad)?;
    let mut in_r: [Range<usize>; MAX_INPUTS] = Default::default();
    for (r, &id) in in_r.iter_mut().zip(&op.inputs) {
        *r = plan.tensor_range(id).ok_or(bad)?;
    }
    let n_in = op.inputs.len();
    let mut ins: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
    let (out, scratch) = split(act, out_r, scr_r, &in_r[..n_in], &mut ins, i)?;
    let op_consts = consts.get(plan.const_range(i).ok_or(bad)?).ok_or(bad)?;
    kind.eval(Eval {
        g,
        plan,
        i,
        op,
        ins,
        out,
        scratch,
        consts: op_consts,
        all_consts: consts,
        isa,
        x: plan.shape(op.inputs[0]).ok_or(bad)?,
        out_shape: plan.shape(op.output).ok_or(bad)?,
    })
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

#[cfg(test)]
mod tests {
    //! The engine's safe API at a small size on [`crate::blob::TEST_BLOB`], with the portable
    //! kernels, sized for Miri (`cargo +nightly miri test -p depthor-core --lib engine::`).
    use super::*;
    use crate::blob::TEST_BLOB;
    use std::vec;
    use std::vec::Vec;

    /// 8×8 natively; 4×4 under Miri (every op of the network still runs).
    const H: usize = if cfg!(miri) { 4 } else { 8 };
    const W: usize = H;

    fn frame() -> (Vec<u8>, Vec<f32>) {
        let rgb = (0..3 * H * W).map(|i| (i * 37 % 256) as u8).collect();
        let sparse = (0..H * W)
            .map(|i| {
                if i % 5 == 3 {
                    0.5 + i as f32 / 16.0
                } else {
                    0.0
                }
            })
            .collect();
        (rgb, sparse)
    }

    fn run(memory: Memory, in_place: bool) -> Vec<f32> {
        let need = required_arena_bytes_with(TEST_BLOB, H, W, memory).unwrap();
        let mut arena = vec![0u8; need];
        let mut e = Engine::with_memory(TEST_BLOB, &mut arena, H, W, memory).unwrap();
        e.set_kernels(Isa::Portable).unwrap();
        assert_eq!(e.input_shape(), (H, W));
        let (rgb, sparse) = frame();
        let mut out = vec![0f32; H * W];
        let stats = if in_place {
            out.copy_from_slice(&sparse);
            e.run_in_place(&rgb, &mut out).unwrap()
        } else {
            e.run(&rgb, &sparse, &mut out).unwrap()
        };
        assert_eq!(stats.ops, e.graph().ops.len());
        out
    }

    #[test]
    fn runs_at_a_small_size_in_place_and_whole_alike() {
        let out = run(Memory::Streamed, false);
        assert!(out.iter().all(|v| v.is_finite() && *v > 0.0), "{out:?}");
        if cfg!(miri) {
            // Each prepare plans (the order search) and checks the CRC: one engine under Miri.
            return;
        }
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&run(Memory::Streamed, true)), bits(&out));
        assert_eq!(bits(&run(Memory::Whole, false)), bits(&out));
    }

    #[test]
    #[cfg_attr(miri, ignore = "slow under Miri: a second prepare")]
    fn an_engine_built_in_a_slot_runs_alike() {
        let want = run(Memory::Streamed, false);
        let need = required_arena_bytes(TEST_BLOB, H, W).unwrap();
        let mut arena = vec![0u8; need];
        let mut slot = MaybeUninit::uninit();
        let e = Engine::init_in(
            &mut slot,
            TEST_BLOB,
            &mut arena,
            H,
            W,
            Memory::Streamed,
            Io::Caller,
        )
        .unwrap();
        e.set_kernels(Isa::Portable).unwrap();
        let (rgb, sparse) = frame();
        let mut out = vec![0f32; H * W];
        e.run(&rgb, &sparse, &mut out).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&out), bits(&want));
        let mut short = vec![0u8; need / 2];
        let mut slot = MaybeUninit::uninit();
        assert!(matches!(
            Engine::init_in(
                &mut slot,
                TEST_BLOB,
                &mut short,
                H,
                W,
                Memory::Streamed,
                Io::Caller
            ),
            Err(Error::ArenaTooSmall { .. })
        ));
    }

    #[test]
    #[cfg_attr(miri, ignore = "slow under Miri: two more prepares")]
    fn staged_inputs_give_the_same_bits_and_millimetres() {
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for memory in [Memory::Streamed, Memory::Whole] {
            let want = run(memory, false);
            let need = required_arena_bytes_io(TEST_BLOB, H, W, memory, Io::Arena).unwrap();
            let mut arena = vec![0u8; need];
            let mut slot = MaybeUninit::uninit();
            let e =
                Engine::init_in(&mut slot, TEST_BLOB, &mut arena, H, W, memory, Io::Arena).unwrap();
            e.set_kernels(Isa::Portable).unwrap();
            let (rgb, sparse) = frame();
            for _ in 0..2 {
                let s = e.staging().unwrap();
                s.rgb.copy_from_slice(&rgb);
                s.sparse_m.copy_from_slice(&sparse);
                e.run_staged().unwrap();
                assert_eq!(bits(e.output_m().unwrap()), bits(&want), "{memory:?}");
            }
            let mm: Vec<u16> = want.iter().map(|&m| metres_to_mm(m)).collect();
            assert_eq!(e.output_mm().unwrap(), &mm[..]);
        }
        // An engine with the caller's buffers has no staging.
        let need = required_arena_bytes(TEST_BLOB, H, W).unwrap();
        let mut arena = vec![0u8; need];
        let mut e = Engine::with_size(TEST_BLOB, &mut arena, H, W).unwrap();
        assert_eq!(e.staging().unwrap_err(), Error::NotStaged);
        assert_eq!(e.run_staged().unwrap_err(), Error::NotStaged);
        assert_eq!(e.output_m().unwrap_err(), Error::NotStaged);
    }

    #[test]
    #[cfg_attr(
        miri,
        ignore = "slow under Miri: the run above covers the engine's safe API"
    )]
    fn wrong_buffers_and_a_short_arena_are_errors() {
        let need = required_arena_bytes(TEST_BLOB, H, W).unwrap();
        let mut short = vec![0u8; need / 2];
        assert!(matches!(
            Engine::with_size(TEST_BLOB, &mut short, H, W),
            Err(Error::ArenaTooSmall { .. })
        ));
        let mut arena = vec![0u8; need];
        let mut e = Engine::with_size(TEST_BLOB, &mut arena, H, W).unwrap();
        e.set_kernels(Isa::Portable).unwrap();
        let (rgb, sparse) = frame();
        let mut out = vec![0f32; H * W];
        let shape = |r: Result<RunStats, Error>| matches!(r, Err(Error::ShapeMismatch { .. }));
        assert!(shape(e.run(&rgb[1..], &sparse, &mut out)));
        assert!(shape(e.run(&rgb, &sparse[1..], &mut out)));
        assert!(shape(e.run(&rgb, &sparse, &mut out[1..])));
        assert!(shape(e.run_in_place(&rgb, &mut out[1..])));
        assert_eq!(out, vec![0f32; H * W], "output touched by a refused run");
    }
}
