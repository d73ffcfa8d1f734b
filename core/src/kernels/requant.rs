//! Integer requantisation; the conv path is bit-exact with TFLite / gemmlowp / CMSIS-NN.
//!
//! A real multiplier `M > 0` is stored as a Q31 `multiplier` in `[2^30, 2^31)` and a power-of-two
//! `shift` so that `M = multiplier · 2^(shift − 31)`. Applying it to an `i32` accumulator is
//! `RoundingDivideByPOT(SaturatingRoundingDoublingHighMul(x · 2^max(shift,0), multiplier), max(−shift,0))`
//! exactly as `MultiplyByQuantizedMultiplier` in TFLite's `common.h`, so host and Cortex-M give the
//! same bits. Element-wise kernels, whose operands are small code differences, use
//! [`Requant::apply_rounded`] instead: the same multiplier with one rounding of the exact 64-bit
//! product (the two-step form would cost them up to a code per element). The only floating
//! point here is [`Requant::from_real`], run once at prepare time.

/// Per-tensor affine quantisation of int8 activations: `real = scale · (q − zero_point)` (of
/// int16 ones too, with zero point 0: [`super::wide`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QParams {
    /// Real value of one quantisation step (> 0).
    pub scale: f32,
    /// The code of real 0 (int8: in `-128..=127`; int16: 0).
    pub zero_point: i32,
}

impl QParams {
    /// Quantises `x`: `clamp(round_half_away(x / scale) + zero_point, -128, 127)`.
    pub fn quantize(&self, x: f32) -> i8 {
        let v = x / self.scale;
        let r = round_half_away(v);
        let q = if r >= 255.0 {
            255
        } else if r <= -256.0 {
            -256
        } else {
            r as i32
        };
        (q + self.zero_point).clamp(-128, 127) as i8
    }

    /// Quantises `x` to an int16 code (zero point 0): `clamp(round_half_away(x / scale),
    /// −32768, 32767)`.
    pub fn quantize_i16(&self, x: f32) -> i16 {
        round_half_away(x / self.scale).clamp(-32768.0, 32767.0) as i16
    }

    /// Dequantises a code: `scale · (q − zero_point)`.
    pub fn dequantize(&self, q: i8) -> f32 {
        self.dequantize_code(q as i32)
    }

    /// Dequantises a code of any width: `scale · (q − zero_point)`.
    pub fn dequantize_code(&self, q: i32) -> f32 {
        self.scale * (q - self.zero_point) as f32
    }
}

/// Rounds half away from zero without `std` (like C's `roundf`); NaN maps to 0.
pub fn round_half_away(v: f32) -> f32 {
    if v.is_nan() {
        return 0.0;
    }
    if v.abs() >= 8_388_608.0 {
        return v; // already integral (or infinite)
    }
    let t = (v.abs() + 0.5) as i32 as f32;
    if v < 0.0 {
        -t
    } else {
        t
    }
}

/// A real multiplier in Q31 + shift form (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C)]
pub struct Requant {
    /// Q31 mantissa in `[2^30, 2^31)`, or 0 for a zero multiplier.
    pub multiplier: i32,
    /// Power-of-two exponent: positive shifts left before the multiply, negative rounds right after.
    pub shift: i32,
}

impl Requant {
    /// Encodes a real multiplier (TFLite `QuantizeMultiplier`). Zero, negative, NaN and values
    /// below 2^-32 give the zero multiplier; values ≥ 2^30 saturate.
    pub fn from_real(real: f64) -> Requant {
        if real.is_nan() || real <= 0.0 {
            return Requant::default();
        }
        let bits = real.to_bits();
        let exp_bits = ((bits >> 52) & 0x7ff) as i32;
        if exp_bits == 0 {
            return Requant::default(); // subnormal: far below anything representable
        }
        if exp_bits == 0x7ff {
            return Requant {
                multiplier: i32::MAX,
                shift: 30,
            };
        }
        // frexp: real = q · 2^e with q in [0.5, 1).
        let mut e = exp_bits - 1022;
        let q = f64::from_bits((bits & !(0x7ffu64 << 52)) | (1022u64 << 52));
        let mut q_fixed = (q * 2_147_483_648.0 + 0.5) as i64; // exact scaling, round half up
        if q_fixed == 1i64 << 31 {
            q_fixed /= 2;
            e += 1;
        }
        if e < -31 {
            return Requant::default();
        }
        if e > 30 {
            return Requant {
                multiplier: i32::MAX,
                shift: 30,
            };
        }
        Requant {
            multiplier: q_fixed as i32,
            shift: e,
        }
    }

