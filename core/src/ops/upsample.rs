//! `upsample_bilinear` (docs/graph.md): int8 (into its input's quantisation or its own) or f32,
//! to a fixed size, by integer factors, or to another tensor's size. Kernel: [`crate::kernels::resize`]. A one-channel f32 upsample giving
//! a refinement's `D_0` may run row by row inside it ([`super::refine`]).

use super::{typed, typed_mut, Eval, PlanCtx, Types};
use crate::blob::format::{upsample_mode, MAX_TENSORS, NONE};
use crate::blob::parse::{bad, Attrs, DType, Reader};
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, PlanError};
use crate::engine::Error;
use crate::kernels::resize;
use crate::kernels::Shape;

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
    Ok(())
}

/// Resizes the input.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let (i, kerr) = (e.i, e.kerr());
    match e.g.tensor(e.op.output)?.dtype {
        DType::I8 => {
            let (x, out) = (typed(e.ins[0], i)?, typed_mut(e.out, i)?);
            let (from, to) = (e.g.tensor(e.op.inputs[0])?.q, e.g.tensor(e.op.output)?.q);
            let r = (from != to).then(|| resize::ResizeRescale::new(from, to, e.x, e.out_shape));
            resize::upsample_bilinear_to(x, e.x, out, e.out_shape, r.as_ref()).map_err(kerr)?
        }
        DType::F32 => {
            let (x, out) = (typed(e.ins[0], i)?, typed_mut(e.out, i)?);
            resize::upsample_bilinear_f32(x, e.x, out, e.out_shape).map_err(kerr)?
        }
        DType::I16 => return Err(e.bad()),
    }
    Ok(())
}
