//! `mul` (docs/graph.md): int8 × int8, the second operand of the first's shape, `[1, H, W]`
//! (broadcast over channels) or `[C, 1, 1]` (over space). Kernel:
//! [`crate::kernels::elementwise::mul`].

use super::{bad_op, first, split, typed, typed_mut, write_first, ConstCtx, Eval, PlanCtx, Types};
use crate::blob::format::MAX_INPUTS;
use crate::blob::parse::OpInfo;
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, Plan, PlanError};
use crate::engine::Error;
use crate::kernels::broadcast::Broadcast;
use crate::kernels::elementwise::{self, MulQuant};
use crate::kernels::isa::Isa;
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

/// [`eval`] writing the product over the first operand ([`Plan::in_place_of`]):
/// [`elementwise::mul_in_place`], the same bits.
pub(crate) fn eval_in_place(
    plan: &Plan,
    (i, op): (usize, &OpInfo),
    consts: &[u8],
    act: &mut [u8],
    isa: Isa,
) -> Result<(), Error> {
    let bad = bad_op(i);
    let q: MulQuant = first(consts, i)?;
    let x = plan.shape(op.inputs[0]).ok_or(bad)?;
    let y = plan.shape(op.inputs[1]).ok_or(bad)?;
    let out_r = plan.tensor_range(op.output).ok_or(bad)?;
    let b_r = plan.tensor_range(op.inputs[1]).ok_or(bad)?;
    let scr_r = plan.scratch_range(i).ok_or(bad)?;
    let mut ins: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
    let (out_b, _) = split(act, out_r, scr_r.start..scr_r.start, &[b_r], &mut ins, i)?;
    let b: &[i8] = typed(ins[0], i)?;
    let b = b.get(..y.len().ok_or(bad)?).ok_or(bad)?;
    let out: &mut [i8] = typed_mut(out_b, i)?;
    let out = out.get_mut(..x.len().ok_or(bad)?).ok_or(bad)?;
    elementwise::mul_in_place(isa, &q, out, x, b, plan.broadcast(i))
        .map_err(|error| Error::Kernel { op: i, error })
}
