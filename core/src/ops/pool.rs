//! `global_avg_pool`, `global_max_pool` (over space: `[C, 1, 1]` out) and `channel_mean`,
//! `channel_max` (over channels: `[1, H, W]` out), int8 (docs/graph.md). Kernels:
//! [`crate::kernels::pool`].

use super::{first, typed, typed_mut, write_first, ConstCtx, Eval, PlanCtx, Types};
use crate::blob::format::opcode;
use crate::blob::BlobError;
use crate::engine::plan::{OpPlan, PlanError};
use crate::engine::Error;
use crate::kernels::elementwise::Rescale;
use crate::kernels::pool::{self, MeanQuant};
use crate::kernels::Shape;
use core::mem::size_of;

/// One input.
pub(crate) const ARITY: (usize, usize) = (1, 1);

/// int8 in and out; the input's channels out (over space) or one (over channels).
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    k.all_i8()?;
    Ok(match k.op.code {
        opcode::GLOBAL_AVG_POOL | opcode::GLOBAL_MAX_POOL => k.x.channels == k.out.channels,
        _ => k.out.channels == 1,
    })
}

/// `[C, 1, 1]` over space; a [`MeanQuant`] for the means, a [`Rescale`] for the maxima.
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    let code = c.op.code;
    if matches!(code, opcode::GLOBAL_AVG_POOL | opcode::GLOBAL_MAX_POOL) {
        p.out = Shape::new(c.out_c, 1, 1);
    }
    p.consts = match code {
        opcode::GLOBAL_AVG_POOL | opcode::CHANNEL_MEAN => size_of::<MeanQuant>(),
        _ => size_of::<Rescale>(),
    };
    Ok(())
}

/// The mean's [`MeanQuant`] (over `H·W` or `C` values) or the maximum's [`Rescale`].
pub(crate) fn write_consts(c: &ConstCtx, region: &mut [u8]) -> Result<(), Error> {
    let (in_q, out_q) = (c.q(c.op.inputs[0])?, c.q(c.op.output)?);
    match c.op.code {
        opcode::GLOBAL_AVG_POOL | opcode::CHANNEL_MEAN => {
            let s = c.plan.shape(c.op.inputs[0]).ok_or(super::bad_op(c.i))?;
            let n = if c.op.code == opcode::CHANNEL_MEAN {
                s.c
            } else {
                s.h * s.w
            };
            write_first(region, c.i, MeanQuant::new(in_q, out_q, n))?;
        }
        _ => {
            write_first(region, c.i, Rescale::new(in_q, out_q))?;
        }
    }
    Ok(())
}

/// Pools the input.
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let (i, kerr, cb) = (e.i, e.kerr(), e.consts);
    let (x, out) = (typed(e.ins[0], i)?, typed_mut(e.out, i)?);
    match e.op.code {
        opcode::GLOBAL_AVG_POOL => pool::global_avg_pool(&first(cb, i)?, x, e.x, out),
        opcode::GLOBAL_MAX_POOL => pool::global_max_pool(&first(cb, i)?, x, e.x, out),
        opcode::CHANNEL_MEAN => pool::channel_mean_with(e.isa, &first(cb, i)?, x, e.x, out),
        _ => pool::channel_max(&first(cb, i)?, x, e.x, out),
    }
    .map_err(kerr)?;
    Ok(())
}
