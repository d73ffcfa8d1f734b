//! Whether the held-out frames can show anything: the sign-flip test over `n` scored frames
//! (2-fold cross-fitting scores every frame, each under the fit of the other half) cannot return
//! a p-value below `2^−n` (all gains positive: only the identity pattern reaches the observed
//! sum), nor below `1/(permutations + 1)`. When that floor is above the level the
//! selection tests at, "no significant missing physics" would say nothing about the data, so the
//! report says "inconclusive" with the frames a conclusive run needs.
//!
//! A conclusive run that accepts nothing (or nothing more) still says what it could not have
//! missed: per effect family, the smallest effect these frames would have shown
//! ([`detection_limits`]). The calibrated unit of each family (`host/data/gap_units.json`, the
//! size the tool names in half of the 40-frame calibration recordings) comes with the expected
//! held-out log-likelihood gain `G_ref` of an effect of that size on the calibration scenes
//! ([`reference_gains`]); on a recording, the family's limit is the size whose expected gain on
//! *these* frames equals `G_ref` ([`expected_gain`]). The expected gain sums over the frames and
//! zones the recording has and reads the covariates where the family acts, so it scales the
//! calibrated limit to the recording's frame count (about as 1/√frames) and covariate spread (a
//! recording without dark surfaces cannot show `dark_dropout`): the sign-flip test's z grows as
//! the square root of the summed gain, so equal expected gains give equal power.

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;

use super::effects::{by_name, library, ALL};
use super::likelihood::{Density, Draw};
use super::model::{eval_frame, scenarios, transform, Prepared, T3_SCALE_OF_GAUSSIAN};
use super::units::{calibrated, max_multiple, needed, scale, unit_size};
use crate::rng::Rng;
use crate::sim::SimConfig;

/// The power of one run's held-out test, as `report.json` carries it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Power {
    /// Whether the run could have found an effect: it found one, or the smallest achievable p
    /// is at or below the level.
    pub conclusive: bool,
    /// Frames scored by a fit that did not see them (every frame: each half is held out from
    /// the other half's fit).
    pub heldout_frames: usize,
    /// Smallest p-value the sign-flip test can return with these frames.
    pub min_achievable_p: f64,
    /// Level the first test of a selection round must reach (α/2).
    pub level: f64,
    /// Frames in the recording for the smallest achievable p to reach the level.
    pub frames_needed: usize,
}

impl Power {
    /// Power of a run with `heldout` scored frames, `permutations` sign patterns and test
    /// level `level`; `found`: whether the run accepted any effect.
    pub fn of(heldout: usize, permutations: usize, level: f64, found: bool) -> Power {
        let floor_mc = 1.0 / (permutations as f64 + 1.0);
        let min_p = 0.5f64.powi(heldout.min(1000) as i32).max(floor_mc);
        // Smallest n with 2^−n ≤ level; every frame is scored.
        let mut n = 0usize;
        while 0.5f64.powi(n as i32) > level && n < 1000 {
            n += 1;
        }
        Power {
            conclusive: found || min_p <= level,
            heldout_frames: heldout,
            min_achievable_p: min_p,
            level,
            frames_needed: n,
        }
    }

    /// The first line of `report.md` when the run is inconclusive.
    pub fn headline(&self) -> Option<String> {
        (!self.conclusive).then(|| {
            format!(
                "**Inconclusive**: with {} held-out frames the sign-flip test cannot reach p ≤ {} \
                 (smallest achievable p = {:.4}); nothing can be called significant. Record at \
                 least {} frames.",
                self.heldout_frames, self.level, self.min_achievable_p, self.frames_needed
            )
        })
    }
}

/// Pseudo-observations per frame in [`expected_gain`].
pub const PSEUDO_PER_FRAME: usize = 4;

