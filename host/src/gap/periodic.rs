//! Period search of the periodic range error (`bin_wiggle`, issue 44 item 3): a real sensor's
//! range error may repeat with a period other than the library's bin width (another bin width,
//! a reference-clock beat, an optical ghost). Before its amplitudes are fitted, the period is
//! searched over [`PERIOD_RANGE_M`] on the fitting frames: a weighted least-squares periodogram
//! of the real distances' residuals `r ≈ c + A·sin(2πd/P) + B·cos(2πd/P)` against the mean
//! distance `d` of the draws of the mode the real return belongs to (each draw weighted by its
//! responsibility for the real distance under the tool's Student-t₃ kernel: the draws of a zone
//! are multimodal, several surfaces or a missed peak, and their plain mean sat 16 cm from the
//! real distance in half the zones), each zone weighted by the inverse of its predictive
//! variance (the mode's spread, the draws' noise and the kernel floor), over a frequency grid [`OVERSAMPLE`] times finer than the independent frequencies
//! `1/span` of the recording's range span, residuals beyond 4 robust standard deviations left
//! out (outliers). The [`PEAKS`] highest local maxima of the explained sum of squares are the
//! candidate periods; the gap tool fits the amplitudes by the likelihood at each and keeps the
//! best (`select::Ctx::fit_one`).
//!
//! The search tries about [`independent_periods`] independent periods, so on a null recording
//! its best training gain is the largest of that many chance gains: [`search_dims`] charges it
//! in the model-selection criterion (`ln` of the independent periods, in Akaike's currency of
//! one nat per parameter and fold), and the held-out gate, which scores the period chosen on
//! the other frames, keeps nulls null.

use super::model::{transform, Prepared};
use crate::sim::SimConfig;

/// Periods searched, metres: from 0.1 m (15 cm of ToF bin width is about the finest a dToF
/// histogram has) to 2 m (longer periods look like a smooth bias over an indoor range span).
pub const PERIOD_RANGE_M: [f64; 2] = [0.1, 2.0];

/// Frequencies tried per independent frequency `1/span`.
pub const OVERSAMPLE: f64 = 8.0;

/// Periodogram peaks handed to the likelihood.
pub const PEAKS: usize = 3;

/// One zone of the periodogram: the draws' mean distance, the residual, its weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// The mean distance of the draws, weighted by survival and responsibility, metres.
    pub d: f64,
    /// The real distance minus `d`, metres.
    pub r: f64,
    /// Inverse predictive variance, 1/m².
    pub w: f64,
}

/// Residuals of every valid zone with a predicted return in frames `idx` under `model`, with
/// kernel floor `kernel_m` in their weights.
pub fn residuals(
    model: &SimConfig,
    base: &SimConfig,
    frames: &[Prepared],
    idx: &[usize],
    kernel_m: f64,
) -> Vec<Point> {
    let mut out = Vec::new();
    for &f in idx {
        let prep = &frames[f];
        let draws = transform(model, base, prep, [0, 0]);
        let z_n = prep.zones();
        for z in 0..z_n {
            let Some(y) = prep.real[z] else { continue };
            // Each draw's responsibility for the real distance under the tool's Student-t₃
            // kernel: the draws of the mode the real return belongs to.
            let y = f64::from(y);
            let (mut sp, mut sd, mut sdd, mut ss) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for k in 0..prep.k {
                let x = &draws[k * z_n + z];
                let (p, d, s) = (f64::from(x.p), f64::from(x.d), f64::from(x.s));
                if p <= 0.0 {
                    continue;
                }
                let sc = (kernel_m * kernel_m + s * s).sqrt();
                let u = (y - d) / sc;
                let q = p * (1.0 + u * u / 3.0).powi(-2) / sc;
                sp += q;
                sd += q * d;
                sdd += q * d * d;
                ss += q * s * s;
            }
            if sp > 1e-12 {
                let d = sd / sp;
                let var = (sdd / sp - d * d).max(0.0) + ss / sp + kernel_m * kernel_m;
                out.push(Point {
                    d,
                    r: y - d,
                    w: 1.0 / var.max(1e-8),
                });
            }
        }
    }
    out
}

/// The span of the distances `d` of `points` (max − min), metres; 0 when empty.
fn span(points: &[Point]) -> f64 {
    let (lo, hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.d), hi.max(p.d))
        });
    if hi > lo {
        hi - lo
    } else {
        0.0
    }
}

/// Number of independent periods in [`PERIOD_RANGE_M`] over a range span of `span_m` metres:
/// the frequency band `1/0.1 − 1/2 m⁻¹` divided by the frequency resolution `1/span` (at least
/// 1).
pub fn independent_periods(span_m: f64) -> f64 {
    (span_m * (1.0 / PERIOD_RANGE_M[0] - 1.0 / PERIOD_RANGE_M[1])).max(1.0)
}

/// The period search's charge in the selection criterion, in parameters (one nat each per
/// fold): `ln` of the independent periods over the range span of `frames`' zones (the expected
/// excess of the best of `M` chance gains over one is ≈ `ln M` nats), rounded.
pub fn search_dims(frames: &[Prepared]) -> usize {
    let (lo, hi) = frames
        .iter()
        .flat_map(|p| p.cov.iter())
        .filter(|c| c.mean_m > 0.0)
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), c| {
            (lo.min(c.mean_m), hi.max(c.mean_m))
        });
    let s = if hi > lo { f64::from(hi - lo) } else { 0.0 };
    independent_periods(s).ln().round() as usize
}

