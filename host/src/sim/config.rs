//! [`SimConfig`]: the sensor's zone grid plus a list of independently switchable aspects, each
//! defined (parameters and forward model) in its own module. JSON via serde; unknown fields are
//! rejected, missing aspects are off.
//!
//! Adding an aspect: a new module with its parameter struct implementing
//! `frame::ZoneEffect`, a `#[serde(default)]` field here, and one entry in
//! `SimConfig::zone_effects` (which fixes where in the pipeline it runs). An effect the gap tool
//! fits goes under `effects/` with its fit description and an entry in [`super::effects::ALL`].

use serde::{Deserialize, Serialize};

use super::anomalies::Anomalies;
use super::dark::DarkAspect;
use super::effects::bin_wiggle::BinWiggle;
use super::effects::border_dropout::BorderDropout;
use super::effects::calibration_shift::CalibrationShift;
use super::effects::dark_dropout::DarkDropout;
use super::effects::edge_mixing::EdgeMixing;
use super::effects::multipath::Multipath;
use super::effects::radial_distance::RadialDistance;
use super::effects::range_bias::RangeBias;
use super::effects::range_dropout::RangeDropout;
use super::effects::range_noise::RangeNoise;
use super::effects::zone_crosstalk::ZoneCrosstalk;
use super::error::SimError;
use super::estimator::ZoneEstimator;
use super::frame::ZoneEffect;
use super::grid::{GridConfig, OverallDistribution};
use super::halving::DepthHalving;
use super::learned::Learned;
use super::misregistration::Misregistration;
use super::range::RangeAspect;
use super::signal_loss::SignalLoss;
use super::surfaces::{Surface, SurfaceAspect};

/// Parses JSON text; a syntax error is reported as the field `JSON syntax`.
fn parse_json(text: &str) -> Result<serde_json::Value, SimError> {
    serde_json::from_str(text).map_err(|e| SimError::Json {
        field: "JSON syntax".into(),
        message: e.to_string(),
    })
}

/// Default memory limit of a run (see [`SimConfig::check_memory`]): 8 GiB, or
/// `DEPTHOR_MEMORY_LIMIT_MIB` from the environment.
pub fn memory_limit_bytes() -> u64 {
    std::env::var("DEPTHOR_MEMORY_LIMIT_MIB")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok())
        .map_or(8 << 30, |mib| mib.saturating_mul(1 << 20))
}

/// What [`SimConfig::memory_estimate`] counts, in bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// Zone sampling windows (indices and gathered depths) of the frames simulated at once.
    pub windows_bytes: u64,
    /// Images (inputs, rendering buffers) of the frames held and simulated.
    pub images_bytes: u64,
}

impl MemoryEstimate {
    /// Windows plus images.
    pub fn total(&self) -> u64 {
        self.windows_bytes.saturating_add(self.images_bytes)
    }
}

/// Complete simulator configuration (see the module docs of each aspect for its physics and
/// figures). The paper's Table 4 groups: OD = `overall_distribution`; SR = `transparent`,
/// `specular`, `dark`, `range` (and l5's `signal_loss`); RA = `anomalies`; calibration errors =
/// `calibration_shift`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// Zone grid, FoV bounds and iFoV (always applied).
    pub grid: GridConfig,
    /// Hypersim-style halving of over-deep frames (before sampling).
    #[serde(default)]
    pub depth_halving: DepthHalving,
    /// Random window motion and peak-of-histogram zone values.
    #[serde(default)]
    pub overall_distribution: OverallDistribution,
    /// The value a zone reports from its window's depths (peak, mean, median, nearest).
    #[serde(default)]
    pub zone_estimator: ZoneEstimator,
    /// Rigid shift of the whole zone grid against the image (extrinsic calibration error).
    #[serde(default)]
    pub misregistration: Misregistration,
    /// Transparent surfaces (label 1): loss or the surface behind.
    #[serde(default)]
    pub transparent: SurfaceAspect,
    /// Specular surfaces (label 2): loss or a farther, mirrored-path distance.
    #[serde(default)]
    pub specular: SurfaceAspect,
    /// Low reflectivity (HSV V below a threshold, label 3): loss.
    #[serde(default)]
    pub dark: DarkAspect,
    /// Long range: loss rising from the practical range to the limit.
    #[serde(default)]
    pub range: RangeAspect,
    /// Random signal loss of low-power sensors.
    #[serde(default)]
    pub signal_loss: SignalLoss,
    /// Background zones shifted by a calibration error.
    #[serde(default)]
    pub calibration_shift: CalibrationShift,
    /// Random noise and blank zones.
    #[serde(default)]
    pub anomalies: Anomalies,
    /// Sim-to-real: range along the ray instead of planar z.
    #[serde(default)]
    pub radial_distance: RadialDistance,
    /// Sim-to-real: offset and scale error of the distance.
    #[serde(default)]
    pub range_bias: RangeBias,
    /// Sim-to-real: mixed returns on zones straddling depth edges.
    #[serde(default)]
    pub edge_mixing: EdgeMixing,
    /// Sim-to-real: farther returns on transparent/specular zones.
    #[serde(default)]
    pub multipath: Multipath,
    /// Sim-to-real: returns blurred into neighbouring zones.
    #[serde(default)]
    pub zone_crosstalk: ZoneCrosstalk,
    /// Sim-to-real: periodic range error of histogram binning.
    #[serde(default)]
    pub bin_wiggle: BinWiggle,
    /// Sim-to-real: noise growing with range.
    #[serde(default)]
    pub range_noise: RangeNoise,
    /// Sim-to-real: dropout rising with range (signal ∝ ρ/r²).
    #[serde(default)]
    pub range_dropout: RangeDropout,
    /// Sim-to-real: dropout on dark (low-reflectance) zones.
    #[serde(default)]
    pub dark_dropout: DarkDropout,
    /// Sim-to-real: dropout rising toward the grid's corners.
    #[serde(default)]
    pub border_dropout: BorderDropout,
    /// Sim-to-real physics fitted as curves over zone covariates (the gap tool's flexible forms,
    /// `super::learned`).
    #[serde(default)]
    pub learned: Learned,
}