    /// Applies the multiplier to an accumulator (TFLite `MultiplyByQuantizedMultiplier`).
    #[inline]
    pub fn apply(&self, x: i32) -> i32 {
        let left = self.shift.clamp(0, 30);
        let right = (-self.shift).clamp(0, 31);
        let shifted = x.saturating_mul(1i32 << left);
        rounding_divide_by_pot(
            saturating_rounding_doubling_high_mul(shifted, self.multiplier),
            right,
        )
    }

    /// Applies the multiplier with a single rounding (half away from zero) of the exact 64-bit
    /// product `x · multiplier · 2^(shift − 31)`.
    ///
    /// [`Requant::apply`] rounds twice (after the high multiply, then after the right shift), which
    /// is harmless on conv accumulators but costs up to one code when `x` is a small int8
    /// difference and the multiplier is near 1 (rescaling one tensor's codes to another's,
    /// means, products). The element-wise kernels use this form; saturates to `i32`.
    #[inline]
    pub fn apply_rounded(&self, x: i32) -> i32 {
        if self.multiplier == 0 {
            return 0;
        }
        // |x · multiplier| < 2^62; `right` is in 1..=62 because shift is in −31..=30.
        let product = x as i64 * self.multiplier as i64;
        let right = (31 - self.shift).clamp(1, 62);
        let half = 1i64 << (right - 1);
        let magnitude = (product.unsigned_abs() as i64 + half) >> right;
        let rounded = if product < 0 { -magnitude } else { magnitude };
        rounded.clamp(i32::MIN as i64, i32::MAX as i64) as i32
    }

    /// The real value this multiplier encodes (for tests and reports).
    pub fn to_real(&self) -> f64 {
        let mut v = self.multiplier as f64 / 2_147_483_648.0;
        let mut s = self.shift;
        while s > 0 {
            v *= 2.0;
            s -= 1;
        }
        while s < 0 {
            v *= 0.5;
            s += 1;
        }
        v
    }
}

/// gemmlowp `SaturatingRoundingDoublingHighMul`: `round(a·b / 2^31)`, saturating the one overflow.
#[inline]
pub fn saturating_rounding_doubling_high_mul(a: i32, b: i32) -> i32 {
    if a == i32::MIN && b == i32::MIN {
        return i32::MAX;
    }
    let ab = a as i64 * b as i64;
    // gemmlowp: trunc((ab + nudge) / 2^31) with nudge 2^30 for ab ≥ 0 and 1 − 2^30 for ab < 0,
    // which equals floor((ab + 2^30) / 2^31) for both signs (for ab < 0, trunc(t / 2^31) =
    // floor((t + 2^31 − 1) / 2^31)): one shift, no 64-bit division (a library call on 32-bit
    // targets).
    ((ab + (1 << 30)) >> 31) as i32
}

/// gemmlowp `RoundingDivideByPOT`: `x / 2^exponent`, rounding half away from zero.
/// `exponent` is clamped to `0..=31`.
#[inline]
pub fn rounding_divide_by_pot(x: i32, exponent: i32) -> i32 {
    let e = exponent.clamp(0, 31);
    let mask = ((1i64 << e) - 1) as i32;
    let remainder = x & mask;
    let threshold = (mask >> 1) + i32::from(x < 0);
    (x >> e) + i32::from(remainder > threshold)
}

