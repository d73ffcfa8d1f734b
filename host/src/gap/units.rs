//! Unit ("1×") sizes of the benchmark's effects, measured: for each effect, the smallest size at
//! which the gap tool names it in at least half of the trials, on rendered scenes whose seeds are
//! disjoint from the benchmark's (`depthor gap-bench --calibrate-units`). The result is committed
//! as `host/data/gap_units.json` (with the command that produced it) and compiled in;
//! [`start_unit`], the old hand estimates (each effect's `EffectFit::start_unit`), is only where
//! the calibration ladder starts (and the fallback for an effect the table lacks). A name outside
//! the library is an error ([`UnknownEffect`]) everywhere here.

use std::collections::BTreeMap;
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use super::bench::{run_case, Case, SceneSet};
use super::effects::{by_name, UnknownEffect};
use super::{GapError, GapOptions};
use crate::scene::SceneFrame;
use crate::sim::SimConfig;

/// Hand estimate of effect `name`'s minimum detectable size with ~20 held-out 8×8 frames
/// (`EffectFit::start_unit`): the calibration ladder's starting point (the first continuous
/// parameter, `calibration_shift`'s frame probability, is the one whose recovery is scored;
/// integer parameters are kept).
pub fn start_unit(name: &str) -> Result<Vec<f64>, UnknownEffect> {
    Ok(by_name(name)?.start_unit.to_vec())
}

/// One effect's calibrated unit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibratedUnit {
    /// Parameters at 1× (in `EffectFit::params` order).
    pub params: Vec<f64>,
    /// 1× as a multiple of [`start_unit`].
    pub multiple: f64,
    /// Every rung tried: (multiple of the start, detections, trials run).
    pub ladder: Vec<(f64, usize, usize)>,
    /// False when no rung up to the parameter's bound reached the detection threshold (then
    /// `multiple` is the largest rung tried).
    pub bracketed: bool,
    /// Expected held-out gain (nats) of the effect at 1× on the calibration's scenes
    /// ([`super::power::reference_gains`], the mean over the reference scene sets): what a
    /// recording must offer for the tool to name it in half of the trials
    /// ([`super::power::detection_limits`]). Absent in tables written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_gain_nats: Option<f64>,
}

/// `host/data/gap_units.json`: the calibrated units and how they were obtained.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct UnitTable {
    /// The command that wrote the table.
    pub command: String,
    /// Frames per recording (cross-fitted: each half fits, the other half scores).
    pub frames: usize,
    /// Trials per rung (each on its own scene set).
    pub trials: usize,
    /// First scene seed (trial `t` renders seeds `seed + t·frames …`).
    pub seed: u64,
    /// Image size.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Monte-Carlo draws per frame.
    pub draws: usize,
    /// Detection rate a rung must reach.
    pub threshold: f64,
    /// Geometric ratio between rungs before the refinement.
    pub step: f64,
    /// Log-bisection steps after the bracket.
    pub refine: usize,
    /// Wall time of the calibration, seconds.
    pub wall_s: f64,
    /// Per effect.
    pub units: BTreeMap<String, CalibratedUnit>,
    /// The command that added the reference gains (`depthor gap-bench --reference-gains`;
    /// empty when the table has none).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub reference_command: String,
}

/// The committed table (`host/data/gap_units.json`); empty when it does not parse.
pub fn calibrated() -> &'static UnitTable {
    static T: OnceLock<UnitTable> = OnceLock::new();
    T.get_or_init(|| {
        serde_json::from_str(include_str!("../../data/gap_units.json")).unwrap_or_default()
    })
}

/// Unit ("1×") size of effect `name`: the calibrated one, or [`start_unit`] when the table lacks
/// it.
pub fn unit_size(name: &str) -> Result<Vec<f64>, UnknownEffect> {
    let start = start_unit(name)?;
    Ok(calibrated()
        .units
        .get(name)
        .map_or(start, |u| u.params.clone()))
}

/// `unit` × `multiple` for the continuous parameters, clamped to their bounds (integer
/// parameters kept).
pub fn scale(name: &str, unit: &[f64], multiple: f64) -> Result<Vec<f64>, UnknownEffect> {
    let c = by_name(name)?;
    Ok(unit
        .iter()
        .zip(c.params)
        .map(|(v, s)| {
            if s.integer {
                *v
            } else {
                (v * multiple).clamp(s.lo, s.hi)
            }
        })
        .collect())
}

/// The largest multiple of `unit` before a continuous parameter of `name` reaches its bound.
pub fn max_multiple(name: &str, unit: &[f64]) -> Result<f64, UnknownEffect> {
    Ok(unit
        .iter()
        .zip(by_name(name)?.params)
        .filter(|(v, s)| !s.integer && v.abs() > 0.0)
        .map(|(v, s)| if *v > 0.0 { s.hi / v } else { s.lo / v })
        .fold(f64::INFINITY, f64::min))
}

/// The smallest multiple for which `passes` holds, assumed monotone: from `start`, down the
/// geometric ladder `start / stepᵏ` while it passes (at most 8 rungs) or up `start · stepᵏ`
/// (capped at `max`) until it does, then `refine` bisections in log space inside the bracket.
/// Returns the multiple and whether a passing rung was found (else the largest rung tried).
pub fn ladder_search<E>(
    start: f64,
    step: f64,
    max: f64,
    refine: usize,
    mut passes: impl FnMut(f64) -> Result<bool, E>,
) -> Result<(f64, bool), E> {
    let (mut lo, mut hi) = (None, None);
    if passes(start)? {
        hi = Some(start);
        for k in 1..=8 {
            let m = start / step.powi(k);
            if passes(m)? {
                hi = Some(m);
            } else {
                lo = Some(m);
                break;
            }
        }
    } else {
        lo = Some(start);
        let mut m = start;
        while m < max {
            m = (m * step).min(max);
            if passes(m)? {
                hi = Some(m);
                break;
            }
            lo = Some(m);
        }
    }
    let Some(mut hi) = hi else {
        return Ok((lo.unwrap_or(start), false));
    };
    if let Some(mut lo) = lo {
        for _ in 0..refine {
            let mid = (lo * hi).sqrt();
            if passes(mid)? {
                hi = mid;
            } else {
                lo = mid;
            }
        }
    }
    Ok((hi, true))
}

