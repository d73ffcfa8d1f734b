//! `refine` (docs/graph.md): mixed-affinity refinement of `D_0` with the affinities of kernels
//! 3, 5, 7 and the kmix / tmix maps, f32 metres out. Kernel: [`crate::kernels::refine`]. Where
//! the plan fused the producers into it ([`crate::engine::FusedRefine`]), the affinity, kmix and
//! tmix heads and `D_0`'s upsample run row by row inside it ([`eval_streamed`]).

use super::conv::{channel_quants, head};
use super::{bad_op, kerr, split, take, typed, typed_mut, Eval, PlanCtx, Types};
use crate::blob::format::{MAX_INPUTS, NONE};
use crate::blob::parse::{bad, Attrs, DType, Graph, OpInfo, Reader};
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, Plan, PlanError};
use crate::engine::{Error, FusedRefine};
use crate::kernels::isa::Isa;
use crate::kernels::refine::{
    self, refine_with, AffinityRows, ConvRows, DepthRows, I8Map, MixConvRows, Neighbourhood,
    RefineAttrs, Sources, UpsampledDepth, WholeDepth, WholeMaps, WholeMix, MAX_ITERATIONS,
};
use crate::kernels::KernelError;
use core::ops::Range;

/// `D_0`, the affinities of kernels 3, 5, 7, kmix, tmix.
pub(crate) const ARITY: (usize, usize) = (6, 6);

/// `T`, the neighbourhood's code (u16), `σ3, σ5, σ7`.
pub(crate) fn read_attrs(a: &mut Reader) -> Result<(Attrs, [u32; 3]), BlobError> {
    let at = a.pos;
    let iterations = a.u16("refine: iterations")? as usize;
    let nb_at = a.pos;
    let neighbourhood =
        Neighbourhood::from_code(a.u16("refine: neighbourhood")?).ok_or_else(|| {
            bad(
                nb_at,
                "refine: neighbourhood must be 0 (window) or 1 (dilated)",
            )
        })?;
    let sigma = [
        a.f32("refine: sigma3")?,
        a.f32("refine: sigma5")?,
        a.f32("refine: sigma7")?,
    ];
    if !iterations.is_multiple_of(2)
        || iterations > MAX_ITERATIONS
        || sigma.iter().any(|s| !(s.is_finite() && *s > 0.0))
    {
        return Err(bad(
            at,
            "refine: iterations must be even and <= 64, sigmas finite and > 0",
        ));
    }
    let attrs = RefineAttrs {
        iterations,
        sigma,
        neighbourhood,
    };
    Ok((Attrs::Refine(attrs), [NONE; 3]))
}

/// f32 `D_0`, int8 affinity maps of one channel per neighbour (8, 24, 48 for the whole
/// windows, 8 each dilated), int8 kmix and tmix of 3; one f32 channel out.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    let Attrs::Refine(attrs) = &k.op.attrs else {
        return Ok(false);
    };
    let want = [
        (DType::F32, 1),
        (DType::I8, attrs.neighbours(0)),
        (DType::I8, attrs.neighbours(1)),
        (DType::I8, attrs.neighbours(2)),
        (DType::I8, 3),
        (DType::I8, 3),
    ];
    let ins_ok =
        k.op.inputs
            .iter()
            .zip(want)
            .all(|(&i, (d, c))| k.t(i).is_ok_and(|ti| ti.dtype == d && ti.channels == c));
    Ok(ins_ok && k.out.dtype == DType::F32 && k.out.channels == 1)
}

/// Inputs of one H×W; scratch for the windows ([`refine::scratch_len`]).
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    for &id in &c.op.inputs {
        let s = c.shape(id)?;
        if (s.h, s.w) != (c.x.h, c.x.w) {
            return Err(c.err("refine: inputs differ in H or W"));
        }
    }
    let Attrs::Refine(attrs) = &c.op.attrs else {
        return Err(c.err("refine: attributes"));
    };
    p.scratch = refine::scratch_len(c.x.w, attrs.iterations)
        .checked_mul(4)
        .ok_or(PlanError::TooLarge)?;
    Ok(())
}

/// Refines from whole maps in the arena.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let Attrs::Refine(attrs) = &e.op.attrs else {
        return Err(e.bad());
    };
    let (i, kerr, bad) = (e.i, e.kerr(), e.bad());
    let p = e.x.plane().ok_or(bad)?;
    let m = |k: usize, c: usize| -> Result<I8Map<'_>, Error> {
        I8Map::new(typed(e.ins[k], i)?, e.q(e.op.inputs[k])?, c, p).map_err(kerr)
    };
    let aff = [
        m(1, attrs.neighbours(0))?,
        m(2, attrs.neighbours(1))?,
        m(3, attrs.neighbours(2))?,
    ];
    let (km, tm) = (m(4, 3)?, m(5, 3)?);
    let (h, w) = (e.x.h, e.x.w);
    let d0: &[f32] = typed(e.ins[0], i)?;
    if d0.len() < p {
        return Err(bad);
    }
    let sources = Sources {
        depth: &mut WholeDepth::new(d0, w),
        aff: &mut WholeMaps::new([&aff[0], &aff[1], &aff[2]], w),
        mix: &mut WholeMix::new(&km, &tm, w),
    };
    let (out, scratch) = (typed_mut(e.out, i)?, typed_mut(e.scratch, i)?);
    refine_with(e.isa, sources, h, w, attrs, out, scratch).map_err(kerr)?;
    Ok(())
}

