//! NEON loop of the refinement step's interior chunks (`refine::step`), four neighbours per
//! pass over four pixels at a time: the table values read lane by lane, then the f32 operations
//! of the scalar loop in the same order (separate `FMUL` and `FADD`, never fused), so the bits
//! are those of every other path.

use crate::kernels::refine::SkRow;
use crate::kernels::requant::QParams;
use core::arch::aarch64::*;

/// For `i < n`: `r_j = lut[q_j[i]] · g_j`, `s[i] = (((s[i] + r0) + r1) + r2) + r3`,
/// `acc[i] = (((acc[i] + r0·d0[i]) + r1·d1[i]) + r2·d2[i]) + r3·d3[i]`, where `n` is the
/// shortest of the ten slices and `lut[q] = relu(scale·(q − zp))` (`q`'s parameters: the
/// branch's table, `Branch::set_quant`). Returns `false` (and does nothing) without NEON or
/// where the slices differ in length.
pub fn four(
    q: [&[i8]; 4],
    d: [&[f32]; 4],
    g: [f32; 4],
    (lut, qp): (&[f32; 256], QParams),
    s: &mut [f32],
    acc: &mut [f32],
) -> bool {
    let n = s.len();
    let same = acc.len() == n && q.iter().all(|x| x.len() == n) && d.iter().all(|x| x.len() == n);
    if !crate::kernels::isa::Isa::Neon.available() || !same {
        return false;
    }
    // The table's values computed 8 at a time where the zero point is an int8 code (then
    // `q − zp` is exact in 16 bits and in f32), else read from the table.
    let qp = (-128..=127).contains(&qp.zero_point).then_some(qp);
    // SAFETY: NEON is available; every read and write has an index below `n`, the length of
    // all ten slices (checked).
    unsafe { four_neon(q, d, g, lut, qp, s, acc, n) };
    true
}

