//! 16-bit activations (TFLite's 16×8 scheme) for the few values where int8 rounding costs the
//! most accuracy: int16 codes, symmetric per tensor (zero point 0), with int8 weights as
//! everywhere else. Only `conv2d` / `linear` (int8 or int16 in, int8 or int16 out) and `concat`
//! (int8 or int16 parts, int8 or int16 out: [`super::elementwise::concat_part`]) handle them;
//! the blob parser rejects an int16 value anywhere else (docs/blob.md).
//!
//! The arithmetic is the int8 spec's ([`super::conv`]): `acc = bias[o] + Σ w · (x − zp_in)` in
//! `i32`, then `MultiplyByQuantizedMultiplier` and a clamp to the output type's range (`[0,
//! 32767]` for ReLU on int16, whose zero point is 0). An int16 input bounds the taps per output to
//! [`MAX_TAPS_WIDE`] so that `acc` cannot overflow `i32` (TFLite's 16×8 kernels accumulate in
//! `i64` instead). The int8 → int16 conv reuses the fast int8 kernels' sums and the int16 →
//! int8 depthwise conv the int8 depthwise kernel's 16-bit rows; everything else is one scalar
//! loop. Sums are exact integers, so every path and target gives the same bits.

use super::conv::{self, Conv2d, OutRows};
use super::depthwise;
use super::isa::Isa;
use super::requant::{rounding_divide_by_pot, saturating_rounding_doubling_high_mul, Requant};
use super::{need, KernelError, Shape};

/// Most taps (`I/groups · kh · kw`) of a conv reading int16: `511 · 32768 · 128 < 2³¹`.
pub const MAX_TAPS_WIDE: usize = 511;

