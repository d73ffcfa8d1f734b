//! NEON int8 `mul` (CBAM's attention products): the product form of
//! [`crate::kernels::elementwise`]'s `Product::apply_high`, 16 codes per pass, and the 256-entry
//! table of a plane scaled by one code read with `TBL`/`TBX`.
//!
//! `apply_high` rounds `|p|·M` (`p = (a − zp_a)(b − zp_b)`, `|p| ≤ 255² < 2¹⁶`, `M < 2³¹`)
//! as `(⌊|p|·M / 2³²⌋ + 2^(s−1)) >> s` with `s = r − 32 ≥ 1`. `SQDMULH(|p|, M)` is
//! `t = ⌊|p|·M / 2³¹⌋` (no saturation: `2·|p|·M < 2⁴⁸`), and `⌊t/2⌋ + 2^(s−1)` shifted right by
//! `s` equals `(t + 2^s) >> (s + 1)`, one `SRSHL` by `−(s + 1)`. Then the sign of `p`
//! (`(m ^ σ) − σ`), the output zero point and two saturating narrows (the clamp to int8): the
//! same integers, so the same bits.

use core::arch::aarch64::*;

/// `out[i] = apply_high(a[i], b[i])` (module doc) for the leading multiple of 16 of
/// `out.len()` (`a` and `b` at least as long); returns how many it did. `zp` are the zero
/// points of a, b and out, `m` the multiplier, `right` its total right shift. Does nothing (0)
/// where NEON is absent, `right` is outside `33..=62`, `m` is not below 2³¹, or a zero point of
/// `a` or `b` lies outside the int8 range (then `|a − zp|` could pass 255).
pub fn mul_high(a: &[i8], b: &[i8], out: &mut [i8], zp: [i32; 3], m: u64, right: u32) -> usize {
    let n = out.len().min(a.len()).min(b.len()) / 16 * 16;
    if !mul_high_ok(zp, m, right) || n == 0 {
        return 0;
    }
    // SAFETY: NEON is available (checked by `mul_high_ok`); `a`, `b` and `out` hold `n` codes
    // each, and `out` does not overlap `a` (a `&mut`).
    unsafe { mul_high_neon(a.as_ptr(), b, out.as_mut_ptr(), n, zp, m as i32, right) };
    n
}

/// [`mul_high`] writing over its first operand: `a_out[i] = apply_high(a_out[i], b[i])` for the
/// leading multiple of 16 (each group read before it is written); returns how many it did.
pub fn mul_high_in_place(a_out: &mut [i8], b: &[i8], zp: [i32; 3], m: u64, right: u32) -> usize {
    let n = a_out.len().min(b.len()) / 16 * 16;
    if !mul_high_ok(zp, m, right) || n == 0 {
        return 0;
    }
    let p = a_out.as_mut_ptr();
    // SAFETY: NEON is available (checked); `a_out` and `b` hold `n` codes each; reading and
    // writing through the same pointer is what `mul_high_neon` allows.
    unsafe { mul_high_neon(p, b, p, n, zp, m as i32, right) };
    n
}

/// Whether NEON is present and the constants are in [`mul_high`]'s ranges.
fn mul_high_ok(zp: [i32; 3], m: u64, right: u32) -> bool {
    let codes = -128..=127;
    crate::kernels::isa::Isa::Neon.available()
        && (33..=62).contains(&right)
        && m < 1 << 31
        && codes.contains(&zp[0])
        && codes.contains(&zp[1])
        && (-(1 << 16)..=1 << 16).contains(&zp[2])
}

