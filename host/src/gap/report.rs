//! The gap tool's outputs: `report.json` exactly as docs/design.md, `report.md` with one card per
//! finding, the fitted `sim_config.json`, and PNG plots.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use super::effects::{library, Covariate};
use super::localise::{pit_histogram, zone_maps, FitMetrics, Slice};
use super::Analysis;
use crate::plot::{bar_chart, line_chart, zone_heat_map, Series, PALETTE};

/// One finding of `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct FindingJson {
    /// Effect name (docs/design.md library).
    pub effect: String,
    /// Fitted parameters.
    pub params: BTreeMap<String, f64>,
    /// ≈ 95 % intervals of the continuous parameters.
    pub ci: BTreeMap<String, [f64; 2]>,
    /// Held-out gain, nats per zone.
    pub heldout_gain_nats_per_zone: f64,
    /// Fraction of held-out zones the effect changes.
    pub zones_affected: f64,
    /// Why, in words.
    pub evidence: String,
    /// Effects accepted jointly with this one (neither explains the residual alone); absent
    /// when none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub joint_with: Vec<String>,
    /// `parametric` (the library's form, `params`) or `flexible` (a curve over the family's
    /// covariate fitted better: `curve`, the `learned` term in `sim_config`).
    pub form: &'static str,
    /// The fitted curve of a flexible finding; absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub curve: Option<crate::sim::learned::Term>,
    /// The covariates the finding is attributed to (both of an inseparable pair).
    pub covariates: Vec<&'static str>,
    /// Conditional tests against correlated covariates ([`super::confound`]); absent when none
    /// was needed.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub separation: Vec<SeparationJson>,
}

/// One conditional test of `report.json` (a finding's covariate against a correlated one).
#[derive(Clone, Debug, Serialize)]
pub struct SeparationJson {
    /// The effect first chosen (the finding's name unless the other covariate won).
    pub chosen: String,
    /// Its covariate.
    pub covariate: &'static str,
    /// The correlated covariate.
    pub other: &'static str,
    /// Pearson r between them over the zones.
    pub correlation: f64,
    /// Held-out gain (nats/zone) and p of a curve over `covariate` on top of a curve over
    /// `other` (both direction-free, of the finding's kind).
    pub own_given_other: [f64; 2],
    /// Held-out gain and p of a curve over `other` on top of a curve over `covariate`.
    pub other_given_own: [f64; 2],
    /// `own`, `other` (renamed after it), `both` or `inseparable`.
    pub verdict: &'static str,
}

/// `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Findings, most important first; empty when nothing significant is missing.
    pub findings: Vec<FindingJson>,
    /// Held-out metrics of the base simulator.
    pub fit_before: FitMetrics,
    /// Held-out metrics of the fitted simulator.
    pub fit_after: FitMetrics,
    /// The fitted simulator configuration (`depthor sim --config`).
    pub sim_config: serde_json::Value,
    /// Whether the held-out frames could show an effect (`conclusive`, `heldout_frames`,
    /// `min_achievable_p`, `level`, `frames_needed`, at the top level).
    #[serde(flatten)]
    pub power: super::power::Power,
    /// Per library family not accepted, the smallest effect these frames could have shown: a
    /// null is "no effect larger than …", never a bare "nothing missing" (empty when the run is
    /// inconclusive).
    pub detection_limits: Vec<super::power::FamilyLimit>,
}

