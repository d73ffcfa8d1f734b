//! Bilinear resize to an explicit size with `align_corners = true` (docs/graph.md `upsample_bilinear`).
//!
//! Source coordinate of output index `o` is `o·(n_in − 1)/(n_out − 1)`, an exact rational
//! `i0 + f/D` with `D = n_out − 1`. The int8 path interpolates the codes with these exact
//! integer weights in `i64` and rounds once (half away from zero), so it is within 0.5 LSB of the
//! real result; input and output share quantisation parameters (as TFLite requires).

use super::{need, KernelError, Shape};

/// Index, numerator and denominator of the source coordinate of output index `o`.
#[inline]
fn src(o: usize, n_in: usize, n_out: usize) -> (usize, i64, i64) {
    if n_out <= 1 || n_in <= 1 {
        return (0, 0, 1);
    }
    let num = o * (n_in - 1);
    let den = n_out - 1;
    (num / den, (num % den) as i64, den as i64)
}

/// The source coordinates of outputs `0, 1, …` in order, as [`src`] gives them, by an exact
/// running remainder instead of a division per output.
struct Coords {
    i0: usize,
    f: i64,
    step: i64,
    den: i64,
}

impl Coords {
    fn new(n_in: usize, n_out: usize) -> Coords {
        let (step, den) = if n_out <= 1 || n_in <= 1 {
            (0, 1)
        } else {
            ((n_in - 1) as i64, (n_out - 1) as i64)
        };
        Coords {
            i0: 0,
            f: 0,
            step,
            den,
        }
    }

    /// `(i0, f, den)` of the current output, then moves to the next.
    #[inline]
    fn next(&mut self) -> (usize, i64, i64) {
        let here = (self.i0, self.f, self.den);
        self.f += self.step;
        while self.f >= self.den {
            self.f -= self.den;
            self.i0 += 1;
        }
        here
    }
}

#[inline]
fn div_round_i32(n: i32, d: i32) -> i32 {
    if n >= 0 {
        (n + d / 2) / d
    } else {
        -((-n + d / 2) / d)
    }
}

fn check<T>(input: &[T], in_shape: Shape, out: &[T], out_shape: Shape) -> Result<(), KernelError> {
    need(input, in_shape)?;
    need(out, out_shape)?;
    if in_shape.c != out_shape.c
        || in_shape.h == 0
        || in_shape.w == 0
        || in_shape.h > 1 << 15
        || in_shape.w > 1 << 15
    {
        return Err(KernelError::Shape);
    }
    if out_shape.h > 1 << 15 || out_shape.w > 1 << 15 {
        return Err(KernelError::Shape);
    }
    Ok(())
}

#[inline]
fn div_round(n: i64, d: i64) -> i64 {
    if n >= 0 {
        (n + d / 2) / d
    } else {
        -((-n + d / 2) / d)
    }
}

/// Reference int8 bilinear resize: every output element computed independently.
pub fn upsample_bilinear_ref(
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
) -> Result<(), KernelError> {
    check(input, in_shape, out, out_shape)?;
    let (ih, iw) = (in_shape.h, in_shape.w);
    for c in 0..out_shape.c {
        for oy in 0..out_shape.h {
            let (y0, fy, dy) = src(oy, ih, out_shape.h);
            let y1 = (y0 + 1).min(ih - 1);
            for ox in 0..out_shape.w {
                let (x0, fx, dx) = src(ox, iw, out_shape.w);
                let x1 = (x0 + 1).min(iw - 1);
                let v = |y: usize, x: usize| input[(c * ih + y) * iw + x] as i64;
                let top = v(y0, x0) * (dx - fx) + v(y0, x1) * fx;
                let bot = v(y1, x0) * (dx - fx) + v(y1, x1) * fx;
                let total = top * (dy - fy) + bot * fy;
                out[(c * out_shape.h + oy) * out_shape.w + ox] =
                    div_round(total, dx * dy).clamp(-128, 127) as i8;
            }
        }
    }
    Ok(())
}