/// Read-only activation codes of either width.
#[derive(Clone, Copy, Debug)]
pub enum Codes<'a> {
    /// int8 codes.
    I8(&'a [i8]),
    /// int16 codes.
    I16(&'a [i16]),
}

/// Writable activation codes of either width.
#[derive(Debug)]
pub enum CodesMut<'a> {
    /// int8 codes.
    I8(&'a mut [i8]),
    /// int16 codes.
    I16(&'a mut [i16]),
}

/// Convolution with an int16 input or output (or both): the same contract as
/// [`super::conv::conv2d_ref`], with `op.quant`'s clamp range that of the output type
/// ([`super::conv::ConvQuant::new_wide`] for int16). An int16 input must have zero point 0 and at
/// most [`MAX_TAPS_WIDE`] taps per output. Where `scratch` (i32, as [`Conv2d::scratch_len`]
/// sizes it) holds their buffers, an int8 → int16 conv runs the fast int8 kernels' sums
/// ([`conv::conv2d_i16_with`]) and a depthwise int16 → int8 conv the int8 depthwise kernel's
/// 16-bit rows (`SMLAD` on Cortex-M, the NEON bands on aarch64); the rest, one scalar loop. Same bits either way.
pub fn conv2d_wide(
    isa: Isa,
    op: &Conv2d,
    input: Codes,
    in_shape: Shape,
    output: CodesMut,
    scratch: &mut [i32],
) -> Result<Shape, KernelError> {
    let out = op.check(in_shape)?;
    let taps = op.weights.len() / out.c.max(1);
    if matches!(input, Codes::I16(_)) && (op.quant.input_zero_point != 0 || taps > MAX_TAPS_WIDE) {
        return Err(KernelError::Attr);
    }
    let depthwise = op.geometry.groups == in_shape.c && out.c == in_shape.c;
    let output = match (input, output) {
        (Codes::I16(x), CodesMut::I8(o)) if depthwise => {
            need(x, in_shape)?;
            need(o, out)?;
            let dst = OutRows {
                rows: 0..out.h,
                stride: out.plane().ok_or(KernelError::Shape)?,
            };
            let call = depthwise::Depthwise {
                isa,
                op,
                input: x,
                in_shape,
                out,
                dst: &dst,
            };
            // NEON: the int8 kernel's bands on the 16-bit rows (SMLAL, exact products).
            let neon = matches!(isa, Isa::Neon | Isa::NeonDot);
            if (neon && depthwise::bands(&call, o, scratch))
                || depthwise::rings_of(&call, o, scratch)
            {
                return Ok(out);
            }
            CodesMut::I8(o)
        }
        (Codes::I8(x), CodesMut::I16(o)) => {
            match conv::conv2d_i16_with(isa, op, x, in_shape, o, scratch) {
                Err(KernelError::Scratch) => {}
                r => return r,
            }
            CodesMut::I16(o)
        }
        (_, o) => o,
    };
    match output {
        CodesMut::I8(o) => into(op, input, in_shape, out, o, |r| r as i8),
        CodesMut::I16(o) => into(op, input, in_shape, out, o, |r| r as i16),
    }
}

/// [`sums`] of either input width into `o`, each requantised value narrowed by `narrow` (its
/// range is the output type's).
fn into<O>(
    op: &Conv2d,
    input: Codes,
    in_shape: Shape,
    out: Shape,
    o: &mut [O],
    narrow: fn(i32) -> O,
) -> Result<Shape, KernelError> {
    need(o, out)?;
    let mut put = |at: usize, v: &[i32]| {
        for (d, &r) in o[at..at + v.len()].iter_mut().zip(v) {
            *d = narrow(r);
        }
    };
    match input {
        Codes::I8(x) => sums(op, x, in_shape, out, &mut put),
        Codes::I16(x) => sums(op, x, in_shape, out, &mut put),
    }
}

/// One output channel's requantisation: `clamp(zp_out + M±·acc)` to `op.quant`'s range (which
/// lies within the output type's), [`Requant::apply`] bit for bit with the shifts resolved once
/// per channel.
pub(super) struct Finish {
    /// (Q31 multiplier, left shift, right shift) for sums ≥ 0 and < 0.
    pos: (i32, u32, i32),
    neg: (i32, u32, i32),
    zp: i32,
    min: i32,
    max: i32,
}

impl Finish {
    pub(super) fn of(op: &Conv2d, o: usize) -> Finish {
        let cq = &op.channels[o];
        let parts = |r: Requant| {
            (
                r.multiplier,
                r.shift.clamp(0, 30) as u32,
                (-r.shift).clamp(0, 31),
            )
        };
        Finish {
            pos: parts(cq.pos),
            neg: parts(cq.neg),
            zp: op.quant.output_zero_point,
            min: op.quant.act_min,
            max: op.quant.act_max,
        }
    }

    #[inline(always)]
    pub(super) fn apply(&self, acc: i32) -> i32 {
        let (m, left, right) = if acc >= 0 { self.pos } else { self.neg };
        let x = if left > 0 {
            acc.saturating_mul(1 << left)
        } else {
            acc
        };
        // Multipliers are ≥ 0, so SaturatingRoundingDoublingHighMul never saturates.
        let q = saturating_rounding_doubling_high_mul(x, m);
        rounding_divide_by_pot(q, right)
            .saturating_add(self.zp)
            .clamp(self.min, self.max)
    }
}

/// Output pixels one row pass accumulates at a time (on the stack).
const CHUNK: usize = 64;

/// Every output's `bias + Σ w · (x − zp)`, requantised, handed to `put(index, values)` a row
/// run at a time. Per output channel and row, up to [`CHUNK`] sums are accumulated tap by tap
/// (two taps per pass), each tap over the run of outputs whose input lies inside the
/// image (padding is real zero), so the inner loop is two multiply-adds per element.
fn sums<T: Copy + Into<i32>>(
    op: &Conv2d,
    input: &[T],
    in_shape: Shape,
    out: Shape,
    put: &mut impl FnMut(usize, &[i32]),
) -> Result<Shape, KernelError> {
    need(input, in_shape)?;
    let g = &op.geometry;
    let (icg, ocg) = (in_shape.c / g.groups, out.c / g.groups);
    let (kh, kw) = (g.kernel[0], g.kernel[1]);
    let (sx, dx, px) = (g.stride[1], g.dilation[1], g.padding[1] as isize);
    let (iw, plane) = (in_shape.w, in_shape.h * in_shape.w);
    let zp = op.quant.input_zero_point;
    let mut acc = [0i32; CHUNK];
    for o in 0..out.c {
        let grp = o / ocg;
        let finish = Finish::of(op, o);
        let bias = op.channels[o].bias;
        let w_o = &op.weights[o * icg * kh * kw..(o + 1) * icg * kh * kw];
        let x_g = &input[grp * icg * plane..(grp + 1) * icg * plane];
        for oy in 0..out.h {
            let y0 = (oy * g.stride[0]) as isize - g.padding[0] as isize;
            let mut c0 = 0;
            while c0 < out.w {
                let n = CHUNK.min(out.w - c0);
                let acc = &mut acc[..n];
                acc.fill(bias);
                for kx in 0..kw {
                    // Outputs c0 + j whose input column (c0 + j)·sx + off is in the row.
                    let off = (kx * dx) as isize - px;
                    let lo = if off >= 0 {
                        0
                    } else {
                        ((-off) as usize).div_ceil(sx).saturating_sub(c0)
                    };
                    let last = iw as isize - 1 - off;
                    if last < 0 {
                        continue;
                    }
                    let hi = (last as usize / sx + 1).saturating_sub(c0).min(n);
                    if lo >= hi {
                        continue;
                    }
                    let col = (((c0 + lo) * sx) as isize + off) as usize;
                    let run = &mut acc[lo..hi];
                    // The taps (input channel, kernel row) inside the image, two per pass.
                    let mut pending: Option<(usize, i32)> = None;
                    for i in 0..icg {
                        for ky in 0..kh {
                            let iy = y0 + (ky * g.dilation[0]) as isize;
                            if iy < 0 || iy >= in_shape.h as isize {
                                continue;
                            }
                            let tap = (
                                i * plane + iy as usize * iw + col,
                                i32::from(w_o[(i * kh + ky) * kw + kx]),
                            );
                            match pending.take() {
                                None => pending = Some(tap),
                                Some(p) => {
                                    let xs = (&x_g[p.0..], &x_g[tap.0..]);
                                    tap_pair(run, xs, (p.1, tap.1), sx, zp);
                                }
                            }
                        }
                    }
                    if let Some((at, w)) = pending {
                        tap_one(run, &x_g[at..], w, sx, zp);
                    }
                }
                for a in acc.iter_mut() {
                    *a = finish.apply(*a);
                }
                put((o * out.h + oy) * out.w + c0, acc);
                c0 += n;
            }
        }
    }
    Ok(out)
}

/// `acc[j] += w·(x[j·sx] − zp)` over `acc`.
#[inline(always)]
fn tap_one<T: Copy + Into<i32>>(acc: &mut [i32], x: &[T], w: i32, sx: usize, zp: i32) {
    if sx == 1 {
        for (d, &a) in acc.iter_mut().zip(x) {
            *d = d.wrapping_add(w * (a.into() - zp));
        }
    } else if let Some(x) = x.get(..acc.len().saturating_sub(1) * sx + 1) {
        for (j, d) in acc.iter_mut().enumerate() {
            let a = x.get(j * sx).map_or(zp, |&v| v.into());
            *d = d.wrapping_add(w * (a - zp));
        }
    }
}

/// `acc[j] += wa·(xa[j·sx] − zp) + wb·(xb[j·sx] − zp)` over `acc`.
#[inline(always)]
fn tap_pair<T: Copy + Into<i32>>(
    acc: &mut [i32],
    (xa, xb): (&[T], &[T]),
    (wa, wb): (i32, i32),
    sx: usize,
    zp: i32,
) {
    let term = |a: T, b: T| wa * (a.into() - zp) + wb * (b.into() - zp);
    if sx == 1 {
        for ((d, &a), &b) in acc.iter_mut().zip(xa).zip(xb) {
            *d = d.wrapping_add(term(a, b));
        }
    } else {
        let len = acc.len().saturating_sub(1) * sx + 1;
        if let (Some(xa), Some(xb)) = (xa.get(..len), xb.get(..len)) {
            for (j, d) in acc.iter_mut().enumerate() {
                if let (Some(&a), Some(&b)) = (xa.get(j * sx), xb.get(j * sx)) {
                    *d = d.wrapping_add(term(a, b));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::conv::{conv2d_ref, Activation, ChannelQuant, ConvGeometry, ConvQuant};
    use crate::kernels::requant::QParams;
    use std::vec;
    use std::vec::Vec;

    /// A 3×3, stride-2, padded conv over 2 channels into 3 (groups 1) with the given zero
    /// points, scales and activation.
    fn op<'a>(
        weights: &'a [i8],
        channels: &'a [ChannelQuant],
        quant: ConvQuant,
        groups: usize,
    ) -> Conv2d<'a> {
        Conv2d {
            geometry: ConvGeometry {
                kernel: [3, 3],
                stride: [2, 2],
                dilation: [1, 1],
                padding: [1, 1],
                groups,
            },
            quant,
            weights,
            channels,
        }
    }

    fn weights(n: usize) -> Vec<i8> {
        (0..n).map(|i| ((i * 37 + 11) % 255) as i8).collect()
    }

    #[test]
    fn int8_in_and_out_match_the_reference() {
        let w = weights(3 * 2 * 9);
        let cq: Vec<ChannelQuant> = (0..3)
            .map(|o| ChannelQuant::new(o * 50 - 40, 0.02, 0.01, 0.05, Activation::LeakyRelu(0.1)))
            .collect();
        let conv = op(
            &w,
            &cq,
            ConvQuant::new(-7, 3, Activation::LeakyRelu(0.1)),
            1,
        );
        let s = Shape::new(2, 7, 6);
        let x: Vec<i8> = (0..s.len().unwrap())
            .map(|i| ((i * 53) % 256) as u8 as i8)
            .collect();
        let mut want = vec![0i8; 3 * 4 * 3];
        conv2d_ref(&conv, &x, s, &mut want, &mut []).unwrap();
        let mut got = vec![0i8; want.len()];
        conv2d_wide(
            Isa::best(),
            &conv,
            Codes::I8(&x),
            s,
            CodesMut::I8(&mut got),
            &mut [],
        )
        .unwrap();
        assert_eq!(got, want);
    }

    /// An int16 output holds the sums 256× finer: dequantised it stays within half an int16
    /// step of the real conv, where int8 is off by up to half an int8 step.
    #[test]
    fn int16_output_is_the_real_conv_to_half_a_step() {
        let w = weights(3 * 2 * 9);
        let (s_in, s_w) = (0.02f32, 0.01f32);
        let out16 = QParams {
            scale: 0.05 / 256.0,
            zero_point: 0,
        };
        let cq: Vec<ChannelQuant> = (0..3)
            .map(|o| ChannelQuant::new(o * 50, s_in, s_w, out16.scale, Activation::Relu))
            .collect();
        let conv = op(&w, &cq, ConvQuant::new_wide(0, Activation::Relu), 1);
        let s = Shape::new(2, 5, 5);
        let x: Vec<i8> = (0..50).map(|i| ((i * 29) % 200) as i8).collect();
        let mut y = vec![0i16; 3 * 3 * 3];
        conv2d_wide(
            Isa::best(),
            &conv,
            Codes::I8(&x),
            s,
            CodesMut::I16(&mut y),
            &mut [],
        )
        .unwrap();
        // The real conv by plain loops.
        for o in 0..3 {
            for oy in 0..3 {
                for ox in 0..3 {
                    let mut acc = (o * 50) as f64 * (s_in * s_w) as f64;
                    for i in 0..2 {
                        for ky in 0..3 {
                            for kx in 0..3 {
                                let (iy, ix) =
                                    ((oy * 2 + ky) as isize - 1, (ox * 2 + kx) as isize - 1);
                                if iy < 0 || ix < 0 || iy >= 5 || ix >= 5 {
                                    continue;
                                }
                                let xv = x[i * 25 + iy as usize * 5 + ix as usize] as f64;
                                let wv = w[(o * 2 + i) * 9 + ky * 3 + kx] as f64;
                                acc += xv * wv * (s_in * s_w) as f64;
                            }
                        }
                    }
                    let real = acc.max(0.0).min(32767.0 * out16.scale as f64);
                    let got = y[(o * 3 + oy) * 3 + ox] as f64 * out16.scale as f64;
                    assert!(
                        (got - real).abs() <= 0.51 * out16.scale as f64,
                        "{got} vs {real}"
                    );
                }
            }
        }
    }

    /// Depthwise (groups = channels) on an int16 input equals the int8 reference on inputs that
    /// fit int8 with zero point 0, and clamps to the int8 range on an int8 output.
    #[test]
    fn int16_input_depthwise_matches_int8_on_small_codes() {
        let w = weights(2 * 9);
        let cq: Vec<ChannelQuant> = (0..2)
            .map(|o| ChannelQuant::new(o * 10, 0.02, 0.01, 0.05, Activation::None))
            .collect();
        let conv = op(&w, &cq, ConvQuant::new(0, -5, Activation::None), 2);
        let s = Shape::new(2, 6, 6);
        let x8: Vec<i8> = (0..72).map(|i| ((i * 41) % 256) as u8 as i8).collect();
        let x16: Vec<i16> = x8.iter().map(|&v| v as i16).collect();
        let mut want = vec![0i8; 2 * 9];
        conv2d_ref(&conv, &x8, s, &mut want, &mut []).unwrap();
        let mut got = vec![0i8; want.len()];
        conv2d_wide(
            Isa::best(),
            &conv,
            Codes::I16(&x16),
            s,
            CodesMut::I8(&mut got),
            &mut [],
        )
        .unwrap();
        assert_eq!(got, want);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Any geometry (stride, dilation, padding, groups, odd sizes): int8 in and out gives
        /// the reference's bits, and so do the same codes as int16 (zero point folded in).
        #[test]
        fn any_geometry_matches_the_reference(c in crate::kernels::conv::tests::arb_case()) {
            let Some(out) = c.geometry.output_shape(c.in_shape, c.out_c) else {
                return Ok(());
            };
            let ch: Vec<ChannelQuant> = (0..c.out_c)
                .map(|o| ChannelQuant::new(c.bias[o], c.in_q.scale, c.w_scales[o], c.out_q.scale, c.act))
                .collect();
            let quant = ConvQuant::new(c.in_q.zero_point, c.out_q.zero_point, c.act);
            let conv = Conv2d { geometry: c.geometry, quant, weights: &c.weights, channels: &ch };
            let mut want = vec![0i8; out.len().unwrap()];
            conv2d_ref(&conv, &c.input, c.in_shape, &mut want, &mut []).unwrap();
            let mut got = vec![0i8; want.len()];
            conv2d_wide(Isa::best(), &conv, Codes::I8(&c.input), c.in_shape, CodesMut::I8(&mut got), &mut []).unwrap();
            proptest::prop_assert_eq!(&got, &want);
            let x16: Vec<i16> = c.input.iter().map(|&v| (v as i32 - c.in_q.zero_point) as i16).collect();
            let conv16 = Conv2d { quant: ConvQuant { input_zero_point: 0, ..quant }, ..conv };
            let mut got16 = vec![0i8; want.len()];
            conv2d_wide(Isa::best(), &conv16, Codes::I16(&x16), c.in_shape, CodesMut::I8(&mut got16), &mut []).unwrap();
            proptest::prop_assert_eq!(&got16, &want);
            // With a scratch, depthwise ones run the int8 kernel's 16-bit rows: the same bits.
            let mut scratch = vec![0i32; Conv2d::scratch_len(&c.geometry, c.in_shape, out)];
            for isa in [Isa::Portable, Isa::best()] {
                let mut rows = vec![0i8; want.len()];
                conv2d_wide(isa, &conv16, Codes::I16(&x16), c.in_shape, CodesMut::I8(&mut rows), &mut scratch).unwrap();
                proptest::prop_assert_eq!(&rows, &want);
            }
            // int16 out: the fast kernels' sums with the scalar loop's requantisation.
            let ch16: Vec<ChannelQuant> = (0..c.out_c)
                .map(|o| ChannelQuant::new(c.bias[o], c.in_q.scale, c.w_scales[o], c.out_q.scale / 256.0, c.act))
                .collect();
            let wide = Conv2d { quant: ConvQuant::new_wide(c.in_q.zero_point, c.act), channels: &ch16, ..conv };
            let mut scalar = vec![0i16; want.len()];
            conv2d_wide(Isa::Portable, &wide, Codes::I8(&c.input), c.in_shape, CodesMut::I16(&mut scalar), &mut []).unwrap();
            for isa in [Isa::Portable, Isa::best()] {
                let mut fast = vec![0i16; want.len()];
                conv2d_wide(isa, &wide, Codes::I8(&c.input), c.in_shape, CodesMut::I16(&mut fast), &mut scratch).unwrap();
                proptest::prop_assert_eq!(&fast, &scalar);
            }
        }
    }

    /// The depth encoder's case, a 5 × 5 depthwise conv at stride 2, and the decoder's, 3 × 3
    /// at stride 1 (and 2), on int16 codes over the whole range (far outside int8): the 16-bit
    /// rows of the int8 kernels give the scalar loop's bits on every kernel set, odd and even
    /// widths.
    #[test]
    fn int16_depthwise_rows_equal_the_scalar_loop() {
        let cases = [(5, 2), (3, 1), (3, 2)];
        for ((h, w), (k, stride)) in [(30, 40), (7, 9), (6, 5)]
            .into_iter()
            .flat_map(|hw| cases.map(|ks| (hw, ks)))
        {
            let c = 3;
            let wts: Vec<i8> = (0..c * k * k)
                .map(|i| ((i * 73 + 5) % 255) as u8 as i8)
                .collect();
            let cq: Vec<ChannelQuant> = (0..c)
                .map(|o| {
                    ChannelQuant::new(
                        o as i32 * 300 - 200,
                        1e-4,
                        0.01,
                        0.05,
                        Activation::LeakyRelu(0.1),
                    )
                })
                .collect();
            let conv = Conv2d {
                geometry: ConvGeometry {
                    kernel: [k, k],
                    stride: [stride, stride],
                    dilation: [1, 1],
                    padding: [k / 2, k / 2],
                    groups: c,
                },
                quant: ConvQuant::new(0, 4, Activation::LeakyRelu(0.1)),
                weights: &wts,
                channels: &cq,
            };
            let s = Shape::new(c, h, w);
            let x: Vec<i16> = (0..s.len().unwrap())
                .map(|i| ((i as i64 * 40_503 + 17) % 65_536 - 32_768) as i16)
                .collect();
            let out = conv.geometry.output_shape(s, c).unwrap();
            let mut want = vec![0i8; out.len().unwrap()];
            conv2d_wide(
                Isa::Portable,
                &conv,
                Codes::I16(&x),
                s,
                CodesMut::I8(&mut want),
                &mut [],
            )
            .unwrap();
            assert!(want.iter().any(|&v| v != want[0]), "a non-constant output");
            let mut scratch = vec![0i32; Conv2d::scratch_len(&conv.geometry, s, out)];
            for isa in [Isa::Portable, Isa::best()] {
                let mut got = vec![0i8; want.len()];
                conv2d_wide(
                    isa,
                    &conv,
                    Codes::I16(&x),
                    s,
                    CodesMut::I8(&mut got),
                    &mut scratch,
                )
                .unwrap();
                assert_eq!(got, want, "{k}×{k}/{stride} {h}×{w} on {}", isa.name());
            }
        }
    }

    #[test]
    fn int16_input_refuses_a_zero_point_and_too_many_taps() {
        let cq = [ChannelQuant::new(0, 0.02, 0.01, 0.05, Activation::None)];
        let s = Shape::new(2, 4, 4);
        let x = vec![0i16; 32];
        let w = weights(18);
        let conv = op(&w, &cq, ConvQuant::new(3, 0, Activation::None), 1);
        let r = conv2d_wide(
            Isa::best(),
            &conv,
            Codes::I16(&x),
            s,
            CodesMut::I8(&mut [0i8; 4]),
            &mut [],
        );
        assert_eq!(r, Err(KernelError::Attr));
        let big = Shape::new(MAX_TAPS_WIDE.div_ceil(9) + 1, 2, 2);
        let w = weights(big.c * 9);
        let xb = vec![0i16; big.len().unwrap()];
        let conv = op(&w, &cq, ConvQuant::new(0, 0, Activation::None), 1);
        let r = conv2d_wide(
            Isa::best(),
            &conv,
            Codes::I16(&xb),
            big,
            CodesMut::I8(&mut [0i8; 1]),
            &mut [],
        );
        assert_eq!(r, Err(KernelError::Attr));
    }
}
