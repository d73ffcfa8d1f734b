//! Global pools (`[C,H,W] → [C,1,1]`) and channel reductions (`[C,H,W] → [1,H,W]`) in int8.
//! Means sum `q − zp_in` exactly in `i32` and requantise once with `s_in/(s_out·n)`; maxima take
//! the largest code and requantise it. One pass over memory each, so the reference loops are
//! also the fast path.

use super::elementwise::Rescale;
use super::requant::{clamp_i8, QParams, Requant};
use super::{need, KernelError, Shape};

/// Largest reduction length accepted (keeps the `i32` sum of `±255` terms exact).
pub const MAX_REDUCE: usize = 1 << 23;

/// Constants of an int8 mean over `n` elements.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C)]
pub struct MeanQuant {
    /// Input zero point.
    pub zp_in: i32,
    /// Output zero point.
    pub zp_out: i32,
    /// `s_in/(s_out·n)`.
    pub m: Requant,
}

impl MeanQuant {
    /// For a mean over `n` elements.
    pub fn new(in_q: QParams, out_q: QParams, n: usize) -> MeanQuant {
        MeanQuant {
            zp_in: in_q.zero_point,
            zp_out: out_q.zero_point,
            m: Requant::from_real(in_q.scale as f64 / (out_q.scale as f64 * n.max(1) as f64)),
        }
    }

    #[inline]
    fn finish(&self, sum: i32) -> i8 {
        clamp_i8(
            self.m.apply_rounded(sum).saturating_add(self.zp_out),
            -128,
            127,
        )
    }
}

fn check(input: &[i8], shape: Shape, out: &[i8], out_len: usize) -> Result<usize, KernelError> {
    need(input, shape)?;
    let p = shape.plane().ok_or(KernelError::Shape)?;
    if out.len() < out_len || p == 0 || shape.c == 0 || p > MAX_REDUCE || shape.c > MAX_REDUCE {
        return Err(KernelError::Shape);
    }
    Ok(p)
}

/// Global average pool; `q` built with `n = H·W`.
pub fn global_avg_pool(
    q: &MeanQuant,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let p = check(input, shape, out, shape.c)?;
    for (c, o) in out[..shape.c].iter_mut().enumerate() {
        let sum: i32 = input[c * p..(c + 1) * p]
            .iter()
            .map(|&x| x as i32 - q.zp_in)
            .sum();
        *o = q.finish(sum);
    }
    Ok(())
}

/// Global max pool, requantised with `r` (identity when input and output share parameters).
pub fn global_max_pool(
    r: &Rescale,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let p = check(input, shape, out, shape.c)?;
    for (c, o) in out[..shape.c].iter_mut().enumerate() {
        let m = input[c * p..(c + 1) * p]
            .iter()
            .copied()
            .max()
            .unwrap_or(i8::MIN);
        *o = r.apply(m);
    }
    Ok(())
}

/// Mean over channels; `q` built with `n = C`.
pub fn channel_mean(
    q: &MeanQuant,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let p = check(input, shape, out, shape.h.saturating_mul(shape.w))?;
    for (i, o) in out[..p].iter_mut().enumerate() {
        let mut sum = 0i32;
        for c in 0..shape.c {
            sum += input[c * p + i] as i32 - q.zp_in;
        }
        *o = q.finish(sum);
    }
    Ok(())
}

/// Max over channels, requantised with `r`.
pub fn channel_max(
    r: &Rescale,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let p = check(input, shape, out, shape.h.saturating_mul(shape.w))?;
    out[..p].copy_from_slice(&input[..p]);
    for c in 1..shape.c {
        for (o, &x) in out[..p].iter_mut().zip(&input[c * p..(c + 1) * p]) {
            *o = (*o).max(x);
        }
    }
    if !r.is_identity() {
        for o in out[..p].iter_mut() {
            *o = r.apply(*o);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::float;
    use proptest::prelude::*;
    use std::vec::Vec;

    #[test]
    fn pools_by_hand() {
        let qi = QParams {
            scale: 0.5,
            zero_point: 2,
        };
        let qo = QParams {
            scale: 0.25,
            zero_point: -1,
        };
        let s = Shape::new(2, 1, 3);
        let x = [2, 4, 7, -2, 0, 2]; // real: 0 1 2.5 | −2 −1 0
        let mut y = [0i8; 3];
        global_avg_pool(&MeanQuant::new(qi, qo, 3), &x, s, &mut y).unwrap();
        // means 3.5/3 = 1.1667 → 4.667 → 5 − 1 = 4 ; −1 → −4 − 1 = −5
        assert_eq!(&y[..2], &[4, -5]);
        global_max_pool(&Rescale::new(qi, qo), &x, s, &mut y).unwrap();
        assert_eq!(&y[..2], &[9, -1]); // 2.5 → 10 − 1; 0 → −1
        channel_mean(&MeanQuant::new(qi, qo, 2), &x, s, &mut y).unwrap();
        assert_eq!(y, [-5, -1, 4]); // −1 → −5, 0 → −1, 1.25 → 5 − 1
        channel_max(&Rescale::new(qi, qi), &x, s, &mut y).unwrap();
        assert_eq!(y, [2, 4, 7]);
        assert_eq!(
            channel_max(&Rescale::new(qi, qi), &x[..5], s, &mut y),
            Err(KernelError::Shape)
        );
    }

    proptest! {
        #[test]
        fn means_within_one_lsb(c in 1usize..5, h in 1usize..6, w in 1usize..6, zi in -20i32..20, zo in -20i32..20,
                                si in 0.01f32..0.5, so in 0.01f32..0.5, seed in any::<u32>()) {
            let s = Shape::new(c, h, w);
            let x: Vec<i8> = (0..s.len().unwrap()).map(|i| ((i as u32).wrapping_mul(2654435761) ^ seed) as i8).collect();
            let (qi, qo) = (QParams { scale: si, zero_point: zi }, QParams { scale: so, zero_point: zo });
            let xf: Vec<f32> = x.iter().map(|&q| qi.dequantize(q)).collect();
            let mut y = std::vec![0i8; c.max(h * w)];
            let mut r = std::vec![0f32; c.max(h * w)];
            global_avg_pool(&MeanQuant::new(qi, qo, h * w), &x, s, &mut y).unwrap();
            float::global_avg_pool(&xf, s, &mut r).unwrap();
            for i in 0..c { prop_assert!((y[i] as i32 - qo.quantize(r[i]) as i32).abs() <= 1); }
            channel_mean(&MeanQuant::new(qi, qo, c), &x, s, &mut y).unwrap();
            float::channel_mean(&xf, s, &mut r).unwrap();
            for i in 0..h * w { prop_assert!((y[i] as i32 - qo.quantize(r[i]) as i32).abs() <= 1); }
            channel_max(&Rescale::new(qi, qo), &x, s, &mut y).unwrap();
            float::channel_max(&xf, s, &mut r).unwrap();
            for i in 0..h * w { prop_assert!((y[i] as i32 - qo.quantize(r[i]) as i32).abs() <= 1); }
            global_max_pool(&Rescale::new(qi, qo), &x, s, &mut y).unwrap();
            float::global_max_pool(&xf, s, &mut r).unwrap();
            for i in 0..c { prop_assert!((y[i] as i32 - qo.quantize(r[i]) as i32).abs() <= 1); }
        }
    }
}
