//! `mul` (docs/graph.md): int8 × int8, the second operand of the first's shape, `[1, H, W]`
//! (broadcast over channels) or `[C, 1, 1]` (over space). Kernel:
//! [`crate::kernels::elementwise::mul`].

use super::{first, typed, typed_mut, write_first, ConstCtx, Eval, PlanCtx, Types};
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, PlanError};
use crate::engine::Error;
use crate::kernels::broadcast::Broadcast;
use crate::kernels::elementwise::{self, MulQuant};
use crate::kernels::Shape;
use core::mem::size_of;

/// Two inputs.
pub(crate) const ARITY: (usize, usize) = (2, 2);

/// int8 in and out; the second operand with the first's channels or one.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    k.all_i8()?;
    let y = k.t(k.op.inputs[1])?;
    Ok(k.x.channels == k.out.channels && (y.channels == k.x.channels || y.channels == 1))
}

/// The broadcast the second operand's shape asks for; one [`MulQuant`].
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    let (x, y) = (c.x, c.shape(c.op.inputs[1])?);
    p.broadcast = if y == x {
        Broadcast::None
    } else if y == Shape::new(1, x.h, x.w) {
        Broadcast::OverChannels
    } else if y == Shape::new(x.c, 1, 1) {
        Broadcast::OverSpace
    } else {
        return Err(c.err("mul: second operand neither equal, [1,H,W] nor [C,1,1]"));
    };
    p.consts = size_of::<MulQuant>();
    Ok(())
}

/// The [`MulQuant`].
pub(crate) fn write_consts(c: &ConstCtx, region: &mut [u8]) -> Result<(), Error> {
    let q = MulQuant::new(
        c.q(c.op.inputs[0])?,
        c.q(c.op.inputs[1])?,
        c.q(c.op.output)?,
    );
    write_first(region, c.i, q)
}

/// Multiplies the operands.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let i = e.i;
    let q: MulQuant = first(e.consts, i)?;
    let b: &[i8] = typed(e.ins[1], i)?;
    let b = b
        .get(..e.shape(e.op.inputs[1])?.len().ok_or(e.bad())?)
        .ok_or(e.bad())?;
    let kerr = e.kerr();
    let (a, out) = (typed(e.ins[0], i)?, typed_mut(e.out, i)?);
    elementwise::mul_with(e.isa, &q, a, e.x, b, e.plan.broadcast(i), out).map_err(kerr)?;
    Ok(())
}
