//! 2-D convolution (incl. depthwise, grouped, dilated, 1×1 and `linear` as a 1×1 conv on a 1×1
//! map) with int8 activations, int8 symmetric per-output-channel weights, int32 bias and a fused
//! ReLU / LeakyReLU, per the TFLite int8 spec.
//!
//! For output channel `o`: `acc = bias[o] + Σ w · (x − zp_in)` over the valid taps (padding is
//! real zero, i.e. `zp_in`), then `y = zp_out + M·acc` with `M = s_in·s_w[o]/s_out` for
//! `acc ≥ 0` and `M_neg = α·M` for `acc < 0` (LeakyReLU; `M_neg = M` otherwise), clamped to the
//! activation range (`[zp_out, 127]` for ReLU). Weights are `[O, I/groups, kh, kw]` row-major.

use super::depthwise::{self, Depthwise};
use super::dot::{self, Acc, Steps, Task};
use super::isa::Isa;
use super::pack::{self, Dense, Layout, Pairs, Parts, Quads, SignedQuads, Source, NB, PB};
use super::requant::{clamp_i8, Requant};
use super::wide::Finish;
use super::{need, KernelError, Shape};

/// Activation fused after the bias (sigmoid is a separate LUT op in the blob).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Activation {
    /// Identity.
    None,
    /// `max(x, 0)`.
    Relu,
    /// `x` for `x ≥ 0`, `alpha·x` otherwise (`alpha ≥ 0`).
    LeakyRelu(f32),
}

/// Per-output-channel constants, computed once at prepare time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C)]
pub struct ChannelQuant {
    /// int32 bias in units of `s_in · s_w[o]`.
    pub bias: i32,
    /// Multiplier for non-negative accumulators: `s_in·s_w[o]/s_out`.
    pub pos: Requant,
    /// Multiplier for negative accumulators (`alpha ·` the above for LeakyReLU).
    pub neg: Requant,
}

impl ChannelQuant {
    /// Builds the constants of one channel from the real scales.
    pub fn new(bias: i32, s_in: f32, s_w: f32, s_out: f32, act: Activation) -> ChannelQuant {
        let m = s_in as f64 * s_w as f64 / s_out as f64;
        let pos = Requant::from_real(m);
        let neg = match act {
            Activation::LeakyRelu(a) => Requant::from_real(m * a as f64),
            _ => pos,
        };
        ChannelQuant { bias, pos, neg }
    }
}

/// Kernel size, stride, dilation, symmetric zero padding and groups.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConvGeometry {
    /// Kernel `[kh, kw]`.
    pub kernel: [usize; 2],
    /// Stride `[sh, sw]` (≥ 1).
    pub stride: [usize; 2],
    /// Dilation `[dh, dw]` (≥ 1).
    pub dilation: [usize; 2],
    /// Zero padding `[ph, pw]` on both sides.
    pub padding: [usize; 2],
    /// Groups (divides both channel counts; `groups = C` is depthwise).
    pub groups: usize,
}

impl ConvGeometry {
    /// A 1×1, stride-1, unpadded, ungrouped conv (also `linear` on a `[I,1,1]` input).
    pub const POINTWISE: ConvGeometry = ConvGeometry {
        kernel: [1, 1],
        stride: [1, 1],
        dilation: [1, 1],
        padding: [0, 0],
        groups: 1,
    };

    /// Output shape for an input shape and `out_c` output channels; `None` if inconsistent.
    pub fn output_shape(&self, input: Shape, out_c: usize) -> Option<Shape> {
        let g = self.groups;
        if g == 0
            || !input.c.is_multiple_of(g)
            || !out_c.is_multiple_of(g)
            || out_c == 0
            || input.c == 0
        {
            return None;
        }
        let dim = |n: usize, k: usize, s: usize, d: usize, p: usize| -> Option<usize> {
            if k == 0 || s == 0 || d == 0 {
                return None;
            }
            let span = d.checked_mul(k - 1)?.checked_add(1)?;
            let padded = n.checked_add(p.checked_mul(2)?)?;
            if padded < span {
                return None;
            }
            Some((padded - span) / s + 1)
        };
        let h = dim(
            input.h,
            self.kernel[0],
            self.stride[0],
            self.dilation[0],
            self.padding[0],
        )?;
        let w = dim(
            input.w,
            self.kernel[1],
            self.stride[1],
            self.dilation[1],
            self.padding[1],
        )?;
        Some(Shape::new(out_c, h, w))
    }

    /// Number of weights, `[O, I/groups, kh, kw]`.
    pub fn weight_len(&self, in_c: usize, out_c: usize) -> Option<usize> {
        out_c
            .checked_mul(in_c.checked_div(self.groups)?)?
            .checked_mul(self.kernel[0])?
            .checked_mul(self.kernel[1])
    }
}

/// Zero points and the clamp range of the output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConvQuant {
    /// Input zero point.
    pub input_zero_point: i32,
    /// Output zero point.
    pub output_zero_point: i32,
    /// Lowest output code (`zp_out` for ReLU, −128 otherwise).
    pub act_min: i32,
    /// Highest output code.
    pub act_max: i32,
}

impl ConvQuant {
    /// Zero points and the clamp range for an activation.
    pub fn new(input_zero_point: i32, output_zero_point: i32, act: Activation) -> ConvQuant {
        let act_min = if act == Activation::Relu {
            output_zero_point.max(-128)
        } else {
            -128
        };
        ConvQuant {
            input_zero_point,
            output_zero_point,
            act_min,
            act_max: 127,
        }
    }

    /// Zero points and the clamp range of an int16 output (zero point 0: `[0, 32767]` for
    /// ReLU, `[−32768, 32767]` otherwise; [`super::wide`]).
    pub fn new_wide(input_zero_point: i32, act: Activation) -> ConvQuant {
        ConvQuant {
            input_zero_point,
            output_zero_point: 0,
            act_min: if act == Activation::Relu { 0 } else { -32768 },
            act_max: 32767,
        }
    }
}

/// One prepared convolution: geometry, zero points, weights and per-channel constants.
#[derive(Clone, Copy, Debug)]
pub struct Conv2d<'a> {
    /// Kernel geometry.
    pub geometry: ConvGeometry,
    /// Zero points and clamp range.
    pub quant: ConvQuant,
    /// `[O, I/groups, kh, kw]` int8 weights.
    pub weights: &'a [i8],
    /// One entry per output channel.
    pub channels: &'a [ChannelQuant],
}

/// Largest `I/groups · kh · kw` accepted, so that `acc` cannot overflow `i32`
/// (`127 · 255 · 65536 < 2^31`).
pub const MAX_TAPS: usize = 65_536;

impl Conv2d<'_> {
    /// Checks the op against an input shape; returns the output shape. The input zero point
    /// must be an int8 value (so `x − zp` and its product with a weight fit 16 bits).
    pub fn check(&self, in_shape: Shape) -> Result<Shape, KernelError> {
        if !(-128..=127).contains(&self.quant.input_zero_point) {
            return Err(KernelError::Attr);
        }
        let out_c = self.channels.len();
        let out = self
            .geometry
            .output_shape(in_shape, out_c)
            .ok_or(KernelError::Attr)?;
        let wl = self
            .geometry
            .weight_len(in_shape.c, out_c)
            .ok_or(KernelError::Attr)?;
        if self.weights.len() != wl || wl / out_c > MAX_TAPS {
            return Err(KernelError::Attr);
        }
        Ok(out)
    }

    /// i32 scratch elements [`conv2d`] needs, for every kernel set: the packed input rows of
    /// one output row, the packed weights of one group, `Σw` per output channel and the tap
    /// offsets of the reduction steps ([`super::pack`]), sized for 16-bit elements and channels
    /// rounded up to 4.
    pub fn scratch_len(geometry: &ConvGeometry, in_shape: Shape, out_shape: Shape) -> usize {
        let g = geometry;
        let Some(icg) = in_shape.c.checked_div(g.groups) else {
            return 0;
        };
        let ocg = out_shape.c / g.groups.max(1);
        let c4 = icg.div_ceil(4).saturating_mul(4);
        let k = g.kernel[0].saturating_mul(g.kernel[1]);
        let rows = c4
            .saturating_mul(g.kernel[0])
            .saturating_mul(g.stride[1])
            .saturating_mul(pack::row_width(g, out_shape.w));
        let weights = pack::blocks_per_pack(g, icg, ocg.div_ceil(NB))
            .saturating_mul(NB)
            .saturating_mul(c4)
            .saturating_mul(k);
        // 2-byte elements, in i32 units; then Σw per channel and one u32 per reduction step
        // (tap, channel pair).
        (rows.div_ceil(2))
            .saturating_add(weights.div_ceil(2))
            .saturating_add(ocg)
            .saturating_add(k.saturating_mul(icg.div_ceil(2)))
            .saturating_add(g.kernel[0])
    }

    /// The requantisation constants of channel `o` for sums offset by `base` (`simple` false
    /// where a multiplier shifts left: then [`Conv2d::finish`] runs per element).
    pub(super) fn row_quant(&self, o: usize, base: i32) -> RowQuant {
        let cq = &self.channels[o];
        RowQuant {
            simple: cq.pos.shift <= 0
                && cq.neg.shift <= 0
                && cq.pos.multiplier >= 0
                && cq.neg.multiplier >= 0,
            base,
            pos_m: cq.pos.multiplier,
            neg_m: cq.neg.multiplier,
            pos_r: (-cq.pos.shift).min(31),
            neg_r: (-cq.neg.shift).min(31),
            zp: self.quant.output_zero_point,
            min: self.quant.act_min.max(-128),
            max: self.quant.act_max.min(127),
            narrow: {
                // |x − zp| ≤ 255 and |w| ≤ 128 per tap.
                let taps = self.weights.len() / self.channels.len().max(1);
                let bound = (taps as u64) * 255 * 128 + u64::from(base.unsigned_abs());
                bound < 1 << 30
            },
        }
    }

    /// Requantises the first `nb` rows (`n` sums each) of `acc` for output channels
    /// `o0 ..` into `output` at `at` (channel stride `plane`), vectorised where the set has
    /// vectors (the same integer function, so the same bits).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn finish_block(
        &self,
        isa: Isa,
        rq: &[RowQuant],
        o0: usize,
        acc: &Acc,
        n: usize,
        output: &mut [i8],
        at: usize,
        plane: usize,
    ) {
        #[cfg(target_arch = "x86_64")]
        if matches!(isa, Isa::Avx2 | Isa::Avx512Vnni)
            && Isa::Avx2.available()
            && rq.iter().all(|r| r.simple)
        {
            // SAFETY: AVX2 is available; `acc` holds nb ≤ NB rows of PB ≥ n and the caller's
            // output rows `at + j·plane .. + n` exist.
            unsafe {
                if Isa::Avx512Vnni.available() && isa == Isa::Avx512Vnni {
                    super::x86_64::requant::block512(rq, acc, PB, n, output, at, plane, |k, v| {
                        requant_one(k, v)
                    })
                } else {
                    super::x86_64::requant::block(rq, acc, PB, n, output, at, plane, |k, v| {
                        requant_one(k, v)
                    })
                }
            };
            return;
        }
        #[cfg(target_arch = "aarch64")]
        if matches!(isa, Isa::Neon | Isa::NeonDot)
            && super::aarch64::requant::block(rq, acc, PB, n, output, at, plane, requant_one)
        {
            return;
        }
        let _ = isa;
        for (j, (r, a)) in rq.iter().zip(acc.chunks_exact(PB)).enumerate() {
            let dst = &mut output[at + j * plane..at + j * plane + n];
            if r.simple {
                requant_row(r, a, dst);
            } else {
                for (d, &v) in dst.iter_mut().zip(a) {
                    *d = self.finish(o0 + j, r.base.wrapping_add(v));
                }
            }
        }
    }

    /// Requantises one output channel's sums `acc` (any number) into `dst`, as
    /// [`Conv2d::finish_block`] does a row of a block: the same bits.
    pub(super) fn finish_run(
        &self,
        isa: Isa,
        rq: &RowQuant,
        o: usize,
        acc: &[i32],
        dst: &mut [i8],
    ) {
        let n = acc.len().min(dst.len());
        #[cfg(target_arch = "x86_64")]
        if matches!(isa, Isa::Avx2 | Isa::Avx512Vnni) && Isa::Avx2.available() && rq.simple {
            let rq = core::slice::from_ref(rq);
            // SAFETY: AVX2 is available; `acc` and `dst` hold `n` each (one row, at 0).
            unsafe {
                if Isa::Avx512Vnni.available() && isa == Isa::Avx512Vnni {
                    super::x86_64::requant::block512(rq, acc, n, n, dst, 0, n, |k, v| {
                        requant_one(k, v)
                    })
                } else {
                    super::x86_64::requant::block(rq, acc, n, n, dst, 0, n, |k, v| {
                        requant_one(k, v)
                    })
                }
            };
            return;
        }
        #[cfg(target_arch = "aarch64")]
        if matches!(isa, Isa::Neon | Isa::NeonDot) {
            let one = core::slice::from_ref(rq);
            if super::aarch64::requant::block(one, acc, n, n, dst, 0, n, requant_one) {
                return;
            }
        }
        let _ = isa;
        if rq.simple {
            requant_row(rq, &acc[..n], &mut dst[..n]);
        } else {
            for (d, &v) in dst[..n].iter_mut().zip(acc) {
                *d = self.finish(o, rq.base.wrapping_add(v));
            }
        }
    }

    /// [`Conv2d::finish_block`] for rows of `n ≤ stride` sums `stride` apart (a whole output
    /// row of blocks, `run_pack` on aarch64): the NEON requantisation, else the portable loops.
    #[cfg(target_arch = "aarch64")]
    #[allow(clippy::too_many_arguments)]
    fn finish_wide(
        &self,
        rq: &[RowQuant],
        o0: usize,
        (acc, stride, n): (&[i32], usize, usize),
        output: &mut [i8],
        at: usize,
        plane: usize,
    ) {
        if super::aarch64::requant::block(rq, acc, stride, n, output, at, plane, requant_one) {
            return;
        }
        for (j, r) in rq.iter().enumerate() {
            let a = &acc[j * stride..j * stride + n];
            let dst = &mut output[at + j * plane..at + j * plane + n];
            if r.simple {
                requant_row(r, a, dst);
            } else {
                for (d, &v) in dst.iter_mut().zip(a) {
                    *d = self.finish(o0 + j, r.base.wrapping_add(v));
                }
            }
        }
    }

    #[inline]
    pub(super) fn finish(&self, o: usize, acc: i32) -> i8 {
        let cq = &self.channels[o];
        let r = if acc >= 0 {
            cq.pos.apply(acc)
        } else {
            cq.neg.apply(acc)
        };
        clamp_i8(
            r.saturating_add(self.quant.output_zero_point),
            self.quant.act_min,
            self.quant.act_max,
        )
    }
}

