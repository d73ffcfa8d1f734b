//! NEON [`crate::kernels::pack::Pairs`] kernel (ARMv8.0): `LD2` splits 16 pixels' channel pairs
//! into the even and the odd channel, then `SMLAL`/`SMLAL2` by element multiply 4 pixels' 16-bit
//! codes by one weight and add them into 32-bit lanes (no saturation: 2·255·128 < 2³¹ per
//! pair). Block: the 4 channels of the weight block × 16 pixels (16 accumulators of 4 lanes),
//! once per 16 pixels the call uses.

use crate::kernels::dot::{Acc, Task};
use crate::kernels::pack::{NB, PB};
use core::arch::aarch64::*;

/// Same contract as [`crate::kernels::dot::portable`] for pairs. Returns `false` (and does
/// nothing) if this CPU lacks NEON or a read would leave the slices.
pub fn pairs(t: &Task<i16, i16>, acc: &mut Acc) -> bool {
    if !crate::kernels::isa::Isa::Neon.available() || !t.in_bounds(2) {
        return false;
    }
    // SAFETY: NEON is available and every read is in bounds (both checked).
    unsafe { pairs_neon(t, acc) };
    true
}

/// Channel `j`'s 16 accumulators `c` += the even codes `e` × weight lane `E` + the odd codes
/// `o` × weight lane `O` (`E = 2j`, `O = 2j + 1`).
#[inline(always)]
fn mac<const E: i32, const O: i32>(
    c: &mut [int32x4_t],
    e: [int16x8_t; 2],
    o: [int16x8_t; 2],
    w: int16x8_t,
) {
    // SAFETY: plain register arithmetic; NEON is part of every aarch64 target this module is
    // built for (the caller runs only where `Isa::Neon` is available).
    unsafe {
        for q in 0..2 {
            c[2 * q] = vmlal_laneq_s16::<E>(c[2 * q], vget_low_s16(e[q]), w);
            c[2 * q] = vmlal_laneq_s16::<O>(c[2 * q], vget_low_s16(o[q]), w);
            c[2 * q + 1] = vmlal_high_laneq_s16::<E>(c[2 * q + 1], e[q], w);
            c[2 * q + 1] = vmlal_high_laneq_s16::<O>(c[2 * q + 1], o[q], w);
        }
    }
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn pairs_neon(t: &Task<i16, i16>, acc: &mut Acc) {
    const _: () = assert!(NB == 4 && PB.is_multiple_of(16));
    for half in 0..t.pixels.clamp(1, PB).div_ceil(16) {
        let mut c = [vdupq_n_s32(0); 16];
        let mut wq = t.weights.as_ptr();
        let row = t.rows.as_ptr().add(2 * (t.ox0 + 16 * half));
        for &step in t.steps.iter() {
            let pr = row.add(step as usize);
            let x0 = vld2q_s16(pr);
            let x1 = vld2q_s16(pr.add(16));
            let w = vld1q_s16(wq);
            let (e, o) = ([x0.0, x1.0], [x0.1, x1.1]);
            mac::<0, 1>(&mut c[0..4], e, o, w);
            mac::<2, 3>(&mut c[4..8], e, o, w);
            mac::<4, 5>(&mut c[8..12], e, o, w);
            mac::<6, 7>(&mut c[12..16], e, o, w);
            wq = wq.add(2 * NB);
        }
        for j in 0..NB {
            let dst = acc.as_mut_ptr().add(j * PB + 16 * half);
            for q in 0..4 {
                vst1q_s32(dst.add(4 * q), c[4 * j + q]);
            }
        }
    }
}
