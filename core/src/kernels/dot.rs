//! Dot-product micro-kernels of the convolution: for one output row, [`NB`] output channels ×
//! [`PB`] pixels starting at `ox0`,
//! `acc[j·PB + p] = Σ_cg Σ_tap Σ_l rows[cg·cg_stride + tap + (ox0 + p)·L + l] · w[(cg, tap), j, l]`
//! over the [`super::pack`] layouts. The portable version is here, the per-architecture ones in
//! `x86_64/` and `arm/`; all give the same bits (exact integer sums; nothing saturates since
//! `|x − zp| ≤ 255`, `|w| ≤ 128` and there are at most [`super::conv::MAX_TAPS`] taps).

use super::pack::{NB, PB};

/// Accumulators of one call.
pub type Acc = [i32; NB * PB];

/// One micro-kernel call.
#[derive(Clone, Copy, Debug)]
pub struct Task<'a, E, W> {
    /// All packed rows of the output row.
    pub rows: &'a [E],
    /// One weight block, `[cg][tap][NB][L]`.
    pub weights: &'a [W],
    /// Element offset of each tap inside a channel group's rows.
    pub taps: &'a [u32],
    /// Channel groups.
    pub n_cg: usize,
    /// Elements per channel group's rows.
    pub cg_stride: usize,
    /// First output column.
    pub ox0: usize,
}

impl<E, W> Task<'_, E, W> {
    /// Whether every read of the call lies inside `rows` and `weights` for `L` lanes.
    pub fn in_bounds(&self, l: usize) -> bool {
        let Some(&max_tap) = self.taps.iter().max() else {
            return false;
        };
        let last = (self.n_cg.max(1) - 1) * self.cg_stride + max_tap as usize + (self.ox0 + PB) * l;
        self.n_cg > 0
            && last <= self.rows.len()
            && self.n_cg * self.taps.len() * NB * l <= self.weights.len()
    }
}

/// Portable kernel for either layout (`L` lanes per word).
pub fn portable<E: Copy + Into<i32>, W: Copy + Into<i32>, const L: usize>(
    t: &Task<E, W>,
    acc: &mut Acc,
) {
    acc.fill(0);
    let mut wi = 0;
    for cg in 0..t.n_cg {
        for &tap in t.taps {
            let base = cg * t.cg_stride + tap as usize + t.ox0 * L;
            let x = &t.rows[base..base + PB * L];
            let wq = &t.weights[wi..wi + NB * L];
            wi += NB * L;
            for (a, wj) in acc.chunks_exact_mut(PB).zip(wq.chunks_exact(L)) {
                for (a, xs) in a.iter_mut().zip(x.chunks_exact(L)) {
                    let mut s = 0i32;
                    for k in 0..L {
                        s += xs[k].into() * wj[k].into();
                    }
                    *a = a.wrapping_add(s);
                }
            }
        }
    }
}
