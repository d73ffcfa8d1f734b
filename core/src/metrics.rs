//! Streaming, allocation-free depth metrics (paper supplement, "Details on Evaluation Metrics").
//!
//! Feed any number of `(prediction, reference)` depth maps to a [`MetricsAccumulator`]; every
//! metric is a ratio of running sums, so several frames pool their pixels (the dataset-level
//! value, not a mean of per-frame values). With `x_p` the prediction and `y_p` the reference
//! ("GT") at pixel `p`, `P` the set of valid pixels and `n = |P|` (absolute values written
//! `abs(·)` in the table):
//!
//! | metric | formula |
//! |---|---|
//! | `delta_i` | `1/n · Σ [max(y_p/x_p, x_p/y_p) < 1.25^i]`, `i = 1, 2, 3` |
//! | `abs_rel` | `1/n · Σ abs(y_p − x_p) / y_p` |
//! | `rmse` | `sqrt(1/n · Σ (y_p − x_p)²)` (metres) |
//! | `log10` | `1/n · Σ abs(log10 y_p − log10 x_p)` |
//! | `mae` | `1/n · Σ abs(y_p − x_p)` (metres) |
//! | `ewmae` | `Σ G_p · abs(y_p − x_p) / Σ G_p` (metres) |
//!
//! **Valid pixels.** `P` holds the pixels whose reference is in `(1e-3, max_depth_m)` (open
//! interval; NaN and 0 = unknown are excluded), as in the paper ("all pixels with valid ground
//! truth"). The prediction does not decide validity, so a model cannot improve its score by
//! emitting NaN. Instead, as in common practice (BTS, AdaBins), the prediction is clamped into
//! `[1e-3, max_depth_m]` before any metric: NaN, ≤ 0 and −∞ become `1e-3`, +∞ becomes
//! `max_depth_m`. Non-finite or ≤ 0 predictions at valid pixels are counted in
//! [`Metrics::invalid_pred`].
//!
//! **EWMAE weights** (Perona–Malik, following MIPI 2022/2023): per map, the reference is
//! normalised by its maximum over the map's valid pixels, `V_p = y_p / max_q y_q`. For each of the
//! four neighbours `D ∈ {N, S, E, W}`, `∇_D = V_{p,D} − V_p` and `G_D = ∇_D² / (∇_D² + κ²)` with
//! `κ = 0.5` ([`EWMAE_KAPPA`]); a neighbour outside the image or with an invalid reference
//! contributes `∇_D = 0`, hence `G_D = 0`. Then `G_p = (G_N + G_S + G_E + G_W) / 4`. The paper's
//! formula carries an extra `1/|P|` factor and sums `G_E` twice (a typo for `G_W`); we follow
//! MIPI's definition above, a weighted mean of the absolute error. When `Σ G_p = 0` (every
//! reference map flat) EWMAE is undefined and reported as NaN.
//!
//! Sums are kept in `f64`; `sqrt` and `log10` come from the crate's precise no_std `f64`
//! routines (relative error below 1e-15), not from micromath's `f32` approximations.

use crate::fmath;

/// Smallest valid reference depth (exclusive) and lower clamp of predictions, metres.
pub const MIN_DEPTH_M: f32 = 1e-3;

/// Regularisation constant `κ` of the EWMAE conduction function (MIPI: 0.5 on the reference
/// normalised to `[0, 1]`).
pub const EWMAE_KAPPA: f64 = 0.5;

/// Threshold of `delta1`; `delta2` and `delta3` use its square and cube.
pub const DELTA_BASE: f64 = 1.25;

