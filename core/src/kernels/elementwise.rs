//! Elementwise int8 ops: 256-entry lookup tables (relu, leaky_relu, sigmoid, reciprocal — the
//! blob stores the table, so the core does no transcendental math for them), add and mul with
//! requantisation (TFLite int8 `ADD` arithmetic; `MUL`, concat and max-pool rescales with one
//! rounding of the exact product, [`Requant::apply_rounded`], not TFLite's two), concat with
//! per-input requantisation, pixel_shuffle and minmax_norm.

use super::broadcast::{broadcast_index, broadcast_len, Broadcast};
use super::isa::Isa;
use super::requant::{clamp_i8, rounding_divide_by_pot, QParams, Requant};
use super::wide::{Codes, CodesMut};
use super::{need, KernelError, Shape};

/// A 256-entry int8→int8 table, indexed by `q as u8` (so code −128 is entry 128).
pub type Lut = [i8; 256];

/// Builds the table of `f` for the given input and output quantisation (at prepare / export
/// time; `f` is the op's float reference, e.g. [`super::float::sigmoid`]).
pub fn build_lut(in_q: QParams, out_q: QParams, f: impl Fn(f32) -> f32) -> Lut {
    let mut t = [0i8; 256];
    for q in -128i32..=127 {
        t[(q as i8) as u8 as usize] = out_q.quantize(f(in_q.dequantize(q as i8)));
    }
    t
}

/// Applies a table: `out[i] = lut[in[i]]`.
pub fn lut(input: &[i8], table: &Lut, output: &mut [i8]) -> Result<(), KernelError> {
    lut_with(Isa::Portable, input, table, output)
}

/// [`lut`] with kernel set `isa`: `neon` and `neon-dot` read the table with `TBL`
/// ([`super::aarch64::elementwise::lookup`]); the same bits.
pub fn lut_with(isa: Isa, input: &[i8], table: &Lut, output: &mut [i8]) -> Result<(), KernelError> {
    if output.len() < input.len() {
        return Err(KernelError::Shape);
    }
    #[cfg(target_arch = "aarch64")]
    let (output, input) = if matches!(isa, Isa::Neon | Isa::NeonDot) {
        let done = super::aarch64::elementwise::lookup(table, input, output);
        (&mut output[done..], &input[done..])
    } else {
        (output, input)
    };
    #[cfg(not(target_arch = "aarch64"))]
    let _ = isa;
    for (o, &x) in output.iter_mut().zip(input) {
        *o = table[x as u8 as usize];
    }
    Ok(())
}

/// `x = table[x]` for every code of `data`, four codes per word read and written (one load,
/// four lookups, one store).
fn lut_in_place(table: &[i8; 256], data: &mut [i8]) {
    let mut words = data.chunks_exact_mut(4);
    for w in &mut words {
        let v = u32::from_le_bytes([w[0] as u8, w[1] as u8, w[2] as u8, w[3] as u8]);
        let t = |s: u32| u32::from(table[(v >> s) as u8 as usize] as u8) << s;
        let r = t(0) | t(8) | t(16) | t(24);
        w.copy_from_slice(&r.to_le_bytes().map(|b| b as i8));
    }
    for x in words.into_remainder() {
        *x = table[*x as u8 as usize];
    }
}

/// Requantisation of one int8 code from one tensor's parameters to another's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C)]
pub struct Rescale {
    /// `s_in / s_out`.
    pub m: Requant,
    /// Input zero point.
    pub zp_in: i32,
    /// Output zero point.
    pub zp_out: i32,
}

impl Rescale {
    /// From the input and output parameters.
    pub fn new(from: QParams, to: QParams) -> Rescale {
        Rescale {
            m: Requant::from_real(from.scale as f64 / to.scale as f64),
            zp_in: from.zero_point,
            zp_out: to.zero_point,
        }
    }

    /// True when codes pass through unchanged.
    pub fn is_identity(&self) -> bool {
        self.zp_in == self.zp_out && self.m == Requant::from_real(1.0)
    }

    /// Requantises one code.
    #[inline(always)]
    pub fn apply(&self, q: i8) -> i8 {
        self.apply_code(q as i32)
    }

    /// Requantises one code of any width (an int16 one: [`super::wide`]) to int8.
    #[inline(always)]
    pub fn apply_code(&self, q: i32) -> i8 {
        clamp_i8(
            self.m
                .apply_rounded(q.wrapping_sub(self.zp_in))
                .saturating_add(self.zp_out),
            -128,
            127,
        )
    }

    /// Requantises one code of any width to an int16 one (zero point 0: [`super::wide`]),
    /// clamped to `-32768..=32767`.
    #[inline(always)]
    pub fn apply_code_i16(&self, q: i32) -> i16 {
        self.m
            .apply_rounded(q.wrapping_sub(self.zp_in))
            .saturating_add(self.zp_out)
            .clamp(-32768, 32767) as i16
    }
}

/// Constants of int8 `add` (TFLite: inputs shifted left by 20 bits, scaled to `2·max(s_a, s_b)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C)]
pub struct AddQuant {
    /// Zero points of a, b and out.
    pub zp: [i32; 3],
    /// `s_a / (2·max)`.
    pub ma: Requant,
    /// `s_b / (2·max)`.
    pub mb: Requant,
    /// `2·max / (2^20 · s_out)`.
    pub mo: Requant,
}

/// Left shift applied to add inputs (TFLite's `left_shift = 20` for int8).
pub const ADD_LEFT_SHIFT: i32 = 20;

impl AddQuant {
    /// From the three tensors' parameters.
    pub fn new(a: QParams, b: QParams, out: QParams) -> AddQuant {
        let twice_max = 2.0 * (a.scale.max(b.scale) as f64);
        AddQuant {
            zp: [a.zero_point, b.zero_point, out.zero_point],
            ma: Requant::from_real(a.scale as f64 / twice_max),
            mb: Requant::from_real(b.scale as f64 / twice_max),
            mo: Requant::from_real(
                twice_max / ((1u64 << ADD_LEFT_SHIFT) as f64 * out.scale as f64),
            ),
        }
    }

    #[inline]
    fn apply(&self, a: i8, b: i8) -> i8 {
        self.finish(self.rescale_a(a), self.rescale_b(b))
    }

    /// Input `a`'s code on the common scale.
    #[inline]
    fn rescale_a(&self, a: i8) -> i32 {
        self.ma.apply((a as i32 - self.zp[0]) << ADD_LEFT_SHIFT)
    }

    /// Input `b`'s code on the common scale.
    #[inline]
    fn rescale_b(&self, b: i8) -> i32 {
        self.mb.apply((b as i32 - self.zp[1]) << ADD_LEFT_SHIFT)
    }

    /// The output code of two rescaled inputs.
    #[inline]
    fn finish(&self, xa: i32, xb: i32) -> i8 {
        clamp_i8(
            self.mo
                .apply(xa.saturating_add(xb))
                .saturating_add(self.zp[2]),
            -128,
            127,
        )
    }
}

/// Reference `add`: same-shape operands, plain loop.
pub fn add_ref(q: &AddQuant, a: &[i8], b: &[i8], out: &mut [i8]) -> Result<(), KernelError> {
    if a.len() != b.len() || out.len() < a.len() {
        return Err(KernelError::Shape);
    }
    for i in 0..a.len() {
        out[i] = q.apply(a[i], b[i]);
    }
    Ok(())
}

