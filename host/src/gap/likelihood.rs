//! The simulator's predictive distribution of one zone and the likelihood of a real measurement
//! under it.
//!
//! `K` Monte-Carlo runs of the simulator on the frame's reference depth, RGB and labels (seeds
//! differ, input is the same) give `K` draws per zone. A draw carries the probability `p` that it
//! still has a return (1 or 0 after the simulator; the gap tool's dropout effects multiply it by
//! their survival probability, which keeps fits smooth), its distance `d`, and an extra noise
//! scale `s` (from `range_noise`). A zone's dropout probability is
//! `π = 1 − (Σp + ½) / (K + 1)` (add-½ smoothing: never 0 or 1), and a valid real distance `y` has
//! density `(1 − ε) · Σ p_k t₃(y; d_k, √(s₀² + s_k²)) / Σp + ε / R`: a kernel mixture of
//! Student-t (3 d.o.f., heavy tails) around the simulated returns plus an outlier rate `ε` uniform
//! over the sensor's range `R`.

use std::f64::consts::PI;

/// One Monte-Carlo draw of one zone.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Draw {
    /// Probability that the draw has a return.
    pub p: f32,
    /// Distance of the return, metres.
    pub d: f32,
    /// Extra noise standard deviation, metres.
    pub s: f32,
    /// Ground-truth peak of the zone in this draw (background threshold of `calibration_shift`).
    pub peak: f32,
}

/// Constants of the predictive density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Density {
    /// Kernel floor `s₀`, metres: the spread the simulator's draws do not resolve.
    pub kernel_m: f64,
    /// Outlier rate `ε`.
    pub outlier: f64,
    /// Support `R` of the outliers, metres.
    pub range_m: f64,
}

impl Default for Density {
    /// 2 cm kernel (the 5 cm histogram bins' ≈ 1.4 cm rounding plus millimetre storage), 2 %
    /// outliers over 8 m.
    fn default() -> Self {
        Density {
            kernel_m: 0.02,
            outlier: 0.02,
            range_m: 8.0,
        }
    }
}

/// Student-t density with 3 degrees of freedom at standardised `z`, divided by the scale later.
fn t3(z: f64) -> f64 {
    // Γ(2) / (Γ(1.5) √(3π)) = 2 / (π √3).
    2.0 / (PI * 3f64.sqrt()) * (1.0 + z * z / 3.0).powi(-2)
}

/// Student-t (3 d.o.f.) cumulative distribution at standardised `z`.
fn t3_cdf(z: f64) -> f64 {
    let x = z / 3f64.sqrt();
    0.5 + (x / (1.0 + x * x) + x.atan()) / PI
}

/// What the predictive distribution says about one zone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZoneFit {
    /// Negative log-likelihood of the real measurement, nats.
    pub nll: f64,
    /// Predicted dropout probability π.
    pub p_drop: f64,
    /// Probability integral transform of a valid real distance (NaN when the real zone is
    /// invalid).
    pub pit: f64,
    /// Real minus the draws' weighted median distance (NaN when either has no return).
    pub residual_m: f64,
}

impl Density {
    /// Scores a real zone (`real`: its distance when valid) against its `draws`.
    pub fn score(&self, draws: &[Draw], real: Option<f32>) -> ZoneFit {
        let k = draws.len() as f64;
        let sp: f64 = draws.iter().map(|d| f64::from(d.p)).sum();
        let p_valid = (sp + 0.5) / (k + 1.0);
        let Some(y) = real else {
            return ZoneFit {
                nll: -(1.0 - p_valid).ln(),
                p_drop: 1.0 - p_valid,
                pit: f64::NAN,
                residual_m: f64::NAN,
            };
        };
        let y = f64::from(y);
        let (mut dens, mut cdf) = (0.0, 0.0);
        if sp > 1e-9 {
            for d in draws {
                if d.p <= 0.0 {
                    continue;
                }
                let s = (self.kernel_m * self.kernel_m + f64::from(d.s) * f64::from(d.s)).sqrt();
                let z = (y - f64::from(d.d)) / s;
                dens += f64::from(d.p) * t3(z) / s;
                cdf += f64::from(d.p) * t3_cdf(z);
            }
            dens /= sp;
            cdf /= sp;
        }
        let w = if sp > 1e-9 { 1.0 - self.outlier } else { 0.0 };
        let eps = 1.0 - w;
        let density = w * dens + eps / self.range_m;
        let pit = w * cdf + eps * (y / self.range_m).clamp(0.0, 1.0);
        ZoneFit {
            nll: -p_valid.ln() - density.ln(),
            p_drop: 1.0 - p_valid,
            pit,
            residual_m: if sp > 1e-9 {
                y - weighted_median(draws)
            } else {
                f64::NAN
            },
        }
    }
}

/// Median of the draws' distances weighted by `p` (draws with `p > 0` only; 0 when none).
pub fn weighted_median(draws: &[Draw]) -> f64 {
    let mut v: Vec<(f32, f32)> = draws
        .iter()
        .filter(|d| d.p > 0.0)
        .map(|d| (d.d, d.p))
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    let half = v.iter().map(|x| x.1).sum::<f32>() / 2.0;
    let mut acc = 0.0;
    for &(d, p) in &v {
        acc += p;
        if acc >= half {
            return f64::from(d);
        }
    }
    f64::from(v[v.len() - 1].0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn draw(p: f32, d: f32) -> Draw {
        Draw {
            p,
            d,
            s: 0.0,
            peak: d,
        }
    }

    #[test]
    fn dropout_probability_is_smoothed() {
        let den = Density::default();
        // 3 of 4 draws valid: P(valid) = 3.5 / 5 = 0.7; a real dropout costs −ln 0.3.
        let draws = [
            draw(1.0, 2.0),
            draw(1.0, 2.0),
            draw(1.0, 2.0),
            draw(0.0, 0.0),
        ];
        let f = den.score(&draws, None);
        assert!((f.p_drop - 0.3).abs() < 1e-12);
        assert!((f.nll - -(0.3f64.ln())).abs() < 1e-12);
    }

    #[test]
    fn valid_density_hand_computed() {
        let den = Density {
            kernel_m: 0.1,
            outlier: 0.0,
            range_m: 8.0,
        };
        // One draw at 2 m, real at 2 m: t₃(0)/0.1 = 2/(π√3)/0.1 = 3.6755; P(valid) = 1.5/2.
        let f = den.score(&[draw(1.0, 2.0)], Some(2.0));
        let expect = -(0.75f64.ln()) - (2.0 / (PI * 3f64.sqrt()) / 0.1).ln();
        assert!((f.nll - expect).abs() < 1e-9, "{} vs {expect}", f.nll);
        assert!((f.pit - 0.5).abs() < 1e-12);
        assert_eq!(f.residual_m, 0.0);
        // No simulated return: the outlier density alone.
        let den = Density {
            outlier: 0.02,
            ..den
        };
        let f = den.score(&[draw(0.0, 0.0)], Some(1.0));
        assert!((f.nll - (-(0.25f64.ln()) + 8f64.ln())).abs() < 1e-9);
    }

    #[test]
    fn t3_cdf_matches_known_values() {
        assert!((t3_cdf(0.0) - 0.5).abs() < 1e-12);
        // Student t, 3 d.o.f.: P(T ≤ 3.182446) = 0.975.
        assert!((t3_cdf(3.182_446) - 0.975).abs() < 1e-6);
        assert_eq!(
            weighted_median(&[draw(1.0, 3.0), draw(1.0, 1.0), draw(1.0, 2.0)]),
            2.0
        );
    }
}
