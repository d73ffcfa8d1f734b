//! Sim-to-real gap tool (`depthor gap`, docs/design.md "Sim-to-real gap tool"): compares real zones
//! with the simulator's predictive distribution for the same reference depth, RGB and labels,
//! localises the mismatch, names the missing physics from the effect library, fits it, and proves
//! the fit on held-out frames.
//!
//! Pipeline: [`model::prepare`] (Monte-Carlo draws of the base simulator per frame, zone
//! covariates) → [`likelihood`] (per-zone dropout probability and heavy-tailed density) →
//! [`select::select`] (fit on even frames and test on odd ones, and the reverse: 2-fold
//! cross-fitting; Holm-controlled acceptance, confounded covariates ([`confound`]), joint
//! refit, pruning, confounding) →
//! [`localise`] (residual slices with BH control, PIT, zone maps) → [`report`] (report.md,
//! report.json, plots, fitted `sim_config`).

pub mod bench;
pub mod confound;
pub mod data;
pub mod effects;
pub mod flexible;
pub mod leave_one_out;
pub mod likelihood;
pub mod localise;
pub mod model;
pub mod periodic;
pub mod power;
pub mod report;
pub mod select;
pub mod shapes;
pub mod stats;
pub mod units;

pub use data::{load_recording, GapData, GapError, GapFrame};
pub use report::Report;
pub use select::SelectOptions;

use crate::sim::SimConfig;
use likelihood::Density;
use localise::{metrics, records, slices, FitMetrics, Slice, ZoneRecord};
use select::{select, Ctx, Selection};

/// Options of [`analyze`].
#[derive(Clone, Debug, PartialEq)]
pub struct GapOptions {
    /// Monte-Carlo draws of the simulator per frame.
    pub draws: usize,
    /// Seed of the draws.
    pub seed: u64,
    /// Selection knobs.
    pub select: SelectOptions,
}

impl Default for GapOptions {
    /// 32 draws (16 leave the predictive distribution of blurred or lengthened returns too
    /// sparse: `zone_crosstalk` lost to `range_noise` and `multipath` lacked power), seed 1.
    fn default() -> Self {
        GapOptions {
            draws: 32,
            seed: 1,
            select: SelectOptions::default(),
        }
    }
}

/// Everything the analysis found.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// The base configuration.
    pub base: SimConfig,
    /// Selection result (fitted model, findings, confounds, log).
    pub selection: Selection,
    /// Held-out zones under the base model.
    pub before: Vec<ZoneRecord>,
    /// Held-out zones under the fitted model.
    pub after: Vec<ZoneRecord>,
    /// Held-out metrics before.
    pub fit_before: FitMetrics,
    /// Held-out metrics after.
    pub fit_after: FitMetrics,
    /// Residual slices before.
    pub slices_before: Vec<Slice>,
    /// Residual slices after (significant ones are unexplained).
    pub slices_after: Vec<Slice>,
    /// Zone grid (rows, cols).
    pub grid: (usize, usize),
    /// Frames used (train, held-out).
    pub split: (usize, usize),
    /// Whether the held-out frames could show an effect.
    pub power: power::Power,
    /// Per library family not accepted, the smallest effect these frames could have shown
    /// ([`power::detection_limits`]); empty when the run is inconclusive.
    pub limits: Vec<power::FamilyLimit>,
}

/// Compares `data` with `base`: prepares the draws, selects and fits effects, localises what is
/// left. `progress` gets a short message per step and is called once per prepared frame with
/// `None`.
pub fn analyze(
    data: &GapData,
    base: &SimConfig,
    opts: &GapOptions,
    progress: &(dyn Fn(Option<&str>) + Sync),
) -> Result<Analysis, GapError> {
    base.validate()?;
    if data.frames.is_empty() {
        return Err(GapError::Empty("(in memory)".into()));
    }
    if data.grid != (base.grid.rows, base.grid.cols) {
        return Err(GapError::GridMismatch {
            real: data.grid,
            sim: (base.grid.rows, base.grid.cols),
        });
    }
    if data.frames.len() < 4 {
        return Err(GapError::TooFewFrames(data.frames.len()));
    }
    let frames = model::prepare(base, data, opts.draws.max(2), opts.seed, &|| progress(None))?;
    let density = Density {
        range_m: f64::from(data.max_range_m).max(1.0),
        ..opts.select.density
    };
    let n = frames.len();
    let ctx = Ctx {
        density,
        base,
        frames: &frames,
        train: (0..n).step_by(2).collect(),
        test: (1..n).step_by(2).collect(),
    };
    let selection = select(&ctx, &opts.select, |m| progress(Some(m)));
    let power = power::Power::of(
        n,
        opts.select.permutations,
        opts.select.alpha / 2.0,
        !selection.findings.is_empty(),
    );
    let limits = if power.conclusive {
        progress(Some("detection limits"));
        let accepted: Vec<&str> = selection
            .findings
            .iter()
            .map(|f| f.effect.as_str())
            .collect();
        let families: Vec<&str> = effects::ALL
            .iter()
            .filter(|c| !c.enabled(base) && !accepted.contains(&c.name))
            .filter(|c| !opts.select.exclude.iter().any(|e| e == c.name))
            .filter(|c| localise::varies(&frames, c.stratum))
            .map(|c| c.name)
            .collect();
        power::detection_limits(
            &density,
            base,
            &selection.estimate,
            &frames,
            &families,
            opts.seed,
        )
    } else {
        Vec::new()
    };
    let before = records(&density, base, base, &frames, &ctx.test);
    let after = records(&density, &selection.model, base, &frames, &ctx.test);
    Ok(Analysis {
        base: base.clone(),
        fit_before: metrics(&before),
        fit_after: metrics(&after),
        slices_before: slices(&before, 5),
        slices_after: slices(&after, 5),
        before,
        after,
        grid: (usize::from(base.grid.rows), usize::from(base.grid.cols)),
        split: (ctx.train.len(), ctx.test.len()),
        power,
        limits,
        selection,
    })
}