/// Fast `add`: same bits as [`add_ref`], iterator form without bounds checks in the loop.
pub fn add(q: &AddQuant, a: &[i8], b: &[i8], out: &mut [i8]) -> Result<(), KernelError> {
    add_with(Isa::Portable, q, a, b, out)
}

/// [`add`] with kernel set `isa`: `neon` and `neon-dot` compute the fast path 16 codes per
/// pass ([`super::aarch64::elementwise::add_rescaled`]); the same bits.
pub fn add_with(
    isa: Isa,
    q: &AddQuant,
    a: &[i8],
    b: &[i8],
    out: &mut [i8],
) -> Result<(), KernelError> {
    #[cfg(not(target_arch = "aarch64"))]
    let _ = isa;
    if a.len() != b.len() || out.len() < a.len() {
        return Err(KernelError::Shape);
    }
    // The two input rescales depend on one code each: 256-entry tables (the same function, so
    // the same bits) where there are more elements than codes, then one requantisation each.
    if a.len() <= 256 {
        for ((o, &x), &y) in out.iter_mut().zip(a).zip(b) {
            *o = q.apply(x, y);
        }
        return Ok(());
    }
    let ta: [i32; 256] = core::array::from_fn(|c| q.rescale_a(c as u8 as i8));
    let tb: [i32; 256] = core::array::from_fn(|c| q.rescale_b(c as u8 as i8));
    let widest = |t: &[i32; 256]| t.iter().map(|v| v.unsigned_abs()).max().unwrap_or(0);
    if q.mo.shift <= 0 && q.mo.multiplier >= 0 && widest(&ta) + widest(&tb) < 1 << 30 {
        // No left shift, and every sum of two rescaled codes is below 2^30 in magnitude: the
        // sums need no saturation and the doubling high multiply is the floor of
        // `(s·m + 2^30) / 2^31` (gemmlowp's nudge for negative products gives the same
        // integer), so the output's requantisation is a few 32/64-bit steps: the same bits.
        let (m, right, zp) = (i64::from(q.mo.multiplier), -q.mo.shift, q.zp[2]);
        // The same integers 16 at a time where the inputs' multipliers shift right only.
        #[cfg(target_arch = "aarch64")]
        let (out, a, b) =
            if matches!(isa, Isa::Neon | Isa::NeonDot) && q.ma.shift <= 0 && q.mb.shift <= 0 {
                let r = |m: &Requant| (m.multiplier, (-m.shift).min(31));
                let consts = [r(&q.ma), r(&q.mb), r(&q.mo)];
                let done = super::aarch64::elementwise::add_rescaled(a, b, out, q.zp, consts);
                (&mut out[done..], &a[done..], &b[done..])
            } else {
                (out, a, b)
            };
        for ((o, &x), &y) in out.iter_mut().zip(a).zip(b) {
            let sum = ta[x as u8 as usize] + tb[y as u8 as usize];
            let high = doubling_high_mul_narrow(sum, m);
            *o = clamp_i8(
                rounding_divide_by_pot(high, right).saturating_add(zp),
                -128,
                127,
            );
        }
        return Ok(());
    }
    for ((o, &x), &y) in out.iter_mut().zip(a).zip(b) {
        *o = q.finish(ta[x as u8 as usize], tb[y as u8 as usize]);
    }
    Ok(())
}

/// gemmlowp's saturating rounding doubling high multiply of `x` by `m ≥ 0` where
/// `|x| < 2^30`: `⌊(x·m + 2^30) / 2^31⌋`, which for negative products equals gemmlowp's
/// truncated `(x·m + 1 − 2^30) / 2^31` (and nothing saturates).
#[inline(always)]
fn doubling_high_mul_narrow(x: i32, m: i64) -> i32 {
    ((i64::from(x) * m + (1 << 30)) >> 31) as i32
}

/// Constants of int8 `mul`: `out = zp_out + (s_a·s_b/s_out)·(a − zp_a)(b − zp_b)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C)]
pub struct MulQuant {
    /// Zero points of a, b and out.
    pub zp: [i32; 3],
    /// `s_a·s_b/s_out`.
    pub m: Requant,
}

impl MulQuant {
    /// From the three tensors' parameters.
    pub fn new(a: QParams, b: QParams, out: QParams) -> MulQuant {
        MulQuant {
            zp: [a.zero_point, b.zero_point, out.zero_point],
            m: Requant::from_real(a.scale as f64 * b.scale as f64 / out.scale as f64),
        }
    }

    #[inline]
    fn apply(&self, a: i8, b: i8) -> i8 {
        let p = (a as i32 - self.zp[0]) * (b as i32 - self.zp[1]);
        clamp_i8(
            self.m.apply_rounded(p).saturating_add(self.zp[2]),
            -128,
            127,
        )
    }

    /// [`MulQuant::apply`] with its constants unpacked once per call.
    fn product(&self) -> Product {
        Product {
            zp: self.zp,
            m: self.m.multiplier.max(0) as u64,
            right: (31 - self.m.shift).clamp(1, 62) as u32,
        }
    }
}

/// [`MulQuant::apply`] for a loop: the rounded product `(|p|·M + 2^(r−1)) >> r` of
/// `p = (a − zp_a)(b − zp_b)` is one unsigned 32×32 → 64-bit multiply (`M < 2^31`), and any
/// magnitude past 1024 saturates the int8 result either way: the same bits without the signed
/// 64-bit steps.
#[derive(Clone, Copy)]
struct Product {
    zp: [i32; 3],
    m: u64,
    right: u32,
}

impl Product {
    #[inline(always)]
    fn apply(&self, a: i8, b: i8) -> i8 {
        let p = (a as i32 - self.zp[0]) * (b as i32 - self.zp[1]);
        let half = 1u64 << (self.right - 1);
        let magnitude = ((u64::from(p.unsigned_abs()) * self.m + half) >> self.right).min(1024);
        self.finish(p, magnitude as u32)
    }

    /// [`Product::apply`] where `right ≥ 33` (the usual case: products of scales below one):
    /// with `|p|·M = hi·2^32 + lo`, `(|p|·M + 2^(r−1)) >> r = (hi + 2^(r−33)) >> (r − 32)`
    /// exactly (dividing by 2^32 first drops only `lo`), so only the high word of the product
    /// is used and every step is 32-bit: the same bits. `|p| ≤ 2^16` and `M < 2^31` bound the
    /// magnitude by 2^15 + 1, so it needs no clamp before the sign and the int8 saturation
    /// (which turn anything past 255 into the same code as 1024 does).
    #[inline(always)]
    fn apply_high(&self, a: i8, b: i8) -> i8 {
        let p = (a as i32 - self.zp[0]) * (b as i32 - self.zp[1]);
        let hi = ((u64::from(p.unsigned_abs()) * self.m) >> 32) as u32;
        let k = 1u32 << ((self.right - 33) & 31);
        let magnitude = (hi + k) >> ((self.right - 32) & 31);
        // The sign of `p` without a branch: `(m ^ s) − s` with `s = p >> 31` (0 or −1).
        let sign = p >> 31;
        ((magnitude as i32 ^ sign) - sign + self.zp[2]).clamp(-128, 127) as i8
    }

