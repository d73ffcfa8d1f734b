//! `conv2d` and `linear` (docs/graph.md): int8 2-D convolution with per-channel weight scales and
//! a fused activation; `linear` is a pointwise conv on a `[C, 1, 1]` input. Kernel:
//! [`crate::kernels::conv`]. A conv whose input is a concat read only by it reads the concat's
//! parts in place ([`eval_on_parts`]); a conv fused into a refinement runs there row by row
//! ([`head`]).

use super::{bad_op, kerr, split, typed, typed_mut, ConstCtx, Eval, PlanCtx, Types};
use crate::blob::format::{activation, opcode, MAX_INPUTS};
use crate::blob::parse::{bad, f32_at, i32_at, Attrs, DType, Geometry, Graph, Reader, NO_PARAM};
use crate::blob::BlobError;
use crate::engine::plan::{wide_parts_bytes, OpPlan, Plan, PlanError};
use crate::engine::Error;
use crate::kernels::conv::{
    conv2d_parts_with, conv2d_with, Activation, ChannelQuant, Conv2d, ConvGeometry, ConvQuant,
    OutRows,
};
use crate::kernels::elementwise::{self, Rescale};
use crate::kernels::isa::Isa;
use crate::kernels::pack::Parts;
use crate::kernels::refine::Head;
use crate::kernels::wide::{conv2d_wide, Codes, CodesMut, MAX_TAPS_WIDE};
use crate::kernels::Shape;
use core::mem::size_of;
use core::ops::Range;

/// One input.
pub(crate) const ARITY: (usize, usize) = (1, 1);

/// Geometry (9 × u16), activation, reserved byte, leaky slope, weight / bias / scale references.
pub(crate) fn read_attrs(code: u8, a: &mut Reader) -> Result<(Attrs, [u32; 3]), BlobError> {
    let at = a.pos;
    let mut raw = [0u16; 9];
    for x in raw.iter_mut() {
        *x = a.u16("conv: geometry")?;
    }
    let v = raw.map(|x| x as usize);
    let act_code = a.u8("conv: activation")?;
    a.u8("conv: reserved")?;
    let alpha = a.f32("conv: alpha")?;
    let refs = [
        a.u32("conv: weight ref")?,
        a.u32("conv: bias ref")?,
        a.u32("conv: scale ref")?,
    ];
    let geometry = ConvGeometry {
        kernel: [v[0], v[1]],
        stride: [v[2], v[3]],
        dilation: [v[4], v[5]],
        padding: [v[6], v[7]],
        groups: v[8],
    };
    if v[..6].contains(&0) || v[8] == 0 {
        return Err(bad(at, "conv: zero kernel, stride, dilation or groups"));
    }
    // Padding past the dilated kernel's reach only adds rows and columns that see no input
    // (an 8 KB blob padded by 65 526 rows asked for 12.8 M MACs at 4×4; no exporter writes it).
    for axis in 0..2 {
        if v[6 + axis] > v[4 + axis] * (v[axis] - 1) {
            return Err(bad(
                at + 2 * (6 + axis),
                "conv: padding beyond the dilated kernel's reach (dilation·(kernel − 1))",
            ));
        }
    }
    if code == opcode::LINEAR && geometry != ConvGeometry::POINTWISE {
        return Err(bad(at, "linear: geometry must be pointwise"));
    }
    let act = match act_code {
        activation::NONE => Activation::None,
        activation::RELU => Activation::Relu,
        activation::LEAKY_RELU if alpha.is_finite() && alpha >= 0.0 => Activation::LeakyRelu(alpha),
        _ => return Err(bad(at + 18, "conv: bad activation or alpha")),
    };
    let attrs = Attrs::Conv {
        geometry: Geometry(raw),
        act,
        weights: NO_PARAM,
        bias: None,
        scales: NO_PARAM,
    };
    Ok((attrs, refs))
}

/// int8 or int16 in and out (an int16 input with at most [`MAX_TAPS_WIDE`] taps per output);
/// channels divisible by the groups.
pub(crate) fn types_ok(k: &Types) -> Result<bool, BlobError> {
    if !(k.int(k.op.inputs[0])? && k.int(k.op.output)?) {
        return Err(bad(
            k.op.offset,
            "conv: input and output must be int8 or int16",
        ));
    }
    let Attrs::Conv { geometry, .. } = &k.op.attrs else {
        return Ok(false);
    };
    let geometry = geometry.get();
    let g = geometry.groups;
    let taps = (k.x.channels / g)
        .saturating_mul(geometry.kernel[0])
        .saturating_mul(geometry.kernel[1]);
    if k.x.dtype == DType::I16 && taps > MAX_TAPS_WIDE {
        return Err(bad(k.op.offset, "conv: too many taps for an int16 input"));
    }
    Ok(k.x.channels.is_multiple_of(g) && k.out.channels.is_multiple_of(g))
}