/// Requantisation constants of one output channel (`simple`: multipliers ≥ 0 shifting right
/// only, the case `requant_one` and the vector paths handle).
#[derive(Clone, Copy, Debug, Default)]
pub struct RowQuant {
    /// Whether `requant_one` applies.
    pub simple: bool,
    /// Added to every accumulator first (bias and packing terms).
    pub base: i32,
    /// Q31 multiplier for sums ≥ 0.
    pub pos_m: i32,
    /// Q31 multiplier for sums < 0.
    pub neg_m: i32,
    /// Right shift for sums ≥ 0 (`0..=31`).
    pub pos_r: i32,
    /// Right shift for sums < 0.
    pub neg_r: i32,
    /// Output zero point.
    pub zp: i32,
    /// Lowest output code.
    pub min: i32,
    /// Highest output code.
    pub max: i32,
    /// Whether every `base + acc` the conv can produce has `|·| < 2^30` (taps · 255 · 128 +
    /// |base| below it), which lets the Cortex-M path double it and use `SMMULR`.
    pub narrow: bool,
}

/// `clamp(zp + MultiplyByQuantizedMultiplier(base + acc, M±))` for `shift ≤ 0` and a
/// non-negative multiplier ([`Requant::apply`] bit for bit, then no left shift and no saturating
/// case) in two roundings that each reduce to one add and one shift:
/// - SaturatingRoundingDoublingHighMul `trunc((ab + nudge) / 2^31)` with
///   `nudge = 2^30` for `ab ≥ 0` and `1 − 2^30` for `ab < 0` equals `floor((ab + 2^30) / 2^31)`
///   for both signs (for `ab < 0`, `trunc(t / 2^31) = floor((t + 2^31 − 1) / 2^31)`);
/// - RoundingDivideByPOT (half away from zero) by `2^e`, `e ≥ 1`, equals
///   `floor((q + 2^(e−1) − [q < 0]) / 2^e)`.
#[inline(always)]
fn requant_one(k: &RowQuant, v: i32) -> i8 {
    let x = k.base.wrapping_add(v);
    let (m, e) = if x < 0 {
        (k.neg_m, k.neg_r)
    } else {
        (k.pos_m, k.pos_r)
    };
    let q = ((x as i64 * m as i64 + (1 << 30)) >> 31) as i32;
    // In 32 bits: floor((q + c) / 2^e) = (q >> e) + floor((q mod 2^e + c) / 2^e), and
    // q mod 2^e + 2^(e−1) − [q < 0] lies in 0 .. 2^31 + 2^30 (u32, e ≤ 31).
    let r = if e <= 0 {
        q
    } else {
        let e = e.min(31) as u32;
        let low = (q as u32 & ((1u32 << e) - 1)) + (1u32 << (e - 1)) - u32::from(q < 0);
        (q >> e) + (low >> e) as i32
    };
    r.saturating_add(k.zp).clamp(k.min, k.max) as i8
}

/// [`requant_one`] over `acc` into `dst` (as many as the shorter holds), with the row's
/// constants hoisted out of the loop and one loop per case (the same multiplier for both signs,
/// with or without a rounding shift): the same bits at about half the instructions on a
/// Cortex-M. Clamping to `min − zp ..= max − zp` before adding `zp` equals the saturating add
/// then the clamp, as the bounds lie in −255 ..= 255.
#[inline(always)]
fn requant_row(k: &RowQuant, acc: &[i32], dst: &mut [i8]) {
    let (lo, hi) = (k.min - k.zp, k.max - k.zp);
    let (base, zp) = (k.base, k.zp);
    let high_mul = |x: i32, m: i32| ((x as i64 * m as i64 + (1 << 30)) >> 31) as i32;
    let fin = |r: i32| (r.max(lo).min(hi) + zp) as i8;
    if k.pos_m != k.neg_m || k.pos_r != k.neg_r {
        #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
        {
            let (pos, neg) = ((k.pos_m, k.pos_r), (k.neg_m, k.neg_r));
            if super::arm::dsp::requant_row_signed(
                acc, dst, base, pos, neg, zp, k.min, k.max, k.narrow,
            ) {
                return;
            }
        }
        for (d, &v) in dst.iter_mut().zip(acc) {
            *d = requant_one(k, v);
        }
        return;
    }
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    if super::arm::dsp::requant_row(
        acc,
        dst,
        base,
        (k.pos_m, k.pos_r),
        zp,
        k.min,
        k.max,
        k.narrow,
    ) {
        return;
    }
    let (m, e) = (k.pos_m, k.pos_r.clamp(0, 31) as u32);
    if e == 0 {
        for (d, &v) in dst.iter_mut().zip(acc) {
            *d = fin(high_mul(base.wrapping_add(v), m));
        }
        return;
    }
    let (mask, half) = ((1u32 << e) - 1, 1u32 << (e - 1));
    for (d, &v) in dst.iter_mut().zip(acc) {
        let q = high_mul(base.wrapping_add(v), m);
        let low = (q as u32 & mask) + half - (q as u32 >> 31);
        *d = fin((q >> e) + (low >> e) as i32);
    }
}

/// Reference convolution: plain loops over every output element and tap (the spec).
pub fn conv2d_ref(
    op: &Conv2d,
    input: &[i8],
    in_shape: Shape,
    output: &mut [i8],
    _scratch: &mut [i32],
) -> Result<Shape, KernelError> {
    let out = op.check(in_shape)?;
    need(input, in_shape)?;
    need(output, out)?;
    let g = &op.geometry;
    let icg = in_shape.c / g.groups;
    let ocg = out.c / g.groups;
    let zp = op.quant.input_zero_point;
    for o in 0..out.c {
        let grp = o / ocg;
        for oy in 0..out.h {
            for ox in 0..out.w {
                let mut acc = op.channels[o].bias;
                for i in 0..icg {
                    let ic = grp * icg + i;
                    for ky in 0..g.kernel[0] {
                        for kx in 0..g.kernel[1] {
                            let iy = (oy * g.stride[0] + ky * g.dilation[0]) as isize
                                - g.padding[0] as isize;
                            let ix = (ox * g.stride[1] + kx * g.dilation[1]) as isize
                                - g.padding[1] as isize;
                            if iy < 0
                                || ix < 0
                                || iy >= in_shape.h as isize
                                || ix >= in_shape.w as isize
                            {
                                continue;
                            }
                            let x = input
                                [(ic * in_shape.h + iy as usize) * in_shape.w + ix as usize]
                                as i32;
                            let w = op.weights
                                [((o * icg + i) * g.kernel[0] + ky) * g.kernel[1] + kx]
                                as i32;
                            acc = acc.wrapping_add(w * (x - zp));
                        }
                    }
                }
                output[(o * out.h + oy) * out.w + ox] = op.finish(o, acc);
            }
        }
    }
    Ok(out)
}