    /// [`Product::apply_high`] over `out` and `b` side by side with the Cortex-M loop
    /// ([`super::arm::mul::high_row`]); `false` (nothing written) where it does not serve.
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    fn arm_high_row(&self, out: &mut [i8], b: &[i8]) -> bool {
        let Ok(m) = u32::try_from(self.m) else {
            return false;
        };
        let q = super::arm::mul::HighProduct {
            zp: self.zp,
            m,
            right: self.right,
        };
        super::arm::mul::high_row(&q, out, b)
    }

    /// The sign of `p` on the rounded magnitude, the output zero point and int8 saturation.
    #[inline(always)]
    fn finish(&self, p: i32, magnitude: u32) -> i8 {
        let r = if p < 0 {
            -(magnitude as i32)
        } else {
            magnitude as i32
        };
        (r + self.zp[2]).clamp(-128, 127) as i8
    }
}

/// [`mul_with`]'s planes for `neon` and `neon-dot` (`out` holds the `n` outputs, planes of
/// `p`): the high-word products 16 per pass and the 256-entry tables through `TBL`
/// ([`super::aarch64::elementwise`]), the rest of each plane as the portable loops do it.
#[cfg(target_arch = "aarch64")]
fn mul_planes_neon(
    q: &MulQuant,
    f: &Product,
    a: &[i8],
    b: &[i8],
    bc: Broadcast,
    out: &mut [i8],
    p: usize,
) {
    use super::aarch64::elementwise::{lookup, mul_high};
    let high = f.right >= 33;
    for (c, (oc, ac)) in out.chunks_exact_mut(p).zip(a.chunks_exact(p)).enumerate() {
        let bp = match bc {
            Broadcast::None => &b[c * p..(c + 1) * p],
            Broadcast::OverChannels => b,
            Broadcast::OverSpace => {
                let y = b[c];
                if p > 256 {
                    let t: [i8; 256] = core::array::from_fn(|x| q.apply(x as u8 as i8, y));
                    let done = lookup(&t, ac, oc);
                    for (o, &x) in oc[done..].iter_mut().zip(&ac[done..]) {
                        *o = t[x as u8 as usize];
                    }
                } else {
                    for (o, &x) in oc.iter_mut().zip(ac) {
                        *o = q.apply(x, y);
                    }
                }
                continue;
            }
        };
        let done = if high {
            mul_high(ac, bp, oc, f.zp, f.m, f.right)
        } else {
            0
        };
        let rest = oc[done..].iter_mut().zip(&ac[done..]).zip(&bp[done..]);
        if high {
            rest.for_each(|((o, &x), &y)| *o = f.apply_high(x, y));
        } else {
            rest.for_each(|((o, &x), &y)| *o = f.apply(x, y));
        }
    }
}

/// Reference `mul` with `b` broadcast per [`Broadcast`] (docs/graph.md: `[1,1,H,W]` or `[1,C,1,1]`).
pub fn mul_ref(
    q: &MulQuant,
    a: &[i8],
    shape: Shape,
    b: &[i8],
    bc: Broadcast,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let n = need(a, shape)?;
    if Some(b.len()) != broadcast_len(bc, shape) || out.len() < n {
        return Err(KernelError::Shape);
    }
    for i in 0..n {
        out[i] = q.apply(a[i], b[broadcast_index(bc, shape, i)]);
    }
    Ok(())
}

/// Fast `mul`: same bits as [`mul_ref`], looping per channel plane so no index arithmetic per
/// element (the portable set's loops).
pub fn mul(
    q: &MulQuant,
    a: &[i8],
    shape: Shape,
    b: &[i8],
    bc: Broadcast,
    out: &mut [i8],
) -> Result<(), KernelError> {
    mul_with(Isa::Portable, q, a, shape, b, bc, out)
}

/// [`mul`] with kernel set `isa`: `neon` and `neon-dot` take 16 products per pass and read a
/// plane's 256-entry table with `TBL` ([`super::aarch64::elementwise`]); the same bits.
pub fn mul_with(
    isa: Isa,
    q: &MulQuant,
    a: &[i8],
    shape: Shape,
    b: &[i8],
    bc: Broadcast,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let n = need(a, shape)?;
    if Some(b.len()) != broadcast_len(bc, shape) || out.len() < n {
        return Err(KernelError::Shape);
    }
    let p = shape.h * shape.w;
    if p == 0 {
        return Ok(());
    }
    // A multiplier below zero never comes from `Requant::from_real` of a product of scales;
    // `mul_ref`'s function handles it (and anything else) element by element.
    if q.m.multiplier < 0 {
        return mul_ref(q, a, shape, b, bc, out);
    }
    let f = q.product();
    let high = f.right >= 33;
    // One loop per case (the high-word form where it applies), so none tests it per element.
    if matches!(isa, Isa::Neon | Isa::NeonDot) {
        #[cfg(target_arch = "aarch64")]
        {
            mul_planes_neon(q, &f, a, b, bc, &mut out[..n], p);
            return Ok(());
        }
    }
    let planes = |oc: &mut [i8], ac: &[i8], bc: &[i8]| {
        let pairs = oc.iter_mut().zip(ac).zip(bc);
        if high {
            pairs.for_each(|((o, &x), &y)| *o = f.apply_high(x, y));
        } else {
            pairs.for_each(|((o, &x), &y)| *o = f.apply(x, y));
        }
    };
    for (c, (oc, ac)) in out[..n]
        .chunks_exact_mut(p)
        .zip(a[..n].chunks_exact(p))
        .enumerate()
    {
        match bc {
            Broadcast::None => planes(oc, ac, &b[c * p..(c + 1) * p]),
            Broadcast::OverChannels => planes(oc, ac, b),
            Broadcast::OverSpace => {
                // One factor per plane: a table of the other's 256 codes when the plane is
                // larger than it (the same function, so the same bits).
                let y = b[c];
                if p > 256 {
                    let t: [i8; 256] = core::array::from_fn(|x| q.apply(x as u8 as i8, y));
                    for (o, &x) in oc.iter_mut().zip(ac) {
                        *o = t[x as u8 as usize];
                    }
                } else {
                    for (o, &x) in oc.iter_mut().zip(ac) {
                        *o = q.apply(x, y);
                    }
                }
            }
        }
    }
    Ok(())
}

