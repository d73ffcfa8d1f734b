//! One frame being simulated: read-only access to the input ([`Scene`]), the zones' running state
//! ([`ZoneGrid`]), and the [`ZoneEffect`] trait every per-zone aspect implements.

use super::error::SimError;
use super::truth::{ZoneEvents, ZoneTruth};
use super::SimInput;
use crate::rng::Rng;

/// The input of one frame plus the per-frame sampling windows of the zones.
pub(crate) struct Scene<'a> {
    /// The caller's input.
    pub input: &'a SimInput<'a>,
    /// Factor applied to every input depth (`depth_halving`); 1 when off.
    pub depth_scale: f32,
    /// Histogram bin width (metres) for peaks over a window.
    pub bin_m: f32,
    /// Pixel indices (`y * width + x`) of all windows, zone after zone.
    window_px: Vec<u32>,
    /// Zone `z`'s pixels are `window_px[window_start[z]..window_start[z + 1]]`.
    window_start: Vec<u32>,
}

impl<'a> Scene<'a> {
    /// A scene with the given windows (see [`super::grid::Layout::windows`]).
    pub fn new(
        input: &'a SimInput<'a>,
        depth_scale: f32,
        bin_m: f32,
        window_px: Vec<u32>,
        window_start: Vec<u32>,
    ) -> Self {
        Scene {
            input,
            depth_scale,
            bin_m,
            window_px,
            window_start,
        }
    }

    /// Pixel indices under zone `z`'s sampling window (only pixels inside the image).
    pub fn window(&self, z: usize) -> &[u32] {
        let a = self.window_start[z] as usize;
        let b = self.window_start[z + 1] as usize;
        &self.window_px[a..b]
    }

    /// Ground-truth planar depth of pixel `i` in metres (scaled); 0 when unknown or not finite.
    #[inline]
    pub fn depth(&self, i: usize) -> f32 {
        sanitize(self.input.depth_m[i]) * self.depth_scale
    }

    /// Depth of the surface behind glass / along the mirrored path at pixel `i`; 0 = none.
    #[inline]
    pub fn second_depth(&self, i: usize) -> f32 {
        self.input
            .second_depth_m
            .map_or(0.0, |s| sanitize(s[i]) * self.depth_scale)
    }

    /// Material label of pixel `i` (0 when no labels were given).
    #[inline]
    pub fn label(&self, i: usize) -> u8 {
        self.input.labels.map_or(0, |l| l[i])
    }

    /// HSV value (V = max(R, G, B), 0–255) of pixel `i`.
    #[inline]
    pub fn value_v(&self, i: usize) -> u8 {
        let p = &self.input.rgb[3 * i..3 * i + 3];
        p[0].max(p[1]).max(p[2])
    }

    /// Fraction of zone `z`'s window whose label is `label` (0 without labels or an empty window).
    pub fn label_fraction(&self, z: usize, label: u8) -> f32 {
        let w = self.window(z);
        if self.input.labels.is_none() || w.is_empty() {
            return 0.0;
        }
        let n = w
            .iter()
            .filter(|&&i| self.label(i as usize) == label)
            .count();
        n as f32 / w.len() as f32
    }
}

/// A depth that is unknown (0, negative or not finite) becomes 0.
#[inline]
fn sanitize(d: f32) -> f32 {
    if d.is_finite() && d > 0.0 {
        d
    } else {
        0.0
    }
}

/// One zone's running state.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Zone {
    /// Current reported distance in metres; 0 = no target.
    pub distance_m: f32,
    /// What happened so far.
    pub truth: ZoneTruth,
}

impl Zone {
    /// True when the zone currently reports a target.
    pub fn has_target(&self) -> bool {
        self.distance_m > 0.0
    }

    /// Drops the return and records `event`, if there was a return to drop.
    pub fn lose(&mut self, event: ZoneEvents) {
        if self.has_target() {
            self.distance_m = 0.0;
            self.truth.events.insert(event);
        }
    }
}

/// All zones of a frame, row-major.
pub(crate) struct ZoneGrid {
    /// Zone rows.
    pub rows: usize,
    /// Zone columns.
    pub cols: usize,
    /// `rows × cols` zones, row-major.
    pub zones: Vec<Zone>,
}

/// A switchable per-zone aspect of the simulation: one module, its parameters and its forward model.
///
/// Implementations must draw the same number of random numbers whatever the zones' state, so that
/// switching another aspect off never changes this one's decisions (common random numbers: the
/// ablations and the gap tool compare runs zone by zone).
pub(crate) trait ZoneEffect {
    /// The aspect's field name in [`super::SimConfig`]; prefixes validation errors and names its
    /// random stream.
    fn name(&self) -> &'static str;
    /// Whether the aspect is switched on.
    fn enabled(&self) -> bool;
    /// Checks the parameters; errors name the field as `<name>.<field>`.
    fn validate(&self) -> Result<(), SimError>;
    /// Applies the aspect to the zones.
    fn apply(&self, scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng);
}

/// The random stream of aspect `name` for frame seed `seed` (FNV-1a of the name), independent of
/// every other aspect's stream.
pub(crate) fn stream(seed: u64, name: &str) -> Rng {
    let mut h: u64 = 0xCBF2_9CE4_8422_2325;
    for b in name.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01B3);
    }
    Rng::derive(seed, h)
}

impl<T: ZoneEffect + ?Sized> ZoneEffect for &T {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn enabled(&self) -> bool {
        (**self).enabled()
    }
    fn validate(&self) -> Result<(), SimError> {
        (**self).validate()
    }
    fn apply(&self, scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        (**self).apply(scene, zones, rng)
    }
}