/// [`mul_high`]'s loop over `n` codes (a multiple of 16) from `a` into `out`; `out` may be `a`
/// itself (each group of 16 is loaded before its result is stored).
///
/// # Safety
/// The CPU must have NEON; `a` and `out` point at `n` codes and `b` holds `n`; `out` is `a` or
/// does not overlap it; the constants are in [`mul_high`]'s ranges.
#[target_feature(enable = "neon")]
unsafe fn mul_high_neon(
    a: *const i8,
    b: &[i8],
    out: *mut i8,
    n: usize,
    zp: [i32; 3],
    m: i32,
    right: u32,
) {
    let (za, zb) = (vdupq_n_s16(zp[0] as i16), vdupq_n_s16(zp[1] as i16));
    let mv = vdupq_n_s32(m);
    let shift = vdupq_n_s32(-(right as i32 - 31));
    let zo = vdupq_n_s32(zp[2]);
    // One lane group of four products → four output codes (as i32, before narrowing).
    let four = |p: int32x4_t| {
        let t = vqdmulhq_s32(vabsq_s32(p), mv);
        let mag = vrshlq_s32(t, shift);
        let sign = vshrq_n_s32::<31>(p);
        vaddq_s32(vsubq_s32(veorq_s32(mag, sign), sign), zo)
    };
    let mut i = 0;
    while i + 16 <= n {
        // SAFETY: `i + 16 ≤ n`, inside all three.
        let (va, vb) = unsafe { (vld1q_s8(a.add(i)), vld1q_s8(b.as_ptr().add(i))) };
        // x − zp in 16 bits (|·| ≤ 255).
        let a_lo = vsubq_s16(vmovl_s8(vget_low_s8(va)), za);
        let a_hi = vsubq_s16(vmovl_high_s8(va), za);
        let b_lo = vsubq_s16(vmovl_s8(vget_low_s8(vb)), zb);
        let b_hi = vsubq_s16(vmovl_high_s8(vb), zb);
        let p0 = vmull_s16(vget_low_s16(a_lo), vget_low_s16(b_lo));
        let p1 = vmull_high_s16(a_lo, b_lo);
        let p2 = vmull_s16(vget_low_s16(a_hi), vget_low_s16(b_hi));
        let p3 = vmull_high_s16(a_hi, b_hi);
        let h0 = vcombine_s16(vqmovn_s32(four(p0)), vqmovn_s32(four(p1)));
        let h1 = vcombine_s16(vqmovn_s32(four(p2)), vqmovn_s32(four(p3)));
        let r = vcombine_s8(vqmovn_s16(h0), vqmovn_s16(h1));
        // SAFETY: as above.
        unsafe { vst1q_s8(out.add(i), r) };
        i += 16;
    }
}

/// `out[i] = table[x[i] as u8]` for the leading multiple of 16 of `out.len()` (`x` at least as
/// long); returns how many it did (0 where NEON is absent).
pub fn lookup(table: &[i8; 256], x: &[i8], out: &mut [i8]) -> usize {
    let n = out.len().min(x.len()) / 16 * 16;
    if !crate::kernels::isa::Isa::Neon.available() || n == 0 {
        return 0;
    }
    // SAFETY: NEON is available; `x` and `out` hold `n` codes each and do not overlap.
    unsafe { lookup_neon(table, x.as_ptr(), out.as_mut_ptr(), n) };
    n
}

/// [`lookup`] over `data` in place (`data[i] = table[data[i] as u8]`) for the leading multiple
/// of 16; returns how many it did (0 where NEON is absent).
pub fn lookup_in_place(table: &[i8; 256], data: &mut [i8]) -> usize {
    let n = data.len() / 16 * 16;
    if !crate::kernels::isa::Isa::Neon.available() || n == 0 {
        return 0;
    }
    let p = data.as_mut_ptr();
    // SAFETY: NEON is available; `data` holds `n` codes; `lookup_neon` allows `out == x`.
    unsafe { lookup_neon(table, p, p, n) };
    n
}