/// `refine` op `i` with the producers the plan fused into it run row by row: the three
/// affinity heads ([`ConvRows`]), kmix and tmix where fused ([`MixConvRows`]), `D_0`'s upsample
/// where fused ([`UpsampledDepth`]); the output into the caller's `ext` where the plan keeps
/// it out of the arena. Scratch as [`crate::engine::RefineScratch`] lays it out.
#[inline(never)]
pub(crate) fn eval_streamed<'a>(
    (g, plan): (&'a Graph, &Plan),
    (i, op): (usize, &OpInfo),
    consts: &'a [u8],
    act: &'a mut [u8],
    ext: &mut [f32],
    isa: Isa,
) -> Result<(), Error> {
    let e = kerr(i);
    let bad = bad_op(i);
    let Attrs::Refine(attrs) = &op.attrs else {
        return Err(bad);
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
    let sz = f.scratch;
    let (win_b, rest) = take(scr_b, sz.windows, i)?;
    let (ring_b, rest) = take(rest, sz.ring, i)?;
    let (c0, rest) = channel_quants(g, plan, usize::from(f.aff[0]), consts, rest)?;
    let (c1, rest) = channel_quants(g, plan, usize::from(f.aff[1]), consts, rest)?;
    let (c2, rest) = channel_quants(g, plan, usize::from(f.aff[2]), consts, rest)?;
    let (conv_b, rest) = take(rest, sz.aff_conv, i)?;
    let hd = |j: u16, ch, k: usize| head(g, plan, i, j, ch, (ins[k], ids[k]));
    let hs = [
        hd(f.aff[0], c0, 3)?,
        hd(f.aff[1], c1, 4)?,
        hd(f.aff[2], c2, 5)?,
    ];
    let (ring, conv) = (typed_mut(ring_b, i)?, typed_mut(conv_b, i)?);
    let mut aff = ConvRows::new(isa, hs, (h, w), attrs, ring, conv).map_err(e)?;
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
    let streams = Streams {
        depth: &mut depth,
        aff: &mut aff,
        ins: &ins,
        ids: &ids,
    };
    refine_mixed(
        (g, plan, i, &f),
        streams,
        (consts, rest),
        isa,
        attrs,
        out,
        scratch,
    )
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

/// The sources [`eval_streamed`] set up, and the arena inputs (by tensor id) the mixing maps
/// or their heads read.
struct Streams<'s, 'a, D, R> {
    depth: &'s mut D,
    aff: &'s mut R,
    ins: &'s [&'a [u8]],
    ids: &'s [u16; 6],
}

/// The rest of [`eval_streamed`]: the mixing maps, streamed by their heads or whole, then the
/// refinement.
fn refine_mixed<D: DepthRows, R: AffinityRows>(
    (g, plan, i, f): (&Graph, &Plan, usize, &FusedRefine),
    s: Streams<'_, '_, D, R>,
    (consts, rest): (&[u8], &mut [u8]),
    isa: Isa,
    attrs: &RefineAttrs,
    out: &mut [f32],
    scratch: &mut [f32],
) -> Result<(), Error> {
    let e = kerr(i);
    let bad = bad_op(i);
    let shape = plan.shape(g.ops.get(i).ok_or(bad)?.output).ok_or(bad)?;
    let (h, w) = (shape.h, shape.w);
    let (ins, ids) = (s.ins, s.ids);
    let Some(mix) = f.mix else {
        let p = shape.plane().ok_or(bad)?;
        let map = |k: usize| I8Map::new(typed(ins[k], i)?, g.tensor(ids[k])?.q, 3, p).map_err(e);
        let (km, tm) = (map(1)?, map(2)?);
        let sources = Sources {
            depth: s.depth,
            aff: s.aff,
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
    let hd = |j: u16, ch, k: usize| head(g, plan, i, j, ch, (ins[k], ids[k]));
    let heads = [hd(mix[0], k_ch, 1)?, hd(mix[1], t_ch, 2)?];
    let rings = [typed_mut(k_ring, i)?, typed_mut(t_ring, i)?];
    let convs = [typed_mut(k_conv, i)?, typed_mut(t_conv, i)?];
    let t = attrs.iterations;
    let mut mix = MixConvRows::new(isa, heads, h, w, t, rings, convs).map_err(e)?;
    let sources = Sources {
        depth: s.depth,
        aff: s.aff,
        mix: &mut mix,
    };
    refine_with(isa, sources, h, w, attrs, out, scratch).map_err(e)
}
