//! Localisation: where the real zones disagree with the predictive distribution. Every zone of the
//! held-out frames gets its dropout excess (real dropout − π) and its PIT; both are sliced along
//! the covariates (equal-count bins) and tested (z-scores under the model: Σ(drop − π) has
//! variance Σπ(1 − π), a PIT is uniform with variance 1/12), with Benjamini–Hochberg control of
//! the false-discovery rate over all slices.

use super::effects::Covariate;
use super::likelihood::{Density, ZoneFit};
use super::model::{eval_frame, Prepared};
use super::stats::{benjamini_hochberg, normal_two_sided_p};
use crate::sim::SimConfig;

/// One zone of one held-out frame under a model.
#[derive(Clone, Copy, Debug)]
pub struct ZoneRecord {
    /// Zone index (row-major).
    pub zone: usize,
    /// Covariate values in [`Covariate::ALL`] order.
    pub cov: [f64; 8],
    /// The model's fit of the zone.
    pub fit: ZoneFit,
    /// Whether the real zone had no target.
    pub dropped: bool,
}

/// The records of frames `idx` under `model`.
pub fn records(
    density: &Density,
    model: &SimConfig,
    base: &SimConfig,
    frames: &[Prepared],
    idx: &[usize],
) -> Vec<ZoneRecord> {
    let mut out = Vec::new();
    for &f in idx {
        let prep = &frames[f];
        let ev = eval_frame(density, model, base, prep, true);
        for (z, fit) in ev.zones.into_iter().enumerate() {
            out.push(ZoneRecord {
                zone: z,
                cov: zone_covariates(prep, z),
                fit,
                dropped: prep.real[z].is_none(),
            });
        }
    }
    out
}

/// The covariates of zone `z` of `prep`, in [`Covariate::ALL`]'s order.
pub fn zone_covariates(prep: &Prepared, z: usize) -> [f64; 8] {
    let c = &prep.cov[z];
    [
        f64::from(c.mean_m),
        f64::from(c.spread_m),
        f64::from(c.brightness),
        f64::from(c.nonlambertian_fraction),
        f64::from(c.radius),
        (z / prep.cols) as f64,
        (z % prep.cols) as f64,
        prep.t_s,
    ]
}

/// Whether covariate `cov` takes more than one value over the zones of `frames`.
pub fn varies(frames: &[Prepared], cov: Covariate) -> bool {
    let ci = Covariate::ALL.iter().position(|&c| c == cov).unwrap_or(0);
    let mut values = frames
        .iter()
        .flat_map(|p| (0..p.zones()).map(move |z| zone_covariates(p, z)[ci]));
    let Some(first) = values.next() else {
        return false;
    };
    values.any(|v| v.total_cmp(&first).is_ne())
}

/// One slice of one covariate.
#[derive(Clone, Debug, PartialEq)]
pub struct Slice {
    /// Covariate.
    pub covariate: Covariate,
    /// Covariate range `[lo, hi]` of the slice.
    pub range: [f64; 2],
    /// Zones in the slice.
    pub n: usize,
    /// Mean real-minus-predicted dropout.
    pub dropout_excess: f64,
    /// Its z-score.
    pub dropout_z: f64,
    /// Mean PIT − ½ of the valid zones (> 0: real farther than predicted).
    pub pit_shift: f64,
    /// Its z-score.
    pub pit_z: f64,
    /// Mean real-minus-median distance of the valid zones, metres.
    pub residual_m: f64,
    /// Smaller of the two p-values.
    pub p: f64,
    /// Discovery under Benjamini–Hochberg (q = 0.05 over 2 tests per slice).
    pub significant: bool,
}