/// Fast convolution with the fastest kernel set of this CPU ([`Isa::best`]): same contract
/// and bits as [`conv2d_ref`]. `scratch` holds ≥ [`Conv2d::scratch_len`] i32.
pub fn conv2d(
    op: &Conv2d,
    input: &[i8],
    in_shape: Shape,
    output: &mut [i8],
    scratch: &mut [i32],
) -> Result<Shape, KernelError> {
    conv2d_with(Isa::best(), op, input, in_shape, output, scratch)
}

/// As [`conv2d`] with the kernel set `isa` (`Err(Isa)` if this CPU cannot run it).
///
/// Per group, the weights are packed once ([`pack::pack_weights`]); per output row, the input
/// input rows it reads that the previous output row did not are packed with channels innermost
/// into row slots ([`pack::pack_row`], [`pack::row_slot`]); then for each
/// [`PB`]-pixel block and [`NB`]-channel block one micro-kernel ([`super::dot`]) computes the
/// sums in registers before requantisation.
pub fn conv2d_with(
    isa: Isa,
    op: &Conv2d,
    input: &[i8],
    in_shape: Shape,
    output: &mut [i8],
    scratch: &mut [i32],
) -> Result<Shape, KernelError> {
    let out = op.check(in_shape)?;
    let plane = out.plane().ok_or(KernelError::Shape)?;
    let dst = OutRows {
        rows: 0..out.h,
        stride: plane,
    };
    conv2d_rows_with(isa, op, input, in_shape, &dst, output, scratch)?;
    Ok(out)
}

/// Where [`conv2d_rows_with`] writes: output rows `rows` of every channel, channel `o`'s row
/// `y` at `o · stride + (y − rows.start) · W` of the output slice.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutRows {
    /// Output rows computed.
    pub rows: core::ops::Range<usize>,
    /// Elements between two channels in the output slice (≥ `rows.len() · W`).
    pub stride: usize,
}

/// Checks `dst` against the output shape and the output and scratch lengths; returns the
/// scratch the conv uses.
fn check_buffers(
    isa: Isa,
    op: &Conv2d,
    in_shape: Shape,
    out: Shape,
    dst: &OutRows,
    output_len: usize,
    scratch_len: usize,
) -> Result<usize, KernelError> {
    let band = dst
        .rows
        .len()
        .checked_mul(out.w)
        .ok_or(KernelError::Shape)?;
    let last = (out.c.saturating_sub(1))
        .checked_mul(dst.stride)
        .and_then(|n| n.checked_add(band))
        .ok_or(KernelError::Shape)?;
    if dst.rows.start > dst.rows.end
        || dst.rows.end > out.h
        || dst.stride < band
        || output_len < last
    {
        return Err(KernelError::Shape);
    }
    if !isa.available() {
        return Err(KernelError::Isa);
    }
    let len = Conv2d::scratch_len(&op.geometry, in_shape, out);
    if scratch_len < len {
        return Err(KernelError::Scratch);
    }
    Ok(len)
}

/// As [`conv2d_with`] for the output rows `dst.rows` only, written at `dst`'s layout: each
/// row gets the bits the whole convolution gives it (the refinement computes its affinity
/// heads one row at a time this way). Returns the whole output's shape.
pub fn conv2d_rows_with(
    isa: Isa,
    op: &Conv2d,
    input: &[i8],
    in_shape: Shape,
    dst: &OutRows,
    output: &mut [i8],
    scratch: &mut [i32],
) -> Result<Shape, KernelError> {
    conv2d_rows_packed(isa, op, input, in_shape, dst, output, scratch, false)
}

/// As [`conv2d_rows_with`]; with `weights_packed`, a one-group conv skips packing its weights
/// and uses those its previous call (same `isa`, `op`, `in_shape` and `input`) left in
/// `scratch`, and the input rows it packed there: the refinement's heads pack their weights
/// once per branch, not once per row, and each input row about once.
#[allow(clippy::too_many_arguments)]
pub fn conv2d_rows_packed(
    isa: Isa,
    op: &Conv2d,
    input: &[i8],
    in_shape: Shape,
    dst: &OutRows,
    output: &mut [i8],
    scratch: &mut [i32],
    weights_packed: bool,
) -> Result<Shape, KernelError> {
    let packed = weights_packed;
    let out = op.check(in_shape)?;
    need(input, in_shape)?;
    let len = check_buffers(isa, op, in_shape, out, dst, output.len(), scratch.len())?;
    let depthwise = op.geometry.groups == in_shape.c
        && out.c == in_shape.c
        && len >= out.w.div_ceil(PB) * PB + in_shape.w;
    let scratch = &mut scratch[..len];
    let src = Dense {
        data: input,
        plane: in_shape.plane().ok_or(KernelError::Shape)?,
    };
    match isa {
        _ if depthwise => {
            let call = Depthwise {
                isa,
                op,
                input,
                in_shape,
                out,
                dst,
            };
            depthwise::conv(&call, output, scratch)
        }
        Isa::Avx512Vnni => {
            run::<Quads, _, _>(isa, op, &src, in_shape, out, dst, output, scratch, packed)
        }
        Isa::NeonDot => {
            run::<SignedQuads, _, _>(isa, op, &src, in_shape, out, dst, output, scratch, packed)
        }
        _ => run::<Pairs, _, _>(isa, op, &src, in_shape, out, dst, output, scratch, packed),
    }
    Ok(out)
}

/// As [`conv2d_rows_with`] on an input given as the parts of a concat, read in place (each
/// part's codes mapped to the concat's by its table): the bits of the conv run on the concat's
/// output. `in_shape.c` must equal the parts' channels; depthwise convs are not accepted
/// (`Err(Attr)`).
pub fn conv2d_parts_with(
    isa: Isa,
    op: &Conv2d,
    input: &Parts,
    in_shape: Shape,
    dst: &OutRows,
    output: &mut [i8],
    scratch: &mut [i32],
) -> Result<Shape, KernelError> {
    let out = op.check(in_shape)?;
    if input.channels() != in_shape.c {
        return Err(KernelError::Shape);
    }
    let len = check_buffers(isa, op, in_shape, out, dst, output.len(), scratch.len())?;
    if op.geometry.groups == in_shape.c && out.c == in_shape.c && in_shape.c > 1 {
        return Err(KernelError::Attr);
    }
    let scratch = &mut scratch[..len];
    match isa {
        Isa::Avx512Vnni => {
            run::<Quads, _, _>(isa, op, input, in_shape, out, dst, output, scratch, false)
        }
        Isa::NeonDot => {
            run::<SignedQuads, _, _>(isa, op, input, in_shape, out, dst, output, scratch, false)
        }
        _ => run::<Pairs, _, _>(isa, op, input, in_shape, out, dst, output, scratch, false),
    }
    Ok(out)
}

/// As [`conv2d_with`] into int16 codes (`op.quant` from [`ConvQuant::new_wide`]): the fast
/// kernels' sums, each requantised by [`super::wide`]'s rule (the same bits as its scalar loop).
/// Every geometry runs the dense path (no depthwise special case).
pub fn conv2d_i16_with(
    isa: Isa,
    op: &Conv2d,
    input: &[i8],
    in_shape: Shape,
    output: &mut [i16],
    scratch: &mut [i32],
) -> Result<Shape, KernelError> {
    let out = op.check(in_shape)?;
    need(input, in_shape)?;
    let dst = OutRows {
        rows: 0..out.h,
        stride: out.plane().ok_or(KernelError::Shape)?,
    };
    let len = check_buffers(isa, op, in_shape, out, &dst, output.len(), scratch.len())?;
    let scratch = &mut scratch[..len];
    let src = Dense {
        data: input,
        plane: in_shape.plane().ok_or(KernelError::Shape)?,
    };
    match isa {
        Isa::Avx512Vnni => {
            run::<Quads, _, _>(isa, op, &src, in_shape, out, &dst, output, scratch, false)
        }
        Isa::NeonDot => {
            run::<SignedQuads, _, _>(isa, op, &src, in_shape, out, &dst, output, scratch, false)
        }
        _ => run::<Pairs, _, _>(isa, op, &src, in_shape, out, &dst, output, scratch, false),
    }
    Ok(out)
}

/// Splits 4-aligned scratch into `n` elements of `T` (a 1-, 2- or 4-byte integer, rounded up
/// to whole i32) and the rest.
pub(super) fn take<T: Copy>(s: &mut [i32], n: usize) -> (&mut [T], &mut [i32]) {
    let words = (n * size_of::<T>()).div_ceil(4);
    let (head, rest) = s.split_at_mut(words);
    // SAFETY: `T` is a plain integer with alignment ≤ 4 (every bit pattern valid), so the whole
    // of the i32 slice is the aligned middle.
    let (_, mid, _) = unsafe { head.align_to_mut::<T>() };
    (&mut mid[..n], rest)
}

/// The micro-kernel of layout `F` for kernel set `isa` (the portable one where `isa` has none
/// for this layout).
trait Micro: Layout + Sized {
    fn kernel(isa: Isa, t: &Task<Self::Elem, Self::W>, acc: &mut Acc);
    /// As [`Micro::kernel`], channel `j`'s sums written at `dst + j·stride` (the kernel's
    /// whole 16-pixel groups); `false` (nothing done) where the set has no such kernel.
    ///
    /// # Safety
    /// `dst + j·stride + i` must be valid for writes for `j < t.channels`,
    /// `i < 16·⌈t.pixels/16⌉`.
    #[cfg(target_arch = "aarch64")]
    unsafe fn kernel_into(
        _isa: Isa,
        _t: &Task<Self::Elem, Self::W>,
        _dst: *mut i32,
        _stride: usize,
    ) -> bool {
        false
    }
}

impl Micro for Pairs {
    #[inline]
    fn kernel(isa: Isa, t: &Task<i16, i16>, acc: &mut Acc) {
        let done = match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => super::x86_64::avx2::pairs(t, acc),
            #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
            Isa::ArmDsp => super::arm::dsp::pairs(t, acc),
            #[cfg(target_arch = "aarch64")]
            Isa::Neon => super::aarch64::neon::pairs(t, acc),
            _ => false,
        };
        if !done {
            dot::portable::<i16, i16, 2>(t, acc);
        }
    }
}

impl Micro for Quads {
    #[inline]
    fn kernel(isa: Isa, t: &Task<u8, i8>, acc: &mut Acc) {
        let done = match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512Vnni => super::x86_64::avx512_vnni::quads(t, acc),
            _ => false,
        };
        if !done {
            dot::portable::<u8, i8, 4>(t, acc);
        }
    }
}

