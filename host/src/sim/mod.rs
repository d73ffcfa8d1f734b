//! dToF simulator (paper §3.1 "Training Strategy with dToF Data Simulation" and supplement
//! "Details of dToF Simulation Method"): turns a ground-truth depth map, its RGB image and optional
//! material labels into the zone measurements a light-weight dToF sensor would report.
//!
//! Pipeline of one frame, each stage an aspect in its own module, switchable in [`SimConfig`]:
//! 1. [`halving`]: optional Hypersim trick, halve over-deep frames.
//! 2. [`grid`]: lay the zone grid over the FoV bounds, move the iFoV windows by a random
//!    translation and rotation (and by [`misregistration`], a rigid shift of the whole grid), and
//!    let each zone report one value of its depths ([`estimator`]: the histogram peak by default).
//! 3. Per-zone physics: [`surfaces`] (transparent, specular), [`dark`], [`range`],
//!    [`signal_loss`].
//! 4. [`effects::calibration_shift`]: background zones take a neighbour's measurement.
//! 5. [`anomalies`]: random noise and blank zones.
//! 6. The gap tool's sim-to-real effects (off by default), one module each under [`effects`]:
//!    `radial_distance`, `range_bias`, `edge_mixing`, `multipath`, `zone_crosstalk`,
//!    `bin_wiggle`, `range_noise`, `range_dropout`, `dark_dropout`, `border_dropout`.
//!
//! [`effects`] holds every effect the gap tool can fit (these ten and `calibration_shift`): its
//! parameters, forward model and fit description ([`effects::EffectFit`], listed in
//! [`effects::ALL`]).
//!
//! Each aspect draws from its own random stream (derived from the seed and its name), and draws
//! the same numbers whatever the other aspects did: switching one aspect off changes only the
//! zones that aspect touched. Same `(config, input, seed)` ⇒ identical output.
//!
//! ```
//! use depthor_host::sim::{preset, simulate, SimInput};
//! let (w, h) = (160u32, 120u32);
//! let depth = vec![2.0f32; (w * h) as usize];
//! let rgb = vec![128u8; (3 * w * h) as usize];
//! let input = SimInput { width: w, height: h, depth_m: &depth, rgb: &rgb,
//!                        labels: None, reflectance: None, second_depth_m: None };
//! let out = simulate(&preset("mcu").unwrap(), &input, 7).unwrap();
//! assert_eq!((out.rows, out.cols, out.distance_mm.len()), (8, 8, 64));
//! ```

pub mod anomalies;
pub mod config;
pub mod covariates;
pub mod dark;
pub mod effects;
pub mod error;
pub mod estimator;
mod frame;
pub mod grid;
pub mod halving;
pub mod learned;
pub mod misregistration;
pub mod mix;
pub mod presets;
pub mod range;
pub mod signal_loss;
pub mod surfaces;
pub mod truth;

pub use config::{memory_limit_bytes, MemoryEstimate, SimConfig};
pub use error::SimError;
pub use mix::MeasurementMix;
pub use presets::{preset, PRESETS};
pub use truth::{ZoneEvents, ZoneTruth};

use depthor_core::hal::{STATUS_NO_TARGET, STATUS_VALID};
use frame::{stream, Scene};

/// One frame of ground truth to simulate from. All arrays are row-major, `width × height`.
#[derive(Clone, Copy, Debug)]
pub struct SimInput<'a> {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Planar depth (z) in metres; 0 (or non-finite) = unknown.
    pub depth_m: &'a [f32],
    /// 8-bit sRGB, interleaved RGB (`3 × width × height`).
    pub rgb: &'a [u8],
    /// Material labels (0 diffuse, 1 transparent, 2 specular, 3 dark); none = all diffuse.
    pub labels: Option<&'a [u8]>,
    /// Diffuse reflectance in [0, 1], for aspects that model signal strength (none uses it yet).
    pub reflectance: Option<&'a [f32]>,
    /// Depth of the surface behind glass / along the mirrored path, metres; 0 = none.
    pub second_depth_m: Option<&'a [f32]>,
}

impl<'a> SimInput<'a> {
    /// The input of a measured frame (a recording's or a resampled one): depth, RGB and
    /// optional labels, with no reflectance and no second surface, which only rendered scenes
    /// have (theirs is [`crate::scene::SceneFrame::sim_input`]).
    pub fn observed(
        width: u32,
        height: u32,
        depth_m: &'a [f32],
        rgb: &'a [u8],
        labels: Option<&'a [u8]>,
    ) -> Self {
        SimInput {
            width,
            height,
            depth_m,
            rgb,
            labels,
            reflectance: None,
            second_depth_m: None,
        }
    }

