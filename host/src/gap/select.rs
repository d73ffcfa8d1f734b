//! Selection: fit each candidate effect on the training frames, accept it only if its held-out
//! gain is significantly positive (paired sign-flip test over held-out frames, Holm across the
//! candidates of a round), refit the accepted effects jointly, prune, and flag confounded pairs.

use std::collections::BTreeMap;

use super::effects::{self, Candidate, LIBRARY};
use super::likelihood::Density;
use super::model::{eval_frame, frame_nlls, Prepared};
use super::stats::{fixed_sequence, grid_golden_min, holm, sign_flip_p};
use crate::sim::SimConfig;

/// Knobs of the selection.
#[derive(Clone, Debug, PartialEq)]
pub struct SelectOptions {
    /// Family-wise level of each round's Holm procedure (and of pruning).
    pub alpha: f64,
    /// Smallest held-out gain (nats per zone) worth a finding.
    pub min_gain: f64,
    /// Sign patterns of the randomisation test.
    pub permutations: usize,
    /// Most effects accepted.
    pub max_effects: usize,
    /// Golden-section steps per parameter.
    pub iters: usize,
    /// Grid points scanned per parameter before the golden-section refinement.
    pub grid: usize,
    /// Predictive density constants.
    pub density: Density,
}

impl Default for SelectOptions {
    /// α = 0.05, gain ≥ 0.002 nats/zone, 1999 sign patterns, ≤ 4 effects, a 16-point grid then
    /// 12 golden-section steps.
    fn default() -> Self {
        SelectOptions {
            alpha: 0.05,
            min_gain: 0.002,
            permutations: 1999,
            max_effects: 4,
            iters: 12,
            grid: 16,
            density: Density::default(),
        }
    }
}

/// One accepted effect.
#[derive(Clone, Debug, PartialEq)]
pub struct Finding {
    /// Effect name.
    pub effect: String,
    /// Fitted parameters.
    pub params: BTreeMap<String, f64>,
    /// Likelihood-ratio intervals (≈ 95 %) of the continuous parameters, others held fixed.
    pub ci: BTreeMap<String, [f64; 2]>,
    /// Held-out gain of the final model over the final model without this effect, nats per zone.
    pub heldout_gain: f64,
    /// p-value of that gain (sign-flip over held-out frames).
    pub p_value: f64,
    /// Fraction of held-out zones whose NLL changes by more than 0.05 nats with the effect.
    pub zones_affected: f64,
    /// Effects that explain the same residual.
    pub confounded_with: Vec<String>,
}

/// A confounded pair.
#[derive(Clone, Debug, PartialEq)]
pub struct Confound {
    /// Accepted effect.
    pub kept: String,
    /// Look-alike.
    pub other: String,
    /// Share of the kept effect's held-out gain the look-alike reaches in its place.
    pub share: f64,
    /// What data would separate them.
    pub separate_with: String,
}

/// The result of selection.
#[derive(Clone, Debug)]
pub struct Selection {
    /// Base plus the accepted effects, fitted.
    pub model: SimConfig,
    /// Accepted effects, most important first.
    pub findings: Vec<Finding>,
    /// Confounded pairs.
    pub confounds: Vec<Confound>,
    /// Round-by-round log: candidate, gain, p.
    pub log: Vec<String>,
}

/// The frames, their split and the base configuration.
pub struct Ctx<'a> {
    /// Density constants.
    pub density: Density,
    /// Base configuration (what the draws were simulated with).
    pub base: &'a SimConfig,
    /// Prepared frames.
    pub frames: &'a [Prepared],
    /// Training frame indices.
    pub train: Vec<usize>,
    /// Held-out frame indices.
    pub test: Vec<usize>,
}

