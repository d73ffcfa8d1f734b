//! Metrics on small maps, every expected value worked out by hand in the comments.

use depthor_core::metrics::{Metrics, MetricsAccumulator, MetricsError};

fn close(got: f64, want: f64, what: &str) {
    assert!(
        (got - want).abs() <= 1e-6 * want.abs().max(1.0),
        "{what}: got {got}, want {want}"
    );
}

/// 2×2, max depth 10 m. Row-major, (x, y):
///
/// ```text
/// gt   = [1.0, 2.0,     pred = [1.1, 2.0,
///         4.0, 0.0]             2.5, 5.0]
/// ```
/// Pixel (1, 1) has gt 0 (unknown) and is not counted: n = 3.
/// - p0: x 1.1, y 1: err 0.1, ratio 1.1 (δ1 δ2 δ3), rel 0.1, sq 0.01, |log10(1/1.1)| = 0.0413927
/// - p1: x 2, y 2: err 0, ratio 1 (δ1 δ2 δ3)
/// - p2: x 2.5, y 4: err 1.5, ratio 1.6 (only δ3 < 1.953125), rel 0.375, sq 2.25,
///   log10 1.6 = 0.2041200
///
/// δ1 = δ2 = 2/3, δ3 = 1, AbsRel = 0.475/3, RMSE = √(2.26/3), log10 = (0.0413927 + 0.2041200)/3,
/// MAE = 1.6/3.
///
/// EWMAE: V = gt/4 → p0 0.25, p1 0.5, p2 1.0, p3 invalid; κ² = 0.25; G(∇) = ∇²/(∇² + 0.25).
/// - p0: N out, S = p2 (∇ 0.75 → 0.5625/0.8125 = 9/13), E = p1 (∇ 0.25 → 0.0625/0.3125 = 1/5),
///   W out → G = (9/13 + 1/5)/4 = 29/130
/// - p1: N out, S = p3 invalid → 0, E out, W = p0 (1/5) → G = 1/20
/// - p2: N = p0 (9/13), S out, E = p3 invalid, W out → G = 9/52
///
/// EWMAE = (29/130·0.1 + 1/20·0 + 9/52·1.5) / (29/130 + 1/20 + 9/52)
///       = (733/2600) / (116/260) = 733/1160 = 0.6318966
const GT_2X2: [f32; 4] = [1.0, 2.0, 4.0, 0.0];
const PRED_2X2: [f32; 4] = [1.1, 2.0, 2.5, 5.0];

#[test]
fn two_by_two_by_hand() {
    let mut acc = MetricsAccumulator::new(10.0);
    acc.add_map(&PRED_2X2, &GT_2X2, 2, 2).unwrap();
    let m = acc.finish();
    assert_eq!(m.count, 3);
    assert_eq!(m.invalid_pred, 0);
    close(m.delta1, 2.0 / 3.0, "delta1");
    close(m.delta2, 2.0 / 3.0, "delta2");
    close(m.delta3, 1.0, "delta3");
    close(m.abs_rel, 0.475 / 3.0, "abs_rel");
    close(m.rmse, (2.26f64 / 3.0).sqrt(), "rmse");
    close(m.log10, (0.041_392_685 + 0.204_119_983) / 3.0, "log10");
    close(m.mae, 1.6 / 3.0, "mae");
    close(m.ewmae, 733.0 / 1160.0, "ewmae");
}

/// 3×3, max depth 10 m: a 3 m bump in a 1 m plane.
///
/// ```text
/// gt   = [1, 1, 1,      pred = [1.5, 1, 1,
///         1, 3, 1,              1,   2, 1,
///         1, 1, 1]              1,   1, 1]
/// ```
/// n = 9; errors 0.5 at the corner (0, 0), 1 at the centre. MAE = 1.5/9, RMSE = √(1.25/9).
/// Ratios: 1.5 (δ2, δ3) and 1.5 (δ2, δ3) → δ1 = 7/9, δ2 = δ3 = 1.
/// AbsRel = (0.5/1 + 1/3)/9. log10 = (log10 1.5 + log10 1.5)/9.
///
/// EWMAE: V = gt/3 → 1/3 everywhere, 1 at the centre; ∇ centre↔edge = ±2/3,
/// G = (4/9)/(4/9 + 1/4) = 16/25. Centre: four such neighbours → G = 16/25. Edge midpoints: one
/// (the centre) → G = 4/25 each. Corners: all neighbours equal or outside → G = 0, so the corner's
/// error does not count. EWMAE = (16/25·1 + 0·0.5) / (16/25 + 4·4/25) = 0.64/1.28 = 0.5.
const GT_3X3: [f32; 9] = [1.0, 1.0, 1.0, 1.0, 3.0, 1.0, 1.0, 1.0, 1.0];
const PRED_3X3: [f32; 9] = [1.5, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 1.0];