    /// Checks that every array matches the image size.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.width == 0 || self.height == 0 {
            return Err(SimError::EmptyImage {
                width: self.width,
                height: self.height,
            });
        }
        let n = self.width as usize * self.height as usize;
        let check = |field, expected, got| {
            if expected == got {
                Ok(())
            } else {
                Err(SimError::InputSize {
                    field,
                    expected,
                    got,
                })
            }
        };
        check("depth_m", n, self.depth_m.len())?;
        check("rgb", 3 * n, self.rgb.len())?;
        if let Some(l) = self.labels {
            check("labels", n, l.len())?;
        }
        if let Some(r) = self.reflectance {
            check("reflectance", n, r.len())?;
        }
        if let Some(s) = self.second_depth_m {
            check("second_depth_m", n, s.len())?;
        }
        Ok(())
    }
}

/// The simulated sensor frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SimOutput {
    /// Zone rows.
    pub rows: u16,
    /// Zone columns.
    pub cols: u16,
    /// Reported distance per zone (row-major), millimetres; 0 where `status` is no target.
    pub distance_mm: Vec<f32>,
    /// ST target status per zone: 5 valid, 255 no target.
    pub status: Vec<u8>,
    /// Nominal iFoV rectangle `[y0, x0, y1, x1]` per zone in camera pixels (recording.json's
    /// `dtof.zone_rects_px`); the zone's point belongs at its centre.
    pub zone_rects_px: Vec<[f32; 4]>,
    /// What the simulator did to each zone.
    pub truth: Vec<ZoneTruth>,
    /// Factor applied to the input depths (`depth_halving`; 1 when not applied). Scale the
    /// ground truth by it to supervise with these zones.
    pub depth_scale: f32,
}

impl SimOutput {
    /// Whether zone `z` reports a target.
    pub fn is_valid(&self, z: usize) -> bool {
        self.status[z] == STATUS_VALID
    }
}

/// Simulates one dToF frame from `input` under `cfg`; deterministic in `(cfg, input, seed)`.
pub fn simulate(cfg: &SimConfig, input: &SimInput<'_>, seed: u64) -> Result<SimOutput, SimError> {
    simulate_inner(cfg, input, seed, false).map(|(out, _)| out)
}

/// [`simulate`] plus each zone's covariates over the frame's own (moved) sampling windows: what
/// the window-dependent effects (`dark_dropout`, `edge_mixing`, `multipath`) saw in this draw. The
/// gap tool transforms its draws with these, so its forward models get the inputs the simulator's
/// did (the nominal windows differ by up to half an iFoV once `overall_distribution` moves them).
pub fn simulate_with_covariates(
    cfg: &SimConfig,
    input: &SimInput<'_>,
    seed: u64,
) -> Result<(SimOutput, Vec<covariates::ZoneCovariates>), SimError> {
    simulate_inner(cfg, input, seed, true)
}

fn simulate_inner(
    cfg: &SimConfig,
    input: &SimInput<'_>,
    seed: u64,
    with_covariates: bool,
) -> Result<(SimOutput, Vec<covariates::ZoneCovariates>), SimError> {
    cfg.validate()?;
    input.validate()?;
    // One frame at a time here; callers running many at once check their own total first.
    cfg.check_memory(input.width, input.height, 1, 0, memory_limit_bytes())?;
    let depth_scale = cfg.depth_halving.scale(input);
    let layout = cfg.grid.layout(input.width, input.height);
    let dist = &cfg.overall_distribution;
    let mut pose = dist.draw_pose(&layout, &mut stream(seed, grid::DISTRIBUTION));
    let misregistration = &cfg.misregistration;
    let [dy, dx] =
        misregistration.offset_px(layout.cell_px, &mut stream(seed, misregistration::NAME));
    pose.translation_px[0] += dy;
    pose.translation_px[1] += dx;
    let (px, start, centres) = layout.windows(&pose);
    let scene = Scene::new(input, depth_scale, dist.bin_m, px, start);
    let mut zones = dist.measure(
        &layout,
        &scene,
        &centres,
        &cfg.zone_estimator,
        misregistration.enabled,
    );
    for effect in cfg.zone_effects() {
        if effect.enabled() {
            effect.apply(&scene, &mut zones, &mut stream(seed, effect.name()));
        }
    }
    let cov = if with_covariates {
        covariates::scene_covariates(&scene, &zones)
    } else {
        Vec::new()
    };
    let status = zones
        .zones
        .iter()
        .map(|z| {
            if z.has_target() {
                STATUS_VALID
            } else {
                STATUS_NO_TARGET
            }
        })
        .collect();
    let out = SimOutput {
        rows: cfg.grid.rows,
        cols: cfg.grid.cols,
        distance_mm: zones
            .zones
            .iter()
            .map(|z| z.distance_m.max(0.0) * 1000.0)
            .collect(),
        status,
        zone_rects_px: cfg.grid.zone_rects_px(input.width, input.height),
        truth: zones.zones.iter().map(|z| z.truth).collect(),
        depth_scale,
    };
    Ok((out, cov))
}
