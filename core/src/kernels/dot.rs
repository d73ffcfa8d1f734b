//! Dot-product micro-kernels of the convolution: for one output row, [`NB`] output channels ×
//! [`PB`] pixels starting at `ox0`,
//! `acc[j·PB + p] = Σ_k Σ_l rows[steps[k] + (ox0 + p)·L + l] · w[k][j][l]` over the reduction
//! steps `k = (tap, channel group)`
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
    /// One weight block, `[step][NB][L]`.
    pub weights: &'a [W],
    /// Element offset in `rows` of each reduction step `(tap, channel group)`, in the weights'
    /// order (tap-major).
    pub steps: &'a [u32],
    /// First output column.
    pub ox0: usize,
    /// Output columns of the block that are used (`1..=PB`; a kernel may leave the
    /// accumulators of the others unset, as the Cortex-M one does at narrow layers).
    pub pixels: usize,
}

impl<E, W> Task<'_, E, W> {
    /// Whether every read of the call lies inside `rows` and `weights` for `L` lanes.
    pub fn in_bounds(&self, l: usize) -> bool {
        let Some(&max) = self.steps.iter().max() else {
            return false;
        };
        max as usize + (self.ox0 + PB) * l <= self.rows.len()
            && self.steps.len() * NB * l <= self.weights.len()
    }
}

/// Portable kernel for either layout (`L` lanes per word).
pub fn portable<E: Copy + Into<i32>, W: Copy + Into<i32>, const L: usize>(
    t: &Task<E, W>,
    acc: &mut Acc,
) {
    acc.fill(0);
    for (&step, wq) in t.steps.iter().zip(t.weights.chunks_exact(NB * L)) {
        let base = step as usize + t.ox0 * L;
        let x = &t.rows[base..base + PB * L];
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