/// `relu(scale·(q − zp))` of 8 codes at `p`, as `Branch::set_quant` computes the table: the
/// difference exact in 16 bits and in f32, one `FMUL` (commutative, so `scale · x` is `x ·
/// scale`), then `x` where `x > 0` and `+0` elsewhere (`FCMGT` and `AND`: NaN and `−0` give
/// `+0`, as `scalar::relu` does).
///
/// # Safety
/// The CPU must have NEON; `p` points at 8 readable codes.
#[target_feature(enable = "neon")]
#[inline]
unsafe fn relu_dequant8(p: *const i8, zp: int16x8_t, scale: float32x4_t) -> [float32x4_t; 2] {
    // SAFETY: 8 codes at `p` (the caller's contract).
    let x = vsubq_s16(vmovl_s8(unsafe { vld1_s8(p) }), zp);
    let f = |x: int32x4_t| {
        let v = vmulq_f32(scale, vcvtq_f32_s32(x));
        vreinterpretq_f32_u32(vandq_u32(vcgtzq_f32(v), vreinterpretq_u32_f32(v)))
    };
    [f(vmovl_s16(vget_low_s16(x))), f(vmovl_high_s16(x))]
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller); `qp`, where given, is the table's parameters with an int8 zero
/// point.
#[target_feature(enable = "neon")]
#[allow(clippy::too_many_arguments)]
unsafe fn four_neon(
    q: [&[i8]; 4],
    d: [&[f32]; 4],
    g: [f32; 4],
    lut: &[f32; 256],
    qp: Option<QParams>,
    s: &mut [f32],
    acc: &mut [f32],
    n: usize,
) {
    let lp = lut.as_ptr();
    let (sp, ap) = (s.as_mut_ptr(), acc.as_mut_ptr());
    let mut i = 0;
    if let Some(qp) = qp {
        let zp = vdupq_n_s16(qp.zero_point as i16);
        let scale = vdupq_n_f32(qp.scale);
        while i + 8 <= n {
            let mut sv = [vld1q_f32(sp.add(i)), vld1q_f32(sp.add(i + 4))];
            let mut av = [vld1q_f32(ap.add(i)), vld1q_f32(ap.add(i + 4))];
            for j in 0..4 {
                let t = relu_dequant8(q[j].as_ptr().add(i), zp, scale);
                for h in 0..2 {
                    let r = vmulq_n_f32(t[h], g[j]);
                    sv[h] = vaddq_f32(sv[h], r);
                    let dj = vld1q_f32(d[j].as_ptr().add(i + 4 * h));
                    av[h] = vaddq_f32(av[h], vmulq_f32(r, dj));
                }
            }
            for h in 0..2 {
                vst1q_f32(sp.add(i + 4 * h), sv[h]);
                vst1q_f32(ap.add(i + 4 * h), av[h]);
            }
            i += 8;
        }
    }
    while i + 4 <= n {
        let mut sv = vld1q_f32(sp.add(i));
        let mut av = vld1q_f32(ap.add(i));
        for j in 0..4 {
            let qj = q[j].as_ptr().add(i);
            let mut t = vdupq_n_f32(0.0);
            t = vld1q_lane_f32::<0>(lp.add(*qj as u8 as usize), t);
            t = vld1q_lane_f32::<1>(lp.add(*qj.add(1) as u8 as usize), t);
            t = vld1q_lane_f32::<2>(lp.add(*qj.add(2) as u8 as usize), t);
            t = vld1q_lane_f32::<3>(lp.add(*qj.add(3) as u8 as usize), t);
            let r = vmulq_n_f32(t, g[j]);
            sv = vaddq_f32(sv, r);
            av = vaddq_f32(av, vmulq_f32(r, vld1q_f32(d[j].as_ptr().add(i))));
        }
        vst1q_f32(sp.add(i), sv);
        vst1q_f32(ap.add(i), av);
        i += 4;
    }
    while i < n {
        let r = |j: usize| lut[*q[j].as_ptr().add(i) as u8 as usize] * g[j];
        let (r0, r1, r2, r3) = (r(0), r(1), r(2), r(3));
        let d = |j: usize| *d[j].as_ptr().add(i);
        *sp.add(i) = (((*sp.add(i) + r0) + r1) + r2) + r3;
        *ap.add(i) = (((*ap.add(i) + r0 * d(0)) + r1 * d(1)) + r2 * d(2)) + r3 * d(3);
        i += 1;
    }
}

/// `out[i] += (σ_ti(t, tt)[i] · σ_k(m, kt)[i]) · cur[i]` for the leading multiple of 8 of
/// `out.len()` (`refine::accumulate` on int8 maps), where `σ_c(q, e)[i] = a_c / ((a_0 + a_1) +
/// a_2)` with `a_j = e[max(q_0, q_1, q_2)[i] − q_j[i]]` (`Mix::one`): the code distances 8 per
/// pass with `SMAX`/`SUB`, the table read lane by lane, then the scalar loop's f32 operations
/// in its order (IEEE `FDIV`, separate `FMUL`/`FADD`). Returns how many values it did (0
/// without NEON, where a slice is shorter than that, or where `ti` or `k` is past 2).
#[allow(clippy::too_many_arguments)]
pub fn accumulate(
    out: &mut [f32],
    cur: &[f32],
    t: [&[i8]; 3],
    m: [&[i8]; 3],
    tt: &[f32; 256],
    kt: &[f32; 256],
    ti: usize,
    k: usize,
    sk: SkRow<'_>,
) -> usize {
    let n = out.len() / 8 * 8;
    let short = cur.len() < n || t.iter().chain(&m).any(|r| r.len() < n);
    let sk_short = match &sk {
        SkRow::Compute => false,
        SkRow::Fill(r) => r.len() < n,
        SkRow::Use(r) => r.len() < n,
    };
    if !crate::kernels::isa::Isa::Neon.available() || n == 0 || short || sk_short || ti > 2 || k > 2
    {
        return 0;
    }
    let (o, c) = (out.as_mut_ptr(), cur.as_ptr());
    let (t, m) = (t.map(|r| r.as_ptr()), m.map(|r| r.as_ptr()));
    let e = (tt, kt);
    let sk = match sk {
        SkRow::Compute => Sk::Compute,
        SkRow::Fill(r) => Sk::Fill(r.as_mut_ptr()),
        SkRow::Use(r) => Sk::Use(r.as_ptr()),
    };
    // SAFETY (each arm): NEON is available; `out`, `cur`, the six rows and a cached row hold
    // ≥ `n` values (checked above), `n` a multiple of 8.
    unsafe {
        match (ti, k) {
            (0, 0) => accumulate_neon::<0, 0>(o, c, t, m, e, n, sk),
            (0, 1) => accumulate_neon::<0, 1>(o, c, t, m, e, n, sk),
            (0, _) => accumulate_neon::<0, 2>(o, c, t, m, e, n, sk),
            (1, 0) => accumulate_neon::<1, 0>(o, c, t, m, e, n, sk),
            (1, 1) => accumulate_neon::<1, 1>(o, c, t, m, e, n, sk),
            (1, _) => accumulate_neon::<1, 2>(o, c, t, m, e, n, sk),
            (_, 0) => accumulate_neon::<2, 0>(o, c, t, m, e, n, sk),
            (_, 1) => accumulate_neon::<2, 1>(o, c, t, m, e, n, sk),
            (_, _) => accumulate_neon::<2, 2>(o, c, t, m, e, n, sk),
        }
    }
    n
}