impl Ctx<'_> {
    /// Sum of training NLL.
    pub fn train_nll(&self, m: &SimConfig) -> f64 {
        frame_nlls(&self.density, m, self.base, self.frames, &self.train)
            .iter()
            .sum()
    }

    /// Per-frame held-out NLL.
    pub fn test_nlls(&self, m: &SimConfig) -> Vec<f64> {
        frame_nlls(&self.density, m, self.base, self.frames, &self.test)
    }

    /// Zones in the held-out frames.
    pub fn test_zones(&self) -> f64 {
        self.test
            .iter()
            .map(|&f| self.frames[f].zones())
            .sum::<usize>() as f64
    }

    /// Fits effect `c` in `model` (switched on if off), other effects fixed: per continuous
    /// parameter a grid scan then golden-section refinement ([`grid_golden_min`]).
    pub fn fit_one(&self, model: &SimConfig, c: &Candidate, opts: &SelectOptions) -> SimConfig {
        let mut m = model.clone();
        let mut v = if effects::enabled(&m, c.name) {
            effects::get(&m, c.name)
        } else {
            c.params
                .iter()
                .map(|s| {
                    if s.integer {
                        s.lo
                    } else {
                        0.0f64.clamp(s.lo, s.hi)
                    }
                })
                .collect()
        };
        let ints: Vec<usize> = (0..c.params.len())
            .filter(|&i| c.params[i].integer)
            .collect();
        let conts: Vec<usize> = (0..c.params.len())
            .filter(|&i| !c.params[i].integer)
            .collect();
        let int_values: Vec<f64> = match ints.first() {
            Some(&i) => {
                let s = c.params[i];
                (s.lo as i64..=s.hi as i64).map(|x| x as f64).collect()
            }
            None => vec![f64::NAN],
        };
        let sweeps = if conts.len() > 1 { 3 } else { 1 };
        let mut best: Option<(f64, Vec<f64>)> = None;
        for iv in int_values {
            let mut w = v.clone();
            if let Some(&i) = ints.first() {
                w[i] = iv;
            }
            let mut fbest = f64::INFINITY;
            for _ in 0..sweeps {
                for &i in &conts {
                    let s = c.params[i];
                    let (x, fx) = grid_golden_min(
                        |x| {
                            let mut t = w.clone();
                            t[i] = x;
                            effects::set(&mut m, c.name, Some(&t));
                            self.train_nll(&m)
                        },
                        s.lo,
                        s.hi,
                        opts.grid,
                        opts.iters,
                    );
                    w[i] = x;
                    fbest = fx;
                }
            }
            if best.as_ref().is_none_or(|b| fbest < b.0) {
                best = Some((fbest, w));
            }
        }
        if let Some((_, w)) = best {
            v = w;
        }
        effects::set(&mut m, c.name, Some(&v));
        m
    }

    /// Refits the effects `names` of `model` jointly (coordinate descent, two sweeps).
    pub fn refit(
        &self,
        model: &SimConfig,
        names: &[&'static str],
        opts: &SelectOptions,
    ) -> SimConfig {
        let mut m = model.clone();
        let sweeps = if names.len() > 1 { 2 } else { 1 };
        for _ in 0..sweeps {
            for n in names {
                if let Some(c) = effects::candidate(n) {
                    m = self.fit_one(&m, c, opts);
                }
            }
        }
        m
    }

    /// Held-out gain per zone and its p-value, from per-frame NLLs before and after.
    pub fn gain(&self, before: &[f64], after: &[f64], perms: usize, seed: u64) -> (f64, f64) {
        let g: Vec<f64> = before.iter().zip(after).map(|(b, a)| b - a).collect();
        (
            g.iter().sum::<f64>() / self.test_zones(),
            sign_flip_p(&g, perms, seed),
        )
    }
}