/// Fast int8 bilinear resize: same bits as [`upsample_bilinear_ref`], with the row weights and
/// row slices hoisted out of the column loop.
pub fn upsample_bilinear(
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
) -> Result<(), KernelError> {
    check(input, in_shape, out, out_shape)?;
    let (ih, iw) = (in_shape.h, in_shape.w);
    // The column blend of `narrow_row`, one past the row, and its output columns' taps (made
    // once per call).
    let mut blend = [0i32; ROW + 1];
    let mut taps = [0u32; OUT_ROW];
    let tabled = out_shape.w <= OUT_ROW && iw <= ROW;
    if tabled {
        let mut cols = Coords::new(iw, out_shape.w);
        for t in taps[..out_shape.w].iter_mut() {
            let (x0, f, _) = cols.next();
            // x0 < iw ≤ 256 and f < den < 2^15 (checked by `check`).
            *t = x0 as u32 | (f as u32) << 16;
        }
    }
    for c in 0..out_shape.c {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        for oy in 0..out_shape.h {
            let (y0, fy, dy) = src(oy, ih, out_shape.h);
            let y1 = (y0 + 1).min(ih - 1);
            let (r0, r1) = (&chan[y0 * iw..(y0 + 1) * iw], &chan[y1 * iw..(y1 + 1) * iw]);
            let orow = &mut out
                [(c * out_shape.h + oy) * out_shape.w..(c * out_shape.h + oy + 1) * out_shape.w];
            let mut cols = Coords::new(iw, out_shape.w);
            // |sum| ≤ 128·dx·dy: in 32 bits (a hardware divide on Cortex-M) unless huge.
            let narrow = cols.den * dy <= 1 << 23;
            if narrow && tabled {
                let den = cols.den as i32;
                narrow_row(r0, r1, fy as i32, dy as i32, den, &taps, orow, &mut blend);
                continue;
            }
            for o in orow.iter_mut() {
                let (x0, fx, dx) = cols.next();
                let x1 = (x0 + 1).min(iw - 1);
                if narrow {
                    let (fx, dx, fy, dy) = (fx as i32, dx as i32, fy as i32, dy as i32);
                    let top = i32::from(r0[x0]) * (dx - fx) + i32::from(r0[x1]) * fx;
                    let bot = i32::from(r1[x0]) * (dx - fx) + i32::from(r1[x1]) * fx;
                    *o = div_round_i32(top * (dy - fy) + bot * fy, dx * dy).clamp(-128, 127) as i8;
                } else {
                    let top = r0[x0] as i64 * (dx - fx) + r0[x1] as i64 * fx;
                    let bot = r1[x0] as i64 * (dx - fx) + r1[x1] as i64 * fx;
                    *o = div_round(top * (dy - fy) + bot * fy, dx * dy).clamp(-128, 127) as i8;
                }
            }
        }
    }
    Ok(())
}

/// Widest input row of [`narrow_row`] (its column blend lives on the stack).
const ROW: usize = 256;

/// Widest output row of [`narrow_row`] (its column taps live on the stack).
const OUT_ROW: usize = 1024;

/// One output row in 32 bits: the two input rows blended once per input column,
/// `v[x] = r0[x]·(dy − fy) + r1[x]·fy` (with `v[iw] = v[iw − 1]`, the clamped right
/// neighbour), then `v[x0]·(den − f) + v[x0 + 1]·f` per output column (`taps[o] = x0 | f << 16`,
/// [`Coords`]' sequence, `den` its denominator), the same integer as the reference's
/// `top·(dy − fy) + bot·fy` (exact), rounded half away from zero without a branch on the sign:
/// the same bits. `|sum| ≤ 128·den·dy < 2^31`, `r0.len() ≤ ROW`, every `x0 < r0.len()`.
#[allow(clippy::too_many_arguments)]
fn narrow_row(
    r0: &[i8],
    r1: &[i8],
    fy: i32,
    dy: i32,
    den: i32,
    taps: &[u32; OUT_ROW],
    orow: &mut [i8],
    v: &mut [i32; ROW + 1],
) {
    let iw = r0.len().min(r1.len()).min(ROW);
    if iw == 0 {
        return;
    }
    for ((v, &a), &b) in v.iter_mut().zip(r0).zip(r1) {
        *v = i32::from(a) * (dy - fy) + i32::from(b) * fy;
    }
    v[iw] = v[iw - 1];
    let d = den * dy;
    let half = d / 2;
    for (o, &t) in orow.iter_mut().zip(taps) {
        // The mask keeps both reads inside `v` without a bounds branch (x0 < iw ≤ ROW already).
        let x0 = t as usize & (ROW - 1);
        let f = (t >> 16) as i32;
        let n = v[x0] * (den - f) + v[x0 + 1] * f;
        // |n| rounded half up, then the sign back: `div_round_i32(n, d)`.
        let sign = n >> 31;
        let q = (((((n ^ sign) - sign) + half) / d) ^ sign) - sign;
        *o = q.clamp(-128, 127) as i8;
    }
}

/// f32 bilinear resize (`align_corners = true`); used for depth maps and as the float reference.
pub fn upsample_bilinear_f32(
    input: &[f32],
    in_shape: Shape,
    out: &mut [f32],
    out_shape: Shape,
) -> Result<(), KernelError> {
    check(input, in_shape, out, out_shape)?;
    for c in 0..out_shape.c {
        for oy in 0..out_shape.h {
            let at = (c * out_shape.h + oy) * out_shape.w;
            upsample_bilinear_f32_row(
                input,
                in_shape,
                c,
                oy,
                &mut out[at..at + out_shape.w],
                out_shape,
            )?;
        }
    }
    Ok(())
}

