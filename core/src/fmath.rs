//! Precise elementary functions for `no_std` (`core` has no `sqrt`, `ln`, `tan` or `exp` on floats).
//!
//! `micromath`'s `F32Ext` approximations (used first, then dropped) are fast but coarse (its `sqrt`
//! is documented to 5 %, its `tan` to 0.6 absolute, its `exp` measured at 2.4e-3 relative), too
//! coarse for sub-pixel projection, metrics and the bins softmax. These versions use
//! range reduction plus a converging series or Newton iteration and are accurate to a few ULP of
//! `f64` (relative error below 1e-15 over the ranges used; the unit tests check this against
//! `std`). They are not fast and are meant for per-zone and per-metric work, not per-pixel loops
//! on a Cortex-M (there `f64` is soft-float).
//!
//! [`exp_f32`] is the one per-pixel function: `f32` only (the Cortex-M4F FPU is single precision),
//! accurate to about 2 ULP, built from `+`, `−`, `×` and bit operations only, so it gives the same
//! bits on every IEEE-754 target (Rust never fuses `a·b + c` into an FMA on its own).

/// `sqrt(x)`: NaN for negative or NaN input, `+inf` for `+inf`, exact zero for zero.
///
/// Seeds from halving the exponent bits (within about 4 %), then five Newton steps
/// (`y ← (y + x/y)/2`, quadratic convergence: 4e-2 → 8e-4 → 3e-7 → 5e-14 → ULP).
pub(crate) fn sqrt(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 || x == f64::INFINITY {
        return x;
    }
    // Subnormals: scale into the normal range first (2^108 = (2^54)^2).
    let (x, scale) = if x < f64::MIN_POSITIVE {
        (x * TWO_POW_108, 1.0 / TWO_POW_54)
    } else {
        (x, 1.0)
    };
    let mut y = f64::from_bits((x.to_bits() >> 1) + (0x3ff_u64 << 51));
    for _ in 0..5 {
        y = 0.5 * (y + x / y);
    }
    y * scale
}

const TWO_POW_54: f64 = 18_014_398_509_481_984.0;
const TWO_POW_108: f64 = TWO_POW_54 * TWO_POW_54;

/// Natural logarithm: NaN for negative or NaN input, `-inf` for zero, `+inf` for `+inf`.
///
/// Writes `x = m · 2^e` with `m ∈ [√½, √2)`, then `ln m = 2·atanh(s)`, `s = (m−1)/(m+1)`,
/// `|s| ≤ 0.172`, summing `s^(2k+1)/(2k+1)` until the terms vanish (`s² ≤ 0.0295`, so 12 terms
/// reach 1e-18 relative).
pub(crate) fn ln(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return f64::NEG_INFINITY;
    }
    if x == f64::INFINITY {
        return x;
    }
    let (x, extra_exp) = if x < f64::MIN_POSITIVE {
        (x * TWO_POW_54, -54)
    } else {
        (x, 0)
    };
    let bits = x.to_bits();
    let mut e = ((bits >> 52) & 0x7ff) as i32 - 1023 + extra_exp;
    // Mantissa with exponent 0: m ∈ [1, 2).
    let mut m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | (0x3ff_u64 << 52));
    if m > core::f64::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let mut term = s;
    let mut sum = 0.0;
    let mut k = 0u32;
    while k < 14 {
        sum += term / f64::from(2 * k + 1);
        term *= s2;
        k += 1;
    }
    2.0 * sum + f64::from(e) * core::f64::consts::LN_2
}

/// Base-10 logarithm, `ln(x) / ln(10)`.
pub(crate) fn log10(x: f64) -> f64 {
    ln(x) / core::f64::consts::LN_10
}

/// `tan(x)` for `x ∈ [0, π/2)` (a half field of view); NaN outside that range.
///
/// Reduces `x > π/4` with `tan x = 1 / tan(π/2 − x)`, then evaluates Taylor series of `sin` and
/// `cos` on `[0, π/4]` up to degree 24 (remainder below 1e-20). Close to π/2 the relative error
/// grows like `6e-17 / (π/2 − x)` (the rounding of `π/2` itself): 3e-15 at 89°.
pub(crate) fn tan_half_fov(x: f64) -> f64 {
    use core::f64::consts::{FRAC_PI_2, FRAC_PI_4};
    if x.is_nan() || !(0.0..FRAC_PI_2).contains(&x) {
        return f64::NAN;
    }
    let (r, invert) = if x > FRAC_PI_4 {
        (FRAC_PI_2 - x, true)
    } else {
        (x, false)
    };
    let r2 = r * r;
    // sin r = Σ (−1)^k r^(2k+1)/(2k+1)!, cos r = Σ (−1)^k r^(2k)/(2k)!
    let mut sin_term = r;
    let mut cos_term = 1.0;
    let mut sin = 0.0;
    let mut cos = 0.0;
    let mut k = 0u32;
    while k < 13 {
        sin += sin_term;
        cos += cos_term;
        let a = f64::from(2 * k + 1);
        let b = f64::from(2 * k + 2);
        let c = f64::from(2 * k + 3);
        cos_term *= -r2 / (a * b);
        sin_term *= -r2 / (b * c);
        k += 1;
    }
    if invert {
        cos / sin
    } else {
        sin / cos
    }
}

