//! The leave-one-out benchmark of physics outside the library (`depthor gap-bench
//! --leave-one-out`, docs/gap.md): each effect in turn is hidden in a "real" recording (at a
//! multiple of its unit) and removed from the tool's candidates (`SelectOptions::exclude`), so
//! the library lacks the physics. The tool should then fit a `learned` curve of the effect's kind
//! (loss, bias or noise) over its covariate ([`super::select::Ctx::fit_learned`]) and improve the
//! held-out NLL with it.

use super::bench::{at_size, run_case, Case, SceneSet};
use super::flexible::LEARNED;
use super::{GapError, GapOptions};
use crate::scene::SceneFrame;
use crate::sim::learned::{TermCovariate, TermKind};
use crate::sim::SimConfig;

/// The effects left out in turn, with what their residual changes and the covariate it lies
/// along.
pub const LEFT_OUT: [(&str, TermKind, TermCovariate); 6] = [
    ("range_dropout", TermKind::Dropout, TermCovariate::Range),
    ("dark_dropout", TermKind::Dropout, TermCovariate::Brightness),
    ("border_dropout", TermKind::Dropout, TermCovariate::Radius),
    ("range_bias", TermKind::Bias, TermCovariate::Range),
    ("radial_distance", TermKind::Bias, TermCovariate::Radius),
    ("range_noise", TermKind::Noise, TermCovariate::Range),
];

/// The outcome of one left-out case.
#[derive(Clone, Debug, PartialEq)]
pub struct LooResult {
    /// Case label.
    pub label: String,
    /// The effect hidden and left out.
    pub effect: &'static str,
    /// What its residual changes.
    pub kind: TermKind,
    /// Its covariate.
    pub expected: TermCovariate,
    /// The learned curve's kind and covariate, when one was accepted.
    pub learned_on: Option<(TermKind, TermCovariate)>,
    /// The learned finding's held-out gain, nats per zone.
    pub learned_gain: Option<f64>,
    /// Every effect named.
    pub named: Vec<String>,
}

impl LooResult {
    /// A learned curve of the right kind over the right covariate that improves the held-out
    /// NLL.
    pub fn right(&self) -> bool {
        self.learned_on == Some((self.kind, self.expected))
            && self.learned_gain.is_some_and(|g| g > 0.0)
    }
}

/// Runs the left-out cases on `scenes` at `size` × each effect's unit, `repeats` recordings each
/// (seeds from `seed` and the label); `log` gets each case's label and selection log.
pub fn run(
    scenes: &[SceneFrame],
    base: &SimConfig,
    opts: &GapOptions,
    (size, repeats, seed): (f64, usize, u64),
    log: &mut dyn FnMut(&str, &[String]),
) -> Result<Vec<LooResult>, GapError> {
    let mut out = Vec::new();
    for r in 0..repeats {
        for (effect, kind, expected) in LEFT_OUT {
            let label = format!("loo:{effect}@{size}x#{r}");
            let case = Case {
                label: label.clone(),
                hidden: vec![at_size(effect, size)],
                size,
                outside: false,
                scenes: SceneSet::Sim,
            };
            let mut o = opts.clone();
            o.select.exclude = vec![effect.to_string()];
            let (res, a) = run_case(
                scenes,
                base,
                &case,
                &o,
                super::bench::case_seed(seed, &label),
            )?;
            log(&label, &a.selection.log);
            let learned = a.selection.findings.iter().find(|f| f.effect == LEARNED);
            out.push(LooResult {
                label,
                effect,
                kind,
                expected,
                learned_on: learned
                    .and_then(|f| f.curve.as_ref())
                    .map(|t| (t.kind, t.on)),
                learned_gain: learned.map(|f| f.heldout_gain),
                named: res.named,
            });
        }
    }
    Ok(out)
}

/// Markdown table of `results` and the share of cases with a learned curve over the right
/// covariate that improves the held-out NLL.
pub fn table(results: &[LooResult]) -> String {
    let mut s = String::from(
        "| case | left out | its kind and covariate | named | learned | learned gain (nats/zone) | right |\n|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        s.push_str(&format!(
            "| {} | {} | {:?} / {} | {} | {} | {} | {} |\n",
            r.label,
            r.effect,
            r.kind,
            r.expected.name(),
            if r.named.is_empty() {
                "—".into()
            } else {
                r.named.join(", ")
            },
            r.learned_on
                .map_or("—".into(), |(k, c)| format!("{k:?} / {}", c.name())),
            r.learned_gain.map_or("—".into(), |g| format!("{g:.4}")),
            if r.right() { "yes" } else { "no" },
        ));
    }
    let right = results.iter().filter(|r| r.right()).count();
    s.push_str(&format!(
        "\nLearned curve of the right kind over the right covariate with a positive held-out gain: {right} of {} ({:.0} %).\n",
        results.len(),
        100.0 * right as f64 / results.len().max(1) as f64
    ));
    s
}
