//! `concat` (docs/graph.md): int8 (or int16) tensors of one spatial size joined along channels
//! into int8 (or int16), each rescaled to the output's quantisation. Kernels:
//! [`crate::kernels::elementwise::concat_part`].
//! Where one conv alone reads it, the planner lets that conv read the parts in place instead
//! ([`super::conv::eval_on_parts`]).

use super::{typed, typed_mut, ConstCtx, Eval, PlanCtx, Types};
use crate::blob::parse::{bad, DType};
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, PlanError};
use crate::engine::Error;
use crate::kernels::elementwise::{self, Rescale};
use crate::kernels::wide::{Codes, CodesMut};
use core::mem::size_of;

/// One to [`crate::blob::format::MAX_INPUTS`] inputs.
pub(crate) const ARITY: (usize, usize) = (1, crate::blob::format::MAX_INPUTS);

/// int8 or int16 in, int8 or int16 out; the output's channels are the inputs' sum.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    let ins =
        k.op.inputs
            .iter()
            .try_fold(true, |ok, &i| Ok(ok && k.int(i)?))?;
    if !(ins && matches!(k.out.dtype, DType::I8 | DType::I16)) {
        return Err(bad(k.op.offset, "concat: int8 or int16 in and out"));
    }
    let sum =
        k.op.inputs
            .iter()
            .try_fold(0usize, |s, &i| k.t(i).map(|ti| s + ti.channels))?;
    Ok(sum == k.out.channels)
}

/// Inputs of one H×W; a [`Rescale`] per input.
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    for &id in &c.op.inputs {
        let s = c.shape(id)?;
        if (s.h, s.w) != (c.x.h, c.x.w) {
            return Err(c.err("concat: inputs differ in H or W"));
        }
    }
    p.consts = c.op.inputs.len() * size_of::<Rescale>();
    Ok(())
}

/// The inputs' [`Rescale`]s.
pub(crate) fn write_consts(c: &ConstCtx, region: &mut [u8]) -> Result<(), Error> {
    let out_q = c.q(c.op.output)?;
    let dst: &mut [Rescale] = typed_mut(region, c.i)?;
    for (d, &id) in dst.iter_mut().zip(&c.op.inputs) {
        *d = Rescale::new(c.q(id)?, out_q);
    }
    Ok(())
}

/// Copies every input, rescaled, into its channels of the output.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let (i, bad, kerr) = (e.i, e.bad(), e.kerr());
    let rs: &[Rescale] = typed(e.consts, i)?;
    let wide_out = e.g.tensor(e.op.output)?.dtype == DType::I16;
    let mut c0 = 0;
    for ((&id, r), b) in e.op.inputs.iter().zip(rs).zip(&e.ins) {
        let s = e.plan.shape(id).ok_or(bad)?;
        let x = if e.g.tensor(id)?.dtype == DType::I16 {
            Codes::I16(typed(b, i)?)
        } else {
            Codes::I8(typed(b, i)?)
        };
        let out = if wide_out {
            CodesMut::I16(typed_mut(e.out, i)?)
        } else {
            CodesMut::I8(typed_mut(e.out, i)?)
        };
        elementwise::concat_part_with(e.isa, x, s, r, out, e.out_shape, c0).map_err(kerr)?;
        c0 += s.c;
    }
    Ok(())
}