/// Runs forward selection, joint refits, pruning and the confounding check.
pub fn select(ctx: &Ctx<'_>, opts: &SelectOptions, mut progress: impl FnMut(&str)) -> Selection {
    let mut model = ctx.base.clone();
    let mut accepted: Vec<&'static str> = Vec::new();
    let mut log = Vec::new();
    let mut cur = ctx.test_nlls(&model);
    let pool: Vec<&'static Candidate> = LIBRARY
        .iter()
        .filter(|c| !effects::enabled(ctx.base, c.name))
        .collect();
    // First-round (solo) gain of every candidate, for the confounding check.
    let mut solo: BTreeMap<&'static str, (f64, bool)> = BTreeMap::new();
    for round in 0..opts.max_effects {
        let cands: Vec<&&Candidate> = pool
            .iter()
            .filter(|c| !accepted.contains(&c.name))
            .collect();
        if cands.is_empty() {
            break;
        }
        let mut res = Vec::new();
        let mut train_gain = Vec::new();
        let train_cur = ctx.train_nll(&model);
        for c in &cands {
            progress(&format!("round {} · fitting {}", round + 1, c.name));
            let m = ctx.fit_one(&model, c, opts);
            let tg = train_cur - ctx.train_nll(&m);
            let after = ctx.test_nlls(&m);
            let (g, p) = ctx.gain(&cur, &after, opts.permutations, 17 + round as u64);
            log.push(format!(
                "round {} {:<18} gain {:+.4} nats/zone  p {:.4}  (training gain {:+.1} nats)",
                round + 1,
                c.name,
                g,
                p,
                tg
            ));
            res.push((c.name, m, g, p));
            train_gain.push(tg);
        }
        let ps: Vec<f64> = res.iter().map(|r| r.3).collect();
        // The gate: Holm at α/2 (no candidate favoured) or fixed-sequence at α/2 in the order of
        // training gain (set on the training frames, before any held-out p is seen: powerful for
        // an effect confined to a few frames, whose p cannot reach Holm's α/m). Bonferroni over
        // the two keeps the family-wise error ≤ α.
        let mut order: Vec<usize> = (0..res.len()).collect();
        order.sort_by(|&a, &b| train_gain[b].total_cmp(&train_gain[a]));
        let fixed = fixed_sequence(&ps, &order, opts.alpha / 2.0);
        let sig: Vec<bool> = holm(&ps, opts.alpha / 2.0)
            .into_iter()
            .zip(fixed)
            .map(|(a, b)| a || b)
            .collect();
        if round == 0 {
            for (r, &s) in res.iter().zip(&sig) {
                solo.insert(r.0, (r.2, s && r.2 >= opts.min_gain));
            }
        }
        // Gatekeeping: the gate decides whether anything is missing (family-wise error ≤ α); the
        // effect accepted is then the one with the largest held-out gain among those significant
        // on their own, so a weaker look-alike with a smaller p-value does not win attribution.
        if !res
            .iter()
            .zip(&sig)
            .any(|(r, &s)| s && r.2 >= opts.min_gain)
        {
            break;
        }
        let best = res
            .iter()
            .filter(|r| r.3 <= opts.alpha && r.2 >= opts.min_gain)
            .max_by(|a, b| a.2.total_cmp(&b.2));
        let Some(b) = best else { break };
        accepted.push(b.0);
        model = ctx.refit(&b.1, &accepted, opts);
        cur = ctx.test_nlls(&model);
    }
    // Prune: drop effects whose conditional held-out gain is no longer significant.
    let mut cond: BTreeMap<&'static str, (f64, f64, SimConfig)> = BTreeMap::new();
    let mut k = 0;
    while k < accepted.len() {
        let name = accepted[k];
        progress(&format!("pruning {name}"));
        let rest: Vec<&'static str> = accepted.iter().copied().filter(|&n| n != name).collect();
        let mut without = model.clone();
        effects::set(&mut without, name, None);
        let without = if rest.is_empty() {
            without
        } else {
            ctx.refit(&without, &rest, opts)
        };
        let (g, p) = ctx.gain(
            &ctx.test_nlls(&without),
            &cur,
            opts.permutations,
            99 + k as u64,
        );
        if p > opts.alpha || g < opts.min_gain {
            log.push(format!("pruned {name}: conditional gain {g:+.4}, p {p:.4}"));
            accepted.remove(k);
            model = without;
            cur = ctx.test_nlls(&model);
            cond.clear();
            k = 0;
            continue;
        }
        cond.insert(name, (g, p, without));
        k += 1;
    }
    // Confounding: a look-alike that, in the accepted effect's place, reaches ≥ half its gain.
    let mut confounds = Vec::new();
    for &a in &accepted {
        let Some((ga, _, without)) = cond.get(a) else {
            continue;
        };
        let base_nll = ctx.test_nlls(without);
        for (&b, &(gb, sig_b)) in &solo {
            if accepted.contains(&b) || !sig_b || gb < 0.25 * ga {
                continue;
            }
            progress(&format!("confounding {a} / {b}"));
            let Some(cb) = effects::candidate(b) else {
                continue;
            };
            let swap = ctx.fit_one(without, cb, opts);
            let (gs, _) = ctx.gain(&base_nll, &ctx.test_nlls(&swap), 0, 0);
            if gs >= 0.5 * ga {
                confounds.push(Confound {
                    kept: a.to_string(),
                    other: b.to_string(),
                    share: gs / ga,
                    separate_with: effects::separating_data(a, b),
                });
            }
        }
    }
    let mut findings: Vec<Finding> = accepted
        .iter()
        .filter_map(|&a| {
            let (g, p, without) = cond.get(a)?;
            let c = effects::candidate(a)?;
            Some(finding(ctx, opts, &model, without, c, *g, *p, &confounds))
        })
        .collect();
    findings.sort_by(|a, b| b.heldout_gain.total_cmp(&a.heldout_gain));
    Selection {
        model,
        findings,
        confounds,
        log,
    }
}