/// Four table values `e[d[L..L + 4]]` (`L` = 0 or 4).
///
/// # Safety
/// The CPU must have NEON (every `u8` index is inside the 256-entry table).
#[target_feature(enable = "neon")]
#[inline]
unsafe fn gather4<const L: i32>(e: &[f32; 256], d: uint8x8_t) -> float32x4_t {
    let p = e.as_ptr();
    // SAFETY: each index is a `u8`, below the table's 256 entries.
    unsafe {
        let (i0, i1, i2, i3) = match L {
            0 => (
                vget_lane_u8::<0>(d),
                vget_lane_u8::<1>(d),
                vget_lane_u8::<2>(d),
                vget_lane_u8::<3>(d),
            ),
            _ => (
                vget_lane_u8::<4>(d),
                vget_lane_u8::<5>(d),
                vget_lane_u8::<6>(d),
                vget_lane_u8::<7>(d),
            ),
        };
        let v = vld1q_dup_f32(p.add(i0 as usize));
        let v = vld1q_lane_f32::<1>(p.add(i1 as usize), v);
        let v = vld1q_lane_f32::<2>(p.add(i2 as usize), v);
        vld1q_lane_f32::<3>(p.add(i3 as usize), v)
    }
}

/// Softmax component `C` of the three code rows `q` at pixels `i..i + 8` through table `e`
/// (`Mix::one`'s operations per lane), as two halves.
///
/// # Safety
/// The CPU must have NEON; the rows hold ≥ `i + 8` codes.
#[target_feature(enable = "neon")]
#[inline]
unsafe fn softmax8<const C: usize>(
    q: [*const i8; 3],
    e: &[f32; 256],
    i: usize,
) -> [float32x4_t; 2] {
    // SAFETY: the rows hold ≥ `i + 8` codes (the caller's condition).
    let (q0, q1, q2) = unsafe {
        (
            vld1_s8(q[0].add(i)),
            vld1_s8(q[1].add(i)),
            vld1_s8(q[2].add(i)),
        )
    };
    let mx = vmax_s8(vmax_s8(q0, q1), q2);
    // max − q ∈ 0..=255: the wrapping byte difference read as unsigned is that value.
    let d = [q0, q1, q2].map(|q| vreinterpret_u8_s8(vsub_s8(mx, q)));
    // SAFETY: NEON is available.
    unsafe {
        let half = |a: [float32x4_t; 3]| {
            let s = vaddq_f32(vaddq_f32(a[0], a[1]), a[2]);
            vdivq_f32(a[C], s)
        };
        let lo = d.map(|d| gather4::<0>(e, d));
        let hi = d.map(|d| gather4::<4>(e, d));
        [half(lo), half(hi)]
    }
}