/// Median of `v` (sorted in place); 0 when empty.
fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Explained weighted sum of squares of the weighted least-squares fit of `r ≈ c + a·sin(ωd) +
/// b·cos(ωd)` over `points` beyond the constant alone (0 when the normal equations are
/// singular).
fn explained(points: &[Point], omega: f64) -> f64 {
    // Weighted-centred sums: the constant is projected out.
    let n: f64 = points.iter().map(|p| p.w).sum();
    let (mut ss, mut sc, mut sr) = (0.0, 0.0, 0.0);
    let trig: Vec<(f64, f64)> = points.iter().map(|p| (omega * p.d).sin_cos()).collect();
    for ((s, c), p) in trig.iter().zip(points) {
        ss += p.w * s;
        sc += p.w * c;
        sr += p.w * p.r;
    }
    let (ms, mc, mr) = (ss / n, sc / n, sr / n);
    let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for ((s, c), p) in trig.iter().zip(points) {
        let (s, c, r, w) = (s - ms, c - mc, p.r - mr, p.w);
        a11 += w * s * s;
        a12 += w * s * c;
        a22 += w * c * c;
        b1 += w * s * r;
        b2 += w * c * r;
    }
    let det = a11 * a22 - a12 * a12;
    if det <= 1e-12 * (a11 * a22).max(1e-300) {
        return 0.0;
    }
    let x1 = (a22 * b1 - a12 * b2) / det;
    let x2 = (a11 * b2 - a12 * b1) / det;
    x1 * b1 + x2 * b2
}

/// The periods in [`PERIOD_RANGE_M`] whose sine and cosine best explain the residuals
/// `points` ([`residuals`]): the `peaks` highest local maxima of the periodogram, best first;
/// empty with fewer than 8 points or no range span.
pub fn best_periods(points: &[Point], peaks: usize) -> Vec<f64> {
    let mut r: Vec<f64> = points.iter().map(|p| p.r).collect();
    let med = median(&mut r);
    let mut dev: Vec<f64> = points.iter().map(|p| (p.r - med).abs()).collect();
    let sd = (1.4826 * median(&mut dev)).max(1e-3);
    let kept: Vec<Point> = points
        .iter()
        .copied()
        .filter(|p| (p.r - med).abs() <= 4.0 * sd && p.w.is_finite())
        .collect();
    let s = span(&kept);
    if kept.len() < 8 || s <= 0.0 {
        return Vec::new();
    }
    let (f_lo, f_hi) = (1.0 / PERIOD_RANGE_M[1], 1.0 / PERIOD_RANGE_M[0]);
    let df = 1.0 / (OVERSAMPLE * s);
    let steps = ((f_hi - f_lo) / df).ceil() as usize;
    let gram: Vec<(f64, f64)> = (0..=steps)
        .map(|i| (f_lo + i as f64 * df).min(f_hi))
        .map(|f| (explained(&kept, std::f64::consts::TAU * f), 1.0 / f))
        .collect();
    let mut maxima: Vec<(f64, f64)> = (0..gram.len())
        .filter(|&i| {
            (i == 0 || gram[i].0 >= gram[i - 1].0)
                && (i + 1 == gram.len() || gram[i].0 > gram[i + 1].0)
        })
        .map(|i| gram[i])
        .collect();
    maxima.sort_by(|a, b| b.0.total_cmp(&a.0));
    maxima.into_iter().take(peaks).map(|(_, p)| p).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Residuals of a sine of period `p` over 1–5 m with a deterministic jitter; every fifth
    /// zone an edge whose large residual has a small weight.
    fn wave(p: f64, amp: f64) -> Vec<Point> {
        (0..800)
            .map(|i| {
                let d = 1.0 + 4.0 * (i as f64 * 0.618_034).fract();
                let jitter = 0.004 * ((i * 7919 % 101) as f64 / 50.0 - 1.0);
                let edge = i % 5 == 0;
                Point {
                    d,
                    r: 0.01
                        + amp * (std::f64::consts::TAU * d / p + 0.7).sin()
                        + jitter
                        + if edge { 0.02 * (d * 0.9).sin() } else { 0.0 },
                    w: if edge { 1.0 } else { 400.0 },
                }
            })
            .collect()
    }

    #[test]
    fn finds_off_library_periods_within_two_percent() {
        for p in [0.13, 0.47, 1.3, 1.9] {
            let got = best_periods(&wave(p, 0.005), PEAKS);
            assert_eq!(got.len(), PEAKS);
            assert!((got[0] - p).abs() / p < 0.02, "{p}: {got:?}");
        }
    }

    #[test]
    fn too_few_points_or_no_span_give_none() {
        assert!(best_periods(&wave(0.5, 0.01)[..5], PEAKS).is_empty());
        let flat = Point {
            d: 2.0,
            r: 0.01,
            w: 1.0,
        };
        assert!(best_periods(&[flat; 20], PEAKS).is_empty());
        assert!(best_periods(&[], PEAKS).is_empty());
    }

    #[test]
    fn the_search_charge_grows_with_the_span() {
        assert_eq!(independent_periods(0.0), 1.0);
        assert!((independent_periods(4.0) - 38.0).abs() < 1e-9);
        // ln 38 ≈ 3.6: four parameters' worth.
        assert_eq!(independent_periods(4.0).ln().round() as usize, 4);
        assert_eq!(search_dims(&[]), 0);
    }
}