/// Row `oy` of channel `c` of [`upsample_bilinear_f32`]'s output (`out_shape.w` values into
/// `dst`), the same bits, so a consumer can resize one row at a time.
pub fn upsample_bilinear_f32_row(
    input: &[f32],
    in_shape: Shape,
    c: usize,
    oy: usize,
    dst: &mut [f32],
    out_shape: Shape,
) -> Result<(), KernelError> {
    let (ih, iw) = (in_shape.h, in_shape.w);
    let ok = c < in_shape.c.min(out_shape.c)
        && oy < out_shape.h
        && ih > 0
        && iw > 0
        && dst.len() >= out_shape.w
        && in_shape.len().is_some_and(|n| n <= input.len());
    if !ok {
        return Err(KernelError::Shape);
    }
    let (y0, fy, dy) = src(oy, ih, out_shape.h);
    let y1 = (y0 + 1).min(ih - 1);
    let wy = fy as f32 / dy as f32;
    let r0 = &input[(c * ih + y0) * iw..][..iw];
    let r1 = &input[(c * ih + y1) * iw..][..iw];
    let mut cols = Coords::new(iw, out_shape.w);
    for o in dst[..out_shape.w].iter_mut() {
        let (x0, fx, dx) = cols.next();
        let x1 = (x0 + 1).min(iw - 1);
        // Both are below 2^31 (a row of `out_shape.w` values exists): the same f32 through
        // i32, without a 64-bit conversion call.
        let wx = fx as i32 as f32 / dx as i32 as f32;
        let top = r0[x0] * (1.0 - wx) + r0[x1] * wx;
        let bot = r1[x0] * (1.0 - wx) + r1[x1] * wx;
        *o = top * (1.0 - wy) + bot * wy;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::kernel_tests;
    use proptest::prelude::*;
    use std::vec::Vec;

    #[derive(Clone, Debug)]
    struct Case {
        x: Vec<i8>,
        s: Shape,
        o: Shape,
        expect: Option<Vec<i8>>,
    }

    type Impl = fn(&[i8], Shape, &mut [i8], Shape) -> Result<(), KernelError>;

    fn check_case(c: &Case, f: Impl) {
        let mut y = std::vec![0i8; c.o.len().unwrap()];
        f(&c.x, c.s, &mut y, c.o).unwrap();
        let xf: Vec<f32> = c.x.iter().map(|&v| v as f32).collect();
        let mut r = std::vec![0f32; y.len()];
        upsample_bilinear_f32(&xf, c.s, &mut r, c.o).unwrap();
        for (i, (&q, &v)) in y.iter().zip(&r).enumerate() {
            assert!((q as f32 - v).abs() <= 0.5 + 1e-3, "[{i}] {q} vs {v}");
        }
        if let Some(e) = &c.expect {
            assert_eq!(&y, e);
        }
        let mut y2 = std::vec![0i8; y.len()];
        upsample_bilinear_ref(&c.x, c.s, &mut y2, c.o).unwrap();
        assert_eq!(y, y2);
    }

    fn golden() -> Vec<Case> {
        std::vec![
            // 1×2 → 1×3 align_corners: 0, mid, 10.
            Case {
                x: std::vec![0, 10],
                s: Shape::new(1, 1, 2),
                o: Shape::new(1, 1, 3),
                expect: Some(std::vec![0, 5, 10])
            },
            // 1×2 → 1×4: 0, 10/3, 20/3, 10 → 0, 3, 7, 10; negative: −10/3 → −3, −20/3 → −7
            Case {
                x: std::vec![0, 10],
                s: Shape::new(1, 1, 2),
                o: Shape::new(1, 1, 4),
                expect: Some(std::vec![0, 3, 7, 10])
            },
            Case {
                x: std::vec![0, -10],
                s: Shape::new(1, 1, 2),
                o: Shape::new(1, 1, 4),
                expect: Some(std::vec![0, -3, -7, -10])
            },
            // 2×2 → 3×3 centre = mean of 4 corners (1+2+3+5)/4 = 2.75 → 3
            Case {
                x: std::vec![1, 2, 3, 5],
                s: Shape::new(1, 2, 2),
                o: Shape::new(1, 3, 3),
                expect: Some(std::vec![1, 2, 2, 2, 3, 4, 3, 4, 5])
            },
        ]
    }

    prop_compose! {
        fn arb()(c in 1usize..3, ih in 1usize..6, iw in 1usize..6, oh in 1usize..12, ow in 1usize..12, seed in any::<u32>()) -> Case {
            let s = Shape::new(c, ih, iw);
            let x = (0..s.len().unwrap()).map(|i| ((i as u32).wrapping_mul(2654435761) ^ seed) as i8).collect();
            Case { x, s, o: Shape::new(c, oh, ow), expect: None }
        }
    }

    #[test]
    fn running_coordinates_equal_the_division() {
        for n_in in 1..40 {
            for n_out in 1..90 {
                let mut c = Coords::new(n_in, n_out);
                for o in 0..n_out {
                    assert_eq!(c.next(), src(o, n_in, n_out), "{n_in} → {n_out} at {o}");
                }
            }
        }
    }

    kernel_tests!(suite, ref: upsample_bilinear_ref, fast: upsample_bilinear, golden: golden, arb: arb(), check: check_case);
}