impl Micro for SignedQuads {
    #[inline]
    fn kernel(isa: Isa, t: &Task<i8, i8>, acc: &mut Acc) {
        let done = match isa {
            #[cfg(target_arch = "aarch64")]
            Isa::NeonDot => super::aarch64::dotprod::quads(t, acc),
            _ => false,
        };
        if !done {
            dot::portable::<i8, i8, 4>(t, acc);
        }
    }
    /// # Safety
    /// As the trait's.
    #[cfg(target_arch = "aarch64")]
    #[inline]
    unsafe fn kernel_into(isa: Isa, t: &Task<i8, i8>, dst: *mut i32, stride: usize) -> bool {
        // SAFETY: the caller's contract is `quads_into`'s.
        isa == Isa::NeonDot && unsafe { super::aarch64::dotprod::quads_into(t, dst, stride) }
    }
}

#[allow(clippy::too_many_arguments)]
fn run<F: Micro, S: Source, O: Sink + ?Sized>(
    isa: Isa,
    op: &Conv2d,
    input: &S,
    in_shape: Shape,
    out: Shape,
    dst: &OutRows,
    output: &mut O,
    scratch: &mut [i32],
    weights_packed: bool,
) {
    let g = &op.geometry;
    let (kh, kw) = (g.kernel[0], g.kernel[1]);
    let icg = in_shape.c / g.groups;
    let ocg = out.c / g.groups;
    let dims = pack::Dims::new(g, icg, ocg, out.w, F::L);
    let per_pack = pack::blocks_per_pack(g, icg, dims.n_blocks);
    let (rows, rest) = take::<F::Elem>(scratch, dims.rows_len());
    let (weights, rest) = take::<F::W>(rest, per_pack * dims.block_len);
    let (sums, rest) = take::<i32>(rest, ocg);
    let (steps, rest) = take::<u32>(rest, kh * kw * dims.n_cg);
    // Input row held by each row slot (`pack::row_slot`); the packed rows depend on the input
    // only, so they stay valid across packs and, with `weights_packed`, across calls.
    let (slots, _) = take::<i32>(rest, kh);
    if !weights_packed || g.groups > 1 {
        slots.fill(i32::MIN);
    }
    let group_shape = Shape::new(icg, in_shape.h, in_shape.w);
    let mut acc: Acc = [0; NB * PB];
    let taps = icg * kh * kw;
    // The packed weights stay valid across calls only where one pack holds them all.
    let keep = weights_packed && g.groups == 1 && per_pack >= dims.n_blocks;
    for grp in 0..g.groups {
        if grp > 0 {
            slots.fill(i32::MIN);
        }
        let o_first = grp * ocg;
        for first_block in (0..dims.n_blocks).step_by(per_pack) {
            // Channels c0 .. c0 + nc of the group, packed together.
            let c0 = first_block * NB;
            let nc = (per_pack * NB).min(ocg - c0);
            let w = &op.weights[(o_first + c0) * taps..(o_first + c0 + nc) * taps];
            if !keep {
                pack::pack_weights::<F>(g, w, icg, nc, &dims, weights, sums);
            }
            let pack = Pack {
                weights,
                sums,
                first: o_first + c0,
                channels: nc,
            };
            run_pack::<F, S, O>(
                isa,
                op,
                input,
                grp * icg,
                group_shape,
                out,
                dst,
                output,
                (&mut *rows, &mut *steps, &mut *slots),
                &dims,
                &pack,
                &mut acc,
            );
        }
    }
}

/// Where [`run`] puts a block's sums, requantised: int8 codes ([`Conv2d::finish_block`]) or
/// int16 codes ([`super::wide`]'s rule, scalar).
trait Sink {
    /// The int8 codes, where the sink is int8 (the wide-row requantisation of `run_pack`).
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn as_i8(&mut self) -> Option<&mut [i8]> {
        None
    }
    /// Requantises the first `n` sums of each of the `rq.len()` rows of `acc` (output channels
    /// `o0 ..`) to `self` at `at`, channel stride `plane`.
    fn block(
        &mut self,
        op: &Conv2d,
        isa: Isa,
        rows: (&[RowQuant], usize),
        sums: (&Acc, usize),
        at: usize,
        plane: usize,
    );
}

impl Sink for [i8] {
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn as_i8(&mut self) -> Option<&mut [i8]> {
        Some(self)
    }
    #[inline(always)]
    fn block(
        &mut self,
        op: &Conv2d,
        isa: Isa,
        (rq, o0): (&[RowQuant], usize),
        (acc, n): (&Acc, usize),
        at: usize,
        plane: usize,
    ) {
        op.finish_block(isa, rq, o0, acc, n, self, at, plane);
    }
}

impl Sink for [i16] {
    #[inline(always)]
    fn block(
        &mut self,
        op: &Conv2d,
        isa: Isa,
        (rq, o0): (&[RowQuant], usize),
        (acc, n): (&Acc, usize),
        at: usize,
        plane: usize,
    ) {
        #[cfg(target_arch = "aarch64")]
        if matches!(isa, Isa::Neon | Isa::NeonDot) {
            let bounds = (op.quant.act_min, op.quant.act_max);
            if super::aarch64::requant::block_i16(rq, bounds, acc, PB, n, self, at, plane) {
                return;
            }
        }
        let _ = isa;
        for (j, (r, a)) in rq.iter().zip(acc.chunks_exact(PB)).enumerate() {
            let f = Finish::of(op, o0 + j);
            if let Some(dst) = self.get_mut(at + j * plane..at + j * plane + n) {
                for (d, &v) in dst.iter_mut().zip(a) {
                    *d = f.apply(r.base.wrapping_add(v)) as i16;
                }
            }
        }
    }
}

/// The packed weights of output channels `first .. first + channels` and their sums.
struct Pack<'p, W> {
    weights: &'p [W],
    sums: &'p [i32],
    first: usize,
    channels: usize,
}