/// Clamps an `i32` into an activation range and narrows it to int8.
#[inline]
pub fn clamp_i8(x: i32, min: i32, max: i32) -> i8 {
    x.clamp(min, max).clamp(-128, 127) as i8
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;

    #[test]
    fn srdhm_matches_hand_values() {
        // 2^30 · 2^30 / 2^31 = 2^29
        assert_eq!(
            saturating_rounding_doubling_high_mul(1 << 30, 1 << 30),
            1 << 29
        );
        assert_eq!(
            saturating_rounding_doubling_high_mul(i32::MIN, i32::MIN),
            i32::MAX
        );
        // 3 · 2^30 / 2^31 = 1.5 → 2; gemmlowp's nudge rounds −1.5 toward zero → −1
        assert_eq!(saturating_rounding_doubling_high_mul(3, 1 << 30), 2);
        assert_eq!(saturating_rounding_doubling_high_mul(-3, 1 << 30), -1);
    }

    proptest::proptest! {
        /// The one-shift form equals gemmlowp's nudged truncating division, edges included.
        #[test]
        fn srdhm_equals_gemmlowp_division(
            a in proptest::prop_oneof![proptest::prelude::any::<i32>(), -4i32..4, proptest::sample::select(vec![i32::MIN, i32::MAX, i32::MIN + 1, 1 << 30, -(1 << 30)])],
            b in proptest::prop_oneof![proptest::prelude::any::<i32>(), proptest::sample::select(vec![i32::MIN, i32::MAX, 1 << 30, (1 << 30) + 1])],
        ) {
            let ab = a as i64 * b as i64;
            let nudge: i64 = if ab >= 0 { 1 << 30 } else { 1 - (1 << 30) };
            let want = if a == i32::MIN && b == i32::MIN { i32::MAX } else { ((ab + nudge) / (1i64 << 31)) as i32 };
            proptest::prop_assert_eq!(saturating_rounding_doubling_high_mul(a, b), want);
        }
    }

    #[test]
    fn rdbpot_rounds_half_away() {
        assert_eq!(rounding_divide_by_pot(5, 1), 3); // 2.5 → 3
        assert_eq!(rounding_divide_by_pot(-5, 1), -3); // −2.5 → −3
        assert_eq!(rounding_divide_by_pot(7, 2), 2); // 1.75 → 2
        assert_eq!(rounding_divide_by_pot(-6, 2), -2); // −1.5 → −2
        assert_eq!(rounding_divide_by_pot(100, 0), 100);
    }

    #[test]
    fn from_real_encodes_hand_values() {
        assert_eq!(
            Requant::from_real(0.5),
            Requant {
                multiplier: 1 << 30,
                shift: 0
            }
        );
        assert_eq!(
            Requant::from_real(1.0),
            Requant {
                multiplier: 1 << 30,
                shift: 1
            }
        );
        assert_eq!(
            Requant::from_real(0.25),
            Requant {
                multiplier: 1 << 30,
                shift: -1
            }
        );
        assert_eq!(Requant::from_real(0.0), Requant::default());
        assert_eq!(Requant::from_real(-1.0), Requant::default());
        assert_eq!(Requant::from_real(f64::NAN), Requant::default());
        // 0.75 = 0.75 · 2^0 → 0.75·2^31
        assert_eq!(
            Requant::from_real(0.75),
            Requant {
                multiplier: 1_610_612_736,
                shift: 0
            }
        );
    }

    #[test]
    fn apply_matches_real_product() {
        let r = Requant::from_real(0.0123);
        for x in [-100_000, -777, -1, 0, 1, 555, 99_999] {
            let want = (x as f64 * 0.0123).round();
            assert!((r.apply(x) as f64 - want).abs() <= 1.0, "{x}");
        }
        let big = Requant::from_real(3.0);
        assert_eq!(big.apply(7), 21);
        // The left shift saturates first (as in TFLite), then 0.75 · i32::MAX: no panic.
        assert_eq!(big.apply(i32::MAX), 1_610_612_735);
    }

    #[test]
    fn apply_rounded_rounds_once() {
        // 0.454 = 0.908 · 2^-1: the two-step form rounds 1 · 0.908 up to 1, then 0.5 up to 1.
        let r = Requant::from_real(0.454);
        assert_eq!(r.apply(1), 1);
        assert_eq!(r.apply_rounded(1), 0);
        assert_eq!(r.apply_rounded(-1), 0);
        assert_eq!(r.apply_rounded(3), 1); // 1.362
        assert_eq!(r.apply_rounded(-5), -2); // −2.27
        assert_eq!(Requant::from_real(0.5).apply_rounded(-3), -2); // −1.5 → −2
        assert_eq!(Requant::default().apply_rounded(12345), 0);
        assert_eq!(Requant::from_real(1e9).apply_rounded(i32::MAX), i32::MAX);
    }

    #[test]
    fn quantize_round_trips() {
        let q = QParams {
            scale: 0.1,
            zero_point: -3,
        };
        assert_eq!(q.quantize(0.0), -3);
        assert_eq!(q.quantize(0.25), 0); // 2.5 → 3 (half away) − 3
        assert_eq!(q.quantize(1e9), 127);
        assert_eq!(q.quantize(-1e9), -128);
        assert_eq!(q.quantize(f32::NAN), -3);
        assert!((q.dequantize(7) - 1.0).abs() < 1e-6);
    }

    proptest::proptest! {
        #[test]
        fn apply_within_one_of_real(x in -1_000_000i32..1_000_000, m in 1e-6f64..4.0) {
            let r = Requant::from_real(m);
            let want = x as f64 * m;
            proptest::prop_assert!((r.apply(x) as f64 - want).abs() <= 1.0);
            // One rounding of the encoded multiplier: within half a unit, plus the encoding's
            // relative error of 2^-31.
            let exact = x as f64 * r.to_real();
            proptest::prop_assert!((r.apply_rounded(x) as f64 - exact).abs() <= 0.5 + 1e-6);
        }
    }
}
