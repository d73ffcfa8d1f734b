//! `upsample_bilinear` (docs/graph.md): int8 (into its input's quantisation or its own, then
//! with a [`resize::ResizeRescale`] made once at prepare time) or f32, to a fixed size, by
//! integer factors, or to another tensor's size. Kernel: [`crate::kernels::resize`]. A
//! one-channel f32 upsample giving a refinement's `D_0` may run row by row inside it
//! ([`super::refine`]).

use super::{typed, typed_mut, ConstCtx, Eval, PlanCtx, Types};
use crate::blob::format::{upsample_mode, MAX_TENSORS, NONE};
use crate::blob::parse::{bad, Attrs, DType, Graph, OpInfo, Reader};
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, PlanError};
use crate::engine::Error;
use crate::kernels::resize;
use crate::kernels::Shape;
use core::mem::size_of;

/// One input.
pub(crate) const ARITY: (usize, usize) = (1, 1);

/// Mode, reserved byte, two sizes (rows / columns, factors, or a tensor id), reserved.
pub(crate) fn read_attrs(a: &mut Reader) -> Result<(Attrs, [u32; 3]), BlobError> {
    let at = a.pos;
    let mode = a.u8("upsample: mode")?;
    a.u8("upsample: reserved")?;
    let x = a.u16("upsample: a")? as usize;
    let y = a.u16("upsample: b")? as usize;
    a.zero16("upsample: reserved")?;
    let ok = match mode {
        upsample_mode::FIXED | upsample_mode::SCALE => x > 0 && y > 0,
        upsample_mode::LIKE => x < MAX_TENSORS,
        _ => false,
    };
    if !ok {
        return Err(bad(at, "upsample: bad mode or size"));
    }
    Ok((Attrs::Upsample { mode, a: x, b: y }, [NONE; 3]))
}

/// One dtype (int8 or f32) in and out, as many channels; int8 may change its quantisation
/// ([`resize::ResizeRescale`]); a size tensor produced earlier.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    let Attrs::Upsample { mode, a, .. } = &k.op.attrs else {
        return Ok(false);
    };
    let (x, out) = (k.x, k.out);
    let like_ok = *mode != upsample_mode::LIKE || (*a < k.tensors.len() && k.produced[*a]);
    Ok(like_ok && x.channels == out.channels && x.dtype == out.dtype && x.dtype != DType::I16)
}

/// The output size of the mode.
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    let Attrs::Upsample { mode, a, b } = &c.op.attrs else {
        return Err(c.err("op attributes do not match the opcode"));
    };
    let x = c.x;
    let (h, w) = match *mode {
        upsample_mode::FIXED => (*a, *b),
        upsample_mode::SCALE => (
            x.h.checked_mul(*a).ok_or(PlanError::TooLarge)?,
            x.w.checked_mul(*b).ok_or(PlanError::TooLarge)?,
        ),
        _ => {
            let s = c
                .shapes
                .get(*a)
                .copied()
                .filter(|s| s.c > 0)
                .ok_or(c.err("upsample: size tensor unknown"))?;
            (s.h, s.w)
        }
    };
    p.out = Shape::new(c.out_c, h, w);
    if rescales(c.g, c.op).map_err(|_| c.err("upsample: tensor id"))? {
        p.consts = size_of::<resize::ResizeRescale>();
    }
    Ok(())
}

/// True for an int8 upsample whose output parameters differ from its input's.
fn rescales(g: &Graph, op: &OpInfo) -> Result<bool, BlobError> {
    let (x, out) = (g.tensor(op.inputs[0])?, g.tensor(op.output)?);
    Ok(out.dtype == DType::I8 && x.q != out.q)
}

/// The [`resize::ResizeRescale`] of an upsample that changes parameters (computed once: it
/// depends on the run size's shapes and the two tensors' parameters).
pub(crate) fn write_consts(c: &ConstCtx, region: &mut [u8]) -> Result<(), Error> {
    if !rescales(c.g, c.op)? {
        return Ok(());
    }
    let bad = Error::Blob(bad(c.op.offset, "upsample: shapes unknown"));
    let (x, out) = (c.op.inputs[0], c.op.output);
    let (xs, os) = (c.plan.shape(x).ok_or(bad)?, c.plan.shape(out).ok_or(bad)?);
    let dst: &mut [resize::ResizeRescale] = typed_mut(region, c.i)?;
    *dst.first_mut().ok_or(bad)? = resize::ResizeRescale::new(c.q(x)?, c.q(out)?, xs, os);
    Ok(())
}

/// Resizes the input.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let (i, kerr, bad) = (e.i, e.kerr(), e.bad());
    match e.g.tensor(e.op.output)?.dtype {
        DType::I8 => {
            let r = if rescales(e.g, e.op)? {
                let rs: &[resize::ResizeRescale] = typed(e.consts, i)?;
                Some(rs.first().ok_or(bad)?)
            } else {
                None
            };
            let (x, out) = (typed(e.ins[0], i)?, typed_mut(e.out, i)?);
            resize::upsample_bilinear_to_with(e.isa, x, e.x, out, e.out_shape, r).map_err(kerr)?
        }
        DType::F32 => {
            let (x, out) = (typed(e.ins[0], i)?, typed_mut(e.out, i)?);
            resize::upsample_bilinear_f32_with(e.isa, x, e.x, out, e.out_shape).map_err(kerr)?
        }
        DType::I16 => return Err(bad),
    }
    Ok(())
}