/// Final metric values; every field but the counts is NaN when `count == 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Number of valid pixels `|P|` over all maps.
    pub count: u64,
    /// Fraction of pixels with `max(y/x, x/y) < 1.25`.
    pub delta1: f64,
    /// Fraction of pixels with `max(y/x, x/y) < 1.25²`.
    pub delta2: f64,
    /// Fraction of pixels with `max(y/x, x/y) < 1.25³`.
    pub delta3: f64,
    /// Mean absolute relative error `|y − x| / y`.
    pub abs_rel: f64,
    /// Root mean squared error, metres.
    pub rmse: f64,
    /// Mean `|log10 y − log10 x|`.
    pub log10: f64,
    /// Mean absolute error, metres.
    pub mae: f64,
    /// Edge-weighted mean absolute error, metres (NaN when no pixel has weight).
    pub ewmae: f64,
    /// Valid pixels whose prediction was NaN, infinite or ≤ 0 (and was clamped).
    pub invalid_pred: u64,
}

/// Why a map could not be added.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum MetricsError {
    /// `pred` or `gt` is not `width * height` long.
    SizeMismatch {
        /// `width * height`.
        expected: usize,
        /// Length of the prediction.
        pred: usize,
        /// Length of the reference.
        gt: usize,
    },
    /// `width * height` overflows `usize`.
    TooLarge,
}

impl core::fmt::Display for MetricsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            MetricsError::SizeMismatch { expected, pred, gt } => write!(
                f,
                "depth maps must have {expected} pixels: prediction has {pred}, reference has {gt}"
            ),
            MetricsError::TooLarge => f.write_str("map width * height overflows usize"),
        }
    }
}

impl core::error::Error for MetricsError {}

/// Running sums for [`Metrics`]; `Copy`, fixed size, no allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetricsAccumulator {
    max_depth_m: f32,
    count: u64,
    invalid_pred: u64,
    delta: [u64; 3],
    sum_abs_rel: f64,
    sum_sq: f64,
    sum_log10: f64,
    sum_abs: f64,
    sum_weighted_abs: f64,
    sum_weight: f64,
}

impl MetricsAccumulator {
    /// An empty accumulator; reference depths must be below `max_depth_m` (metres) to count.
    ///
    /// `max_depth_m` should be finite and > 1e-3: with NaN no pixel is ever valid, with +∞
    /// infinite predictions stay infinite.
    pub const fn new(max_depth_m: f32) -> Self {
        MetricsAccumulator {
            max_depth_m,
            count: 0,
            invalid_pred: 0,
            delta: [0; 3],
            sum_abs_rel: 0.0,
            sum_sq: 0.0,
            sum_log10: 0.0,
            sum_abs: 0.0,
            sum_weighted_abs: 0.0,
            sum_weight: 0.0,
        }
    }

    /// The `max_depth_m` this accumulator was made with.
    pub fn max_depth_m(&self) -> f32 {
        self.max_depth_m
    }

    /// Clamps a prediction into `[MIN_DEPTH_M, max_depth_m]`; the flag says it was not finite > 0.
    fn clamp_pred(&self, pred: f32) -> (f32, bool) {
        if pred.is_nan() || pred <= 0.0 {
            (MIN_DEPTH_M, true)
        } else if pred == f32::INFINITY {
            (self.max_depth_m, true)
        } else {
            (pred.max(MIN_DEPTH_M).min(self.max_depth_m), false)
        }
    }

