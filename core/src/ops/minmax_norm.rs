//! `minmax_norm` (docs/graph.md): int8 `(x − min) / (max − min + eps)` over the whole tensor.
//! Kernel: [`crate::kernels::elementwise::minmax_norm`].

use super::{typed, typed_mut, Eval, Types};
use crate::blob::format::NONE;
use crate::blob::parse::{bad, Attrs, Reader};
use crate::blob::BlobError;
use crate::engine::Error;
use crate::kernels::elementwise;

/// One input.
pub(crate) const ARITY: (usize, usize) = (1, 1);

/// `eps` (f32, finite, ≥ 0).
pub(crate) fn read_attrs(a: &mut Reader) -> Result<(Attrs, [u32; 3]), BlobError> {
    let at = a.pos;
    let eps = a.f32("minmax_norm: eps")?;
    if !(eps.is_finite() && eps >= 0.0) {
        return Err(bad(at, "minmax_norm: eps must be finite and >= 0"));
    }
    Ok((Attrs::MinMax(eps), [NONE; 3]))
}

/// int8 in and out, as many channels.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    k.all_i8()?;
    Ok(k.x.channels == k.out.channels)
}

/// Normalises the input.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let Attrs::MinMax(eps) = e.op.attrs else {
        return Err(e.bad());
    };
    let (i, kerr, bad) = (e.i, e.kerr(), e.bad());
    let n = e.x.len().ok_or(bad)?;
    let x: &[i8] = typed(e.ins[0], i)?;
    let (in_q, out_q) = (e.q(e.op.inputs[0])?, e.q(e.op.output)?);
    let out = typed_mut(e.out, i)?;
    let x = x.get(..n).ok_or(bad)?;
    elementwise::minmax_norm_with(e.isa, x, in_q, eps, out_q, out).map_err(kerr)?;
    Ok(())
}
