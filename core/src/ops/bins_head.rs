//! `bins_head` (docs/graph.md): the adaptive-bins depth head: bin centres from the bin logits,
//! a 1×1 int8 head of per-pixel logits, softmax expectation in f32 metres. Kernel:
//! [`crate::kernels::bins`].

use super::{typed, typed_mut, ConstCtx, Eval, PlanCtx, Types};
use crate::blob::parse::{bad, f32_at, i32_at, Attrs, DType, Reader, NO_PARAM};
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, PlanError};
use crate::engine::Error;
use crate::kernels::bins::{
    bin_centres, bins_head_i8, BinChannel, BinsAttrs, MAX_BINS, MAX_BIN_FEATURES,
};
use crate::kernels::Shape;
use core::mem::size_of;

/// Features and bin logits.
pub(crate) const ARITY: (usize, usize) = (2, 2);

/// `N`, reserved u16, depth range, weight / bias / scale references.
pub(crate) fn read_attrs(a: &mut Reader) -> Result<(Attrs, [u32; 3]), BlobError> {
    let at = a.pos;
    let n_bins = a.u16("bins_head: n_bins")? as usize;
    a.zero16("bins_head: reserved")?;
    let min_depth = a.f32("bins_head: min_depth")?;
    let max_depth = a.f32("bins_head: max_depth")?;
    let refs = [
        a.u32("bins_head: weight ref")?,
        a.u32("bins_head: bias ref")?,
        a.u32("bins_head: scale ref")?,
    ];
    if n_bins == 0
        || n_bins > MAX_BINS
        || !(min_depth.is_finite() && max_depth.is_finite() && min_depth < max_depth)
    {
        return Err(bad(at, "bins_head: bad n_bins or depth range"));
    }
    let attrs = BinsAttrs {
        n_bins,
        min_depth,
        max_depth,
    };
    let attrs = Attrs::Bins {
        attrs,
        weights: NO_PARAM,
        bias: None,
        scales: NO_PARAM,
    };
    Ok((attrs, refs))
}

/// int8 features (≤ [`MAX_BIN_FEATURES`] channels), `N` logits, one f32 channel out.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    let Attrs::Bins { attrs, .. } = &k.op.attrs else {
        return Ok(false);
    };
    let l = k.t(k.op.inputs[1])?;
    Ok(k.x.dtype == DType::I8
        && k.x.channels <= MAX_BIN_FEATURES
        && l.channels == attrs.n_bins
        && l.dtype != DType::I16
        && k.out.dtype == DType::F32
        && k.out.channels == 1)
}

/// Logits `[N, 1, 1]`; a [`BinChannel`] per bin; MACs = pixels × C × N.
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    let Attrs::Bins { attrs, .. } = &c.op.attrs else {
        return Err(c.err("op attributes do not match the opcode"));
    };
    if c.shape(c.op.inputs[1])? != Shape::new(attrs.n_bins, 1, 1) {
        return Err(c.err("bins_head: bin logits must be [N,1,1]"));
    }
    p.consts = attrs.n_bins * size_of::<BinChannel>();
    p.macs = (c.x.plane().ok_or(PlanError::TooLarge)? as u64)
        .saturating_mul((c.x.c * attrs.n_bins) as u64);
    Ok(())
}

/// The bins' [`BinChannel`]s.
pub(crate) fn write_consts(c: &ConstCtx, region: &mut [u8]) -> Result<(), Error> {
    let Attrs::Bins { bias, scales, .. } = &c.op.attrs else {
        return Ok(());
    };
    let in_q = c.q(c.op.inputs[0])?;
    let dst: &mut [BinChannel] = typed_mut(region, c.i)?;
    let sb = c.g.bytes(*scales);
    for (o, bc) in dst.iter_mut().enumerate() {
        let b = bias.map_or(0, |p| i32_at(c.g.bytes(p), o));
        *bc = BinChannel {
            bias: b,
            scale: in_q.scale * f32_at(sb, o),
        };
    }
    Ok(())
}

/// Depth in metres per pixel.
///
/// Out of line: its two 1 KiB tables stay out of `Kind::eval`'s frame, which the refinement's
/// deep frames sit on (the firmware's stack high-water).
#[inline(never)]
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let Attrs::Bins { attrs, weights, .. } = &e.op.attrs else {
        return Err(e.bad());
    };
    let (i, kerr) = (e.i, e.kerr());
    let li = e.g.tensor(e.op.inputs[1])?;
    let mut logits = [0f32; MAX_BINS];
    let nb = attrs.n_bins.min(MAX_BINS);
    match li.dtype {
        DType::I8 => {
            for (l, &q) in logits[..nb].iter_mut().zip(typed::<i8>(e.ins[1], i)?) {
                *l = li.q.dequantize(q);
            }
        }
        DType::F32 => {
            for (l, &v) in logits[..nb].iter_mut().zip(typed::<f32>(e.ins[1], i)?) {
                *l = v;
            }
        }
        DType::I16 => return Err(e.bad()),
    }
    let mut centres = [0f32; MAX_BINS];
    bin_centres(&logits[..nb], attrs, &mut centres).map_err(kerr)?;
    let fz = e.q(e.op.inputs[0])?.zero_point;
    let (x, w) = (typed(e.ins[0], i)?, typed(e.g.bytes(*weights), i)?);
    let (ch, out) = (typed(e.consts, i)?, typed_mut(e.out, i)?);
    bins_head_i8(e.isa, x, e.x, fz, w, ch, &centres[..nb], out).map_err(kerr)?;
    Ok(())
}