/// [`lookup`]'s loop over `n` codes (a multiple of 16): the table in 16 registers, four
/// `TBL`/`TBX` of 64 entries per 16 codes (an index past 63 gives 0 in `TBL` and leaves the lane
/// in `TBX`). `out` may be `x` itself (each group is loaded before it is stored).
///
/// # Safety
/// The CPU must have NEON; `x` and `out` point at `n` codes, and `out` is `x` or does not
/// overlap it.
#[target_feature(enable = "neon")]
unsafe fn lookup_neon(table: &[i8; 256], x: *const i8, out: *mut i8, n: usize) {
    let t = table.as_ptr();
    // SAFETY: `table` holds 4 · 64 bytes.
    let (t0, t1, t2, t3) = unsafe {
        (
            vld1q_s8_x4(t),
            vld1q_s8_x4(t.add(64)),
            vld1q_s8_x4(t.add(128)),
            vld1q_s8_x4(t.add(192)),
        )
    };
    let k64 = vdupq_n_u8(64);
    let mut i = 0;
    while i + 16 <= n {
        // SAFETY: `i + 16 ≤ n`.
        let idx = unsafe { vreinterpretq_u8_s8(vld1q_s8(x.add(i))) };
        let i1 = vsubq_u8(idx, k64);
        let i2 = vsubq_u8(i1, k64);
        let i3 = vsubq_u8(i2, k64);
        let r = vqtbl4q_s8(t0, idx);
        let r = vqtbx4q_s8(r, t1, i1);
        let r = vqtbx4q_s8(r, t2, i2);
        let r = vqtbx4q_s8(r, t3, i3);
        // SAFETY: as above.
        unsafe { vst1q_s8(out.add(i), r) };
        i += 16;
    }
}

/// `out[i] = table[x[i] as u8]` (16-bit entries) for the leading multiple of 16 of
/// `out.len()` (`x` at least as long); returns how many it did (0 where NEON is absent). The
/// table is split into its low and high bytes, each read with `TBL`/`TBX` as [`lookup`] does,
/// and `ST2` interleaves them back into little-endian halfwords.
pub fn lookup_i16(table: &[i16; 256], x: &[i8], out: &mut [i16]) -> usize {
    let n = out.len().min(x.len()) / 16 * 16;
    if !crate::kernels::isa::Isa::Neon.available() || n == 0 {
        return 0;
    }
    let lo: [i8; 256] = core::array::from_fn(|i| table[i] as u8 as i8);
    let hi: [i8; 256] = core::array::from_fn(|i| (table[i] >> 8) as i8);
    // SAFETY: NEON is available; `x` and `out` hold `n` codes each.
    unsafe { lookup_i16_neon(&lo, &hi, x.as_ptr(), out.as_mut_ptr(), n) };
    n
}

/// [`lookup_i16`]'s loop over `n` codes (a multiple of 16).
///
/// # Safety
/// The CPU must have NEON; `x` points at `n` codes and `out` at `n` halfwords.
#[target_feature(enable = "neon")]
unsafe fn lookup_i16_neon(lo: &[i8; 256], hi: &[i8; 256], x: *const i8, out: *mut i16, n: usize) {
    let k64 = vdupq_n_u8(64);
    let read = |t: &[i8; 256], i: [uint8x16_t; 4]| {
        let p = t.as_ptr();
        // SAFETY: `t` holds 4 · 64 bytes.
        unsafe {
            let r = vqtbl4q_s8(vld1q_s8_x4(p), i[0]);
            let r = vqtbx4q_s8(r, vld1q_s8_x4(p.add(64)), i[1]);
            let r = vqtbx4q_s8(r, vld1q_s8_x4(p.add(128)), i[2]);
            vqtbx4q_s8(r, vld1q_s8_x4(p.add(192)), i[3])
        }
    };
    let mut i = 0;
    while i + 16 <= n {
        // SAFETY: `i + 16 ≤ n`.
        let i0 = unsafe { vreinterpretq_u8_s8(vld1q_s8(x.add(i))) };
        let i1 = vsubq_u8(i0, k64);
        let i2 = vsubq_u8(i1, k64);
        let idx = [i0, i1, i2, vsubq_u8(i2, k64)];
        let v = int8x16x2_t(read(lo, idx), read(hi, idx));
        // SAFETY: as above; 16 halfwords are 32 bytes at `out + i`.
        unsafe { vst2q_s8(out.add(i) as *mut i8, v) };
        i += 16;
    }
}