impl Report {
    /// The report of `a`.
    pub fn of(a: &Analysis) -> Report {
        let findings = a
            .selection
            .findings
            .iter()
            .map(|f| {
                let mut evidence = format!(
                    "cross-fitted held-out NLL falls by {:.4} nats/zone (sign-flip p over every frame = {:.4}, Holm-controlled) when added to the other accepted effects",
                    f.heldout_gain, f.p_value
                );
                for c in a.selection.confounds.iter().filter(|c| c.kept == f.effect) {
                    let _ = write!(
                        evidence,
                        "; confounded with {} (reaches {:.0} % of the gain in its place); to separate them record {}",
                        c.other,
                        100.0 * c.share,
                        c.separate_with
                    );
                }
                for j in a
                    .selection
                    .joints
                    .iter()
                    .filter(|j| j.effects.contains(&f.effect))
                {
                    let _ = write!(
                        evidence,
                        "; fitted jointly with {} (confounded: {}): the pair beats every single effect in its place by {:.4} nats/zone (p = {:.4})",
                        j.effects.iter().filter(|e| **e != f.effect).cloned().collect::<Vec<_>>().join(", "),
                        j.why,
                        j.gain_over_single,
                        j.p_value
                    );
                }
                let separation: Vec<SeparationJson> = a
                    .selection
                    .separations
                    .iter()
                    .filter(|s| s.named == f.effect)
                    .map(|s| {
                        let _ = write!(evidence, "; {}", s.evidence());
                        SeparationJson {
                            chosen: s.effect.clone(),
                            covariate: s.covariate.name(),
                            other: s.other.name(),
                            correlation: s.correlation,
                            own_given_other: [s.own_given_other.0, s.own_given_other.1],
                            other_given_own: [s.other_given_own.0, s.other_given_own.1],
                            verdict: s.verdict.name(),
                        }
                    })
                    .collect();
                if let Some(t) = &f.curve {
                    let shown: Vec<String> = t
                        .knots
                        .iter()
                        .zip(&t.values)
                        .map(|(k, v)| format!("{k:.2}→{v:.3}"))
                        .collect();
                    let _ = write!(
                        evidence,
                        "; its shape differs from the library's form: a {:?} curve over {} fits better ({})",
                        t.kind,
                        t.on.name(),
                        shown.join(", ")
                    );
                }
                FindingJson {
                    form: if f.curve.is_some() { "flexible" } else { "parametric" },
                    curve: f.curve.clone(),
                    joint_with: f.joint_with.clone(),
                    effect: f.effect.clone(),
                    params: f.params.clone(),
                    ci: f.ci.clone(),
                    heldout_gain_nats_per_zone: f.heldout_gain,
                    zones_affected: f.zones_affected,
                    evidence,
                    covariates: a.selection.attributed_covariates(&f.effect),
                    separation,
                }
            })
            .collect();
        Report {
            findings,
            fit_before: a.fit_before,
            fit_after: a.fit_after,
            sim_config: serde_json::to_value(&a.selection.estimate).unwrap_or_default(),
            power: a.power,
            detection_limits: a.limits.clone(),
        }
    }
}

/// Curves of one covariate: dropout excess and PIT shift per slice.
type Curve = Vec<(f64, f64)>;

fn curves(slices: &[Slice], cov: Covariate) -> (Curve, Curve) {
    let s: Vec<&Slice> = slices.iter().filter(|s| s.covariate == cov).collect();
    let x = |s: &Slice| (s.range[0] + s.range[1]) / 2.0;
    (
        s.iter().map(|s| (x(s), s.dropout_excess)).collect(),
        s.iter().map(|s| (x(s), s.pit_shift)).collect(),
    )
}

fn slice_line(s: &Slice) -> String {
    format!(
        "| {} | {:.3}–{:.3} | {} | {:+.3} (z {:+.1}) | {:+.3} (z {:+.1}) | {:+.3} |",
        s.covariate.name(),
        s.range[0],
        s.range[1],
        s.n,
        s.dropout_excess,
        s.dropout_z,
        s.pit_shift,
        s.pit_z,
        s.residual_m
    )
}

/// Why the report could not be written (each keeps the underlying message).
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// Creating the folder or writing a file.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// Serialising `report.json`.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// Drawing a plot.
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
}

