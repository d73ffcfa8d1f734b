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

/// The reduction steps of a [`Task`] (element offsets, see [`Task::steps`]) with what the
/// kernels check before reading: the largest offset and the OR of all (their low bits tell
/// alignment). Made once per output row and shared by the row's tasks, so no kernel folds the
/// offsets per call; the fields are private, so the bounds always describe the offsets.
#[derive(Clone, Copy, Debug)]
pub struct Steps<'a> {
    offsets: &'a [u32],
    max: u32,
    bits: u32,
}

impl<'a> Steps<'a> {
    /// The steps `offsets` with their bounds.
    pub fn new(offsets: &'a [u32]) -> Steps<'a> {
        let (bits, max) = offsets
            .iter()
            .fold((0u32, 0u32), |(b, m), &s| (b | s, m.max(s)));
        Steps { offsets, max, bits }
    }

    /// The largest offset, `None` when there are no steps.
    pub fn max(&self) -> Option<u32> {
        (!self.offsets.is_empty()).then_some(self.max)
    }

    /// The bitwise OR of every offset (0 when there are none).
    pub fn bits(&self) -> u32 {
        self.bits
    }
}

impl core::ops::Deref for Steps<'_> {
    type Target = [u32];
    fn deref(&self) -> &[u32] {
        self.offsets
    }
}

/// One micro-kernel call.
#[derive(Clone, Copy, Debug)]
pub struct Task<'a, E, W> {
    /// All packed rows of the output row.
    pub rows: &'a [E],
    /// One weight block, `[step][NB][L]`.
    pub weights: &'a [W],
    /// Element offset in `rows` of each reduction step `(tap, channel group)`, in the weights'
    /// order (tap-major).
    pub steps: Steps<'a>,
    /// First output column.
    pub ox0: usize,
    /// Output columns of the block that are used (`1..=PB`; a kernel may leave the
    /// accumulators of the others unset, as the Cortex-M one does at narrow layers).
    pub pixels: usize,
    /// Output channels of the weight block that are used (`1..=NB`; a kernel may leave the
    /// accumulators of the others unset, as the `neon-dot` one does for 1 to 3).
    pub channels: usize,
}

impl<E, W> Task<'_, E, W> {
    /// Whether every read of the call lies inside `rows` and `weights` for `L` lanes.
    pub fn in_bounds(&self, l: usize) -> bool {
        let Some(max) = self.steps.max() else {
            return false;
        };
        max as usize + (self.ox0 + PB) * l <= self.rows.len()
            && self.steps.len() * NB * l <= self.weights.len()
    }
}

/// Portable kernel for either layout (`L` lanes per word). Sums the block's used columns
/// only (`t.pixels`; the others stay 0), so narrow layers cost what they use.
pub fn portable<E: Copy + Into<i32>, W: Copy + Into<i32>, const L: usize>(
    t: &Task<E, W>,
    acc: &mut Acc,
) {
    acc.fill(0);
    // A whole block (most of them) keeps a trip count known at compile time, which the
    // compiler vectorises (a variable one cost aarch64's portable set 84 → 119 M instructions
    // per mcu_lite frame).
    if t.pixels >= PB {
        sum_columns::<E, W, L>(t, acc, PB);
    } else {
        sum_columns::<E, W, L>(t, acc, t.pixels);
    }
}

/// [`portable`]'s sums over the first `columns` columns of the block.
#[inline(always)]
fn sum_columns<E: Copy + Into<i32>, W: Copy + Into<i32>, const L: usize>(
    t: &Task<E, W>,
    acc: &mut Acc,
    columns: usize,
) {
    for (&step, wq) in t.steps.iter().zip(t.weights.chunks_exact(NB * L)) {
        let base = step as usize + t.ox0 * L;
        let x = &t.rows[base..base + PB * L];
        for (a, wj) in acc.chunks_exact_mut(PB).zip(wq.chunks_exact(L)) {
            for (a, xs) in a.iter_mut().zip(x.chunks_exact(L)).take(columns) {
                let mut s = 0i32;
                for k in 0..L {
                    s += xs[k].into() * wj[k].into();
                }
                *a = a.wrapping_add(s);
            }
        }
    }
}