/// [`mul_with`] writing the product over its first operand `a_out` (the same per-element
/// functions in the same cases, each code read before it is written: the same bits; on `neon`
/// and `neon-dot` the high-word products and the per-channel tables 16 codes per pass).
pub fn mul_in_place(
    isa: Isa,
    q: &MulQuant,
    a_out: &mut [i8],
    shape: Shape,
    b: &[i8],
    bc: Broadcast,
) -> Result<(), KernelError> {
    let n = need(a_out, shape)?;
    if Some(b.len()) != broadcast_len(bc, shape) {
        return Err(KernelError::Shape);
    }
    let p = shape.h * shape.w;
    if p == 0 {
        return Ok(());
    }
    if q.m.multiplier < 0 {
        for i in 0..n {
            a_out[i] = q.apply(a_out[i], b[broadcast_index(bc, shape, i)]);
        }
        return Ok(());
    }
    let f = q.product();
    let high = f.right >= 33;
    #[cfg(target_arch = "aarch64")]
    let neon = matches!(isa, Isa::Neon | Isa::NeonDot);
    #[cfg(not(target_arch = "aarch64"))]
    let _ = isa;
    let planes = |oc: &mut [i8], bc: &[i8]| {
        #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
        if high && f.arm_high_row(oc, bc) {
            return;
        }
        #[cfg(target_arch = "aarch64")]
        let (oc, bc) = if high && neon {
            let done = super::aarch64::elementwise::mul_high_in_place(oc, bc, f.zp, f.m, f.right);
            (&mut oc[done..], &bc[done.min(bc.len())..])
        } else {
            (oc, bc)
        };
        let pairs = oc.iter_mut().zip(bc);
        if high {
            pairs.for_each(|(o, &y)| *o = f.apply_high(*o, y));
        } else {
            pairs.for_each(|(o, &y)| *o = f.apply(*o, y));
        }
    };
    for (c, oc) in a_out[..n].chunks_exact_mut(p).enumerate() {
        match bc {
            Broadcast::None => planes(oc, &b[c * p..(c + 1) * p]),
            Broadcast::OverChannels => planes(oc, b),
            Broadcast::OverSpace => {
                let y = b[c];
                if p > 256 {
                    #[cfg(target_arch = "aarch64")]
                    let t = if neon && high {
                        // The table itself as 256 NEON high-word products of every code by `y`
                        // (`apply_high`: the same bits as `apply`).
                        let codes: [i8; 256] = core::array::from_fn(|x| x as u8 as i8);
                        let mut t = [0i8; 256];
                        let ys = [y; 256];
                        let e = super::aarch64::elementwise::mul_high(
                            &codes, &ys, &mut t, f.zp, f.m, f.right,
                        );
                        for (d, &x) in t[e..].iter_mut().zip(&codes[e..]) {
                            *d = f.apply_high(x, y);
                        }
                        t
                    } else {
                        core::array::from_fn(|x| q.apply(x as u8 as i8, y))
                    };
                    #[cfg(not(target_arch = "aarch64"))]
                    let t: [i8; 256] = core::array::from_fn(|x| q.apply(x as u8 as i8, y));
                    #[cfg(target_arch = "aarch64")]
                    let oc = if neon {
                        let done = super::aarch64::elementwise::lookup_in_place(&t, oc);
                        &mut oc[done..]
                    } else {
                        oc
                    };
                    lut_in_place(&t, oc);
                } else {
                    for o in oc.iter_mut() {
                        *o = q.apply(*o, y);
                    }
                }
            }
        }
    }
    Ok(())
}

/// The channels `c_offset ..` of the concat output `out` (`out_shape`) that a part of
/// `in_shape` fills (its H and W must be the output's).
#[inline(always)]
fn concat_dst<T>(
    out: &mut [T],
    out_shape: Shape,
    in_shape: Shape,
    c_offset: usize,
) -> Result<&mut [T], KernelError> {
    let n = in_shape.len().ok_or(KernelError::Shape)?;
    need(out, out_shape)?;
    let end = c_offset.checked_add(in_shape.c).ok_or(KernelError::Shape)?;
    if in_shape.h != out_shape.h || in_shape.w != out_shape.w || end > out_shape.c {
        return Err(KernelError::Shape);
    }
    let p = out_shape.h * out_shape.w;
    Ok(&mut out[c_offset * p..c_offset * p + n])
}

/// Writes one input of a channel concat (int8 or int16 codes) into `out` (shape `out_shape`,
/// int8, or int16: [`super::wide`]) starting at channel `c_offset`, requantised to the output's
/// parameters.
pub fn concat_part(
    input: Codes,
    in_shape: Shape,
    rescale: &Rescale,
    out: CodesMut,
    out_shape: Shape,
    c_offset: usize,
) -> Result<(), KernelError> {
    concat_part_with(
        Isa::Portable,
        input,
        in_shape,
        rescale,
        out,
        out_shape,
        c_offset,
    )
}

/// [`concat_part`] with kernel set `isa`: `neon` and `neon-dot` read an int8 part's 256-entry
/// table (into int8 or int16 codes) with `TBL` ([`super::aarch64::elementwise::lookup`],
/// [`super::aarch64::elementwise::lookup_i16`]); the same bits.
pub fn concat_part_with(
    isa: Isa,
    input: Codes,
    in_shape: Shape,
    rescale: &Rescale,
    out: CodesMut,
    out_shape: Shape,
    c_offset: usize,
) -> Result<(), KernelError> {
    #[cfg(not(target_arch = "aarch64"))]
    let _ = isa;
    let out = match out {
        CodesMut::I8(out) => out,
        CodesMut::I16(out) => {
            let dst = concat_dst(out, out_shape, in_shape, c_offset)?;
            match input {
                Codes::I8(x) => {
                    let n = need(x, in_shape)?;
                    // A table of the 256 codes where it pays (the same function, the same bits).
                    if n > 256 {
                        let t: [i16; 256] = core::array::from_fn(|c| {
                            rescale.apply_code_i16(i32::from(c as u8 as i8))
                        });
                        #[cfg(target_arch = "aarch64")]
                        let (dst, x) = if matches!(isa, Isa::Neon | Isa::NeonDot) {
                            let done = super::aarch64::elementwise::lookup_i16(&t, x, dst);
                            (&mut dst[done..], &x[done..])
                        } else {
                            (dst, x)
                        };
                        for (o, &v) in dst.iter_mut().zip(x) {
                            *o = t[v as u8 as usize];
                        }
                    } else {
                        for (o, &v) in dst.iter_mut().zip(x) {
                            *o = rescale.apply_code_i16(i32::from(v));
                        }
                    }
                }
                Codes::I16(x) => {
                    need(x, in_shape)?;
                    for (o, &v) in dst.iter_mut().zip(x) {
                        *o = rescale.apply_code_i16(i32::from(v));
                    }
                }
            }
            return Ok(());
        }
    };
    let input = match input {
        Codes::I8(x) => x,
        Codes::I16(x) => {
            need(x, in_shape)?;
            let dst = concat_dst(out, out_shape, in_shape, c_offset)?;
            for (o, &v) in dst.iter_mut().zip(x) {
                *o = rescale.apply_code(i32::from(v));
            }
            return Ok(());
        }
    };
    let n = need(input, in_shape)?;
    let dst = concat_dst(out, out_shape, in_shape, c_offset)?;
    if rescale.is_identity() {
        dst.copy_from_slice(&input[..n]);
    } else if n > 256 {
        // A table of the 256 codes (the same function, so the same bits).
        let t: [i8; 256] = core::array::from_fn(|x| rescale.apply(x as u8 as i8));
        #[cfg(target_arch = "aarch64")]
        let (dst, input) = if matches!(isa, Isa::Neon | Isa::NeonDot) {
            let done = super::aarch64::elementwise::lookup(&t, input, dst);
            (&mut dst[done..], &input[done..])
        } else {
            (dst, input)
        };
        for (o, &x) in dst.iter_mut().zip(input) {
            *o = t[x as u8 as usize];
        }
    } else {
        for (o, &x) in dst.iter_mut().zip(input) {
            *o = rescale.apply(x);
        }
    }
    Ok(())
}

