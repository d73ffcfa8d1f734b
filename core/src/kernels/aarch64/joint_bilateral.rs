//! NEON sums of the joint bilateral interpolation (`crate::interp::JointBilateral`) for 4
//! pixels of a row at once, bit for bit its portable lanes: each lane runs the definition's
//! operations in order (separate multiplies and adds), and a lane that does not take a point
//! adds +0, which leaves its sums' bits as they were.

use super::vmath::exp_f32x4;
use crate::interp::{Group, Terms, LANES};
use crate::projection::ProjectedPoint;
use core::arch::aarch64::*;

const _: () = assert!(LANES == 4, "one NEON register of f32 per group");

/// `(Σ w·depth, Σ w)` of the group's pixels over `candidates` (zone column, point, point
/// colour), in the order given.
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
pub(crate) unsafe fn group_sums<'a>(
    candidates: impl Iterator<Item = (u32, &'a ProjectedPoint, [f32; 3])>,
    g: &Group,
    t: &Terms,
) -> ([f32; LANES], [f32; LANES]) {
    // SAFETY: every array read or written here holds exactly 4 lanes.
    unsafe {
        let xf = vld1q_f32(g.xf.as_ptr());
        let [cr, cg, cb] = g.rgb.map(|plane| vld1q_f32(plane.as_ptr()));
        let col_lo = vld1q_u32(g.col_lo.as_ptr());
        let col_hi = vld1q_u32(g.col_hi.as_ptr());
        let spacing = vdupq_n_f32(t.spacing);
        let colour = vdupq_n_f32(t.colour);
        let reach2 = vdupq_n_f32(t.reach2);
        let yf = g.y as f32;
        let mut num = vdupq_n_f32(0.0);
        let mut den = vdupq_n_f32(0.0);
        for (zc, p, pc) in candidates {
            let dv = p.v - yf;
            let du = vsubq_f32(vdupq_n_f32(p.u), xf);
            let d2 = vaddq_f32(vmulq_f32(du, du), vdupq_n_f32(dv * dv));
            let zc = vdupq_n_u32(zc);
            let take = vandq_u32(
                vandq_u32(vcleq_u32(col_lo, zc), vcltq_u32(zc, col_hi)),
                vcleq_f32(d2, reach2),
            );
            if vmaxvq_u32(take) == 0 {
                continue;
            }
            let r = vsubq_f32(cr, vdupq_n_f32(pc[0]));
            let gr = vsubq_f32(cg, vdupq_n_f32(pc[1]));
            let b = vsubq_f32(cb, vdupq_n_f32(pc[2]));
            let r2 = vaddq_f32(
                vaddq_f32(vmulq_f32(r, r), vmulq_f32(gr, gr)),
                vmulq_f32(b, b),
            );
            let arg = vsubq_f32(vdivq_f32(vnegq_f32(d2), spacing), vdivq_f32(r2, colour));
            let w = vreinterpretq_f32_u32(vandq_u32(vreinterpretq_u32_f32(exp_f32x4(arg)), take));
            num = vaddq_f32(num, vmulq_f32(w, vdupq_n_f32(p.depth_m)));
            den = vaddq_f32(den, w);
        }
        let mut out = ([0.0f32; LANES], [0.0f32; LANES]);
        vst1q_f32(out.0.as_mut_ptr(), num);
        vst1q_f32(out.1.as_mut_ptr(), den);
        out
    }
}