/// `e^x` in `f32`: `+inf` above ≈88.72, `0` below ≈−103.97 (subnormal results are kept), NaN for NaN.
///
/// Cody–Waite reduction `x = k·ln2 + r`, `|r| ≤ ln2/2` (ln2 split into a 16-bit-exact high part
/// and a low part, so `k·LN2_HI` is exact for the `k` that occur), a degree-7 Taylor polynomial
/// of `e^r` in Horner form (truncation below 3e-9 relative), then `2^k` applied through the
/// exponent bits in two steps so that `k` down to −150 and up to 128 scale without overflow.
#[inline(always)] // hot in the bins head and the mixing tables; not worth a call
pub(crate) fn exp_f32(x: f32) -> f32 {
    if x.is_nan() {
        return x;
    }
    if x > EXP_MAX {
        return f32::INFINITY;
    }
    if x < EXP_MIN {
        return 0.0;
    }
    let kf = x * LOG2_E;
    let k = if kf >= 0.0 {
        (kf + 0.5) as i32
    } else {
        (kf - 0.5) as i32
    };
    exp_reduced(x, k)
}

/// [`exp_f32`] on `N` lanes at once, bit for bit: the same operations on each lane, with the
/// special cases (NaN, overflow, underflow) selected after the arithmetic instead of branched
/// around it, and `2^k` always applied in [`exp_reduced`]'s two steps (equal to its one step
/// wherever that one is taken), so that the compiler can keep the lanes in SIMD registers.
#[inline(always)]
pub(crate) fn exp_f32_lanes<const N: usize>(x: [f32; N]) -> [f32; N] {
    let mut out = [0.0f32; N];
    for (o, &xl) in out.iter_mut().zip(x.iter()) {
        // Inside the range the clamp changes nothing; outside it the value is selected away.
        // `max` turns NaN into the bound (`clamp` would keep it), as the conversion below needs.
        #[allow(clippy::manual_clamp)]
        let xc = xl.max(EXP_MIN).min(EXP_MAX);
        let kf = xc * LOG2_E;
        // `kf ± 0.5` by the sign bit: only −0 takes −0.5 where `exp_f32` adds 0.5, and both
        // truncate to 0.
        let kr = kf + 0.5f32.copysign(kf);
        // SAFETY: `xc` is finite and within [EXP_MIN, EXP_MAX], so `|kr| < 151`: finite and
        // inside `i32`, where the unchecked conversion is the truncation `as i32` makes (and,
        // without `as`'s saturation, one the compiler can vectorise).
        let k: i32 = unsafe { kr.to_int_unchecked() };
        let (k1, k2) = (k / 2, k - k / 2);
        let p = exp_poly((xc - k as f32 * LN2_HI) - k as f32 * LN2_LO);
        let v = p * pow2i(k1) * pow2i(k2);
        let v = if xl < EXP_MIN { 0.0 } else { v };
        let v = if xl > EXP_MAX { f32::INFINITY } else { v };
        *o = if xl.is_nan() { xl } else { v };
    }
    out
}

/// Natural logarithm in `f32` of a positive normal `x` (NaN for NaN, zero, negative or
/// subnormal input, `+inf` for `+inf`).
///
/// Writes `x = m · 2^e` with `m ∈ [√½, √2)`, then `ln m = 2·atanh(s)`, `s = (m−1)/(m+1)`,
/// `|s| ≤ 0.172`, summed to `s⁹/9` in Horner form (truncation below 4e-9 relative), plus
/// `e·ln2` with ln2 split as in `exp_f32` (so `e·LN2_HI` is exact).
#[inline(always)]
pub(crate) fn ln_f32(x: f32) -> f32 {
    if x.is_nan() || x < f32::MIN_POSITIVE {
        return f32::NAN;
    }
    if x == f32::INFINITY {
        return x;
    }
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000); // [1, 2)
    if m > core::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = s * (2.0 + s2 * (2.0 / 3.0 + s2 * (0.4 + s2 * (2.0 / 7.0 + s2 * (2.0 / 9.0)))));
    let ef = e as f32;
    ef * LN2_HI + (series + ef * LN2_LO)
}