/// PyTorch `pixel_shuffle` for any element type: `out[c, y·r+i, x·r+j] = in[c·r²+i·r+j, y, x]`.
pub fn pixel_shuffle<T: Copy>(
    input: &[T],
    in_shape: Shape,
    r: usize,
    out: &mut [T],
) -> Result<Shape, KernelError> {
    let rr = r.checked_mul(r).ok_or(KernelError::Attr)?;
    if r == 0 || !in_shape.c.is_multiple_of(rr) {
        return Err(KernelError::Attr);
    }
    let os = Shape::new(
        in_shape.c / rr,
        in_shape.h.checked_mul(r).ok_or(KernelError::Shape)?,
        in_shape.w.checked_mul(r).ok_or(KernelError::Shape)?,
    );
    need(input, in_shape)?;
    need(out, os)?;
    for c in 0..os.c {
        for i in 0..r {
            for j in 0..r {
                let src = &input[(c * rr + i * r + j) * in_shape.h * in_shape.w..];
                for y in 0..in_shape.h {
                    let orow = (c * os.h + y * r + i) * os.w;
                    for x in 0..in_shape.w {
                        out[orow + x * r + j] = src[y * in_shape.w + x];
                    }
                }
            }
        }
    }
    Ok(os)
}

/// int8 `minmax_norm`: finds the code range `[lo, hi]` of the tensor, then maps each code through
/// a table built with f32 from `(q − lo)·s/((hi − lo)·s + eps)` and the output parameters.
pub fn minmax_norm(
    input: &[i8],
    in_q: QParams,
    eps: f32,
    out_q: QParams,
    out: &mut [i8],
) -> Result<(), KernelError> {
    minmax_norm_with(Isa::Portable, input, in_q, eps, out_q, out)
}