/// Expected held-out NLL gain (nats, summed over `frames`) of `with` over `null` when the real
/// zones follow `with`: per frame, [`PSEUDO_PER_FRAME`] pseudo-observations, each one draw of the
/// frame under `with` (its frame scenario drawn by weight, its survival probability and added
/// noise sampled), scored under `null` and `with` by the frame's other draws (the draw itself
/// left out). Both configurations must hold the effects of `base` (the draws' configuration);
/// the same `seed` gives the same random numbers for any `with` (common random numbers, so the
/// gain is smooth in an effect's size).
pub fn expected_gain(
    density: &Density,
    base: &SimConfig,
    frames: &[Prepared],
    null: &SimConfig,
    with: &SimConfig,
    seed: u64,
) -> f64 {
    let sc = scenarios(with, base);
    frames
        .par_iter()
        .enumerate()
        .filter(|(_, prep)| prep.k >= 2)
        .map(|(f, prep)| {
            let z_n = prep.zones();
            let mut g = 0.0;
            for r in 0..PSEUDO_PER_FRAME {
                let mut rng = Rng::derive(seed ^ 0x90_3E41, (f as u64) << 8 | r as u64);
                let j = rng.below(prep.k as u64) as usize;
                let mut u = rng.f64();
                let shift = sc
                    .iter()
                    .find(|(w, _)| {
                        u -= w;
                        u < 0.0
                    })
                    .map_or([0, 0], |s| s.1);
                let drawn = transform(with, base, prep, shift);
                let real: Vec<Option<f32>> = drawn[j * z_n..(j + 1) * z_n]
                    .iter()
                    .map(|x: &Draw| {
                        let (keep, n) = (rng.f32(), rng.normal());
                        (x.p > 0.0 && keep < x.p)
                            .then(|| (x.d + x.s / T3_SCALE_OF_GAUSSIAN * n).max(1e-3))
                    })
                    .collect();
                let loo = Prepared {
                    draws: without_draw(&prep.draws, j, z_n),
                    draw_cov: without_draw(&prep.draw_cov, j, z_n),
                    k: prep.k - 1,
                    real,
                    ..prep.clone()
                };
                g += eval_frame(density, null, base, &loo, false).nll
                    - eval_frame(density, with, base, &loo, false).nll;
            }
            g / PSEUDO_PER_FRAME as f64
        })
        .sum()
}

/// The draw-major per-zone values `v` (`zones` per draw) without draw `j`.
fn without_draw<T: Copy>(v: &[T], j: usize, zones: usize) -> Vec<T> {
    v.iter()
        .enumerate()
        .filter(|(i, _)| i / zones != j)
        .map(|(_, x)| *x)
        .collect()
}

/// `model` with effect `name` at `multiple` × its calibrated unit.
fn with_effect(model: &SimConfig, name: &str, multiple: f64) -> Option<SimConfig> {
    let v = scale(name, &unit_size(name).ok()?, multiple).ok()?;
    let mut m = model.clone();
    library(name).set(&mut m, Some(&v));
    Some(m)
}

/// [`expected_gain`] of every library effect (those `base` lacks) at its calibrated unit on
/// `frames`, prepared under `base`: the reference of [`detection_limits`], computed on the
/// calibration's scenes and committed beside the units (`reference_gain_nats`).
pub fn reference_gains(
    density: &Density,
    base: &SimConfig,
    frames: &[Prepared],
    seed: u64,
) -> BTreeMap<String, f64> {
    ALL.iter()
        .filter(|c| !c.enabled(base))
        .filter_map(|c| {
            let with = with_effect(base, c.name, 1.0)?;
            Some((
                c.name.to_string(),
                expected_gain(density, base, frames, base, &with, seed),
            ))
        })
        .collect()
}

/// Writes into `table` each unit's `reference_gain_nats`: the mean of [`reference_gains`] over
/// `scene_sets` (the calibration's scenes, measured by `base` without any effect, prepared with
/// `opts`' draws and seed), and the command that did it.
pub fn add_reference_gains(
    table: &mut super::units::UnitTable,
    base: &SimConfig,
    scene_sets: &[Vec<crate::scene::SceneFrame>],
    opts: &super::GapOptions,
    command: &str,
) -> Result<(), super::GapError> {
    let mut sum: BTreeMap<String, f64> = BTreeMap::new();
    for (t, scenes) in scene_sets.iter().enumerate() {
        let data = super::bench::make_real(scenes, base, 0x5EF_0000 + t as u64, None)?;
        let frames = super::model::prepare(base, &data, opts.draws.max(2), opts.seed, &|| {})?;
        let density = Density {
            range_m: f64::from(data.max_range_m).max(1.0),
            ..opts.select.density
        };
        for (k, g) in reference_gains(&density, base, &frames, opts.seed) {
            *sum.entry(k).or_default() += g;
        }
    }
    for (k, u) in &mut table.units {
        u.reference_gain_nats = sum.get(k).map(|g| g / scene_sets.len().max(1) as f64);
    }
    table.reference_command = command.to_string();
    Ok(())
}