impl SimConfig {
    /// A configuration with the given grid and every aspect off (an ideal sensor that reports the
    /// ground truth at each nominal zone centre).
    pub fn ideal(grid: GridConfig) -> Self {
        SimConfig {
            grid,
            depth_halving: DepthHalving::default(),
            overall_distribution: OverallDistribution::default(),
            zone_estimator: ZoneEstimator::default(),
            misregistration: Misregistration::default(),
            transparent: SurfaceAspect::default(),
            specular: SurfaceAspect::default(),
            dark: DarkAspect::default(),
            range: RangeAspect::default(),
            signal_loss: SignalLoss::default(),
            calibration_shift: CalibrationShift::default(),
            anomalies: Anomalies::default(),
            radial_distance: RadialDistance::default(),
            range_bias: RangeBias::default(),
            edge_mixing: EdgeMixing::default(),
            multipath: Multipath::default(),
            zone_crosstalk: ZoneCrosstalk::default(),
            bin_wiggle: BinWiggle::default(),
            range_noise: RangeNoise::default(),
            range_dropout: RangeDropout::default(),
            dark_dropout: DarkDropout::default(),
            border_dropout: BorderDropout::default(),
            learned: Learned::default(),
        }
    }

    /// The per-zone aspects in pipeline order: the physics of what each zone sees first, then the
    /// projection error that moves background measurements, then sensor-level random anomalies,
    /// then the sim-to-real effects of the gap tool's library (distance transforms, noise,
    /// dropouts; all off unless a fitted configuration switches them on).
    pub(crate) fn zone_effects(&self) -> [Box<dyn ZoneEffect + '_>; 18] {
        [
            Box::new(Surface::transparent(&self.transparent)),
            Box::new(Surface::specular(&self.specular)),
            Box::new(&self.dark),
            Box::new(&self.range),
            Box::new(&self.signal_loss),
            Box::new(&self.calibration_shift),
            Box::new(&self.anomalies),
            Box::new(&self.radial_distance),
            Box::new(&self.range_bias),
            Box::new(&self.edge_mixing),
            Box::new(&self.multipath),
            Box::new(&self.zone_crosstalk),
            Box::new(&self.bin_wiggle),
            Box::new(&self.range_noise),
            Box::new(&self.range_dropout),
            Box::new(&self.dark_dropout),
            Box::new(&self.border_dropout),
            Box::new(&self.learned),
        ]
    }

    /// Checks every parameter, enabled or not; the error names the field (`dark.p_loss`).
    pub fn validate(&self) -> Result<(), SimError> {
        self.grid.validate()?;
        self.depth_halving.validate()?;
        self.overall_distribution.validate()?;
        self.zone_estimator.validate()?;
        self.misregistration.validate()?;
        for e in self.zone_effects() {
            e.validate()?;
        }
        Ok(())
    }

    /// Parses and validates a complete JSON configuration. A wrong type, unknown or missing
    /// field names its JSON path (`grid.rows: invalid type: string "8", expected u16`).
    pub fn from_json(text: &str) -> Result<SimConfig, SimError> {
        let doc = parse_json(text)?;
        let base = super::presets::preset("l5")
            .ok()
            .and_then(|c| serde_json::to_value(c).ok())
            .unwrap_or_default();
        Self::from_value(doc.clone(), &base, &doc)
    }