#[test]
fn three_by_three_by_hand() {
    let mut acc = MetricsAccumulator::new(10.0);
    acc.add_map(&PRED_3X3, &GT_3X3, 3, 3).unwrap();
    let m = acc.finish();
    assert_eq!(m.count, 9);
    close(m.delta1, 7.0 / 9.0, "delta1");
    close(m.delta2, 1.0, "delta2");
    close(m.delta3, 1.0, "delta3");
    close(m.abs_rel, (0.5 + 1.0 / 3.0) / 9.0, "abs_rel");
    close(m.rmse, (1.25f64 / 9.0).sqrt(), "rmse");
    close(m.log10, 2.0 * 1.5f64.log10() / 9.0, "log10");
    close(m.mae, 1.5 / 9.0, "mae");
    close(m.ewmae, 0.5, "ewmae");
}

#[test]
fn frames_pool_their_pixels() {
    // Both maps above in one accumulator: n = 12, MAE = (1.6 + 1.5)/12, EWMAE is the ratio of the
    // pooled sums: (733/2600 + 0.64) / (116/260 + 1.28) (each map normalised by its own max).
    let mut acc = MetricsAccumulator::new(10.0);
    acc.add_map(&PRED_2X2, &GT_2X2, 2, 2).unwrap();
    acc.add_map(&PRED_3X3, &GT_3X3, 3, 3).unwrap();
    let m = acc.finish();
    assert_eq!(m.count, 12);
    close(m.mae, 3.1 / 12.0, "mae");
    close(m.delta1, 9.0 / 12.0, "delta1");
    close(
        m.ewmae,
        (733.0 / 2600.0 + 0.64) / (116.0 / 260.0 + 1.28),
        "ewmae",
    );
    // merge() of two single-map accumulators gives the same (up to summation order).
    let mut a = MetricsAccumulator::new(10.0);
    a.add_map(&PRED_2X2, &GT_2X2, 2, 2).unwrap();
    let mut b = MetricsAccumulator::new(10.0);
    b.add_map(&PRED_3X3, &GT_3X3, 3, 3).unwrap();
    a.merge(&b);
    let merged = a.finish();
    assert_eq!(merged.count, m.count);
    for (got, want) in [
        (merged.delta1, m.delta1),
        (merged.delta2, m.delta2),
        (merged.abs_rel, m.abs_rel),
        (merged.rmse, m.rmse),
        (merged.log10, m.log10),
        (merged.mae, m.mae),
        (merged.ewmae, m.ewmae),
    ] {
        close(got, want, "merged");
    }
}

#[test]
fn validity_and_clamping() {
    // max depth 5 m. gt: 2, 4, 1e-3 (not > 1e-3), 5 (not < 5), NaN, 3, 2 → 4 valid pixels
    // (2, 4, 3, 2) whose predictions are NaN, +inf, 7 and −1.
    // Clamped: NaN → 1e-3 (invalid), +inf → 5 (invalid), 7 → 5 (finite, not counted as invalid),
    // −1 → 1e-3 (invalid). Errors: 1.999, 1, 2, 1.999 → MAE = 6.998/4.
    // The NaN prediction under the invalid gt 1e-3 is ignored.
    let gt = [2.0, 4.0, 1e-3, 5.0, f32::NAN, 3.0, 2.0];
    let pred = [f32::NAN, f32::INFINITY, f32::NAN, 1.0, 1.0, 7.0, -1.0];
    let mut acc = MetricsAccumulator::new(5.0);
    acc.add_map(&pred, &gt, 7, 1).unwrap();
    let m = acc.finish();
    assert_eq!(m.count, 4);
    assert_eq!(m.invalid_pred, 3);
    close(m.mae, (1.999 + 1.0 + 2.0 + 1.999) / 4.0, "mae");
    assert!(m.rmse.is_finite() && m.log10.is_finite() && m.abs_rel.is_finite());
}

#[test]
fn empty_and_flat_maps() {
    let acc = MetricsAccumulator::new(10.0);
    let m: Metrics = acc.finish();
    assert_eq!(m.count, 0);
    assert!(m.mae.is_nan() && m.rmse.is_nan() && m.delta1.is_nan() && m.ewmae.is_nan());
    // A flat reference has no edges: every G_p = 0, EWMAE undefined (NaN), MAE still defined.
    let mut acc = MetricsAccumulator::new(10.0);
    acc.add_map(&[1.0, 2.0], &[1.0, 1.0], 2, 1).unwrap();
    let m = acc.finish();
    close(m.mae, 0.5, "mae");
    assert!(m.ewmae.is_nan());
}

#[test]
fn size_errors_leave_sums_alone() {
    let mut acc = MetricsAccumulator::new(10.0);
    assert_eq!(
        acc.add_map(&[1.0; 3], &[1.0; 4], 2, 2),
        Err(MetricsError::SizeMismatch {
            expected: 4,
            pred: 3,
            gt: 4
        })
    );
    assert_eq!(
        acc.add_map(&[], &[], usize::MAX, 2),
        Err(MetricsError::TooLarge)
    );
    assert_eq!(acc.finish().count, 0);
    assert!(MetricsError::TooLarge.to_string().contains("overflows"));
}