/// The smallest effect of one family a run could have detected, as `report.json` carries it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FamilyLimit {
    /// Effect family (library name).
    pub effect: String,
    /// Its parameters at the limit (the calibrated unit's non-zero continuous parameters scaled
    /// by `multiple`); empty when not `detectable`.
    pub params: BTreeMap<String, f64>,
    /// The limit as a multiple of the family's calibrated unit (40 rendered frames).
    pub multiple: f64,
    /// Expected held-out gain of an effect at the limit on these frames, nats (the calibration
    /// reference: what the tool needs to name it in half of the recordings).
    pub expected_gain_nats: f64,
    /// The calibrated unit was the smallest size tried (named at every rung), so the limit is
    /// an upper bound.
    pub upper_bound: bool,
    /// Whether an effect within the family's parameter bounds reaches the reference gain here.
    pub detectable: bool,
    /// The sentence of `report.md` ("no range_bias larger than offset_m = 0.0041 in these 24
    /// frames").
    pub statement: String,
}

/// The family's parameters at `multiple` of its unit, as `field → value` (non-zero continuous
/// parameters only).
fn limit_params(name: &str, multiple: f64) -> BTreeMap<String, f64> {
    let (Ok(u), Some(c)) = (unit_size(name), by_name(name).ok()) else {
        return BTreeMap::new();
    };
    let v = scale(name, &u, multiple).unwrap_or_default();
    c.params
        .iter()
        .zip(v)
        .filter(|(s, x)| !s.integer && *x != 0.0)
        .map(|(s, x)| (s.field.to_string(), x))
        .collect()
}

/// Per library family that `model` (the accepted effects) and `base` lack and whose covariate
/// varies in `frames` (`candidates`), the smallest effect these frames could have shown: the
/// multiple `m` of its calibrated unit whose [`expected_gain`] on top of `model` equals its
/// reference gain (fixed-point steps `m ← m·√(G_ref / G(m))`, the gain being quadratic in a
/// small effect's size; capped at the parameters' bounds). Families without a committed
/// reference are left out.
pub fn detection_limits(
    density: &Density,
    base: &SimConfig,
    model: &SimConfig,
    frames: &[Prepared],
    candidates: &[&str],
    seed: u64,
) -> Vec<FamilyLimit> {
    let n = frames.len();
    let table = calibrated();
    candidates
        .iter()
        .filter_map(|&name| {
            let unit = table.units.get(name)?;
            let g_ref = unit.reference_gain_nats.filter(|g| *g > 0.0)?;
            let max = max_multiple(name, &unit_size(name).ok()?).ok()?;
            let gain = |m: f64| {
                with_effect(model, name, m)
                    .map_or(0.0, |w| expected_gain(density, base, frames, model, &w, seed))
            };
            let mut m = 1.0f64.min(max);
            for _ in 0..4 {
                let g = gain(m);
                let next = if g > 0.0 {
                    m * (g_ref / g).sqrt()
                } else {
                    8.0 * m
                };
                m = next.clamp(m / 8.0, 8.0 * m).min(max);
            }
            // Within the bounds, or the largest size still falls short of the reference.
            let detectable = m < max || gain(max) >= g_ref;
            let upper_bound = unit
                .ladder
                .iter()
                .all(|r| r.1 >= needed(table.trials, table.threshold));
            let params = if detectable {
                limit_params(name, m)
            } else {
                BTreeMap::new()
            };
            let shown: Vec<String> = params.iter().map(|(k, v)| format!("{k} = {v:.4}")).collect();
            let statement = if detectable {
                format!(
                    "no {name} larger than {} ({m:.2}× its calibrated detection limit{}) in these {n} frames",
                    shown.join(", "),
                    if upper_bound { ", an upper bound" } else { "" }
                )
            } else {
                format!("{name}: not detectable in these {n} frames at any size within its bounds")
            };
            Some(FamilyLimit {
                effect: name.to_string(),
                params,
                multiple: m,
                expected_gain_nats: g_ref,
                upper_bound,
                detectable,
                statement,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_heldout_frames_cannot_reach_the_level() {
        let p = Power::of(4, 1999, 0.025, false);
        assert!(!p.conclusive);
        assert_eq!(p.min_achievable_p, 1.0 / 16.0);
        // 2^−6 = 0.0156 ≤ 0.025 < 2^−5: six frames.
        assert_eq!(p.frames_needed, 6);
        assert!(p.headline().unwrap().contains("6 frames"));
    }

    #[test]
    fn enough_frames_or_a_finding_is_conclusive() {
        assert!(Power::of(6, 1999, 0.025, false).conclusive);
        assert!(Power::of(24, 1999, 0.025, false).conclusive);
        assert!(Power::of(3, 1999, 0.025, true).conclusive);
        assert!(Power::of(24, 1999, 0.025, true).headline().is_none());
        // Too few sign patterns also bound p from below.
        let few = Power::of(24, 20, 0.025, false);
        assert!(!few.conclusive && few.min_achievable_p > 0.04);
    }
}