/// [`SkRow`] as a pointer for [`accumulate_neon`].
#[derive(Clone, Copy)]
enum Sk {
    Compute,
    Fill(*mut f32),
    Use(*const f32),
}

/// [`accumulate`]'s loop over `n` values (a multiple of 8).
///
/// # Safety
/// The CPU must have NEON; `o`, `c`, the six rows and a cached row point at ≥ `n` values.
#[target_feature(enable = "neon")]
unsafe fn accumulate_neon<const TI: usize, const K: usize>(
    o: *mut f32,
    c: *const f32,
    t: [*const i8; 3],
    m: [*const i8; 3],
    (tt, kt): (&[f32; 256], &[f32; 256]),
    n: usize,
    sk: Sk,
) {
    let mut i = 0;
    while i + 8 <= n {
        // SAFETY: `i + 8 ≤ n`, inside every row, both value slices and a cached row.
        unsafe {
            let ct = softmax8::<TI>(t, tt, i);
            let ck = match sk {
                Sk::Use(p) => [vld1q_f32(p.add(i)), vld1q_f32(p.add(i + 4))],
                Sk::Fill(p) => {
                    let ck = softmax8::<K>(m, kt, i);
                    vst1q_f32(p.add(i), ck[0]);
                    vst1q_f32(p.add(i + 4), ck[1]);
                    ck
                }
                Sk::Compute => softmax8::<K>(m, kt, i),
            };
            for h in 0..2 {
                let at = i + 4 * h;
                let add = vmulq_f32(vmulq_f32(ct[h], ck[h]), vld1q_f32(c.add(at)));
                vst1q_f32(o.add(at), vaddq_f32(vld1q_f32(o.add(at)), add));
            }
        }
        i += 8;
    }
}

/// `out[i] = acc[i] / (1 + s[i])` (the step's last operation per pixel: IEEE `FADD` then
/// `FDIV`, 4 lanes at a time, the rest one by one) for `i` below the shortest length.
pub fn divide(out: &mut [f32], s: &[f32], acc: &[f32]) {
    let n = out.len().min(s.len()).min(acc.len());
    let mut i = 0;
    if crate::kernels::isa::Isa::Neon.available() {
        // SAFETY: NEON is available; `i + 4 ≤ n` values of each slice are read or written.
        unsafe {
            let one = vdupq_n_f32(1.0);
            while i + 4 <= n {
                let d = vaddq_f32(one, vld1q_f32(s.as_ptr().add(i)));
                vst1q_f32(
                    out.as_mut_ptr().add(i),
                    vdivq_f32(vld1q_f32(acc.as_ptr().add(i)), d),
                );
                i += 4;
            }
        }
    }
    for ((o, &s), &a) in out[i..n].iter_mut().zip(&s[i..n]).zip(&acc[i..n]) {
        *o = a / (1.0 + s);
    }
}