/// Slices every covariate into `bins` equal-count bins and tests them.
pub fn slices(recs: &[ZoneRecord], bins: usize) -> Vec<Slice> {
    let mut out = Vec::new();
    if recs.is_empty() {
        return out;
    }
    for (ci, &cov) in Covariate::ALL.iter().enumerate() {
        let mut order: Vec<usize> = (0..recs.len()).collect();
        order.sort_by(|&a, &b| recs[a].cov[ci].total_cmp(&recs[b].cov[ci]));
        // A covariate with no spread (e.g. material on imported frames without labels) cannot
        // localise anything: its slices would split the zones arbitrarily.
        let (lo, hi) = (recs[order[0]].cov[ci], recs[order[order.len() - 1]].cov[ci]);
        if lo.total_cmp(&hi).is_eq() {
            continue;
        }
        for b in 0..bins {
            let chunk = &order[b * order.len() / bins..(b + 1) * order.len() / bins];
            if chunk.is_empty() {
                continue;
            }
            let (mut ex, mut var, mut pit, mut npit, mut res, mut nres) =
                (0.0, 0.0, 0.0, 0, 0.0, 0);
            for &i in chunk {
                let r = &recs[i];
                ex += f64::from(u8::from(r.dropped)) - r.fit.p_drop;
                var += r.fit.p_drop * (1.0 - r.fit.p_drop);
                if r.fit.pit.is_finite() {
                    pit += r.fit.pit - 0.5;
                    npit += 1;
                }
                if r.fit.residual_m.is_finite() {
                    res += r.fit.residual_m;
                    nres += 1;
                }
            }
            let n = chunk.len();
            let dz = if var > 0.0 { ex / var.sqrt() } else { 0.0 };
            let pz = if npit > 0 {
                pit / (npit as f64 / 12.0).sqrt()
            } else {
                0.0
            };
            out.push(Slice {
                covariate: cov,
                range: [recs[chunk[0]].cov[ci], recs[chunk[n - 1]].cov[ci]],
                n,
                dropout_excess: ex / n as f64,
                dropout_z: dz,
                pit_shift: if npit > 0 { pit / npit as f64 } else { 0.0 },
                pit_z: pz,
                residual_m: if nres > 0 { res / nres as f64 } else { 0.0 },
                p: normal_two_sided_p(dz).min(normal_two_sided_p(pz)),
                significant: false,
            });
        }
    }
    // Two tests per slice: BH over all of them, a slice is a discovery if either test is.
    let ps: Vec<f64> = out
        .iter()
        .flat_map(|s| [normal_two_sided_p(s.dropout_z), normal_two_sided_p(s.pit_z)])
        .collect();
    let d = benjamini_hochberg(&ps, 0.05);
    for (k, s) in out.iter_mut().enumerate() {
        s.significant = d[2 * k] || d[2 * k + 1];
    }
    out
}

/// Histogram of the PIT values of valid zones in `bins` bins (fractions; flat at `1/bins` when
/// the model is right).
pub fn pit_histogram(recs: &[ZoneRecord], bins: usize) -> Vec<f64> {
    let mut h = vec![0.0; bins];
    let mut n = 0.0;
    for r in recs {
        if r.fit.pit.is_finite() {
            let b = ((r.fit.pit * bins as f64) as usize).min(bins - 1);
            h[b] += 1.0;
            n += 1.0;
        }
    }
    if n > 0.0 {
        h.iter_mut().for_each(|x| *x /= n);
    }
    h
}

/// Per-zone maps over the grid: mean dropout excess and mean PIT − ½.
pub fn zone_maps(recs: &[ZoneRecord], zones: usize) -> (Vec<f64>, Vec<f64>) {
    let mut ex = vec![0.0; zones];
    let mut ne = vec![0.0; zones];
    let mut pit = vec![0.0; zones];
    let mut np = vec![0.0; zones];
    for r in recs.iter().filter(|r| r.zone < zones) {
        ex[r.zone] += f64::from(u8::from(r.dropped)) - r.fit.p_drop;
        ne[r.zone] += 1.0;
        if r.fit.pit.is_finite() {
            pit[r.zone] += r.fit.pit - 0.5;
            np[r.zone] += 1.0;
        }
    }
    let div = |v: Vec<f64>, n: Vec<f64>| {
        v.iter()
            .zip(&n)
            .map(|(a, b)| if *b > 0.0 { a / b } else { 0.0 })
            .collect()
    };
    (div(ex, ne), div(pit, np))
}

/// Held-out fit metrics.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct FitMetrics {
    /// Mean NLL per zone, nats.
    pub heldout_nll_per_zone: f64,
    /// Mean squared error of the dropout probability.
    pub dropout_brier: f64,
    /// Mean |real − predicted median| over zones valid in both, metres.
    pub depth_mae_m: f64,
}