/// Output by the geometry; scratch [`Conv2d::scratch_len`]; one [`ChannelQuant`] per output
/// channel; MACs = outputs × taps.
pub(crate) fn plan(c: &PlanCtx, p: &mut OpPlan) -> Result<(), PlanError> {
    let Attrs::Conv { geometry, .. } = &c.op.attrs else {
        return Err(c.err("op attributes do not match the opcode"));
    };
    let geometry = geometry.get();
    p.out = geometry
        .output_shape(c.x, c.out_c)
        .ok_or(c.err("conv: no output for this input size"))?;
    p.scratch = Conv2d::scratch_len(&geometry, c.x, p.out)
        .checked_mul(4)
        .ok_or(PlanError::TooLarge)?;
    p.consts = c.out_c * size_of::<ChannelQuant>();
    let taps = geometry
        .weight_len(c.x.c, c.out_c)
        .ok_or(PlanError::TooLarge)?
        / c.out_c;
    p.macs = (p.out.len().ok_or(PlanError::TooLarge)? as u64).saturating_mul(taps as u64);
    Ok(())
}

/// The per-channel requantisation constants.
pub(crate) fn write_consts(c: &ConstCtx, region: &mut [u8]) -> Result<(), Error> {
    fill_channel_quants(c.g, c.i, typed_mut(region, c.i)?)
}

/// Writes conv op `i`'s per-channel requantisation constants into `dst` (one per output
/// channel that `dst` holds).
fn fill_channel_quants(g: &Graph, i: usize, dst: &mut [ChannelQuant]) -> Result<(), Error> {
    let op = g.ops.get(i).ok_or(bad_op(i))?;
    let Attrs::Conv {
        act, bias, scales, ..
    } = &op.attrs
    else {
        return Err(bad_op(i));
    };
    let (in_q, out_q) = (g.tensor(op.inputs[0])?.q, g.tensor(op.output)?.q);
    let sb = g.bytes(*scales);
    for (o, cq) in dst.iter_mut().enumerate() {
        let b = bias.map_or(0, |p| i32_at(g.bytes(p), o));
        *cq = ChannelQuant::new(b, in_q.scale, f32_at(sb, o), out_q.scale, *act);
    }
    Ok(())
}

/// Conv op `j`'s per-channel constants and the scratch its kernel may use: from the
/// persistent region, or computed now at the head of `scratch` ([`Plan::channel_bytes`]).
pub(crate) fn channel_quants<'s>(
    g: &Graph,
    plan: &Plan,
    j: usize,
    consts: &'s [u8],
    scratch: &'s mut [u8],
) -> Result<(&'s [ChannelQuant], &'s mut [u8]), Error> {
    let bad = bad_op(j);
    let bytes = plan.channel_bytes(g, j);
    if bytes == 0 {
        let cb = consts.get(plan.const_range(j).ok_or(bad)?).ok_or(bad)?;
        return Ok((typed(cb, j)?, scratch));
    }
    if scratch.len() < bytes {
        return Err(bad);
    }
    let (head, rest) = scratch.split_at_mut(bytes);
    let out_c = g.tensor(g.ops.get(j).ok_or(bad)?.output)?.channels;
    let cq: &mut [ChannelQuant] = typed_mut(head, j)?;
    let cq = cq.get_mut(..out_c).ok_or(bad)?;
    fill_channel_quants(g, j, cq)?;
    Ok((cq, rest))
}

/// The conv op `j` as a kernel [`Conv2d`] (weights in the blob, constants `channels`).
fn conv_of<'g>(g: &'g Graph, j: usize, channels: &'g [ChannelQuant]) -> Result<Conv2d<'g>, Error> {
    let op = g.ops.get(j).ok_or(bad_op(j))?;
    let Attrs::Conv {
        geometry,
        act,
        weights,
        ..
    } = &op.attrs
    else {
        return Err(bad_op(j));
    };
    let (x, out) = (g.tensor(op.inputs[0])?, g.tensor(op.output)?);
    let quant = match out.dtype {
        DType::I16 => ConvQuant::new_wide(x.q.zero_point, *act),
        _ => ConvQuant::new(x.q.zero_point, out.q.zero_point, *act),
    };
    Ok(Conv2d {
        geometry: geometry.get(),
        quant,
        weights: typed(g.bytes(*weights), j)?,
        channels,
    })
}

/// The conv op `j` fused into op `i` as a refinement [`Head`]: per-channel constants `ch`,
/// its input tensor `input_id` read from `input`.
pub(crate) fn head<'a>(
    g: &'a Graph,
    plan: &Plan,
    i: usize,
    j: u16,
    ch: &'a [ChannelQuant],
    (input, input_id): (&'a [u8], u16),
) -> Result<Head<'a>, Error> {
    let out_id = g.ops.get(usize::from(j)).ok_or(bad_op(i))?.output;
    Ok(Head {
        conv: conv_of(g, usize::from(j), ch)?,
        input: typed(input, i)?,
        in_shape: plan.shape(input_id).ok_or(bad_op(i))?,
        out_q: g.tensor(out_id)?.q,
    })
}

