//! Small statistics the gap tool needs: a paired sign-flip test, Holm and Benjamini–Hochberg
//! multiple-testing control, the normal tail, and a bounded 1-D minimiser.

use crate::rng::Rng;

/// One-sided paired sign-flip (randomisation) test that the mean of `gains` is > 0: the share of
/// sign patterns whose sum is at least the observed one. Every one of the `2^n` patterns when
/// there are no more than `rounds + 1` of them (exact: all positive gives `2^−n`), otherwise
/// `rounds` random patterns plus the observed one, over `rounds + 1`. Exact under the null that
/// each gain is symmetric about 0; no normality needed.
pub fn sign_flip_p(gains: &[f64], rounds: usize, seed: u64) -> f64 {
    if gains.is_empty() {
        return 1.0;
    }
    let obs: f64 = gains.iter().sum();
    let n = gains.len();
    if n < 24 && (1usize << n) <= rounds + 1 {
        let hits = (0..1u32 << n)
            .filter(|pattern| {
                let s: f64 = gains
                    .iter()
                    .enumerate()
                    .map(|(i, &g)| if pattern >> i & 1 == 0 { g } else { -g })
                    .sum();
                s >= obs - 1e-12
            })
            .count();
        return hits as f64 / (1u64 << n) as f64;
    }
    let mut rng = Rng::new(seed);
    let mut hits = 0usize;
    for _ in 0..rounds {
        let mut s = 0.0;
        for &g in gains {
            s += if rng.next_u64() & 1 == 1 { g } else { -g };
        }
        hits += usize::from(s >= obs - 1e-12);
    }
    (hits + 1) as f64 / (rounds + 1) as f64
}

/// Holm's step-down procedure: which of the `p` values are rejected at family-wise level `alpha`.
pub fn holm(p: &[f64], alpha: f64) -> Vec<bool> {
    let mut order: Vec<usize> = (0..p.len()).collect();
    order.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut out = vec![false; p.len()];
    for (rank, &i) in order.iter().enumerate() {
        if p[i] <= alpha / (p.len() - rank) as f64 {
            out[i] = true;
        } else {
            break;
        }
    }
    out
}

/// Fixed-sequence testing: the hypotheses are tested in `order` (fixed before the `p` values are
/// seen), each at level `alpha`, until the first that is not rejected. Family-wise error ≤ `alpha`;
/// powerful when the order puts the true effects first (the gap tool orders by training gain).
pub fn fixed_sequence(p: &[f64], order: &[usize], alpha: f64) -> Vec<bool> {
    let mut out = vec![false; p.len()];
    for &i in order {
        if p[i] <= alpha {
            out[i] = true;
        } else {
            break;
        }
    }
    out
}