/// [`minmax_norm`] with kernel set `isa` (its table read as [`lut_with`] reads it).
pub fn minmax_norm_with(
    isa: Isa,
    input: &[i8],
    in_q: QParams,
    eps: f32,
    out_q: QParams,
    out: &mut [i8],
) -> Result<(), KernelError> {
    if out.len() < input.len() || input.is_empty() {
        return Err(KernelError::Shape);
    }
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    let (lo, hi) = super::arm::bytes::min_max_i8(input);
    #[cfg(not(all(target_arch = "arm", feature = "arm-dsp")))]
    let (lo, hi) = (
        input.iter().copied().min().unwrap_or(0),
        input.iter().copied().max().unwrap_or(0),
    );
    let (lo, hi) = (i32::from(lo), i32::from(hi));
    let denom = (hi - lo) as f32 * in_q.scale + eps;
    let mut t = [0i8; 256];
    for q in lo..=hi {
        t[(q as i8) as u8 as usize] = out_q.quantize((q - lo) as f32 * in_q.scale / denom);
    }
    lut_with(isa, input, &t, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::{float, kernel_tests};
    use proptest::prelude::*;
    use std::vec::Vec;

    #[derive(Clone, Debug)]
    struct BinCase {
        name: &'static str,
        shape: Shape,
        a: Vec<i8>,
        b: Vec<i8>,
        bc: Broadcast,
        qa: QParams,
        qb: QParams,
        qo: QParams,
    }

    fn deq(v: &[i8], q: QParams) -> Vec<f32> {
        v.iter().map(|&x| q.dequantize(x)).collect()
    }

    type AddImpl = fn(&AddQuant, &[i8], &[i8], &mut [i8]) -> Result<(), KernelError>;
    type MulImpl =
        fn(&MulQuant, &[i8], Shape, &[i8], Broadcast, &mut [i8]) -> Result<(), KernelError>;

    fn check_add(c: &BinCase, f: AddImpl) {
        let mut y = std::vec![0i8; c.a.len()];
        f(&AddQuant::new(c.qa, c.qb, c.qo), &c.a, &c.b, &mut y).unwrap();
        let mut r = std::vec![0f32; c.a.len()];
        float::add(&deq(&c.a, c.qa), &deq(&c.b, c.qb), &mut r).unwrap();
        for (i, (&q, &x)) in y.iter().zip(&r).enumerate() {
            let want = c.qo.quantize(x) as i32;
            assert!(
                (q as i32 - want).abs() <= 1,
                "{} [{i}]: {q} vs {want}",
                c.name
            );
        }
    }

    fn check_mul(c: &BinCase, f: MulImpl) {
        let mut y = std::vec![0i8; c.a.len()];
        f(
            &MulQuant::new(c.qa, c.qb, c.qo),
            &c.a,
            c.shape,
            &c.b,
            c.bc,
            &mut y,
        )
        .unwrap();
        let mut r = std::vec![0f32; c.a.len()];
        float::mul(&deq(&c.a, c.qa), c.shape, &deq(&c.b, c.qb), c.bc, &mut r).unwrap();
        for (i, (&q, &x)) in y.iter().zip(&r).enumerate() {
            let want = c.qo.quantize(x) as i32;
            assert!(
                (q as i32 - want).abs() <= 1,
                "{} [{i}]: {q} vs {want}",
                c.name
            );
        }
    }

    fn golden_add() -> Vec<BinCase> {
        let q = |s, z| QParams {
            scale: s,
            zero_point: z,
        };
        std::vec![BinCase {
            name: "add_mixed_scales",
            shape: Shape::new(1, 1, 4),
            a: std::vec![10, -20, 127, -128],
            b: std::vec![3, 4, 127, -128],
            bc: Broadcast::None,
            qa: q(0.1, 0),
            qb: q(0.5, 2),
            qo: q(0.25, -5),
        }]
    }

    fn golden_mul() -> Vec<BinCase> {
        let q = |s, z| QParams {
            scale: s,
            zero_point: z,
        };
        std::vec![
            BinCase {
                name: "mul_over_space",
                shape: Shape::new(2, 1, 2),
                a: std::vec![10, 20, 30, 40],
                b: std::vec![64, -128],
                bc: Broadcast::OverSpace,
                qa: q(0.1, 0),
                qb: q(1.0 / 128.0, -128),
                qo: q(0.1, 0),
            },
            BinCase {
                name: "mul_over_channels",
                shape: Shape::new(2, 1, 2),
                a: std::vec![10, 20, 30, 40],
                b: std::vec![0, 127],
                bc: Broadcast::OverChannels,
                qa: q(0.1, 3),
                qb: q(1.0 / 255.0, -128),
                qo: q(0.05, 1),
            },
        ]
    }

    prop_compose! {
        fn arb_bin(bcs: [Broadcast; 3])(c in 1usize..4, h in 1usize..5, w in 1usize..6, k in 0usize..3,
            sa in 0.01f32..1.0, sb in 0.01f32..1.0, so in 0.01f32..1.0, za in -30i32..30, zb in -30i32..30,
            zo in -30i32..30, seed in any::<u64>()) -> BinCase {
            let shape = Shape::new(c, h, w);
            let bc = bcs[k];
            let mut s = seed;
            let mut next = move || { s = s.wrapping_mul(6364136223846793005).wrapping_add(1); (s >> 40) as i8 };
            let a = (0..shape.len().unwrap()).map(|_| next()).collect();
            let b = (0..broadcast_len(bc, shape).unwrap()).map(|_| next()).collect();
            let q = |s, z| QParams { scale: s, zero_point: z };
            BinCase { name: "arb", shape, a, b, bc, qa: q(sa, za), qb: q(sb, zb), qo: q(so, zo) }
        }
    }

    /// Planes past 256 pixels (the 256-entry table paths of a plane scaled by one code), every
    /// set, `mul_with` and `mul_in_place` = the reference.
    #[test]
    fn mul_large_planes_every_set_equals_the_reference() {
        let shape = Shape::new(3, 20, 21);
        let n = shape.len().unwrap();
        let a: Vec<i8> = (0..n)
            .map(|i| (i as u32).wrapping_mul(2654435761) as i8)
            .collect();
        for bc in [
            Broadcast::None,
            Broadcast::OverChannels,
            Broadcast::OverSpace,
        ] {
            let b: Vec<i8> = (0..broadcast_len(bc, shape).unwrap())
                .map(|i| (i as u32).wrapping_mul(40503).wrapping_add(7) as i8)
                .collect();
            for (zp, multiplier, shift) in [
                ([3, -7, 2], 1_500_000_000, -9),
                ([-128, 127, -128], 1_073_741_824, -1),
                ([0, 5, 9], 2_000_000_000, 1),
                ([17, -30, 0], 300_000_000, -20),
            ] {
                let q = MulQuant {
                    zp,
                    m: Requant { multiplier, shift },
                };
                let mut want = std::vec![0i8; n];
                mul_ref(&q, &a, shape, &b, bc, &mut want).unwrap();
                for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                    let mut got = std::vec![0i8; n];
                    mul_with(isa, &q, &a, shape, &b, bc, &mut got).unwrap();
                    assert_eq!(got, want, "{} {bc:?} {zp:?}", isa.name());
                    let mut inplace = a.clone();
                    mul_in_place(isa, &q, &mut inplace, shape, &b, bc).unwrap();
                    assert_eq!(inplace, want, "in place {} {bc:?} {zp:?}", isa.name());
                }
            }
        }
    }

    kernel_tests!(add_suite, ref: add_ref, fast: add, golden: golden_add,
        arb: arb_bin([Broadcast::None; 3]), check: check_add);
    proptest! {
        /// Every set's `mul` equals the reference on any codes and zero points, multipliers
        /// and shifts (the high-word form and the other), planes of 1 to 70 pixels.
        #[test]
        fn mul_every_set_equals_the_reference(
            c in 1usize..4, h in 1usize..3, w in 1usize..36, k in 0usize..3,
            zp in proptest::array::uniform3(-128i32..=127), m in 0i32..=i32::MAX,
            shift in -33i32..2, seed in any::<u64>(),
        ) {
            let shape = Shape::new(c, h, w);
            let bc = [Broadcast::None, Broadcast::OverChannels, Broadcast::OverSpace][k];
            let mut s = seed;
            let mut next = move || { s = s.wrapping_mul(6364136223846793005).wrapping_add(1); (s >> 40) as i8 };
            let extreme = seed % 4 == 0;
            let a: Vec<i8> = (0..shape.len().unwrap()).map(|i| if extreme { [-128, 127][i % 2] } else { next() }).collect();
            let b: Vec<i8> = (0..broadcast_len(bc, shape).unwrap()).map(|i| if extreme { [127, -128][i % 3 % 2] } else { next() }).collect();
            let q = MulQuant { zp, m: Requant { multiplier: m, shift } };
            let n = a.len();
            let (mut want, mut got) = (std::vec![0i8; n], std::vec![0i8; n]);
            mul_ref(&q, &a, shape, &b, bc, &mut want).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                mul_with(isa, &q, &a, shape, &b, bc, &mut got).unwrap();
                prop_assert_eq!(&want, &got, "{}", isa.name());
            }
        }
    }

    kernel_tests!(mul_suite, ref: mul_ref, fast: mul, golden: golden_mul,
        arb: arb_bin([Broadcast::None, Broadcast::OverChannels, Broadcast::OverSpace]), check: check_mul);

    proptest! {
        /// The narrow doubling high multiply is gemmlowp's, exact halves included.
        #[test]
        fn narrow_doubling_high_mul_is_gemmlowps(x in -(1i32 << 30) + 1..(1 << 30), m in 0i32..=i32::MAX, k in 0usize..4) {
            // Exact halves: m = 2^30 makes x·m/2^31 = x/2, a half on every odd x.
            let m = [m, 1 << 30, 3 << 28, 1][k];
            let want = crate::kernels::requant::saturating_rounding_doubling_high_mul(x, m);
            prop_assert_eq!(doubling_high_mul_narrow(x, i64::from(m)), want);
        }

        /// Planes past 256 pixels take the fast kernels' 256-entry tables: the same bits as
        /// the per-element reference.
        #[test]
        fn tables_on_large_planes_equal_the_reference(
            c in arb_bin([Broadcast::None, Broadcast::OverChannels, Broadcast::OverSpace]),
            w in 52usize..90,
        ) {
            let shape = Shape::new(c.shape.c, 5, w);
            let n = shape.len().unwrap();
            let a: Vec<i8> = (0..n).map(|i| c.a[i % c.a.len()] ^ (i as i8)).collect();
            let b: Vec<i8> = (0..broadcast_len(c.bc, shape).unwrap()).map(|i| c.b[i % c.b.len()].wrapping_add(i as i8)).collect();
            let (mut y1, mut y2) = (std::vec![0i8; n], std::vec![0i8; n]);
            let mq = MulQuant::new(c.qa, c.qb, c.qo);
            mul_ref(&mq, &a, shape, &b, c.bc, &mut y1).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                mul_with(isa, &mq, &a, shape, &b, c.bc, &mut y2).unwrap();
                prop_assert_eq!(&y1, &y2, "mul ({})", isa.name());
            }
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut y3 = a.clone();
                mul_in_place(isa, &mq, &mut y3, shape, &b, c.bc).unwrap();
                prop_assert_eq!(&y1, &y3, "mul in place ({})", isa.name());
            }
            let aq = AddQuant::new(c.qa, c.qb, c.qo);
            let b2: Vec<i8> = (0..n).map(|i| b[i % b.len()]).collect();
            add_ref(&aq, &a, &b2, &mut y1).unwrap();
            add(&aq, &a, &b2, &mut y2).unwrap();
            prop_assert_eq!(&y1, &y2, "add");
            // Constants no quantizer writes (a blob's are only checked to be well formed):
            // rescales past one, a left shift on the output, a negative multiplier.
            for (ka, kb, ko) in [(3, 0, 0), (0, 2, 0), (0, 0, 5), (1, 1, 0)] {
                let mut bad = aq;
                bad.ma.shift += ka;
                bad.mb.shift += kb;
                bad.mo.shift += ko;
                if (ka, kb, ko) == (1, 1, 0) {
                    bad.mo.multiplier = -bad.mo.multiplier;
                }
                add_ref(&bad, &a, &b2, &mut y1).unwrap();
                add(&bad, &a, &b2, &mut y2).unwrap();
                prop_assert_eq!(&y1, &y2, "add with {:?}", (ka, kb, ko));
            }
            let r = Rescale::new(c.qa, c.qo);
            concat_part(Codes::I8(&a), shape, &r, CodesMut::I8(&mut y2), shape, 0).unwrap();
            let want: Vec<i8> = a.iter().map(|&x| r.apply(x)).collect();
            prop_assert_eq!(&want, &y2, "concat");
        }
    }

    #[test]
    fn wide_concat_part_rescales_to_int8() {
        // int16 scale 1/256 of the int8 output's: code 256·k → k + zp.
        let r = Rescale::new(
            QParams {
                scale: 0.01 / 256.0,
                zero_point: 0,
            },
            QParams {
                scale: 0.01,
                zero_point: -10,
            },
        );
        let x = [0i16, 256, -512, 128, 32767, -32768];
        let mut out = [0i8; 12];
        concat_part(
            Codes::I16(&x),
            Shape::new(1, 2, 3),
            &r,
            CodesMut::I8(&mut out),
            Shape::new(2, 2, 3),
            1,
        )
        .unwrap();
        assert_eq!(&out[6..], &[-10, -9, -12, -9, 118, -128]);
        assert_eq!(&out[..6], &[0; 6]);
    }

    /// `add` past 256 codes (the tables' fast path and its NEON form) on every set = the
    /// reference, for scale ratios either way, zero points at both ends and tails.
    #[test]
    fn add_every_set_equals_the_reference() {
        let q = |scale: f32, zero_point: i32| QParams { scale, zero_point };
        for (qa, qb, qo) in [
            (q(0.02, -3), q(0.05, 7), q(0.06, 1)),
            (q(0.05, 127), q(0.02, -128), q(0.01, -128)),
            (q(0.1, 0), q(0.1, 0), q(0.2, 0)),
            (q(0.003, 5), q(0.5, -9), q(0.4, 127)),
            (q(1.0, -128), q(0.9, 127), q(0.01, 0)),
        ] {
            let aq = AddQuant::new(qa, qb, qo);
            for n in [257usize, 300, 1000] {
                let a: Vec<i8> = (0..n)
                    .map(|i| (i as u32).wrapping_mul(2654435761) as i8)
                    .collect();
                let b: Vec<i8> = (0..n)
                    .map(|i| (i as u32).wrapping_mul(40503) as i8)
                    .collect();
                let mut want = std::vec![0i8; n];
                add_ref(&aq, &a, &b, &mut want).unwrap();
                for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                    let mut got = std::vec![0i8; n];
                    add_with(isa, &aq, &a, &b, &mut got).unwrap();
                    assert_eq!(got, want, "{} {qa:?} {qb:?} {qo:?} n={n}", isa.name());
                }
            }
        }
    }

    /// The engine's RGB planes through NEON (`LD3`, `TBL`) = the table read byte by byte.
    #[cfg(target_arch = "aarch64")]
    #[test]
    fn rgb_planes_neon_equal_the_table() {
        let t: Lut = core::array::from_fn(|i| (i as u32).wrapping_mul(40503) as u8 as i8);
        for n in [0usize, 15, 16, 17, 47, 48, 100] {
            let rgb: Vec<u8> = (0..3 * n)
                .map(|i| (i as u32).wrapping_mul(2654435761) as u8)
                .collect();
            let (mut r, mut g, mut b) = (std::vec![0i8; n], std::vec![0i8; n], std::vec![0i8; n]);
            let done =
                super::super::aarch64::elementwise::lookup_rgb(&t, &rgb, &mut r, &mut g, &mut b);
            assert_eq!(done, n / 16 * 16);
            for i in 0..done {
                let want = [0, 1, 2].map(|c| t[rgb[3 * i + c] as usize]);
                assert_eq!([r[i], g[i], b[i]], want, "n={n} i={i}");
            }
        }
    }

    /// Table look-ups on every kernel set = the portable bits (lengths around the vector
    /// width).
    #[test]
    fn lut_every_set_equals_portable() {
        let t: Lut = core::array::from_fn(|i| (i as u32).wrapping_mul(40503) as u8 as i8);
        for n in [0usize, 1, 15, 16, 17, 33, 300] {
            let x: Vec<i8> = (0..n)
                .map(|i| (i as u32).wrapping_mul(2654435761) as i8)
                .collect();
            let mut want = std::vec![0i8; n];
            lut(&x, &t, &mut want).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut got = std::vec![0i8; n];
                lut_with(isa, &x, &t, &mut got).unwrap();
                assert_eq!(got, want, "{} n={n}", isa.name());
            }
        }
    }

    /// Rescaled int8 parts into int8 and int16 concats, every kernel set = the portable bits
    /// (the table paths past 256 codes, lengths that leave a tail).
    #[test]
    fn concat_part_every_set_equals_portable() {
        let q = |scale: f32, zero_point: i32| QParams { scale, zero_point };
        let (hw, c) = ((7usize, 11usize), 4usize);
        let n = c * hw.0 * hw.1;
        let x: Vec<i8> = (0..n)
            .map(|i| (i as u32).wrapping_mul(2654435761) as i8)
            .collect();
        let s = Shape::new(c, hw.0, hw.1);
        let os = Shape::new(c + 1, hw.0, hw.1);
        for (from, to8, to16) in [
            (q(0.02, -3), q(0.05, 7), q(0.05 / 256.0, 0)),
            (q(0.1, 100), q(0.013, -120), q(0.1 / 300.0, 0)),
        ] {
            let r8 = Rescale::new(from, to8);
            let r16 = Rescale::new(from, to16);
            let mut want8 = std::vec![0i8; os.len().unwrap()];
            let mut want16 = std::vec![0i16; os.len().unwrap()];
            concat_part(Codes::I8(&x), s, &r8, CodesMut::I8(&mut want8), os, 1).unwrap();
            concat_part(Codes::I8(&x), s, &r16, CodesMut::I16(&mut want16), os, 1).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut got8 = std::vec![0i8; want8.len()];
                let mut got16 = std::vec![0i16; want16.len()];
                let (o8, o16) = (CodesMut::I8(&mut got8), CodesMut::I16(&mut got16));
                concat_part_with(isa, Codes::I8(&x), s, &r8, o8, os, 1).unwrap();
                concat_part_with(isa, Codes::I8(&x), s, &r16, o16, os, 1).unwrap();
                assert_eq!(got8, want8, "{}", isa.name());
                assert_eq!(got16, want16, "{}", isa.name());
            }
        }
    }

    #[test]
    fn concat_part_into_int16() {
        // An int8 part (scale 0.01, zero point −10) into an int16 output of scale 0.01/256:
        // code q → 256·(q + 10); an int16 part of the output's scale passes unchanged.
        let out_q = QParams {
            scale: 0.01 / 256.0,
            zero_point: 0,
        };
        let r8 = Rescale::new(
            QParams {
                scale: 0.01,
                zero_point: -10,
            },
            out_q,
        );
        let mut out = [0i16; 6];
        let os = Shape::new(2, 1, 3);
        concat_part(
            Codes::I8(&[-10, -9, 127]),
            Shape::new(1, 1, 3),
            &r8,
            CodesMut::I16(&mut out),
            os,
            0,
        )
        .unwrap();
        concat_part(
            Codes::I16(&[7, -32768, 32767]),
            Shape::new(1, 1, 3),
            &Rescale::new(out_q, out_q),
            CodesMut::I16(&mut out),
            os,
            1,
        )
        .unwrap();
        assert_eq!(out, [0, 256, 32767, 7, -32768, 32767]);
        assert_eq!(
            concat_part(
                Codes::I8(&[1, 2, 3]),
                Shape::new(1, 1, 3),
                &r8,
                CodesMut::I16(&mut out),
                os,
                2
            ),
            Err(KernelError::Shape)
        );
    }

    #[test]
    fn mul_fast_equals_ref_bits() {
        for c in golden_mul() {
            let mq = MulQuant::new(c.qa, c.qb, c.qo);
            let (mut y1, mut y2) = (std::vec![0i8; 4], std::vec![0i8; 4]);
            mul_ref(&mq, &c.a, c.shape, &c.b, c.bc, &mut y1).unwrap();
            mul(&mq, &c.a, c.shape, &c.b, c.bc, &mut y2).unwrap();
            assert_eq!(y1, y2);
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut y3 = c.a.clone();
                mul_in_place(isa, &mq, &mut y3, c.shape, &c.b, c.bc).unwrap();
                assert_eq!(y1, y3, "mul in place ({})", isa.name());
            }
        }
    }

    /// The loop form of `mul` gives `MulQuant::apply`'s bits on every pair of codes, for zero
    /// points at both ends and scale ratios from far below one code to far above.
    #[test]
    fn product_equals_apply_on_every_code_pair() {
        let mut high = 0;
        for (zp, ratio) in [
            ([0, 0, 0], 1.0f64),
            ([-128, 127, -5], 1.0 / 65_536.0),
            ([127, -128, 3], 0.37),
            ([-3, 7, -128], 3.9),
            ([5, -9, 127], 900.0),
            ([-128, -128, 0], 1e-9),
            // right = 33 and 34 (the smallest high-word shifts), a sigmoid map's 1/256.
            ([0, -128, 0], 0.2),
            ([9, 0, -1], 0.1),
            ([-128, -128, -128], 1.0 / 256.0),
        ] {
            let q = |z: i32| QParams {
                scale: 1.0,
                zero_point: z,
            };
            let mut mq = MulQuant::new(q(zp[0]), q(zp[1]), q(zp[2]));
            mq.m = Requant::from_real(ratio);
            let f = mq.product();
            for a in i8::MIN..=i8::MAX {
                for b in i8::MIN..=i8::MAX {
                    let want = mq.apply(a, b);
                    assert_eq!(f.apply(a, b), want, "{a}·{b} zp {zp:?} m {ratio}");
                    if f.right >= 33 {
                        assert_eq!(
                            f.apply_high(a, b),
                            want,
                            "high: {a}·{b} zp {zp:?} m {ratio}"
                        );
                        high += 1;
                    }
                }
            }
            // The Cortex-M loop of the high-word product, every code pair (a row per `a`).
            #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
            if f.right >= 33 {
                let bs: std::vec::Vec<i8> = (i8::MIN..=i8::MAX).collect();
                for a in i8::MIN..=i8::MAX {
                    let mut row = std::vec![a; bs.len()];
                    assert!(f.arm_high_row(&mut row, &bs), "zp {zp:?} m {ratio}");
                    for (&b, &y) in bs.iter().zip(&row) {
                        assert_eq!(y, mq.apply(a, b), "arm: {a}·{b} zp {zp:?} m {ratio}");
                    }
                }
            }
        }
        assert!(high >= 4 * 65_536, "too few high-word cases: {high}");
    }

    /// The Cortex-M one-pass range equals the iterators' minimum and maximum (lengths around
    /// the word size, codes at both ends).
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    #[test]
    fn arm_min_max_equals_the_iterators() {
        for len in [1usize, 3, 4, 5, 8, 33, 100] {
            for seed in 0..24u32 {
                let x: Vec<i8> = (0..len as u32)
                    .map(|i| match seed {
                        0 => -128,
                        1 => 127,
                        2 => [127, -128][i as usize % 2],
                        _ => (i.wrapping_mul(2_654_435_761).wrapping_add(seed * 7919) >> 11) as i8,
                    })
                    .collect();
                let want = (*x.iter().min().unwrap(), *x.iter().max().unwrap());
                assert_eq!(super::super::arm::bytes::min_max_i8(&x), want, "{x:?}");
            }
        }
    }

    #[test]
    fn sigmoid_lut_within_one_lsb() {
        let qi = QParams {
            scale: 0.0625,
            zero_point: 0,
        };
        let qo = QParams {
            scale: 1.0 / 256.0,
            zero_point: -128,
        };
        let t = build_lut(qi, qo, float::sigmoid);
        assert_eq!(t[0], 0); // sigmoid(0) = 0.5 → 128 − 128
        let x: Vec<i8> = (-128..=127).map(|v| v as i8).collect();
        let mut y = std::vec![0i8; 256];
        lut(&x, &t, &mut y).unwrap();
        for (&q, &yq) in x.iter().zip(&y) {
            let want = (1.0 / (1.0 + (-(q as f64) * 0.0625).exp()) * 256.0 - 128.0)
                .round()
                .clamp(-128.0, 127.0);
            assert!((yq as f64 - want).abs() <= 1.0, "{q}: {yq} vs {want}");
        }
    }

    #[test]
    fn concat_requantises_and_places_channels() {
        let out_q = QParams {
            scale: 0.2,
            zero_point: 0,
        };
        let mut out = [0i8; 6];
        let os = Shape::new(3, 1, 2);
        concat_part(
            Codes::I8(&[5, 6]),
            Shape::new(1, 1, 2),
            &Rescale::new(out_q, out_q),
            CodesMut::I8(&mut out),
            os,
            0,
        )
        .unwrap();
        let q2 = QParams {
            scale: 0.1,
            zero_point: 10,
        };
        concat_part(
            Codes::I8(&[10, 20, 30, 11]),
            Shape::new(2, 1, 2),
            &Rescale::new(q2, out_q),
            CodesMut::I8(&mut out),
            os,
            1,
        )
        .unwrap();
        // (20−10)·0.1/0.2 = 5; (30−10)/2 = 10; (11−10)/2 = 0.5 → 1
        assert_eq!(out, [5, 6, 0, 5, 10, 1]);
        assert_eq!(
            concat_part(
                Codes::I8(&[1, 2]),
                Shape::new(1, 1, 2),
                &Rescale::default(),
                CodesMut::I8(&mut out),
                os,
                3
            ),
            Err(KernelError::Shape)
        );
    }

    #[test]
    fn pixel_shuffle_matches_pytorch_order() {
        // [4,1,1] r=2 → [1,2,2]: channel k goes to (k/2, k%2).
        let mut o = [0u8; 4];
        assert_eq!(
            pixel_shuffle(&[1u8, 2, 3, 4], Shape::new(4, 1, 1), 2, &mut o),
            Ok(Shape::new(1, 2, 2))
        );
        assert_eq!(o, [1, 2, 3, 4]);
        // [4,1,2] r=2 → [1,2,4]
        let mut o = [0u8; 8];
        pixel_shuffle(&[1u8, 5, 2, 6, 3, 7, 4, 8], Shape::new(4, 1, 2), 2, &mut o).unwrap();
        assert_eq!(o, [1, 2, 5, 6, 3, 4, 7, 8]);
        assert_eq!(
            pixel_shuffle(&[0u8; 3], Shape::new(3, 1, 1), 2, &mut o),
            Err(KernelError::Attr)
        );
    }

    #[test]
    fn minmax_norm_by_hand() {
        let qi = QParams {
            scale: 0.5,
            zero_point: 0,
        };
        let qo = QParams {
            scale: 1.0 / 255.0,
            zero_point: -128,
        };
        let mut y = [0i8; 3];
        minmax_norm(&[-4, 0, 6], qi, 0.0, qo, &mut y).unwrap();
        // (x − (−2))/(3 − (−2)): 0, 0.4, 1 → −128, round(102) − 128 = −26, 127
        assert_eq!(y, [-128, -26, 127]);
    }
}
