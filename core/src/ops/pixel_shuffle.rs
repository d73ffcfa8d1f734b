//! `pixel_shuffle` (docs/graph.md): `[C·r², H, W]` → `[C, H·r, W·r]`, int8 or f32. Kernel:
//! [`crate::kernels::elementwise::pixel_shuffle`].

use super::{typed, typed_mut, Eval, PlanCtx, Types};
use crate::blob::format::NONE;
use crate::blob::parse::{bad, Attrs, DType, Reader};
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, PlanError};
use crate::engine::Error;
use crate::kernels::elementwise;
use crate::kernels::Shape;

/// One input.
pub(crate) const ARITY: (usize, usize) = (1, 1);

/// The factor `r` and a reserved u16.
pub(crate) fn read_attrs(a: &mut Reader) -> Result<(Attrs, [u32; 3]), BlobError> {
    let at = a.pos;
    let f = a.u16("pixel_shuffle: factor")? as usize;
    a.zero16("pixel_shuffle: reserved")?;
    if f == 0 {
        return Err(bad(at, "pixel_shuffle: zero factor"));
    }
    Ok((Attrs::PixelShuffle(f), [NONE; 3]))
}

/// `r²` times the output's channels in; one dtype (int8 or f32) and quantisation.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    let Attrs::PixelShuffle(f) = &k.op.attrs else {
        return Ok(false);
    };
    let (x, out) = (k.x, k.out);
    Ok(Some(x.channels) == out.channels.checked_mul(f * f)
        && x.dtype == out.dtype
        && x.dtype != DType::I16
        && (x.dtype == DType::F32 || x.q == out.q))
}

/// `r` times the input's rows and columns.
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    let Attrs::PixelShuffle(r) = &c.op.attrs else {
        return Err(c.err("op attributes do not match the opcode"));
    };
    p.out = Shape::new(
        c.out_c,
        c.x.h.checked_mul(*r).ok_or(PlanError::TooLarge)?,
        c.x.w.checked_mul(*r).ok_or(PlanError::TooLarge)?,
    );
    Ok(())
}

/// Moves every input element to its place.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let Attrs::PixelShuffle(r) = e.op.attrs else {
        return Err(e.bad());
    };
    let (i, kerr) = (e.i, e.kerr());
    match e.g.tensor(e.op.output)?.dtype {
        DType::I8 => {
            let (x, out) = (typed(e.ins[0], i)?, typed_mut(e.out, i)?);
            elementwise::pixel_shuffle::<i8>(x, e.x, r, out)
        }
        DType::F32 => {
            let (x, out) = (typed(e.ins[0], i)?, typed_mut(e.out, i)?);
            elementwise::pixel_shuffle::<f32>(x, e.x, r, out)
        }
        DType::I16 => return Err(e.bad()),
    }
    .map_err(kerr)?;
    Ok(())
}
