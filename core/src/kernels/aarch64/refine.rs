//! NEON loop of the refinement step's interior chunks (`refine::step`), four neighbours per
//! pass over four pixels at a time: the table values read lane by lane, then the f32 operations
//! of the scalar loop in the same order (separate `FMUL` and `FADD`, never fused), so the bits
//! are those of every other path.

use core::arch::aarch64::*;

/// For `i < n`: `r_j = lut[q_j[i]] · g_j`, `s[i] = (((s[i] + r0) + r1) + r2) + r3`,
/// `acc[i] = (((acc[i] + r0·d0[i]) + r1·d1[i]) + r2·d2[i]) + r3·d3[i]`, where `n` is the
/// shortest of the ten slices. Returns `false` (and does nothing) without NEON or where the
/// slices differ in length.
pub fn four(
    q: [&[i8]; 4],
    d: [&[f32]; 4],
    g: [f32; 4],
    lut: &[f32; 256],
    s: &mut [f32],
    acc: &mut [f32],
) -> bool {
    let n = s.len();
    let same = acc.len() == n && q.iter().all(|x| x.len() == n) && d.iter().all(|x| x.len() == n);
    if !crate::kernels::isa::Isa::Neon.available() || !same {
        return false;
    }
    // SAFETY: NEON is available; every read and write has an index below `n`, the length of
    // all ten slices (checked).
    unsafe { four_neon(q, d, g, lut, s, acc, n) };
    true
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn four_neon(
    q: [&[i8]; 4],
    d: [&[f32]; 4],
    g: [f32; 4],
    lut: &[f32; 256],
    s: &mut [f32],
    acc: &mut [f32],
    n: usize,
) {
    let lp = lut.as_ptr();
    let (sp, ap) = (s.as_mut_ptr(), acc.as_mut_ptr());
    let mut i = 0;
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