/// Writes `report.json`, `report.md`, `sim_config.json` and the plots into `out`.
pub fn write(a: &Analysis, out: &Path) -> Result<(), ReportError> {
    std::fs::create_dir_all(out)?;
    let report = Report::of(a);
    std::fs::write(
        out.join("report.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    std::fs::write(out.join("sim_config.json"), a.selection.estimate.to_json())?;
    // Plots (each with its numbers beside it as .csv): per covariate, dropout excess and PIT
    // shift before (solid) and after (dashed) the fit.
    for cov in Covariate::ALL {
        let (db, pb) = curves(&a.slices_before, cov);
        let (da, pa) = curves(&a.slices_after, cov);
        let series = |label: &str, points, colour, dashed| Series {
            label: label.to_string(),
            points,
            colour,
            dashed,
        };
        line_chart(
            &out.join(format!("covariate_{}.png", cov.name())),
            &format!("real − simulated, by {}", cov.name()),
            &format!("{} (slice centre)", cov.name()),
            "dropout excess (fraction) / PIT − ½",
            &[
                series("dropout excess, before fit", db, PALETTE[0], false),
                series("dropout excess, after fit", da, PALETTE[0], true),
                series("PIT shift, before fit", pb, PALETTE[1], false),
                series("PIT shift, after fit", pa, PALETTE[1], true),
            ],
        )?;
    }
    for (tag, recs) in [("before", &a.before), ("after", &a.after)] {
        bar_chart(
            &out.join(format!("pit_{tag}.png")),
            &format!("PIT of the real zone depths under the simulator, {tag} the fit"),
            (0.0, 1.0),
            "PIT value (probability of a simulated depth ≤ the real one)",
            "fraction of valid zones",
            &pit_histogram(recs, 10),
            (0.1, "calibrated: uniform, 0.1 per bin"),
        )?;
    }
    let (rows, cols) = a.grid;
    for (tag, recs) in [("before", &a.before), ("after", &a.after)] {
        let (ex, pit) = zone_maps(recs, rows * cols);
        zone_heat_map(
            &out.join(format!("zones_dropout_{tag}.png")),
            &format!("dropout excess per zone (real − simulated), {tag} the fit"),
            "dropout excess (fraction)",
            &ex,
            rows,
            cols,
        )?;
        zone_heat_map(
            &out.join(format!("zones_pit_{tag}.png")),
            &format!("mean PIT − ½ per zone (> 0: real farther), {tag} the fit"),
            "PIT − ½",
            &pit,
            rows,
            cols,
        )?;
    }
    std::fs::write(out.join("report.md"), markdown(a, &report))?;
    Ok(())
}

fn metrics_row(name: &str, m: &FitMetrics) -> String {
    format!(
        "| {name} | {:.4} | {:.4} | {:.4} |\n",
        m.heldout_nll_per_zone, m.dropout_brier, m.depth_mae_m
    )
}

/// The Markdown report.
pub fn markdown(a: &Analysis, r: &Report) -> String {
    let mut s = String::new();
    if let Some(line) = r.power.headline() {
        let _ = writeln!(s, "{line}\n");
    }
    let _ = writeln!(s, "# Sim-to-real gap report\n");
    let _ = writeln!(
        s,
        "{} frames, 2-fold cross-fitted (fitted on the {} even frames and scored on the {} odd ones, and the reverse; the fit table and plots: the odd frames under the even frames' fit), {}×{} zones. Plots: red = dropout excess before, blue = after; orange = PIT shift before, green = after.\n",
        a.split.0 + a.split.1, a.split.0, a.split.1, a.grid.0, a.grid.1
    );
    s.push_str("| held-out fit | NLL/zone | dropout Brier | depth MAE (m) |\n|---|---|---|---|\n");
    s.push_str(&metrics_row("before", &r.fit_before));
    s.push_str(&metrics_row("after", &r.fit_after));
    if r.findings.is_empty() && r.power.conclusive {
        let _ = writeln!(
            s,
            "\n**No effect larger than the detection limits below** is missing: no effect of the library improves the held-out likelihood significantly, and these {} frames could have shown each family from the size given.",
            a.split.0 + a.split.1
        );
    }
    for f in &r.findings {
        let _ = writeln!(s, "\n## `{}`\n", f.effect);
        let physics = match (&f.curve, f.effect.as_str()) {
            (Some(t), super::flexible::LEARNED) => super::flexible::describe(t),
            _ => library(&f.effect).physics.to_string(),
        };
        let _ = writeln!(s, "Physics: {physics}.\n");
        if f.covariates.len() > 1 {
            let _ = writeln!(
                s,
                "**Inseparable** along {}: the data cannot tell which carries it (evidence below).\n",
                f.covariates.join(" and ")
            );
        }
        if let Some(t) = &f.curve {
            let _ = writeln!(
                s,
                "Fitted as a curve ({:?} over {}):\n",
                t.kind,
                t.on.name()
            );
            s.push_str("| covariate | value |\n|---|---|\n");
            for (k, v) in t.knots.iter().zip(&t.values) {
                let _ = writeln!(s, "| {k:.3} | {v:.4} |");
            }
            s.push('\n');
        }
        s.push_str("| parameter | fitted | ≈95 % interval |\n|---|---|---|\n");
        for (k, v) in &f.params {
            let ci =
                f.ci.get(k)
                    .map_or("—".to_string(), |c| format!("[{:.4}, {:.4}]", c[0], c[1]));
            let _ = writeln!(s, "| {k} | {v:.4} | {ci} |");
        }
        let _ = writeln!(
            s,
            "\nHeld-out gain {:.4} nats/zone; zones affected {:.1} %.\n\nEvidence: {}.\n",
            f.heldout_gain_nats_per_zone,
            100.0 * f.zones_affected,
            f.evidence
        );
        let stratum = match &f.curve {
            Some(t) if f.effect == super::flexible::LEARNED => t.on.name(),
            _ => library(&f.effect).stratum.name(),
        };
        let _ = writeln!(
            s,
            "Before/after in its stratum: ![{stratum}](covariate_{stratum}.png)"
        );
    }
    if !r.detection_limits.is_empty() {
        let _ = writeln!(
            s,
            "\n## {}\n",
            if r.findings.is_empty() {
                "Detection limits"
            } else {
                "Nothing more: detection limits of the other families"
            }
        );
        s.push_str("Per family, the smallest effect these frames could have shown (the calibrated limit, scaled to this recording's frames and covariates by the expected held-out gain):\n\n");
        for l in &r.detection_limits {
            let _ = writeln!(s, "- {}", l.statement);
        }
    }
    let unexplained: Vec<&Slice> = a.slices_after.iter().filter(|x| x.significant).collect();
    let _ = writeln!(s, "\n## Unexplained residual\n");
    if unexplained.is_empty() {
        s.push_str(
            "No residual slice is significant after the fit (Benjamini–Hochberg, q = 0.05).\n",
        );
    } else {
        s.push_str("Slices still significant after the fit (BH q = 0.05): physics outside the library or a misfit.\n\n");
    }
    s.push_str("\n| covariate | range | zones | dropout excess | PIT − ½ | residual (m) |\n|---|---|---|---|---|---|\n");
    for x in &unexplained {
        s.push_str(&slice_line(x));
        s.push('\n');
    }
    let _ = writeln!(s, "\n## Localisation before the fit (significant slices)\n");
    s.push_str("| covariate | range | zones | dropout excess | PIT − ½ | residual (m) |\n|---|---|---|---|---|---|\n");
    for x in a.slices_before.iter().filter(|x| x.significant) {
        s.push_str(&slice_line(x));
        s.push('\n');
    }
    s.push_str("\nZone maps: `zones_dropout_{before,after}.png`, `zones_pit_{before,after}.png`; PIT: `pit_{before,after}.png`.\n");
    let _ = writeln!(s, "\n## Selection log\n\n```");
    for l in &a.selection.log {
        let _ = writeln!(s, "{l}");
    }
    s.push_str("```\n");
    s
}