/// [`run`] for the channels of one [`Pack`], row by row.
#[allow(clippy::too_many_arguments)]
fn run_pack<F: Micro, S: Source, O: Sink + ?Sized>(
    isa: Isa,
    op: &Conv2d,
    input: &S,
    c_in: usize,
    group_shape: Shape,
    out: Shape,
    dst: &OutRows,
    output: &mut O,
    (rows, steps, slots): (&mut [F::Elem], &mut [u32], &mut [i32]),
    dims: &pack::Dims,
    pack: &Pack<'_, F::W>,
    acc: &mut Acc,
) {
    let zp = op.quant.input_zero_point;
    let g = &op.geometry;
    let (kh, kw) = (g.kernel[0], g.kernel[1]);
    let (weights, sums) = (pack.weights, pack.sums);
    // A block's requantisation constants (the same for every row).
    let block_rq = |b: usize| {
        let o0 = pack.first + b * NB;
        let nb = NB.min(pack.channels - b * NB);
        let mut rq = [RowQuant::default(); NB];
        for (j, q) in rq.iter_mut().enumerate().take(nb) {
            let base = op.channels[o0 + j]
                .bias
                .wrapping_sub(F::bias_term(zp, sums[b * NB + j]));
            *q = op.row_quant(o0 + j, base);
        }
        rq
    };
    // Those of the first blocks made once per call where the stack is large (phones and
    // desktops: 5 KiB), else once per row and block.
    #[cfg(any(target_arch = "aarch64", target_arch = "x86_64"))]
    const CACHED: usize = 32;
    #[cfg(not(any(target_arch = "aarch64", target_arch = "x86_64")))]
    const CACHED: usize = 0;
    let n_blocks = pack.channels.div_ceil(NB);
    // Widest output row requantised in one call (aarch64: `NB · WIDE` sums on the stack, left
    // uninitialised; each row of blocks writes the `nb · out.w` it then reads).
    #[cfg(target_arch = "aarch64")]
    const WIDE: usize = 320;
    #[cfg(target_arch = "aarch64")]
    let mut wide_store = core::mem::MaybeUninit::<[i32; NB * WIDE]>::uninit();
    // Only the blocks this pack has are written (a default-filled array cost about 1000
    // instructions per call on aarch64: the refinement's heads run one call per row).
    let mut store = [const { core::mem::MaybeUninit::<[RowQuant; NB]>::uninit() }; CACHED];
    let n_cached = n_blocks.min(CACHED);
    for (b, rq) in store[..n_cached].iter_mut().enumerate() {
        rq.write(block_rq(b));
    }
    // SAFETY: `MaybeUninit<T>` has `T`'s layout, and the first `n_cached` entries were
    // written just above.
    let cached: &[[RowQuant; NB]] =
        unsafe { core::slice::from_raw_parts(store.as_ptr().cast(), n_cached) };
    for oy in dst.rows.clone() {
        // The input rows of output row `oy` into their slots (packed only where a slot does not
        // hold its row already), and the reduction steps' offsets for this slot order.
        for ky in 0..kh {
            let iy = (oy * g.stride[0] + ky * g.dilation[0]) as isize - g.padding[0] as isize;
            let keyed = pack::row_slot(kh, g.dilation[0], iy);
            let slot = keyed.unwrap_or(ky);
            let tag = i32::try_from(iy).unwrap_or(i32::MIN);
            if keyed.is_none() || tag == i32::MIN || slots[slot] != tag {
                pack::pack_row::<F, S>(
                    g,
                    input,
                    c_in,
                    group_shape,
                    out.w,
                    iy,
                    slot,
                    zp,
                    dims,
                    rows,
                );
                slots[slot] = if keyed.is_some() { tag } else { i32::MIN };
            }
            for kx in 0..kw {
                let tap = pack::tap_offset(g, out.w, F::L, slot, kx);
                let at = &mut steps[(ky * kw + kx) * dims.n_cg..][..dims.n_cg];
                for (cg, step) in at.iter_mut().enumerate() {
                    *step = (tap + cg * dims.cg_stride) as u32;
                }
            }
        }
        // The row's steps with their bounds, once for all its tasks.
        let steps = Steps::new(&*steps);
        // Blocks outermost: a block's requantisation constants once per row.
        for b in 0..n_blocks {
            let o0 = pack.first + b * NB;
            let nb = NB.min(pack.channels - b * NB);
            let made;
            let rq = match cached.get(b) {
                Some(rq) => rq,
                None => {
                    made = block_rq(b);
                    &made
                }
            };
            // aarch64 (a large stack): an int8 row of blocks into one buffer, then one
            // requantisation call for the whole row instead of one per block (the same
            // sums and the same function per sum: the same bits).
            #[cfg(target_arch = "aarch64")]
            if matches!(isa, Isa::Neon | Isa::NeonDot) && out.w > PB && out.w <= WIDE {
                if let Some(out8) = output.as_i8() {
                    let base = wide_store.as_mut_ptr().cast::<i32>();
                    // `neon-dot`: the kernel writes row `j` at `j · stride` itself (`stride`
                    // = W rounded up to 16: whole 16-pixel groups, `nb · stride ≤ NB · WIDE`).
                    let stride = out.w.div_ceil(16) * 16;
                    let into = |ox0: usize, n: usize| {
                        let task = Task {
                            rows,
                            weights: &weights[b * dims.block_len..(b + 1) * dims.block_len],
                            steps,
                            ox0,
                            pixels: n,
                            channels: nb,
                        };
                        // SAFETY: rows `j < nb` of the store from `j · stride + ox0`, 16-pixel
                        // groups up to `ox0 + 16·⌈n/16⌉ ≤ stride`: inside `NB · WIDE` (`stride ≤
                        // WIDE`, 320 being a multiple of 16).
                        unsafe { F::kernel_into(isa, &task, base.add(ox0), stride) }
                    };
                    // Every block or none (then the copies below redo the row).
                    let all = (0..out.w)
                        .step_by(PB)
                        .all(|ox0| into(ox0, PB.min(out.w - ox0)));
                    if all {
                        // SAFETY: the kernel wrote every `j · stride + x`, `j < nb`, `x <
                        // stride` (its groups of 16 from `ox0 = 0, PB, …` cover `0 .. stride`).
                        let wide = unsafe { core::slice::from_raw_parts(base, nb * stride) };
                        let at = o0 * dst.stride + (oy - dst.rows.start) * out.w;
                        let sums = (wide, stride, out.w);
                        op.finish_wide(&rq[..nb], o0, sums, out8, at, dst.stride);
                        continue;
                    }
                    // Row `j`'s sums at `j · out.w` (`nb · out.w ≤ NB · WIDE`).
                    for ox0 in (0..out.w).step_by(PB) {
                        let n = PB.min(out.w - ox0);
                        let task = Task {
                            rows,
                            weights: &weights[b * dims.block_len..(b + 1) * dims.block_len],
                            steps,
                            ox0,
                            pixels: n,
                            channels: nb,
                        };
                        F::kernel(isa, &task, acc);
                        for (j, a) in acc.chunks_exact(PB).take(nb).enumerate() {
                            // SAFETY: `j · out.w + ox0 + n ≤ nb · out.w ≤ NB · WIDE` i32 of
                            // the store, and `a` holds `PB ≥ n`; the two do not overlap.
                            // Whole blocks as fixed-size copies (inlined, no `memcpy` call).
                            unsafe {
                                let to = base.add(j * out.w + ox0);
                                if n == PB {
                                    core::ptr::copy_nonoverlapping(a.as_ptr(), to, PB)
                                } else {
                                    core::ptr::copy_nonoverlapping(a.as_ptr(), to, n)
                                }
                            };
                        }
                    }
                    // SAFETY: the loop above wrote every `j · out.w + x`, `j < nb`, `x < out.w`
                    // (`ox0` steps through `0 .. out.w` by `PB`, `n` to the row's end).
                    let wide = unsafe { core::slice::from_raw_parts(base, nb * out.w) };
                    let at = o0 * dst.stride + (oy - dst.rows.start) * out.w;
                    let sums = (wide, out.w, out.w);
                    op.finish_wide(&rq[..nb], o0, sums, out8, at, dst.stride);
                    continue;
                }
            }
            for ox0 in (0..out.w).step_by(PB) {
                let n = PB.min(out.w - ox0);
                let task = Task {
                    rows,
                    weights: &weights[b * dims.block_len..(b + 1) * dims.block_len],
                    steps,
                    ox0,
                    pixels: n,
                    channels: nb,
                };
                F::kernel(isa, &task, acc);
                let at = o0 * dst.stride + (oy - dst.rows.start) * out.w + ox0;
                output.block(op, isa, (&rq[..nb], o0), (acc, n), at, dst.stride);
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::kernels::float;
    use crate::kernels::kernel_tests;
    use crate::kernels::requant::QParams;
    use proptest::prelude::*;
    use std::vec::Vec;

    /// A conv test case with real-valued ground truth.
    #[derive(Clone, Debug)]
    pub struct Case {
        pub name: &'static str,
        pub geometry: ConvGeometry,
        pub in_shape: Shape,
        pub out_c: usize,
        pub input: Vec<i8>,
        pub in_q: QParams,
        pub weights: Vec<i8>,
        pub w_scales: Vec<f32>,
        pub bias: Vec<i32>,
        pub out_q: QParams,
        pub act: Activation,
        /// Exact expected output, when hand-computed.
        pub expect: Option<Vec<i8>>,
    }

    type Impl = fn(&Conv2d, &[i8], Shape, &mut [i8], &mut [i32]) -> Result<Shape, KernelError>;

    fn channels(c: &Case) -> Vec<ChannelQuant> {
        (0..c.out_c)
            .map(|o| {
                ChannelQuant::new(c.bias[o], c.in_q.scale, c.w_scales[o], c.out_q.scale, c.act)
            })
            .collect()
    }

    /// The test wrapper of kernel set `isa`.
    fn impl_of(isa: Isa) -> Impl {
        match isa {
            Isa::Portable => portable,
            Isa::ArmDsp => arm_dsp,
            Isa::Avx2 => avx2,
            Isa::Avx512Vnni => avx512_vnni,
            Isa::Neon => neon,
            Isa::NeonDot => neon_dot,
        }
    }

    fn run(c: &Case, f: Impl) -> (Shape, Vec<i8>) {
        with_op(c, |op, y, scratch| {
            f(op, &c.input, c.in_shape, y, scratch).unwrap()
        })
    }

    /// `c`'s operator, an output and a scratch for `f`, which returns the output shape.
    fn with_op(
        c: &Case,
        f: impl FnOnce(&Conv2d, &mut [i8], &mut [i32]) -> Shape,
    ) -> (Shape, Vec<i8>) {
        let ch = channels(c);
        let op = Conv2d {
            geometry: c.geometry,
            quant: ConvQuant::new(c.in_q.zero_point, c.out_q.zero_point, c.act),
            weights: &c.weights,
            channels: &ch,
        };
        let out = op.check(c.in_shape).unwrap();
        let mut y = std::vec![0i8; out.len().unwrap()];
        let mut scratch = std::vec![0i32; Conv2d::scratch_len(&c.geometry, c.in_shape, out)];
        assert_eq!(f(&op, &mut y, &mut scratch), out);
        (out, y)
    }

    fn check(c: &Case, f: Impl) {
        let (out, y) = run(c, f);
        let (_, yr) = run(c, conv2d_ref);
        assert_eq!(y, yr, "{}: differs from conv2d_ref", c.name);
        if let Some(e) = &c.expect {
            assert_eq!(&y, e, "{}", c.name);
        }
        // Float reference on dequantised values: within 1 LSB of round(real/scale)+zp.
        let xf: Vec<f32> = c.input.iter().map(|&q| c.in_q.dequantize(q)).collect();
        let ocg_len = c.weights.len() / c.out_c;
        let wf: Vec<f32> = c
            .weights
            .iter()
            .enumerate()
            .map(|(i, &q)| q as f32 * c.w_scales[i / ocg_len])
            .collect();
        let bf: Vec<f32> = (0..c.out_c)
            .map(|o| c.bias[o] as f32 * c.in_q.scale * c.w_scales[o])
            .collect();
        let mut yf = std::vec![0f32; out.len().unwrap()];
        float::conv2d(
            &c.geometry,
            &xf,
            c.in_shape,
            &wf,
            Some(&bf),
            c.act,
            &mut yf,
            out,
        )
        .unwrap();
        for (i, (&q, &r)) in y.iter().zip(&yf).enumerate() {
            let want = c.out_q.quantize(r) as i32;
            assert!(
                (q as i32 - want).abs() <= 1,
                "{}: [{i}] {q} vs {want} ({r})",
                c.name
            );
        }
    }

    pub fn golden() -> Vec<Case> {
        let unit = QParams {
            scale: 1.0,
            zero_point: 0,
        };
        std::vec![
            // 1×3×3 input 1..9, 2×2 kernel of ones, stride 1: sums of 2×2 windows.
            Case {
                name: "sum2x2",
                geometry: ConvGeometry {
                    kernel: [2, 2],
                    ..ConvGeometry::POINTWISE
                },
                in_shape: Shape::new(1, 3, 3),
                out_c: 1,
                input: (1..=9).collect(),
                in_q: unit,
                weights: std::vec![1; 4],
                w_scales: std::vec![1.0],
                bias: std::vec![0],
                out_q: unit,
                act: Activation::None,
                expect: Some(std::vec![12, 16, 24, 28]),
            },
            // Same with padding 1, stride 2, zero point 2 (padding is real 0 = code 2), bias 1.
            Case {
                name: "pad_stride_zp",
                geometry: ConvGeometry {
                    kernel: [2, 2],
                    stride: [2, 2],
                    padding: [1, 1],
                    ..ConvGeometry::POINTWISE
                },
                in_shape: Shape::new(1, 3, 3),
                out_c: 1,
                input: (3..=11).collect(), // real 1..9
                in_q: QParams {
                    scale: 1.0,
                    zero_point: 2
                },
                weights: std::vec![1; 4],
                w_scales: std::vec![1.0],
                bias: std::vec![1],
                out_q: unit,
                // windows: {1}, {2,3}, {4,7}, {5,6,8,9} → +1
                act: Activation::None,
                expect: Some(std::vec![2, 6, 12, 29]),
            },
            // Depthwise 2 channels, leaky relu 0.5 and relu semantics via weights −1.
            Case {
                name: "depthwise_leaky",
                geometry: ConvGeometry {
                    kernel: [1, 1],
                    groups: 2,
                    ..ConvGeometry::POINTWISE
                },
                in_shape: Shape::new(2, 1, 2),
                out_c: 2,
                input: std::vec![4, -6, 8, 10],
                in_q: unit,
                weights: std::vec![1, -1],
                w_scales: std::vec![1.0, 0.5],
                bias: std::vec![0, 0],
                out_q: unit,
                act: Activation::LeakyRelu(0.5),
                // ch0: 4, −6·0.5 = −3; ch1: −8·0.5 = −4 → ·0.5 = −2, −10·0.5=−5 → −2.5 → −3
                expect: Some(std::vec![4, -3, -2, -3]),
            },
            // Dilated 1×3 kernel, relu clamps at zp_out = −10.
            Case {
                name: "dilated_relu",
                geometry: ConvGeometry {
                    kernel: [1, 3],
                    dilation: [1, 2],
                    padding: [0, 2],
                    ..ConvGeometry::POINTWISE
                },
                in_shape: Shape::new(1, 1, 4),
                out_c: 1,
                input: std::vec![1, 2, 3, 4],
                in_q: unit,
                weights: std::vec![1, 0, -2],
                w_scales: std::vec![1.0],
                bias: std::vec![0],
                out_q: QParams {
                    scale: 1.0,
                    zero_point: -10
                },
                act: Activation::Relu,
                // taps at x−2, x, x+2 with weights 1,0,−2: x0: −2·3=−6→0; x1: −2·4=−8→0; x2: 1; x3: 2
                expect: Some(std::vec![-10, -10, -9, -8]),
            },
        ]
    }

    prop_compose! {
        pub fn arb_case()(
            groups in 1usize..=3, icg in 1usize..=3, ocg in 1usize..=3,
            kh in 1usize..=3, kw in 1usize..=3, sh in 1usize..=2, sw in 1usize..=3,
            dh in 1usize..=2, dw in 1usize..=2, ph in 0usize..=2, pw in 0usize..=2,
            h in 3usize..=9, w in 3usize..=11, act in 0u8..3,
            in_zp in -20i32..20, out_zp in -20i32..20, seed in any::<u64>(),
        ) -> Case {
            let in_shape = Shape::new(groups * icg, h, w);
            let out_c = groups * ocg;
            let geometry = ConvGeometry { kernel: [kh, kw], stride: [sh, sw], dilation: [dh, dw], padding: [ph, pw], groups };
            let mut s = seed;
            let mut next = move || { s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407); (s >> 33) as u32 };
            let input = (0..in_shape.len().unwrap()).map(|_| next() as i8).collect();
            let weights = (0..geometry.weight_len(in_shape.c, out_c).unwrap()).map(|_| (next() % 255) as i32 as i8 ).map(|v| v.max(-127)).collect();
            let w_scales = (0..out_c).map(|_| 0.001 + (next() % 1000) as f32 * 1e-5).collect();
            let bias = (0..out_c).map(|_| (next() % 2001) as i32 - 1000).collect();
            let act = [Activation::None, Activation::Relu, Activation::LeakyRelu(0.1)][act as usize];
            Case { name: "arb", geometry, in_shape, out_c, input, in_q: QParams { scale: 0.02, zero_point: in_zp },
                   weights, w_scales, bias, out_q: QParams { scale: 0.05, zero_point: out_zp }, act, expect: None }
        }
    }

    fn arb_valid() -> impl Strategy<Value = Case> {
        arb_case().prop_filter("output must exist", |c| {
            c.geometry.output_shape(c.in_shape, c.out_c).is_some()
        })
    }

    kernel_tests!(suite, ref: conv2d_ref, fast: conv2d, golden: golden, arb: arb_valid(), check: check);

    /// Runs kernel set `isa` when this CPU has it; otherwise the reference (so the suite still
    /// checks the case) and a note.
    fn with_isa(
        isa: Isa,
        op: &Conv2d,
        input: &[i8],
        in_shape: Shape,
        output: &mut [i8],
        scratch: &mut [i32],
    ) -> Result<Shape, KernelError> {
        if isa.available() {
            conv2d_with(isa, op, input, in_shape, output, scratch)
        } else {
            std::eprintln!("kernel set {} not on this CPU: not tested here", isa.name());
            conv2d_ref(op, input, in_shape, output, scratch)
        }
    }
    fn portable(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        with_isa(Isa::Portable, op, x, s, y, t)
    }
    fn arm_dsp(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        with_isa(Isa::ArmDsp, op, x, s, y, t)
    }
    fn avx2(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        with_isa(Isa::Avx2, op, x, s, y, t)
    }
    fn avx512_vnni(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        with_isa(Isa::Avx512Vnni, op, x, s, y, t)
    }
    fn neon(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        with_isa(Isa::Neon, op, x, s, y, t)
    }
    fn neon_dot(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        with_isa(Isa::NeonDot, op, x, s, y, t)
    }
    kernel_tests!(suite_portable, ref: conv2d_ref, fast: portable, golden: golden, arb: arb_valid(), check: check);
    kernel_tests!(suite_arm_dsp, ref: conv2d_ref, fast: arm_dsp, golden: golden, arb: arb_valid(), check: check);
    kernel_tests!(suite_avx2, ref: conv2d_ref, fast: avx2, golden: golden, arb: arb_valid(), check: check);
    kernel_tests!(suite_avx512_vnni, ref: conv2d_ref, fast: avx512_vnni, golden: golden, arb: arb_valid(), check: check);
    kernel_tests!(suite_neon, ref: conv2d_ref, fast: neon, golden: golden, arb: arb_valid(), check: check);
    kernel_tests!(suite_neon_dot, ref: conv2d_ref, fast: neon_dot, golden: golden, arb: arb_valid(), check: check);

    /// Input rows packed once into row slots and reused: convs whose weights take several packs
    /// (`MAX_PACKED_WEIGHTS`), dilations whose rows take distinct slots (`gcd(dh, kh) = 1`) and
    /// one where they would collide, stride 2, and row-by-row calls that keep their scratch
    /// (`conv2d_rows_packed` with `weights_packed`, as the refinement's heads call it) all give
    /// the reference's bits on every kernel set.
    #[test]
    fn row_slots_match_reference_across_packs_and_calls() {
        let mut seed = 11u64;
        for (k, s, d, cin, cout, h, w) in [
            (3usize, 1usize, 1usize, 48usize, 48usize, 7usize, 9usize),
            (3, 1, 2, 8, 5, 9, 12),
            (3, 1, 3, 8, 5, 10, 12),
            (5, 2, 1, 6, 7, 11, 13),
            (3, 1, 1, 6, 3, 6, 40),
        ] {
            let mut next = || {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (seed >> 33) as u32
            };
            let geometry = ConvGeometry {
                kernel: [k, k],
                stride: [s, s],
                dilation: [d, d],
                padding: [k / 2 * d, k / 2 * d],
                groups: 1,
            };
            let in_shape = Shape::new(cin, h, w);
            let case = Case {
                name: "row slots",
                geometry,
                in_shape,
                out_c: cout,
                input: (0..in_shape.len().unwrap()).map(|_| next() as i8).collect(),
                in_q: QParams {
                    scale: 0.02,
                    zero_point: 5,
                },
                weights: (0..geometry.weight_len(cin, cout).unwrap())
                    .map(|_| (next() as i8).max(-127))
                    .collect(),
                w_scales: (0..cout).map(|i| 0.0005 + 0.0001 * i as f32).collect(),
                bias: (0..cout).map(|i| i as i32 * 50 - 300).collect(),
                out_q: QParams {
                    scale: 0.05,
                    zero_point: -3,
                },
                act: Activation::None,
                expect: None,
            };
            for f in [portable, arm_dsp, avx2, avx512_vnni, neon, neon_dot] {
                check(&case, f);
            }
            let (out, whole) = run(&case, conv2d_ref);
            let ch = channels(&case);
            let op = Conv2d {
                geometry,
                quant: ConvQuant::new(5, -3, Activation::None),
                weights: &case.weights,
                channels: &ch,
            };
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut y = std::vec![0i8; out.len().unwrap()];
                let mut t = std::vec![0i32; Conv2d::scratch_len(&geometry, in_shape, out)];
                for oy in 0..out.h {
                    let dst = OutRows {
                        rows: oy..oy + 1,
                        stride: out.h * out.w,
                    };
                    let at = &mut y[oy * out.w..];
                    conv2d_rows_packed(isa, &op, &case.input, in_shape, &dst, at, &mut t, oy > 0)
                        .unwrap();
                }
                assert_eq!(y, whole, "{} row by row, k {k} s {s} d {d}", isa.name());
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Any band of output rows, written at any channel stride, holds the whole output's bits
        /// (every kernel set of this CPU; depthwise and grouped cases included).
        #[test]
        fn row_bands_equal_the_whole_output(c in arb_valid(), cut in 0usize..64, extra in 0usize..9) {
            let (out, whole) = run(&c, conv2d_ref);
            let ch = channels(&c);
            let op = Conv2d {
                geometry: c.geometry,
                quant: ConvQuant::new(c.in_q.zero_point, c.out_q.zero_point, c.act),
                weights: &c.weights,
                channels: &ch,
            };
            let y0 = cut % out.h;
            let y1 = (y0 + 1 + cut / 7).min(out.h);
            let stride = (y1 - y0) * out.w + extra;
            let mut scratch = std::vec![0i32; Conv2d::scratch_len(&c.geometry, c.in_shape, out)];
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut band = std::vec![0x55i8; (out.c - 1) * stride + (y1 - y0) * out.w];
                let dst = OutRows { rows: y0..y1, stride };
                conv2d_rows_with(isa, &op, &c.input, c.in_shape, &dst, &mut band, &mut scratch).unwrap();
                for o in 0..out.c {
                    let want = &whole[o * out.h * out.w + y0 * out.w..o * out.h * out.w + y1 * out.w];
                    let got = &band[o * stride..o * stride + (y1 - y0) * out.w];
                    prop_assert_eq!(got, want, "{} channel {} rows {}..{}", isa.name(), o, y0, y1);
                }
            }
        }
    }

    /// Depthwise shapes (the dedicated row path) on every kernel set against the reference:
    /// strides, dilations, paddings, kernel sizes, widths below and above one pixel block.
    #[test]
    fn depthwise_matches_reference_on_every_set() {
        let mut seed = 7u64;
        for (k, s, d, p, h, w) in [
            (3usize, 1usize, 1usize, 1usize, 9usize, 40usize),
            (3, 2, 1, 1, 10, 37),
            (5, 1, 2, 4, 7, 33),
            (3, 1, 1, 0, 5, 6),
            (7, 2, 1, 3, 12, 70),
            (3, 2, 1, 0, 9, 8),
            (3, 1, 1, 2, 4, 3),
            (3, 2, 1, 1, 1, 1),
            // The depth encoder's 5 × 5 at stride 2 (ring_rows), odd and even widths, and
            // stride 1 / other paddings.
            (5, 2, 1, 2, 12, 40),
            (5, 2, 1, 2, 9, 31),
            (5, 2, 1, 0, 6, 11),
            (5, 1, 1, 2, 7, 9),
            (7, 1, 1, 3, 8, 13),
            (5, 2, 1, 2, 2, 3),
        ] {
            let c = 5;
            let geometry = ConvGeometry {
                kernel: [k, k],
                stride: [s, s],
                dilation: [d, d],
                padding: [p, p],
                groups: c,
            };
            let in_shape = Shape::new(c, h, w);
            let mut next = || {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (seed >> 33) as u32
            };
            let case = Case {
                name: "depthwise",
                geometry,
                in_shape,
                out_c: c,
                input: (0..in_shape.len().unwrap()).map(|_| next() as i8).collect(),
                in_q: QParams {
                    scale: 0.02,
                    zero_point: -7,
                },
                weights: (0..c * k * k).map(|_| next() as i8).collect(),
                w_scales: (0..c).map(|i| 0.002 + 0.001 * i as f32).collect(),
                bias: (0..c).map(|i| i as i32 * 100 - 200).collect(),
                out_q: QParams {
                    scale: 0.05,
                    zero_point: 4,
                },
                act: Activation::LeakyRelu(0.1),
                expect: None,
            };
            let (_, yr) = run(&case, conv2d_ref);
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let f = impl_of(isa);
                let (_, y) = run(&case, f);
                assert_eq!(y, yr, "{} k{k} s{s} d{d} p{p} {h}x{w}", isa.name());
            }
            // The vector cores' band path and the Cortex-M paths on every host, whole and in
            // row bands.
            let (_, y) = run(&case, bands);
            assert_eq!(y, yr, "depthwise::bands k{k} s{s} d{d} p{p} {h}x{w}");
            let (_, y) = run(&case, bands_in_bands);
            assert_eq!(
                y, yr,
                "depthwise::bands (bands) k{k} s{s} d{d} p{p} {h}x{w}"
            );
            // The Cortex-M strip paths with portable sums, whole and in three row bands.
            for (name, bands, path) in [
                ("ring3", 1, ring3_or_pixels as DepthwisePath),
                ("ring3 (bands)", 3, ring3_or_pixels),
                ("ring_rows", 1, ring_rows_or_pixels),
                ("ring_rows (bands)", 3, ring_rows_or_pixels),
            ] {
                let y = run_banded(&case, bands, path);
                assert_eq!(y, yr, "depthwise::{name} k{k} s{s} d{d} p{p} {h}x{w}");
            }
            let (_, y) = run(&case, pixels);
            assert_eq!(y, yr, "depthwise::pixels k{k} s{s} d{d} p{p} {h}x{w}");
            let (_, y) = run(&case, pixels_in_bands);
            assert_eq!(
                y, yr,
                "depthwise::pixels (bands) k{k} s{s} d{d} p{p} {h}x{w}"
            );
        }
    }

    /// A depthwise call on the portable kernel set.
    fn portable_call<'a, 'w>(
        op: &'a Conv2d<'w>,
        input: &'a [i8],
        in_shape: Shape,
        out: Shape,
        dst: &'a OutRows,
    ) -> Depthwise<'a, 'w> {
        Depthwise {
            isa: Isa::Portable,
            op,
            input,
            in_shape,
            out,
            dst,
        }
    }

    /// [`depthwise::pixels`] (the arm-dsp depthwise path) with the portable requantisation.
    fn pixels(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        let out = op.check(s)?;
        let plane = out.h * out.w;
        let dst = OutRows {
            rows: 0..out.h,
            stride: plane,
        };
        depthwise::pixels(&portable_call(op, x, s, out, &dst), y, t);
        Ok(out)
    }

    /// [`depthwise::bands`] with the portable requantisation.
    fn bands(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        in_bands(op, x, s, y, t, 1, bands_or_rows)
    }

    /// [`bands`] computed in three row bands into one output, with a scratch that holds a band
    /// of two rows at most.
    fn bands_in_bands(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        in_bands(op, x, s, y, t, 3, |op, x, s, out, dst, y, t| {
            let g = &op.geometry;
            let phase_w = out.w + (g.kernel[1] - 1) * g.dilation[1] / g.stride[1];
            let rows = g.stride[0] + (g.kernel[0] - 1) * g.dilation[0] + 1;
            let pitch = if g.stride == [1, 1] { phase_w } else { out.w };
            let two = 2 * pitch + (rows * g.stride[1] * phase_w).div_ceil(2);
            let len = two.min(t.len());
            bands_or_rows(op, x, s, out, dst, y, &mut t[..len])
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn bands_or_rows(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        out: Shape,
        dst: &OutRows,
        y: &mut [i8],
        t: &mut [i32],
    ) {
        assert!(
            depthwise::bands(&portable_call(op, x, s, out, dst), y, t),
            "the scratch holds a band of one row"
        );
    }

    /// `case` through a depthwise path over `bands` row bands (portable kernel set).
    fn run_banded(c: &Case, bands: usize, path: DepthwisePath) -> Vec<i8> {
        with_op(c, |op, y, t| {
            in_bands(op, &c.input, c.in_shape, y, t, bands, path).unwrap()
        })
        .1
    }

    /// [`depthwise::ring_rows`] with the portable sums, or [`depthwise::pixels`] where it
    /// declines.
    #[allow(clippy::too_many_arguments)]
    fn ring_rows_or_pixels(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        out: Shape,
        dst: &OutRows,
        y: &mut [i8],
        t: &mut [i32],
    ) {
        if !depthwise::ring_rows(&portable_call(op, x, s, out, dst), y, t) {
            depthwise::pixels(&portable_call(op, x, s, out, dst), y, t);
        }
    }

    /// [`depthwise::ring3`] with the portable sums, or [`depthwise::pixels`] where it declines.
    #[allow(clippy::too_many_arguments)]
    fn ring3_or_pixels(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        out: Shape,
        dst: &OutRows,
        y: &mut [i8],
        t: &mut [i32],
    ) {
        if !depthwise::ring3(&portable_call(op, x, s, out, dst), y, t) {
            depthwise::pixels(&portable_call(op, x, s, out, dst), y, t);
        }
    }

    /// A depthwise path: operator, input, its shape, the output shape, rows, output, scratch.
    type DepthwisePath = fn(&Conv2d, &[i8], Shape, Shape, &OutRows, &mut [i8], &mut [i32]);

    /// A depthwise path run over `bands` row bands of the output, each into its own buffer,
    /// gathered into `y`.
    fn in_bands(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
        bands: usize,
        path: DepthwisePath,
    ) -> Result<Shape, KernelError> {
        let out = op.check(s)?;
        let plane = out.h * out.w;
        let step = out.h.div_ceil(bands).max(1);
        for start in (0..out.h).step_by(step) {
            let rows = start..(start + step).min(out.h);
            let mut band = std::vec![0i8; out.c * plane];
            let dst = OutRows {
                rows: rows.clone(),
                stride: plane,
            };
            path(op, x, s, out, &dst, &mut band, t);
            for c in 0..out.c {
                let n = rows.len() * out.w;
                y[c * plane + rows.start * out.w..][..n].copy_from_slice(&band[c * plane..][..n]);
            }
        }
        Ok(out)
    }

    /// [`pixels`] computed as rows `0..h/2` and `h/2..h` into one output.
    fn pixels_in_bands(
        op: &Conv2d,
        x: &[i8],
        s: Shape,
        y: &mut [i8],
        t: &mut [i32],
    ) -> Result<Shape, KernelError> {
        let out = op.check(s)?;
        let plane = out.h * out.w;
        let cut = out.h / 2;
        for rows in [0..cut, cut..out.h] {
            let mut band = std::vec![0i8; out.c * plane];
            let dst = OutRows {
                rows: rows.clone(),
                stride: plane,
            };
            depthwise::pixels(&portable_call(op, x, s, out, &dst), &mut band, t);
            for c in 0..out.c {
                let n = rows.len() * out.w;
                y[c * plane + rows.start * out.w..][..n].copy_from_slice(&band[c * plane..][..n]);
            }
        }
        Ok(out)
    }

    /// Extremes that could saturate a 16-bit pair sum or the biased byte path: all inputs at
    /// −128 / 127 against zero points at the other end, weights at ±127/−128, many taps.
    #[test]
    fn extremes_match_reference_on_every_set() {
        for (x, zp, wv) in [
            (-128i8, 127i32, -128i8),
            (127, -128, 127),
            (127, -128, -128),
            (-128, 127, 127),
        ] {
            let geometry = ConvGeometry {
                kernel: [3, 3],
                padding: [1, 1],
                ..ConvGeometry::POINTWISE
            };
            let in_shape = Shape::new(37, 5, 7);
            let out_c = 6;
            let c = Case {
                name: "extreme",
                geometry,
                in_shape,
                out_c,
                input: std::vec![x; in_shape.len().unwrap()],
                in_q: QParams {
                    scale: 0.02,
                    zero_point: zp,
                },
                weights: std::vec![wv; geometry.weight_len(in_shape.c, out_c).unwrap()],
                w_scales: std::vec![1e-6; out_c],
                bias: std::vec![7; out_c],
                out_q: QParams {
                    scale: 0.05,
                    zero_point: 3,
                },
                act: Activation::None,
                expect: None,
            };
            let (_, yr) = run(&c, conv2d_ref);
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let (_, y) = run(&c, impl_of(isa));
                assert_eq!(y, yr, "{} x={x} zp={zp} w={wv}", isa.name());
            }
        }
    }

    /// Stride-2 convs on rows wide enough for the vector packing of every other column (16
    /// and more output columns per phase), with 1 to 9 input channels (a group of four with
    /// padding lanes, whole groups, a group and a remainder), both column phases, paddings 0
    /// to 2 and odd and even widths: every set equals the reference.
    #[test]
    fn wide_stride2_rows_match_reference_on_every_set() {
        let mut seed = 0x5eed_u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        for in_c in 1..=9usize {
            for (w, pad, k) in [
                (33usize, 1usize, 3usize),
                (70, 0, 3),
                (97, 2, 5),
                (64, 1, 1),
            ] {
                let geometry = ConvGeometry {
                    kernel: [k, k],
                    stride: [2, 2],
                    padding: [pad, pad],
                    ..ConvGeometry::POINTWISE
                };
                let in_shape = Shape::new(in_c, 7, w);
                let out_c = 5;
                let c = Case {
                    name: "wide stride 2",
                    geometry,
                    in_shape,
                    out_c,
                    input: (0..in_shape.len().unwrap()).map(|_| next() as i8).collect(),
                    in_q: QParams {
                        scale: 0.02,
                        zero_point: next() as i32 % 40 - 20,
                    },
                    weights: (0..geometry.weight_len(in_shape.c, out_c).unwrap())
                        .map(|_| (next() % 255) as i32 as i8)
                        .collect(),
                    w_scales: std::vec![0.003; out_c],
                    bias: (0..out_c).map(|_| (next() % 2001) as i32 - 1000).collect(),
                    out_q: QParams {
                        scale: 0.05,
                        zero_point: 3,
                    },
                    act: Activation::LeakyRelu(0.1),
                    expect: None,
                };
                let (_, yr) = run(&c, conv2d_ref);
                for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                    let (_, y) = run(&c, impl_of(isa));
                    assert_eq!(y, yr, "{} in_c={in_c} w={w} pad={pad} k={k}", isa.name());
                }
            }
        }
    }

    /// Speed of every kernel set against the reference on a 3×3 conv, by default 16→16 at
    /// 60×80 (a typical `mcu` half-resolution layer; `CONV_SPEED_SHAPE=ic,oc,h,w` for another).
    /// `CONV_SPEED_DEPTHWISE=1` makes it depthwise, `CONV_SPEED_GEOMETRY=k,stride` sets the
    /// square kernel (padding k/2) and the stride. Run: `cargo test --release -p depthor-core
    /// --lib conv_speed -- --ignored --nocapture`; `CONV_SPEED_ONLY=<set>` runs one kernel set
    /// (e.g. `arm-dsp` under qemu-arm with `--features arm-dsp`; the PC profiler of
    /// firmware-sim/tools/pcprof wrote no counts in qemu-arm user mode when tried).
    #[test]
    #[ignore]
    fn conv_speed() {
        let shape = std::env::var("CONV_SPEED_SHAPE").unwrap_or_default();
        let v: Vec<usize> = shape.split(',').filter_map(|t| t.parse().ok()).collect();
        let (ic, oc, h, w) = match v[..] {
            [ic, oc, h, w] => (ic, oc, h, w),
            _ => (16usize, 16usize, 60usize, 80usize),
        };
        let groups = if std::env::var("CONV_SPEED_DEPTHWISE").is_ok() {
            ic
        } else {
            1
        };
        let geometry = std::env::var("CONV_SPEED_GEOMETRY").unwrap_or_default();
        let kv: Vec<usize> = geometry.split(',').filter_map(|t| t.parse().ok()).collect();
        let (k, stride) = match kv[..] {
            [k, s] => (k, s),
            _ => (3, 1),
        };
        let g = ConvGeometry {
            kernel: [k, k],
            padding: [k / 2, k / 2],
            stride: [stride, stride],
            groups,
            ..ConvGeometry::POINTWISE
        };
        let input: Vec<i8> = (0..ic * h * w).map(|i| (i * 31 % 251) as i8).collect();
        let weights: Vec<i8> = (0..g.weight_len(ic, oc).unwrap())
            .map(|i| (i * 17 % 253) as i8)
            .collect();
        let ch: Vec<ChannelQuant> = (0..oc)
            .map(|_| ChannelQuant::new(0, 0.02, 0.003, 0.1, Activation::Relu))
            .collect();
        let op = Conv2d {
            geometry: g,
            quant: ConvQuant::new(3, -2, Activation::Relu),
            weights: &weights,
            channels: &ch,
        };
        let s = Shape::new(ic, h, w);
        let out = op.check(s).unwrap();
        let mut y = std::vec![0i8; out.len().unwrap()];
        let mut scratch = std::vec![0i32; Conv2d::scratch_len(&g, s, out)];
        let macs = (out.len().unwrap() * ic / groups * k * k) as f64;
        for (name, f) in [
            ("conv2d_ref", conv2d_ref as Impl),
            ("portable", portable as Impl),
            ("arm-dsp", arm_dsp as Impl),
            ("avx2", avx2 as Impl),
            ("avx512-vnni", avx512_vnni as Impl),
            ("neon", neon as Impl),
            ("neon-dot", neon_dot as Impl),
        ] {
            // `CONV_SPEED_ONLY=<name>` runs one kernel set (for a profiler).
            if std::env::var("CONV_SPEED_ONLY").is_ok_and(|only| only != name) {
                continue;
            }
            let t = std::time::Instant::now();
            let reps = 20;
            for _ in 0..reps {
                f(&op, &input, s, &mut y, &mut scratch).unwrap();
            }
            let dt = t.elapsed().as_secs_f64() / reps as f64;
            std::println!("{name}: {:.3} ms, {:.2} GMAC/s", dt * 1e3, macs / dt / 1e9);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// A conv reading the parts of a concat in place (codes mapped by each part's rescale
        /// table) gives the bits of the conv run on the concat's output, on every kernel set.
        #[test]
        fn parts_read_in_place_equal_the_concat(c in arb_valid(), split in 1usize..8, zp in -20i32..20, ratio in 0.3f32..2.5) {
            use crate::kernels::elementwise::{concat_part, Rescale};
            use crate::kernels::pack::Parts;
            prop_assume!(c.geometry.groups == 1 && c.in_shape.c >= 2);
            let s = c.in_shape;
            let plane = s.h * s.w;
            let c1 = 1 + split % (s.c - 1);
            let parts_c = [c1, s.c - c1];
            // Part 0 passes through; part 1 comes from another scale and zero point.
            let from = [c.in_q, QParams { scale: c.in_q.scale * ratio, zero_point: zp }];
            let mut concat = std::vec![0i8; s.len().unwrap()];
            let mut c0 = 0;
            let mut tables = [[0i8; 256]; 2];
            for k in 0..2 {
                let part = &c.input[c0 * plane..(c0 + parts_c[k]) * plane];
                let r = Rescale::new(from[k], c.in_q);
                for (code, t) in tables[k].iter_mut().enumerate() {
                    *t = r.apply(code as u8 as i8);
                }
                concat_part(crate::kernels::wide::Codes::I8(part), Shape::new(parts_c[k], s.h, s.w), &r, crate::kernels::wide::CodesMut::I8(&mut concat), s, c0).unwrap();
                c0 += parts_c[k];
            }
            let ch = channels(&c);
            let op = Conv2d {
                geometry: c.geometry,
                quant: ConvQuant::new(c.in_q.zero_point, c.out_q.zero_point, c.act),
                weights: &c.weights,
                channels: &ch,
            };
            let out = op.check(s).unwrap();
            let mut scratch = std::vec![0i32; Conv2d::scratch_len(&c.geometry, s, out)];
            let mut want = std::vec![0i8; out.len().unwrap()];
            conv2d_ref(&op, &concat, s, &mut want, &mut scratch).unwrap();
            let mut parts = Parts::new(plane);
            assert!(parts.push(&c.input[..c1 * plane], c1, None));
            assert!(parts.push(&c.input[c1 * plane..], s.c - c1, Some(&tables[1])));
            let dst = OutRows { rows: 0..out.h, stride: out.h * out.w };
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut got = std::vec![0i8; out.len().unwrap()];
                conv2d_parts_with(isa, &op, &parts, s, &dst, &mut got, &mut scratch).unwrap();
                prop_assert_eq!(&got, &want, "{}", isa.name());
            }
        }
    }

    proptest! {
        #[test]
        fn requant_one_and_row_are_the_reference_requantisation(
            x in any::<i32>(),
            m in 0i32..=i32::MAX,
            e in 0i32..=31,
            zp in -128i32..=127,
            edge in 0usize..8,
            m_edge in 0usize..4,
            e_edge in 0usize..4,
        ) {
            // Exact halves at both roundings: m = 2^30 (×0.5) on odd x, small x, extremes;
            // small shifts often (where one unit of the high product shows in the result).
            let x = [x, 0, -1, i32::MIN, i32::MAX, x >> 16, x >> 24, (x >> 20) | 1][edge];
            let e = [e, 1, 2, e % 4][e_edge];
            let m = [m, 1 << 30, (1 << 30) + 1, i32::MAX][m_edge];
            let r = crate::kernels::requant::Requant { multiplier: m, shift: -e };
            // A leaky ReLU's second slope (multiplier and shift below zero) on a quarter: with
            // its own shift, or with the same shift (the NEON path's single-shift case).
            let (neg_m, neg_e) = match edge {
                3 => (m / 10, (e + 3).min(31)),
                7 => (m / 10, e),
                _ => (m, e),
            };
            let rn = crate::kernels::requant::Requant { multiplier: neg_m, shift: -neg_e };
            let k = RowQuant {
                simple: true,
                base: 0,
                pos_m: m,
                neg_m,
                pos_r: e,
                neg_r: neg_e,
                zp,
                // A ReLU's floor (the zero point) on half the cases.
                min: if m_edge % 2 == 1 { zp } else { -128 },
                max: 127,
                narrow: x.unsigned_abs() < 1 << 30,
            };
            let want = if x < 0 { rn } else { r }.apply(x).saturating_add(zp).clamp(k.min, 127) as i8;
            prop_assert_eq!(requant_one(&k, x), want);
            let mut row = [0i8; 1];
            requant_row(&k, &[x], &mut row);
            prop_assert_eq!(row[0], want, "requant_row");
            // Rows of every length up to 33 (the arm-dsp loops take two sums per pass, then
            // the odd one; the NEON one 16, then an overlapping 16 or 8s), with sums of both
            // signs, narrow where the single one is.
            let vary = |i: usize| {
                let v = x.wrapping_mul(1 + i as i32 % 3) >> (i % 5);
                if i % 2 == 1 { v.wrapping_neg() } else { v }
            };
            for len in 1..=33usize {
                let sums: std::vec::Vec<i32> = (0..len)
                    .map(|i| if k.narrow { vary(i).clamp(-(1 << 30) + 1, (1 << 30) - 1) } else { vary(i) })
                    .collect();
                let mut got = std::vec![0i8; len + 1];
                requant_row(&k, &sums, &mut got[..len]);
                for (i, &v) in sums.iter().enumerate() {
                    prop_assert_eq!(got[i], requant_one(&k, v), "requant_row, {} of {}", i, len);
                }
                prop_assert_eq!(got[len], 0, "requant_row wrote past its row");
                #[cfg(target_arch = "aarch64")]
                {
                    let one = core::slice::from_ref(&k);
                    let mut neon = std::vec![0i8; len + 1];
                    let ran = crate::kernels::aarch64::requant::block(one, &sums, len, len, &mut neon, 0, len, requant_one);
                    prop_assert!(ran, "the NEON requantisation refused a simple row");
                    prop_assert_eq!(&neon, &got, "NEON requantisation, {} sums", len);
                    // Sums readable past the row (a block's row): a short row through a buffer.
                    let mut padded = sums.clone();
                    padded.resize(len.max(8), i32::MAX);
                    let mut neon = std::vec![0i8; len + 1];
                    let ran = crate::kernels::aarch64::requant::block(one, &padded, len, len, &mut neon, 0, len, requant_one);
                    prop_assert!(ran);
                    prop_assert_eq!(&neon, &got, "NEON requantisation, {} sums + padding", len);
                }
            }
        }
    }

    #[test]
    fn short_slices_are_errors_not_panics() {
        let c = &golden()[0];
        let ch = channels(c);
        let op = Conv2d {
            geometry: c.geometry,
            quant: ConvQuant::new(0, 0, Activation::None),
            weights: &c.weights,
            channels: &ch,
        };
        let mut y = [0i8; 4];
        assert_eq!(
            conv2d(&op, &c.input[..8], c.in_shape, &mut y, &mut [0; 2]),
            Err(KernelError::Shape)
        );
        assert_eq!(
            conv2d(&op, &c.input, c.in_shape, &mut y[..3], &mut [0; 2]),
            Err(KernelError::Shape)
        );
        assert_eq!(
            conv2d(&op, &c.input, c.in_shape, &mut y, &mut [0; 1]),
            Err(KernelError::Scratch)
        );
        let bad = Conv2d {
            weights: &c.weights[..3],
            ..op
        };
        assert_eq!(
            conv2d_ref(&bad, &c.input, c.in_shape, &mut y, &mut []),
            Err(KernelError::Attr)
        );
    }
}