/// The step at four pixels `x .. x + 4` of a row `w` wide where some neighbours fall outside
/// the row (the border columns). Neighbour `j < g.len()` has its four codes at
/// `codes[q0 + j·plane ..]`, its four values at `cur[c0 + delta[j] ..]` (any value in lanes
/// whose neighbour is outside the row), Gaussian `g[j]` and column offset `off[j].1`. From
/// `s = 0`, `acc = cur[c0 .. c0 + 4]`, each term in order adds `r = lut[q]·g` to `s` and `r·d`
/// to `acc` in the lanes whose neighbour column `x + lane + dx` lies in `0 .. w` and leaves the
/// others as they were (`BSL`: a skipped term, as in the scalar loop), then `acc / (1 + s)`:
/// per lane the scalar border pixel's operations in its order. `None` (nothing done) without
/// NEON, where the slices differ in length or a read would leave `codes` or `cur`.
#[allow(clippy::too_many_arguments)]
pub fn edge4(
    (codes, q0, plane): (&[i8], usize, usize),
    (cur, c0): (&[f32], usize),
    (delta, off, g): (&[isize], &[(isize, isize)], &[f32]),
    lut: &[f32; 256],
    x: usize,
    w: usize,
) -> Option<[f32; 4]> {
    let n = g.len();
    let codes_ok = n == 0
        || (n - 1)
            .checked_mul(plane)
            .and_then(|e| e.checked_add(q0 + 4))
            .is_some_and(|e| e <= codes.len());
    let cur_ok = c0 + 4 <= cur.len() && cur.len() <= isize::MAX as usize;
    let ok = delta.len() == n && off.len() == n && codes_ok && cur_ok && w <= i32::MAX as usize;
    if !crate::kernels::isa::Isa::Neon.available() || !ok {
        return None;
    }
    // SAFETY: NEON is available; every read is checked above (term `j`'s four codes at
    // `q0 + j·plane`, the start values at `c0`) or by `edge4_neon` (the neighbours' values);
    // the table reads are `u8` indices into 256 entries.
    Some(unsafe {
        edge4_neon(
            codes.as_ptr().add(q0),
            plane,
            cur,
            c0,
            (delta, off, g),
            lut,
            x,
            w,
        )
    })
}

/// # Safety
/// The CPU must have NEON; the reads [`edge4`] checks are inside their slices (`q` at term 0's
/// codes, `c0 + 4 ≤ cur.len() ≤ isize::MAX`).
#[target_feature(enable = "neon")]
#[allow(clippy::too_many_arguments)]
unsafe fn edge4_neon(
    q: *const i8,
    plane: usize,
    cur: &[f32],
    c0: usize,
    (delta, off, g): (&[isize], &[(isize, isize)], &[f32]),
    lut: &[f32; 256],
    x: usize,
    w: usize,
) -> [f32; 4] {
    let lanes = vld1q_s32([0i32, 1, 2, 3].as_ptr());
    let (wv, xv) = (
        vdupq_n_s32(w as i32),
        vaddq_s32(lanes, vdupq_n_s32(x as i32)),
    );
    let mut s = vdupq_n_f32(0.0);
    let c = cur.as_ptr();
    let mut acc = vld1q_f32(c.add(c0));
    let lp = lut.as_ptr();
    for (j, ((&d, &(_, dx)), &gj)) in delta.iter().zip(off).zip(g).enumerate() {
        let p = vaddq_s32(xv, vdupq_n_s32(dx as i32));
        let m = vandq_u32(vcgezq_s32(p), vcltq_s32(p, wv));
        let qj = q.add(j * plane);
        let v = vld1q_dup_f32(lp.add(*qj as u8 as usize));
        let v = vld1q_lane_f32::<1>(lp.add(*qj.add(1) as u8 as usize), v);
        let v = vld1q_lane_f32::<2>(lp.add(*qj.add(2) as u8 as usize), v);
        let v = vld1q_lane_f32::<3>(lp.add(*qj.add(3) as u8 as usize), v);
        let r = vmulq_n_f32(v, gj);
        s = vbslq_f32(m, vaddq_f32(s, r), s);
        let at = c0 as isize + d;
        let dv = if at >= 0 && at as usize + 4 <= cur.len() {
            vld1q_f32(c.offset(at))
        } else {
            // A run reaching past the buffer (a corner's term): the lanes inside it, the
            // others 0 (their neighbours are outside the row, so the lanes are masked).
            let v: [f32; 4] = core::array::from_fn(|l| {
                usize::try_from(at + l as isize)
                    .ok()
                    .and_then(|i| cur.get(i))
                    .copied()
                    .unwrap_or(0.0)
            });
            vld1q_f32(v.as_ptr())
        };
        acc = vbslq_f32(m, vaddq_f32(acc, vmulq_f32(r, dv)), acc);
    }
    let mut out = [0f32; 4];
    vst1q_f32(
        out.as_mut_ptr(),
        vdivq_f32(acc, vaddq_f32(vdupq_n_f32(1.0), s)),
    );
    out
}