/// Metrics of `recs`.
pub fn metrics(recs: &[ZoneRecord]) -> FitMetrics {
    let n = recs.len().max(1) as f64;
    let nll = recs.iter().map(|r| r.fit.nll).sum::<f64>() / n;
    let brier = recs
        .iter()
        .map(|r| (f64::from(u8::from(r.dropped)) - r.fit.p_drop).powi(2))
        .sum::<f64>()
        / n;
    let res: Vec<f64> = recs
        .iter()
        .map(|r| r.fit.residual_m)
        .filter(|x| x.is_finite())
        .collect();
    FitMetrics {
        heldout_nll_per_zone: nll,
        dropout_brier: brier,
        depth_mae_m: res.iter().map(|x| x.abs()).sum::<f64>() / res.len().max(1) as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(dropped: bool, p_drop: f64, pit: f64, x: f64) -> ZoneRecord {
        ZoneRecord {
            zone: 0,
            cov: [x; 8],
            fit: ZoneFit {
                nll: 1.0,
                p_drop,
                pit,
                residual_m: if dropped { f64::NAN } else { 0.1 },
            },
            dropped,
        }
    }

    #[test]
    fn slice_flags_excess_dropout_and_metrics_hand_computed() {
        // 200 zones: the upper half of the covariate drops every time though π = 0.1.
        let recs: Vec<ZoneRecord> = (0..200)
            .map(|i| {
                if i >= 100 {
                    rec(true, 0.1, f64::NAN, i as f64)
                } else {
                    rec(false, 0.1, 0.5, i as f64)
                }
            })
            .collect();
        let s = slices(&recs, 2);
        let range = &s[0];
        assert_eq!(range.n, 100);
        assert!((range.dropout_excess + 0.1).abs() < 1e-12);
        assert!(s[1].significant && (s[1].dropout_excess - 0.9).abs() < 1e-12);
        let m = metrics(&recs[..2]);
        assert!((m.dropout_brier - 0.01).abs() < 1e-12);
        assert!((m.depth_mae_m - 0.1).abs() < 1e-12);
        let h = pit_histogram(&recs, 4);
        assert_eq!(h, vec![0.0, 0.0, 1.0, 0.0]);
    }

    #[test]
    fn covariates_without_spread_are_not_sliced() {
        // The same zones with the third covariate constant (material on unlabelled frames).
        let recs: Vec<ZoneRecord> = (0..200)
            .map(|i| {
                let mut r = rec(i >= 100, 0.1, 0.5, i as f64);
                r.cov[2] = 0.0;
                r
            })
            .collect();
        let s = slices(&recs, 4);
        assert!(s.iter().all(|x| x.covariate != Covariate::ALL[2]));
        assert_eq!(s.len(), 4 * (Covariate::ALL.len() - 1));
    }

    #[test]
    fn varies_looks_at_every_zone_of_every_frame() {
        use crate::sim::covariates::ZoneCovariates;
        let frame = |material: f32, t_s: f64| Prepared {
            rows: 1,
            cols: 2,
            draws: Vec::new(),
            k: 0,
            cov: vec![
                ZoneCovariates {
                    mean_m: 1.0,
                    ..Default::default()
                },
                ZoneCovariates {
                    mean_m: 2.0,
                    nonlambertian_fraction: material,
                    ..Default::default()
                },
            ],
            draw_cov: Vec::new(),
            real: vec![None, None],
            t_s,
        };
        let unlabelled = [frame(0.0, 0.0), frame(0.0, 0.0)];
        assert!(varies(&unlabelled, Covariate::Range));
        assert!(!varies(&unlabelled, Covariate::Material));
        assert!(!varies(&unlabelled, Covariate::Time));
        // One zone of the second frame differs: the covariate varies.
        let labelled = [frame(0.0, 0.0), frame(0.5, 1.0)];
        assert!(varies(&labelled, Covariate::Material) && varies(&labelled, Covariate::Time));
        assert!(!varies(&[], Covariate::Range));
    }
}