    /// This configuration with the fields a partial JSON configuration names replaced: objects
    /// are merged field by field (`{"anomalies": {"enabled": false}}` switches the anomalies off
    /// and keeps their rates), every other value (numbers, arrays) replaces the one here. Unknown
    /// fields and wrong types are refused with their JSON path (`anomalies.noise_fractio:
    /// unknown field …`); the result is validated.
    pub fn with_overrides(&self, text: &str) -> Result<SimConfig, SimError> {
        let patch = parse_json(text)?;
        self.with_overrides_value(&patch)
    }

    /// [`SimConfig::with_overrides`] of an already parsed JSON value.
    pub fn with_overrides_value(&self, patch: &serde_json::Value) -> Result<SimConfig, SimError> {
        if !patch.is_object() {
            return Err(SimError::Json {
                field: "(root)".into(),
                message: "expected a JSON object of the fields to replace".into(),
            });
        }
        let base = serde_json::to_value(self).map_err(|e| SimError::Json {
            field: "JSON".into(),
            message: e.to_string(),
        })?;
        let mut merged = base.clone();
        crate::json_field::merge(&mut merged, patch);
        Self::from_value(merged, &base, patch)
    }

    /// Deserialises and validates `doc`; a refusal is located by grafting `named` (the values
    /// the user wrote) onto `base` (a configuration serde accepts).
    fn from_value(
        doc: serde_json::Value,
        base: &serde_json::Value,
        named: &serde_json::Value,
    ) -> Result<SimConfig, SimError> {
        let cfg: SimConfig = serde_json::from_value(doc).map_err(|e| {
            let message = e.to_string();
            SimError::Json {
                field: crate::json_field::locate::<SimConfig>(base, named, &message)
                    .unwrap_or_else(|| "JSON".into()),
                message,
            }
        })?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Estimated peak memory of simulating frames at `width × height` with `workers` frames
    /// simulated at once and `frames_held` frames (inputs and outputs) kept in memory.
    pub fn memory_estimate(
        &self,
        width: u32,
        height: u32,
        workers: u64,
        frames_held: u64,
    ) -> MemoryEstimate {
        let px = width as u64 * height as u64;
        let zones = self.grid.rows as u64 * self.grid.cols as u64;
        // The sampling window of a zone, in pixels (as `Layout::windows` rounds it).
        let win = |f: f32, n: u32| (f as f64 * n as f64).round().clamp(1.0, 1e12) as u64;
        let window_px = zones
            .saturating_mul(win(self.grid.ifov[0], height))
            .saturating_mul(win(self.grid.ifov[1], width));
        // Window indices (4 B) plus the depths gathered per window (4 B), per worker.
        let windows = window_px.saturating_mul(8).saturating_mul(workers.max(1));
        // A frame held (RGB 3 B, depth 4 B, labels 1 B, reference depth 4 B per pixel) and a
        // frame being made (also reflectance, second depth and rendering buffers).
        let held = px.saturating_mul(12).saturating_mul(frames_held);
        let making = px.saturating_mul(32).saturating_mul(workers.max(1));
        let images = held.saturating_add(making);
        MemoryEstimate {
            windows_bytes: windows,
            images_bytes: images,
        }
    }

    /// Refuses a run whose [`SimConfig::memory_estimate`] exceeds `limit_bytes`, naming the
    /// setting that drives it.
    pub fn check_memory(
        &self,
        width: u32,
        height: u32,
        workers: u64,
        frames_held: u64,
        limit_bytes: u64,
    ) -> Result<MemoryEstimate, SimError> {
        let m = self.memory_estimate(width, height, workers, frames_held);
        if m.total() <= limit_bytes {
            return Ok(m);
        }
        let mib = |b: u64| b.div_ceil(1 << 20);
        let (field, what) = if m.windows_bytes >= m.images_bytes {
            (
                "grid.ifov",
                format!(
                    "{}×{} zones with an iFoV of {}×{} of a {width}×{height} image; \
                     reduce grid.ifov or grid.rows/cols",
                    self.grid.rows, self.grid.cols, self.grid.ifov[0], self.grid.ifov[1]
                ),
            )
        } else {
            (
                "width/height",
                format!("{frames_held} frames of {width}×{height} held; reduce the image size"),
            )
        };
        Err(SimError::TooMuchMemory {
            field: field.into(),
            need_mib: mib(m.total()),
            limit_mib: mib(limit_bytes),
            what,
        })
    }

    /// Pretty JSON of this configuration.
    pub fn to_json(&self) -> String {
        // A struct of numbers, bools and strings always serialises.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}