/// Int8 `add` for the leading multiple of 16 of `out.len()` (`a`, `b` at least as long):
/// `out = clamp(RDBP(SQRDMULH(r_a + r_b, m_o), e_o) + zp_o)` with `r = RDBP(SQRDMULH((x − zp)
/// << 20, m), e)` per input (`RDBP`: gemmlowp's `RoundingDivideByPOT`, half away from zero;
/// `SQRDMULH` is gemmlowp's saturating rounding doubling high multiply exactly): the portable
/// `add`'s fast path (its tables hold `r_a`, `r_b`) where no multiplier shifts left and every
/// `|r_a + r_b| < 2^30`, which the caller checks. `m` holds each multiplier (≥ 0) and right
/// shift `e` (`0..=31`) for a, b and the output. Returns how many it did (0 without NEON, for
/// constants out of those ranges, or for input zero points outside int8).
pub fn add_rescaled(a: &[i8], b: &[i8], out: &mut [i8], zp: [i32; 3], m: [(i32, i32); 3]) -> usize {
    let n = out.len().min(a.len()).min(b.len()) / 16 * 16;
    let codes = -128..=127;
    let ok = m
        .iter()
        .all(|&(mult, e)| mult >= 0 && (0..=31).contains(&e))
        && codes.contains(&zp[0])
        && codes.contains(&zp[1]);
    if !crate::kernels::isa::Isa::Neon.available() || !ok || n == 0 {
        return 0;
    }
    // SAFETY: NEON is available; `a`, `b` and `out` hold `n` codes each.
    unsafe { add_neon(a.as_ptr(), b.as_ptr(), out.as_mut_ptr(), n, zp, m) };
    n
}

/// `RDBP(SQRDMULH(x, m), e)` of four lanes: `SRSHL` by `−e` rounds half up, so negative
/// values take 1 off first where `e ≥ 1` (`adj` all ones then, else zero).
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
#[inline]
unsafe fn scale4(x: int32x4_t, m: int32x4_t, shift: int32x4_t, adj: int32x4_t) -> int32x4_t {
    let q = vqrdmulhq_s32(x, m);
    vrshlq_s32(vaddq_s32(q, vandq_s32(vshrq_n_s32::<31>(q), adj)), shift)
}

/// [`add_rescaled`]'s loop over `n` codes (a multiple of 16).
///
/// # Safety
/// The CPU must have NEON; `a`, `b` and `out` point at `n` codes; the constants are in
/// [`add_rescaled`]'s ranges.
#[target_feature(enable = "neon")]
unsafe fn add_neon(
    a: *const i8,
    b: *const i8,
    out: *mut i8,
    n: usize,
    zp: [i32; 3],
    m: [(i32, i32); 3],
) {
    let consts = m.map(|(mult, e)| {
        let adj = vdupq_n_s32(if e > 0 { -1 } else { 0 });
        (vdupq_n_s32(mult), vdupq_n_s32(-e), adj)
    });
    let (za, zb) = (vdup_n_s8(zp[0] as i8), vdup_n_s8(zp[1] as i8));
    let (zaq, zbq) = (vdupq_n_s8(zp[0] as i8), vdupq_n_s8(zp[1] as i8));
    let zo = vdupq_n_s32(zp[2]);
    // The 16 rescaled codes of one input, in four lane groups.
    let rescale = |v: int8x16_t, z: int8x8_t, zq: int8x16_t, k: usize| -> [int32x4_t; 4] {
        // x − zp exact in 16 bits, then << 20 (|·| < 2^28).
        let (lo, hi) = (vsubl_s8(vget_low_s8(v), z), vsubl_high_s8(v, zq));
        let (mv, sv, adj) = consts[k];
        let f = |x: int16x4_t| scale4(vshlq_n_s32::<20>(vmovl_s16(x)), mv, sv, adj);
        [
            f(vget_low_s16(lo)),
            f(vget_high_s16(lo)),
            f(vget_low_s16(hi)),
            f(vget_high_s16(hi)),
        ]
    };
    let mut i = 0;
    while i + 16 <= n {
        // SAFETY: `i + 16 ≤ n`, inside all three.
        let (va, vb) = unsafe { (vld1q_s8(a.add(i)), vld1q_s8(b.add(i))) };
        let (ra, rb) = (rescale(va, za, zaq, 0), rescale(vb, zb, zbq, 1));
        let (mo, so, adj) = consts[2];
        let o = |k: usize| vqaddq_s32(scale4(vaddq_s32(ra[k], rb[k]), mo, so, adj), zo);
        let h0 = vcombine_s16(vqmovn_s32(o(0)), vqmovn_s32(o(1)));
        let h1 = vcombine_s16(vqmovn_s32(o(2)), vqmovn_s32(o(3)));
        // SAFETY: as above.
        unsafe { vst1q_s8(out.add(i), vcombine_s8(vqmovn_s16(h0), vqmovn_s16(h1))) };
        i += 16;
    }
}

