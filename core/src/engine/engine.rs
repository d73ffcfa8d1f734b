//! [`Engine`]: prepare once (`new`), run many (`run`).

use super::error::Error;
use super::plan::{plan_with, Memory, Plan, ALIGN};
use crate::blob::format::MAX_INPUTS;
use crate::blob::parse::{parse, DType, Graph, OpInfo};
use crate::kernels::isa::Isa;
use crate::kernels::requant::QParams;
use crate::kernels::KernelError;
use crate::ops::{self, bad_op, split, typed, typed_mut, ConstCtx, Eval, Kind};
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
                // Most pixels have no depth: 0.0 (and −0.0, the same arithmetic) quantises to
                // one code, computed once; the same bits.
                let zero = info.q.quantize(0.0);
                for (i, v) in t.iter_mut().enumerate().take(h * w) {
                    let x = get(i);
                    *v = if x == 0.0 { zero } else { info.q.quantize(x) };
                }
            }
            DType::F32 => {
                let t: &mut [f32] = typed_mut(buf, 0)?;
                for (i, v) in t.iter_mut().enumerate().take(h * w) {
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