    /// Adds one `width × height` map pair (row-major, metres). Fails without changing the sums
    /// when a length does not match.
    pub fn add_map(
        &mut self,
        pred: &[f32],
        gt: &[f32],
        width: usize,
        height: usize,
    ) -> Result<(), MetricsError> {
        let expected = width.checked_mul(height).ok_or(MetricsError::TooLarge)?;
        if pred.len() != expected || gt.len() != expected {
            return Err(MetricsError::SizeMismatch {
                expected,
                pred: pred.len(),
                gt: gt.len(),
            });
        }
        let max_depth = self.max_depth_m;
        let valid_gt = move |g: f32| g > MIN_DEPTH_M && g < max_depth;
        // Normaliser of the EWMAE weights: the largest valid reference of this map.
        let gt_max = gt
            .iter()
            .copied()
            .filter(|&g| valid_gt(g))
            .fold(0.0f32, f32::max);
        if gt_max <= 0.0 {
            return Ok(()); // no valid pixel in this map
        }
        let inv_max = 1.0 / f64::from(gt_max);
        let kappa2 = EWMAE_KAPPA * EWMAE_KAPPA;
        // Normalised reference at (x, y), or None outside the image / where invalid.
        let norm_at = |x: usize, y: usize| -> Option<f64> {
            if x >= width || y >= height {
                return None;
            }
            let g = *gt.get(y * width + x)?;
            valid_gt(g).then(|| f64::from(g) * inv_max)
        };
        let thresholds = [
            DELTA_BASE,
            DELTA_BASE * DELTA_BASE,
            DELTA_BASE * DELTA_BASE * DELTA_BASE,
        ];
        for (i, (&p, &g)) in pred.iter().zip(gt.iter()).enumerate() {
            if !valid_gt(g) {
                continue;
            }
            let (x_f, y_f) = (i % width, i / width);
            let (p, invalid) = self.clamp_pred(p);
            let (x, y) = (f64::from(p), f64::from(g));
            let err = (y - x).abs();
            let ratio = (y / x).max(x / y);
            for (hits, threshold) in self.delta.iter_mut().zip(thresholds) {
                if ratio < threshold {
                    *hits += 1;
                }
            }
            self.count += 1;
            self.invalid_pred += u64::from(invalid);
            self.sum_abs_rel += err / y;
            self.sum_sq += err * err;
            self.sum_log10 += fmath::log10(y / x).abs();
            self.sum_abs += err;

            let v = f64::from(g) * inv_max;
            let neighbours = [
                y_f.checked_sub(1).and_then(|yn| norm_at(x_f, yn)), // N
                norm_at(x_f, y_f + 1),                              // S
                norm_at(x_f + 1, y_f),                              // E
                x_f.checked_sub(1).and_then(|xw| norm_at(xw, y_f)), // W
            ];
            let weight = neighbours
                .iter()
                .map(|n| {
                    let grad = n.map_or(0.0, |vn| vn - v);
                    let g2 = grad * grad;
                    g2 / (g2 + kappa2)
                })
                .sum::<f64>()
                / 4.0;
            self.sum_weighted_abs += weight * err;
            self.sum_weight += weight;
        }
        Ok(())
    }

    /// Pools another accumulator's pixels into this one (e.g. per-thread partial sums). The
    /// `max_depth_m` of `self` is kept.
    pub fn merge(&mut self, other: &MetricsAccumulator) {
        self.count += other.count;
        self.invalid_pred += other.invalid_pred;
        for (a, b) in self.delta.iter_mut().zip(other.delta) {
            *a += b;
        }
        self.sum_abs_rel += other.sum_abs_rel;
        self.sum_sq += other.sum_sq;
        self.sum_log10 += other.sum_log10;
        self.sum_abs += other.sum_abs;
        self.sum_weighted_abs += other.sum_weighted_abs;
        self.sum_weight += other.sum_weight;
    }

    /// The metrics over every pixel added so far (the accumulator keeps going).
    pub fn finish(&self) -> Metrics {
        let n = self.count as f64;
        let mean = |sum: f64| if self.count == 0 { f64::NAN } else { sum / n };
        let [d1, d2, d3] = self.delta.map(|hits| mean(hits as f64));
        Metrics {
            count: self.count,
            delta1: d1,
            delta2: d2,
            delta3: d3,
            abs_rel: mean(self.sum_abs_rel),
            rmse: fmath::sqrt(mean(self.sum_sq)),
            log10: mean(self.sum_log10),
            mae: mean(self.sum_abs),
            ewmae: if self.sum_weight > 0.0 {
                self.sum_weighted_abs / self.sum_weight
            } else {
                f64::NAN
            },
            invalid_pred: self.invalid_pred,
        }
    }
}
