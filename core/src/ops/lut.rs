//! `relu`, `leaky_relu`, `sigmoid`, `reciprocal` (docs/graph.md): int8 → int8 through a
//! 256-entry table the quantizer computed. Kernel: [`crate::kernels::elementwise::lut`].

use super::{typed, typed_mut, Eval, Types};
use crate::blob::format::NONE;
use crate::blob::parse::{bad, Attrs, Param, Reader};
use crate::blob::BlobError;
use crate::engine::Error;
use crate::kernels::elementwise;

/// One input.
pub(crate) const ARITY: (usize, usize) = (1, 1);

/// The 256-byte table, in place.
pub(crate) fn read_attrs(a: &mut Reader) -> Result<(Attrs, [u32; 3]), BlobError> {
    let at = a.pos;
    a.take(256, "table: 256 bytes")?;
    let table = Param {
        offset: u32::try_from(at).map_err(|_| bad(at, "table offset"))?,
        len: 256,
    };
    Ok((Attrs::Lut(table), [NONE; 3]))
}

/// int8 in and out, as many channels.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    k.all_i8()?;
    Ok(k.x.channels == k.out.channels)
}

/// Maps every code through the table.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let Attrs::Lut(p) = &e.op.attrs else {
        return Err(e.bad());
    };
    let t: &[i8; 256] = typed::<i8>(e.g.bytes(*p), e.i)?
        .try_into()
        .map_err(|_| e.bad())?;
    let kerr = e.kerr();
    elementwise::lut_with(e.isa, typed(e.ins[0], e.i)?, t, typed_mut(e.out, e.i)?).map_err(kerr)?;
    Ok(())
}