/// Runs the conv on its input (int16 input or output: [`conv2d_wide`]).
pub(crate) fn eval(e: Eval) -> Result<(), Error> {
    let i = e.i;
    let (channels, scratch) = channel_quants(e.g, e.plan, i, e.all_consts, e.scratch)?;
    let conv = conv_of(e.g, i, channels)?;
    let wide = |id: u16| e.g.tensor(id).map(|t| t.dtype == DType::I16);
    if wide(e.op.inputs[0])? || wide(e.op.output)? {
        let x = if wide(e.op.inputs[0])? {
            Codes::I16(typed(e.ins[0], i)?)
        } else {
            Codes::I8(typed(e.ins[0], i)?)
        };
        let out = if wide(e.op.output)? {
            CodesMut::I16(typed_mut(e.out, i)?)
        } else {
            CodesMut::I8(typed_mut(e.out, i)?)
        };
        conv2d_wide(e.isa, &conv, x, e.x, out, typed_mut(scratch, i)?).map_err(kerr(i))?;
        return Ok(());
    }
    let out = typed_mut(e.out, i)?;
    conv2d_with(
        e.isa,
        &conv,
        typed(e.ins[0], i)?,
        e.x,
        out,
        typed_mut(scratch, i)?,
    )
    .map_err(kerr(i))?;
    Ok(())
}

/// Conv op `i` reading the parts of concat op `c` in place, each mapped by a 256-entry table of
/// the concat's rescale (the codes the concat would have written).
// Out of line: its 2 KiB of rescaling tables stay out of `Engine::execute`'s frame, under
// which every op runs (the firmware's stack high-water).
#[inline(never)]
pub(crate) fn eval_on_parts(
    g: &Graph,
    plan: &Plan,
    (i, c): (usize, usize),
    consts: &[u8],
    act: &mut [u8],
    isa: Isa,
) -> Result<(), Error> {
    let bad = bad_op(i);
    let op = g.ops.get(i).ok_or(bad)?;
    let concat = g.ops.get(c).ok_or(bad)?;
    let n = concat.inputs.len();
    let mut in_r: [Range<usize>; MAX_INPUTS] = Default::default();
    for (r, &id) in in_r.iter_mut().zip(&concat.inputs) {
        *r = plan.tensor_range(id).ok_or(bad)?;
    }
    let mut ins: [&[u8]; MAX_INPUTS] = [&[]; MAX_INPUTS];
    let out_r = plan.tensor_range(op.output).ok_or(bad)?;
    let scr_r = plan.scratch_range(i).ok_or(bad)?;
    let (out_b, scr_b) = split(act, out_r, scr_r, &in_r[..n], &mut ins, i)?;
    let rescales: &[Rescale] = typed(consts.get(plan.const_range(c).ok_or(bad)?).ok_or(bad)?, c)?;
    let x: Shape = plan.shape(op.inputs[0]).ok_or(bad)?;
    let mut tables = [[0i8; 256]; MAX_INPUTS];
    let mut parts = Parts::new(x.plane().ok_or(bad)?);
    for (k, t) in tables.iter_mut().enumerate().take(n) {
        let r = rescales.get(k).ok_or(bad)?;
        for (code, v) in t.iter_mut().enumerate() {
            *v = r.apply(code as u8 as i8);
        }
    }
    // int16 parts: requantised to the concat's int8 codes at the end of the scratch (the
    // concat's own kernel, so the bits it would have written), then read like the others.
    let wide = wide_parts_bytes(g, plan.shapes(), c).map_err(|_| bad)?;
    let keep = scr_b.len().checked_sub(wide).ok_or(bad)?;
    let (scr_b, mut wide_b) = scr_b.split_at_mut(keep);
    for (k, &id) in concat.inputs.iter().enumerate() {
        let r = rescales.get(k).ok_or(bad)?;
        let s = plan.shape(id).ok_or(bad)?;
        if g.tensor(id)?.dtype == DType::I16 {
            let len = s.len().ok_or(bad)?;
            let taken = core::mem::take(&mut wide_b);
            let (part, rest) = taken.split_at_mut(len.next_multiple_of(16).min(taken.len()));
            wide_b = rest;
            let part: &mut [i8] = typed_mut(part.get_mut(..len).ok_or(bad)?, i)?;
            let codes = Codes::I16(typed(ins[k], i)?);
            elementwise::concat_part(codes, s, r, CodesMut::I8(part), s, 0).map_err(kerr(i))?;
            let part: &[i8] = part;
            if !parts.push(part, s.c, None) {
                return Err(bad);
            }
            continue;
        }
        let table = (!r.is_identity()).then_some(&tables[k]);
        if !parts.push(typed(ins[k], i)?, s.c, table) {
            return Err(bad);
        }
    }
    let (channels, scr_b) = channel_quants(g, plan, i, consts, scr_b)?;
    let conv = conv_of(g, i, channels)?;
    let out = plan.shape(op.output).ok_or(bad)?;
    let dst = OutRows {
        rows: 0..out.h,
        stride: out.plane().ok_or(bad)?,
    };
    let (out_b, scr_b) = (typed_mut(out_b, i)?, typed_mut(scr_b, i)?);
    conv2d_parts_with(isa, &conv, &parts, x, &dst, out_b, scr_b).map_err(kerr(i))?;
    Ok(())
}
