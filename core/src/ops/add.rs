//! `add` (docs/graph.md): int8 + int8 of one shape, each operand rescaled to the output's
//! quantisation. Kernel: [`crate::kernels::elementwise::add`].

use super::{first, typed, typed_mut, write_first, ConstCtx, Eval, PlanCtx, Types};
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, PlanError};
use crate::engine::Error;
use crate::kernels::elementwise::{self, AddQuant};
use core::mem::size_of;

/// Two inputs.
pub(crate) const ARITY: (usize, usize) = (2, 2);

/// int8 in and out, every operand with the output's channels.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    k.all_i8()?;
    let y = k.t(k.op.inputs[1])?;
    Ok(k.x.channels == k.out.channels && y.channels == k.x.channels)
}

/// Operands of one shape; one [`AddQuant`].
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    if c.shape(c.op.inputs[1])? != c.x {
        return Err(c.err("add: operand shapes differ"));
    }
    p.consts = size_of::<AddQuant>();
    Ok(())
}

/// The [`AddQuant`].
pub(crate) fn write_consts(c: &ConstCtx, region: &mut [u8]) -> Result<(), Error> {
    let q = AddQuant::new(
        c.q(c.op.inputs[0])?,
        c.q(c.op.inputs[1])?,
        c.q(c.op.output)?,
    );
    write_first(region, c.i, q)
}

/// Adds the operands.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let i = e.i;
    let q: AddQuant = first(e.consts, i)?;
    let n = e.x.len().ok_or(e.bad())?;
    let (a, b): (&[i8], &[i8]) = (typed(e.ins[0], i)?, typed(e.ins[1], i)?);
    let (a, b) = (a.get(..n).ok_or(e.bad())?, b.get(..n).ok_or(e.bad())?);
    let kerr = e.kerr();
    elementwise::add_with(e.isa, &q, a, b, typed_mut(e.out, i)?).map_err(kerr)?;
    Ok(())
}