#[allow(clippy::too_many_arguments)]
fn finding(
    ctx: &Ctx<'_>,
    opts: &SelectOptions,
    model: &SimConfig,
    without: &SimConfig,
    c: &Candidate,
    gain: f64,
    p: f64,
    confounds: &[Confound],
) -> Finding {
    let v = effects::get(model, c.name);
    let f0 = ctx.train_nll(model);
    let mut params = BTreeMap::new();
    let mut ci = BTreeMap::new();
    for (i, s) in c.params.iter().enumerate() {
        params.insert(s.field.to_string(), v[i]);
        if s.integer {
            continue;
        }
        // Likelihood-ratio bound: where the training NLL rises by χ²₁(0.95)/2 = 1.92.
        let nll_at = |x: f64| {
            let mut t = v.clone();
            t[i] = x;
            let mut m = model.clone();
            effects::set(&mut m, c.name, Some(&t));
            ctx.train_nll(&m) - f0 - 1.92
        };
        let bound = |end: f64| {
            if nll_at(end) <= 0.0 {
                return end;
            }
            let (mut inside, mut outside) = (v[i], end);
            for _ in 0..14 {
                let mid = (inside + outside) / 2.0;
                if nll_at(mid) <= 0.0 {
                    inside = mid;
                } else {
                    outside = mid;
                }
            }
            (inside + outside) / 2.0
        };
        ci.insert(s.field.to_string(), [bound(s.lo), bound(s.hi)]);
    }
    let _ = opts;
    let (mut changed, mut total) = (0usize, 0usize);
    for &f in &ctx.test {
        let a = eval_frame(&ctx.density, model, ctx.base, &ctx.frames[f], true);
        let b = eval_frame(&ctx.density, without, ctx.base, &ctx.frames[f], true);
        for (x, y) in a.zones.iter().zip(&b.zones) {
            total += 1;
            changed += usize::from((x.nll - y.nll).abs() > 0.05);
        }
    }
    Finding {
        effect: c.name.to_string(),
        params,
        ci,
        heldout_gain: gain,
        p_value: p,
        zones_affected: changed as f64 / total.max(1) as f64,
        confounded_with: confounds
            .iter()
            .filter(|k| k.kept == c.name)
            .map(|k| k.other.clone())
            .collect(),
    }
}