/// Trials out of `k` a rung must detect to pass at detection rate `threshold` (at least one).
pub fn needed(k: usize, threshold: f64) -> usize {
    ((threshold * k as f64).ceil() as usize).max(1)
}

/// One calibration rung: runs `trial(t)` for `t` in `0..k` until the outcome at `threshold` is
/// settled (enough detections, or too many misses to reach them); returns (detections, trials
/// run).
pub fn rung<E>(
    k: usize,
    threshold: f64,
    mut trial: impl FnMut(usize) -> Result<bool, E>,
) -> Result<(usize, usize), E> {
    let need = needed(k, threshold);
    let (mut hits, mut runs) = (0, 0);
    for t in 0..k {
        if hits >= need || runs - hits > k - need {
            break;
        }
        hits += usize::from(trial(t)?);
        runs += 1;
    }
    Ok((hits, runs))
}

/// Knobs of [`calibrate`].
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrateOptions {
    /// Detection rate a rung must reach (0.5: the minimum detectable size).
    pub threshold: f64,
    /// Geometric ratio between rungs.
    pub step: f64,
    /// Log-bisection steps inside the bracket.
    pub refine: usize,
    /// The analysis options (draws, selection).
    pub gap: GapOptions,
    /// Seed of the hidden measurements.
    pub seed: u64,
}

/// Calibrates the unit of each effect in `names` on `scene_sets` (one per trial; their seeds
/// must be disjoint from the benchmark's) against `base`. A rung passes when the tool names the
/// effect in ≥ `threshold` of the trials (trials stop as soon as the outcome is settled).
/// `progress` gets a line per rung.
pub fn calibrate(
    base: &SimConfig,
    scene_sets: &[Vec<SceneFrame>],
    names: &[&'static str],
    opts: &CalibrateOptions,
    mut progress: impl FnMut(&str),
) -> Result<BTreeMap<String, CalibratedUnit>, GapError> {
    let k = scene_sets.len();
    let mut out = BTreeMap::new();
    for &name in names {
        let start = start_unit(name)?;
        let mut ladder = Vec::new();
        let (multiple, bracketed) = ladder_search(
            1.0,
            opts.step,
            max_multiple(name, &start)?,
            opts.refine,
            |m| -> Result<bool, GapError> {
                let params = scale(name, &start, m)?;
                let (hits, runs) = rung(k, opts.threshold, |t| {
                    let scenes = &scene_sets[t];
                    let label = format!("calibrate:{name}@{m:.4}#{t}");
                    let case = Case {
                        label: label.clone(),
                        hidden: vec![(name, params.clone())],
                        size: m,
                        outside: false,
                        scenes: SceneSet::Sim,
                    };
                    let (r, _) = run_case(
                        scenes,
                        base,
                        &case,
                        &opts.gap,
                        super::bench::case_seed(opts.seed, &label),
                    )?;
                    Ok::<_, GapError>(r.detected())
                })?;
                progress(&format!("{name} × {m:.3}: named in {hits} of {runs}"));
                ladder.push((m, hits, runs));
                Ok(hits >= needed(k, opts.threshold))
            },
        )?;
        out.insert(
            name.to_string(),
            CalibratedUnit {
                params: scale(name, &start, multiple).unwrap_or_default(),
                multiple,
                ladder,
                bracketed,
                reference_gain_nats: None,
            },
        );
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ladder_finds_the_threshold_from_either_side() {
        // Passes from 2.7 up: from below, bracket (2, 2.83], refined twice.
        let pass = |m: f64| Ok::<bool, ()>(m >= 2.7);
        let (m, ok) = ladder_search(1.0, 2f64.sqrt(), 100.0, 2, pass).unwrap();
        assert!(ok && (2.7..2.7 * 1.2).contains(&m), "{m}");
        // From above: 1, 0.71, 0.5 pass, 0.35 fails.
        let (m, ok) = ladder_search(1.0, 2f64.sqrt(), 100.0, 0, |m| Ok::<_, ()>(m >= 0.4)).unwrap();
        assert!(ok && (m - 0.5).abs() < 1e-9, "{m}");
        // Never passes below the cap: not bracketed, the cap returned.
        let (m, ok) = ladder_search(1.0, 2.0, 5.0, 1, |_| Ok::<_, ()>(false)).unwrap();
        assert!(!ok && (m - 5.0).abs() < 1e-9);
    }

    #[test]
    fn committed_table_covers_the_library_or_falls_back() {
        for c in super::super::effects::ALL {
            let u = unit_size(c.name).unwrap();
            assert_eq!(u.len(), c.params.len(), "{}", c.name);
        }
        let u = start_unit("calibration_shift").unwrap();
        assert_eq!(scale("calibration_shift", &u, 8.0).unwrap(), vec![1.0, 1.0]);
        assert!((max_multiple("calibration_shift", &u).unwrap() - 4.0).abs() < 1e-9);
        assert_eq!(unit_size("cover_glass").unwrap_err().name, "cover_glass");
        assert!(scale("cover_glass", &u, 2.0).is_err());
        assert!(max_multiple("cover_glass", &u).is_err());
    }
}