/// `log2 e` in f32.
pub(crate) const LOG2_E: f32 = core::f32::consts::LOG2_E;
/// Above this [`exp_f32`] is `+inf`.
pub(crate) const EXP_MAX: f32 = 88.722_84;
/// Below this [`exp_f32`] is 0.
pub(crate) const EXP_MIN: f32 = -103.972_08;

/// `ln 2` split for the Cody–Waite reduction: 16 significant bits (`0x3f31_7200`, so `k·LN2_HI`
/// is exact) and the rest.
pub(crate) const LN2_HI: f32 = 0.693_145_75;
pub(crate) const LN2_LO: f32 = 1.428_606_8e-6;

/// `e^r` for the reduced `|r| ≤ ln2/2`: the degree-7 Taylor polynomial in Horner form.
#[inline(always)]
fn exp_poly(r: f32) -> f32 {
    1.0 + r
        * (1.0
            + r * (0.5
                + r * (1.0 / 6.0
                    + r * (1.0 / 24.0
                        + r * (1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0)))))))
}

/// `e^x` from its rounded `k = round(x·log2 e)` (half away from zero): the reduction, the
/// polynomial and the scaling of [`exp_f32`].
#[inline(always)]
fn exp_reduced(x: f32, k: i32) -> f32 {
    let p = exp_poly((x - k as f32 * LN2_HI) - k as f32 * LN2_LO);
    if (-126..=127).contains(&k) {
        // One exact power of two: the same single rounding as the two-step form below, whose
        // first product is exact for every k.
        return p * pow2i(k);
    }
    // 2^k = 2^k1 · 2^k2 with both halves inside the normal exponent range [−126, 127].
    let k1 = k / 2;
    let k2 = k - k1;
    p * pow2i(k1) * pow2i(k2)
}

/// `2^(j/32)` for `j = 0..32`, each rounded to the nearest f32 (the bits, so no literal parsing
/// is involved).
pub(crate) const EXP2_32THS: [u32; 32] = [
    0x3f800000, 0x3f82cd87, 0x3f85aac3, 0x3f88980f, 0x3f8b95c2, 0x3f8ea43a, 0x3f91c3d3, 0x3f94f4f0,
    0x3f9837f0, 0x3f9b8d3a, 0x3f9ef532, 0x3fa27043, 0x3fa5fed7, 0x3fa9a15b, 0x3fad583f, 0x3fb123f6,
    0x3fb504f3, 0x3fb8fbaf, 0x3fbd08a4, 0x3fc12c4d, 0x3fc5672a, 0x3fc9b9be, 0x3fce248c, 0x3fd2a81e,
    0x3fd744fd, 0x3fdbfbb8, 0x3fe0ccdf, 0x3fe5b907, 0x3feac0c7, 0x3fefe4ba, 0x3ff5257d, 0x3ffa83b3,
];

/// `32·log2 e` and `ln 2 / 32` in f32 (the constants of [`softmax_exp`]).
pub(crate) const SOFTMAX_T: f32 = 46.166_24;
/// See [`SOFTMAX_T`].
pub(crate) const SOFTMAX_U: f32 = 0.021_660_85;
/// Inputs below this give a softmax weight of 0 (`e^−80 < 2·10⁻³⁵`, so every result is a
/// normal number).
pub(crate) const SOFTMAX_FLOOR: f32 = -80.0;

/// `e^x` for a softmax's `x = l − max ≤ 0` (or NaN, which it returns as NaN), cheaper than
/// [`exp_f32`] on a Cortex-M: `t = x·32·log2 e` truncated to `n` (toward zero), `n = 32q + j`
/// with `j ∈ 0..32`, and `e^x = 2^q · 2^(j/32) · 2^(r/32)` for `r = t − n ∈ (−1, 0]`, the last
/// factor a cubic in `u = r·ln2/32` (`|u| < 0.022`, truncation error below 10⁻⁸), evaluated as
/// `(T[j]·p)·2^q`; `x <` [`SOFTMAX_FLOOR`] (and −∞) gives 0. Relative error below
/// `3·10⁻⁷ + |x|·1.2·10⁻⁷` (the rounding of `t`): far below what a weight's share of the
/// expectation can resolve. `+`, `−`, `×`, conversions and bit operations only, in a fixed order,
/// so every IEEE target (and the AVX2 lanes of `kernels::x86_64::vmath`) gives the same bits.
#[inline(always)]
pub(crate) fn softmax_exp(x: f32) -> f32 {
    if x < SOFTMAX_FLOOR {
        return 0.0;
    }
    let t = x * SOFTMAX_T;
    // `as` truncates toward zero (NaN → 0); |t| ≤ 3 694 here unless x > 0 (not a softmax input).
    let n = t as i32;
    let u = (t - n as f32) * SOFTMAX_U;
    let p = 1.0 + u * (1.0 + u * (0.5 + u * (1.0 / 6.0)));
    let q = n >> 5;
    let table = f32::from_bits(EXP2_32THS[(n & 31) as usize]);
    // 2^q for q ∈ [−116, 0] (x ≤ 0), an exact power of two: one rounding in all.
    table * p * f32::from_bits(((q + 127) as u32) << 23)
}