/// Interleaved RGB bytes into three code planes through one 256-entry table: `r[i] =
/// table[rgb[3i]]`, `g[i] = table[rgb[3i + 1]]`, `b[i] = table[rgb[3i + 2]]` for the leading
/// multiple of 16 pixels that all four hold (`LD3`, then `TBL`/`TBX` as [`lookup`] does, the
/// table held in registers); returns how many pixels it did (0 without NEON).
pub fn lookup_rgb(
    table: &[i8; 256],
    rgb: &[u8],
    r: &mut [i8],
    g: &mut [i8],
    b: &mut [i8],
) -> usize {
    let n = (rgb.len() / 3).min(r.len()).min(g.len()).min(b.len()) / 16 * 16;
    if !crate::kernels::isa::Isa::Neon.available() || n == 0 {
        return 0;
    }
    // SAFETY: NEON is available; `rgb` holds `3n` bytes and each plane `n` codes.
    unsafe { lookup_rgb_neon(table, rgb.as_ptr(), [r, g, b].map(|p| p.as_mut_ptr()), n) };
    n
}

/// [`lookup_rgb`]'s loop over `n` pixels (a multiple of 16).
///
/// # Safety
/// The CPU must have NEON; `rgb` points at `3n` bytes and each plane at `n` codes.
#[target_feature(enable = "neon")]
unsafe fn lookup_rgb_neon(table: &[i8; 256], rgb: *const u8, planes: [*mut i8; 3], n: usize) {
    let t = table.as_ptr();
    // SAFETY: `table` holds 4 · 64 bytes.
    let (t0, t1, t2, t3) = unsafe {
        (
            vld1q_s8_x4(t),
            vld1q_s8_x4(t.add(64)),
            vld1q_s8_x4(t.add(128)),
            vld1q_s8_x4(t.add(192)),
        )
    };
    let k64 = vdupq_n_u8(64);
    let read = |i0: uint8x16_t| {
        let i1 = vsubq_u8(i0, k64);
        let i2 = vsubq_u8(i1, k64);
        let i3 = vsubq_u8(i2, k64);
        let r = vqtbl4q_s8(t0, i0);
        let r = vqtbx4q_s8(r, t1, i1);
        let r = vqtbx4q_s8(r, t2, i2);
        vqtbx4q_s8(r, t3, i3)
    };
    let mut i = 0;
    while i + 16 <= n {
        // SAFETY: `i + 16 ≤ n`: `3i + 48 ≤ 3n` bytes of `rgb`, `i + 16` codes of each plane.
        unsafe {
            let px = vld3q_u8(rgb.add(3 * i));
            vst1q_s8(planes[0].add(i), read(px.0));
            vst1q_s8(planes[1].add(i), read(px.1));
            vst1q_s8(planes[2].add(i), read(px.2));
        }
        i += 16;
    }
}