/// One-sided Clopper–Pearson upper confidence bound on a binomial rate: the `p` at which
/// observing ≤ `x` successes in `n` trials has probability `alpha` (exact, by bisection on the
/// binomial tail). 1 when `n` is 0 or `x ≥ n`.
pub fn clopper_pearson_upper(x: usize, n: usize, alpha: f64) -> f64 {
    if n == 0 || x >= n {
        return 1.0;
    }
    // P(X ≤ x) for X ~ Binomial(n, p), terms in log space.
    let cdf = |p: f64| {
        let (lp, lq) = (p.ln(), (1.0 - p).ln());
        let mut ln_choose = 0.0;
        let mut acc = 0.0;
        for k in 0..=x {
            if k > 0 {
                ln_choose += ((n - k + 1) as f64).ln() - (k as f64).ln();
            }
            acc += (ln_choose + k as f64 * lp + (n - k) as f64 * lq).exp();
        }
        acc
    };
    let (mut lo, mut hi) = (x as f64 / n as f64, 1.0);
    for _ in 0..60 {
        let mid = (lo + hi) / 2.0;
        if cdf(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (lo + hi) / 2.0
}

/// Benjamini–Hochberg: which of the `p` values are discoveries at false-discovery rate `q`.
pub fn benjamini_hochberg(p: &[f64], q: f64) -> Vec<bool> {
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut k = 0;
    for (rank, &i) in order.iter().enumerate() {
        if p[i] <= q * (rank + 1) as f64 / m as f64 {
            k = rank + 1;
        }
    }
    let mut out = vec![false; m];
    for &i in &order[..k] {
        out[i] = true;
    }
    out
}

/// Two-sided normal p-value of a z-score: `erfc(|z|/√2)` (Abramowitz & Stegun 7.1.26, error
/// below 1.5e-7).
pub fn normal_two_sided_p(z: f64) -> f64 {
    if !z.is_finite() {
        return if z.is_nan() { 1.0 } else { 0.0 };
    }
    let x = z.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    (poly * (-x * x).exp()).clamp(0.0, 1.0)
}

/// Minimises `f` on `[lo, hi]`: a scan of `grid` evenly spaced points (ends included) finds the
/// best basin, then golden-section search (`iters` steps) refines within one grid step either side
/// of the best point. The likelihood of a sharp distance effect (`multipath`: real returns match
/// the shifted draws only near the true size) has narrow basins a plain golden-section search
/// over the whole range steps over. Returns `(x, f(x))`, never worse than the best grid point.
pub fn grid_golden_min(
    mut f: impl FnMut(f64) -> f64,
    lo: f64,
    hi: f64,
    grid: usize,
    iters: usize,
) -> (f64, f64) {
    if grid < 3 || hi <= lo {
        return golden_min(f, lo, hi, iters);
    }
    let h = (hi - lo) / (grid - 1) as f64;
    let mut best = (lo, f64::INFINITY);
    for j in 0..grid {
        let x = lo + h * j as f64;
        let fx = f(x);
        if fx < best.1 {
            best = (x, fx);
        }
    }
    let (a, b) = ((best.0 - h).max(lo), (best.0 + h).min(hi));
    let r = golden_min(&mut f, a, b, iters);
    if r.1 < best.1 {
        r
    } else {
        best
    }
}

/// Minimises `f` on `[lo, hi]` by golden-section search (`iters` steps), also trying both ends;
/// returns `(x, f(x))`.
pub fn golden_min(mut f: impl FnMut(f64) -> f64, lo: f64, hi: f64, iters: usize) -> (f64, f64) {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (lo, hi);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    let mut best = if fc < fd { (c, fc) } else { (d, fd) };
    for x in [lo, hi] {
        let fx = f(x);
        if fx < best.1 {
            best = (x, fx);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clopper_pearson_matches_closed_forms() {
        // x = 0: 1 − α^(1/n) (the "rule of three" ≈ 3/n).
        for n in [20, 50, 100] {
            let u = clopper_pearson_upper(0, n, 0.05);
            assert!(
                (u - (1.0 - 0.05f64.powf(1.0 / n as f64))).abs() < 1e-9,
                "{n}: {u}"
            );
        }
        // x = 1, n = 10: (1 − p)^10 + 10 p (1 − p)^9 = 0.05 at p ≈ 0.3942.
        assert!((clopper_pearson_upper(1, 10, 0.05) - 0.3942).abs() < 1e-3);
        assert_eq!(clopper_pearson_upper(3, 3, 0.05), 1.0);
    }

    #[test]
    fn fixed_sequence_stops_at_the_first_acceptance() {
        let p = [0.03, 0.2, 0.001, 0.01];
        assert_eq!(
            fixed_sequence(&p, &[0, 3, 1, 2], 0.05),
            [true, false, false, true]
        );
        assert_eq!(fixed_sequence(&p, &[1, 0, 2, 3], 0.05), [false; 4]);
    }

    #[test]
    fn grid_golden_finds_a_narrow_basin() {
        // A wide shallow basin at 2.5 and a narrow deep one at 0.4 (width ≈ 0.05).
        let f = |x: f64| -0.2 * (-(x - 2.5f64).powi(2)).exp() - (-((x - 0.4) / 0.05).powi(2)).exp();
        let (x, _) = grid_golden_min(f, 0.0, 3.0, 48, 16);
        assert!((x - 0.4).abs() < 1e-3, "{x}");
        let (x, _) = golden_min(f, 0.0, 3.0, 16);
        assert!(
            (x - 2.5).abs() < 0.1,
            "plain golden section finds the wide basin: {x}"
        );
    }

    #[test]
    fn holm_and_bh_hand_computed() {
        let p = [0.01, 0.04, 0.03, 0.2];
        // Holm at 0.05: 0.01 ≤ 0.0125 yes; 0.03 ≤ 0.0167 no → stop.
        assert_eq!(holm(&p, 0.05), vec![true, false, false, false]);
        // BH at 0.05: sorted 0.01, 0.03, 0.04, 0.2 vs 0.0125, 0.025, 0.0375, 0.05 → k = 1.
        assert_eq!(
            benjamini_hochberg(&p, 0.05),
            vec![true, false, false, false]
        );
        // BH at 0.2: thresholds 0.05, 0.1, 0.15, 0.2 → all four.
        assert_eq!(benjamini_hochberg(&p, 0.2), vec![true; 4]);
    }

    #[test]
    fn normal_p_and_sign_flip() {
        assert!((normal_two_sided_p(1.959_964) - 0.05).abs() < 1e-6);
        assert!((normal_two_sided_p(0.0) - 1.0).abs() < 1e-6);
        // All 10 gains positive: only the all-positive pattern (1/1024) reaches the sum.
        let p = sign_flip_p(&[1.0; 10], 4999, 1);
        assert!(p < 0.01, "{p}");
        let p = sign_flip_p(&[1.0, -1.0, 1.0, -1.0], 999, 1);
        assert!(p > 0.3, "{p}");
    }

    #[test]
    fn sign_flip_enumerates_small_samples_exactly() {
        // 8 positive gains: 256 patterns, only the observed one reaches the sum.
        assert_eq!(sign_flip_p(&[1.0; 8], 4999, 1), 1.0 / 256.0);
        // {3, −1, 2}: patterns with sum ≥ 4 are (+,−,+) and (+,+,+): 2 of 8.
        assert_eq!(sign_flip_p(&[3.0, -1.0, 2.0], 4999, 1), 2.0 / 8.0);
        // Too many patterns for the rounds: the Monte-Carlo estimate, floored at 1/(rounds + 1).
        let p = sign_flip_p(&[1.0; 8], 99, 1);
        assert!((0.01..0.06).contains(&p), "{p}");
    }

    #[test]
    fn golden_finds_parabola_minimum_and_ends() {
        let (x, _) = golden_min(|x| (x - 0.3) * (x - 0.3), 0.0, 1.0, 40);
        assert!((x - 0.3).abs() < 1e-6);
        let (x, _) = golden_min(|x| x, 0.0, 1.0, 10);
        assert_eq!(x, 0.0);
    }
}