/// `2^k` for `k ∈ [−126, 127]` from the exponent bits.
fn pow2i(k: i32) -> f32 {
    f32::from_bits(((k + 127) as u32) << 23)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        if a == b {
            0.0
        } else {
            ((a - b) / b).abs()
        }
    }

    #[test]
    fn exp_f32_within_two_ulp_of_std() {
        let mut worst = 0.0f64;
        let mut x = -103.0f32;
        while x < 88.7 {
            let want = std::primitive::f64::exp(x as f64);
            let got = exp_f32(x) as f64;
            if want > 1e-37 {
                // ULP of the f32 result, as a relative size.
                let ulp = (want as f32).to_bits();
                let ulp = f32::from_bits(ulp + 1) as f64 - f32::from_bits(ulp) as f64;
                worst = worst.max((got - want).abs() / ulp);
            }
            x += 0.013_7;
        }
        assert!(worst <= 2.0, "worst {worst} ULP");
        assert_eq!(exp_f32(0.0), 1.0);
        assert_eq!(exp_f32(-200.0), 0.0);
        assert_eq!(exp_f32(100.0), f32::INFINITY);
        assert!(exp_f32(f32::NAN).is_nan());
        assert!(exp_f32(-100.0) > 0.0, "subnormal results kept");
    }

    /// The softmax weight is within `3·10⁻⁷ + |x|·1.2·10⁻⁷` relative of `e^x` (f64) on a dense
    /// sweep of `[−80, 0]`, exact at 0, 0 below the floor and −∞, NaN for NaN.
    #[test]
    fn softmax_exp_is_close_to_exp() {
        let mut x = 0.0f32;
        let mut worst = 0.0f64;
        while x >= SOFTMAX_FLOOR {
            let want = (x as f64).exp();
            let rel = (softmax_exp(x) as f64 - want).abs() / want;
            let bound = 3e-7 + (x as f64).abs() * 1.2e-7;
            assert!(rel <= bound, "x {x}: relative error {rel:e} > {bound:e}");
            worst = worst.max(rel / bound);
            x -= 0.000_973;
        }
        assert!(
            worst > 0.05,
            "the sweep never came near the bound ({worst})"
        );
        assert_eq!(softmax_exp(0.0), 1.0);
        assert_eq!(softmax_exp(-0.0), 1.0);
        assert_eq!(softmax_exp(-80.01), 0.0);
        assert_eq!(softmax_exp(f32::NEG_INFINITY), 0.0);
        assert!(softmax_exp(f32::NAN).is_nan());
        // The table is 2^(j/32) rounded to f32.
        for (j, &b) in EXP2_32THS.iter().enumerate() {
            assert_eq!(
                b,
                (2f64.powf(j as f64 / 32.0) as f32).to_bits(),
                "entry {j}"
            );
        }
    }

    /// Test inputs: every `step`-th f32 bit pattern (both signs: NaN, infinities, subnormals),
    /// each of `points` with its 3 neighbours on either side, and NaN.
    pub(crate) fn bit_sweep(step: u32, points: &[f32]) -> std::vec::Vec<f32> {
        let mut xs: std::vec::Vec<f32> = (0..=u32::MAX / step)
            .map(|i| f32::from_bits(i * step))
            .collect();
        for b in points {
            for d in -3i32..=3 {
                xs.push(f32::from_bits(b.to_bits().wrapping_add_signed(d)));
            }
        }
        xs.push(f32::NAN);
        xs
    }

    /// `exp_f32`'s range limits and the signed zeros and infinities.
    pub(crate) const EXP_EDGES: [f32; 6] = [
        EXP_MAX,
        EXP_MIN,
        0.0,
        -0.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ];

    /// The lane form equals the scalar one bit for bit: a sweep of every 613th f32 bit pattern
    /// and both range limits with their neighbours.
    #[test]
    fn exp_f32_lanes_equals_exp_f32() {
        let xs = bit_sweep(613, &EXP_EDGES);
        let mut in_range = 0;
        for c in xs.chunks(4) {
            let mut lanes = [0.0f32; 4];
            lanes[..c.len()].copy_from_slice(c);
            let got = exp_f32_lanes(lanes);
            for (g, &x) in got.iter().zip(lanes.iter()) {
                let want = exp_f32(x);
                assert!(
                    g.to_bits() == want.to_bits() || (g.is_nan() && want.is_nan()),
                    "x {x:e} ({:#x}): lanes {g:e}, scalar {want:e}",
                    x.to_bits()
                );
                in_range += usize::from((EXP_MIN..=EXP_MAX).contains(&x));
            }
        }
        assert!(in_range > 1_000_000, "{in_range} inputs in range");
    }

    #[test]
    fn exp_f32_one_step_scaling_equals_two_step() {
        let two_step = |p: f32, k: i32| p * pow2i(k / 2) * pow2i(k - k / 2);
        for k in -126..=127 {
            for bits in (0x3f35_04f3u32..=0x3fb5_04f3).step_by(997) {
                let p = f32::from_bits(bits); // [√½, √2]: the polynomial's range
                assert_eq!(
                    (p * pow2i(k)).to_bits(),
                    two_step(p, k).to_bits(),
                    "p {p} k {k}"
                );
            }
        }
    }

    #[test]
    fn sqrt_matches_std() {
        for &x in &[
            1e-310, 1e-300, 1e-12, 0.01, 0.5, 1.0, 2.0, 3.0, 10.0, 12345.678, 1e100, 1.7e308,
        ] {
            assert!(
                rel(sqrt(x), std::primitive::f64::sqrt(x)) < 4e-16,
                "sqrt({x})"
            );
        }
        assert!(sqrt(-1.0).is_nan());
        assert!(sqrt(f64::NAN).is_nan());
        assert_eq!(sqrt(0.0), 0.0);
        assert_eq!(sqrt(f64::INFINITY), f64::INFINITY);
    }

    #[test]
    fn ln_f32_within_two_ulp_of_std() {
        let mut x = 1.0e-30f32;
        while x < 1.0e30 {
            let want = std::primitive::f32::ln(x);
            let got = ln_f32(x);
            let ulp = f32::EPSILON * want.abs().max(f32::MIN_POSITIVE);
            assert!(
                (got - want).abs() <= 2.0 * ulp.max(1e-7),
                "ln_f32({x}) = {got}, std {want}"
            );
            x *= 1.000_37;
        }
        assert_eq!(ln_f32(1.0), 0.0);
        assert!(ln_f32(0.0).is_nan() && ln_f32(-1.0).is_nan() && ln_f32(f32::NAN).is_nan());
        assert_eq!(ln_f32(f32::INFINITY), f32::INFINITY);
    }

    #[test]
    fn ln_and_log10_match_std() {
        for &x in &[
            1e-310, 1e-300, 1e-3, 0.1, 0.7, 1.0, 1.41, 1.5, 2.0, 10.0, 1000.0, 4.1, 1e300,
        ] {
            let want = std::primitive::f64::ln(x);
            let got = ln(x);
            assert!((got - want).abs() <= 1e-15 * want.abs().max(1.0), "ln({x})");
            let want10 = std::primitive::f64::log10(x);
            assert!(
                (log10(x) - want10).abs() <= 1e-15 * want10.abs().max(1.0),
                "log10({x})"
            );
        }
        assert_eq!(ln(1.0), 0.0);
        assert!(ln(-1.0).is_nan());
        assert_eq!(ln(0.0), f64::NEG_INFINITY);
    }

    #[test]
    fn tan_matches_std() {
        let mut x = 0.0;
        // Near π/2 the reduction π/2 − x inherits FRAC_PI_2's own rounding (6e-17 absolute), so
        // the relative error grows like 6e-17 / (π/2 − x): check up to x = 1.55 (89°).
        while x < 1.55 {
            assert!(
                rel(tan_half_fov(x), std::primitive::f64::tan(x)) < 1e-14,
                "tan({x})"
            );
            x += 0.001;
        }
        assert!(tan_half_fov(-0.1).is_nan());
        assert!(tan_half_fov(core::f64::consts::FRAC_PI_2).is_nan());
        assert!(tan_half_fov(f64::NAN).is_nan());
    }
}
