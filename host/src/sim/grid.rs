//! Overall distribution (paper §3.1 "Overall Distribution"; supplement "Details of dToF Simulation
//! Method"): the zone grid over the sensor's FoV bounds in the image, each zone's iFoV window, the
//! per-frame random translation and rotation of the sampling windows, and the value a zone reports —
//! the **peak** (dominant mode) of the depth histogram over its iFoV, as a dToF pixel's TCSPC
//! histogram does (supplement "Preliminary: dToF Imaging").

use serde::{Deserialize, Serialize};

use super::error::{check_above, check_in, invalid, SimError};
use super::estimator::ZoneEstimator;
use super::frame::{Scene, Zone, ZoneGrid};
use super::truth::{ZoneEvents, ZoneTruth};
use crate::rng::Rng;

/// Most zones along one axis of the grid (the phone preset has 40; dToF sensors have ≤ 64).
pub const MAX_ZONES_PER_AXIS: u16 = 128;

/// Allowed range of each FoV bound, in fractions of the image (a FoV may overhang the image).
pub const FOV_BOUNDS: [f32; 2] = [-1.0, 2.0];

/// Largest iFoV, as a fraction of the image size.
pub const MAX_IFOV: f32 = 1.0;

/// Sensor geometry in the image: not switchable (every frame has a zone grid).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridConfig {
    /// Zone rows (top to bottom).
    pub rows: u16,
    /// Zone columns (left to right).
    pub cols: u16,
    /// Projected FoV bounds `[top, bottom, left, right]`: top/bottom as fractions of the image
    /// height, left/right of its width. May extend beyond `[0, 1]` (l5's top is −25/480).
    pub fov_bounds: [f32; 4],
    /// iFoV `[height, width]` of one zone as fractions of the image height and width.
    pub ifov: [f32; 2],
}

impl GridConfig {
    /// Checks the geometry; errors name the field as `grid.<field>`.
    pub fn validate(&self) -> Result<(), SimError> {
        for (field, n) in [("rows", self.rows), ("cols", self.cols)] {
            if !(1..=MAX_ZONES_PER_AXIS).contains(&n) {
                return Err(invalid(
                    "grid",
                    field,
                    format!("{n} is out of range (allowed 1 to {MAX_ZONES_PER_AXIS} zones)"),
                ));
            }
        }
        for (i, name) in ["top", "bottom", "left", "right"].into_iter().enumerate() {
            let field = format!("fov_bounds[{i}]");
            check_in(
                "grid",
                &field,
                self.fov_bounds[i],
                FOV_BOUNDS,
                &format!(" ({name}, image fractions)"),
            )?;
        }
        let [t, b, l, r] = self.fov_bounds;
        if t >= b || l >= r {
            return Err(invalid(
                "grid",
                "fov_bounds",
                format!(
                    "{:?} is not a rectangle (allowed top < bottom and left < right)",
                    self.fov_bounds
                ),
            ));
        }
        check_above(
            "grid",
            "ifov[0]",
            self.ifov[0],
            [0.0, MAX_IFOV],
            " of the image height",
        )?;
        check_above(
            "grid",
            "ifov[1]",
            self.ifov[1],
            [0.0, MAX_IFOV],
            " of the image width",
        )
    }

    /// Nominal iFoV rectangle `[y0, x0, y1, x1]` of every zone (row-major) in pixels of a
    /// `width × height` image: the iFoV centred on the zone's grid cell. This is what a recording's
    /// `dtof.zone_rects_px` gets; its centre is where the zone's sparse point is projected.
    pub fn zone_rects_px(&self, width: u32, height: u32) -> Vec<[f32; 4]> {
        let l = self.layout(width, height);
        let [hh, hw] = [l.ifov_px[0] / 2.0, l.ifov_px[1] / 2.0];
        l.centres
            .iter()
            .map(|&[y, x]| [y - hh, x - hw, y + hh, x + hw])
            .collect()
    }

    /// The grid laid out on a `width × height` image.
    pub(crate) fn layout(&self, width: u32, height: u32) -> Layout {
        let (h, w) = (height as f32, width as f32);
        let [t, b, l, r] = self.fov_bounds;
        let (rows, cols) = (self.rows as usize, self.cols as usize);
        let (cell_h, cell_w) = ((b - t) * h / rows as f32, (r - l) * w / cols as f32);
        let mut centres = Vec::with_capacity(rows * cols);
        for row in 0..rows {
            for col in 0..cols {
                centres.push([
                    t * h + (row as f32 + 0.5) * cell_h,
                    l * w + (col as f32 + 0.5) * cell_w,
                ]);
            }
        }
        Layout {
            width: width as usize,
            height: height as usize,
            rows,
            cols,
            centres,
            ifov_px: [self.ifov[0] * h, self.ifov[1] * w],
            cell_px: [cell_h, cell_w],
            fov_centre: [(t + b) / 2.0 * h, (l + r) / 2.0 * w],
        }
    }
}

/// The zone grid on one image size.
pub(crate) struct Layout {
    pub width: usize,
    pub height: usize,
    pub rows: usize,
    pub cols: usize,
    /// Nominal zone centres `[y, x]`, row-major.
    pub centres: Vec<[f32; 2]>,
    /// iFoV `[height, width]` in pixels.
    pub ifov_px: [f32; 2],
    /// One zone cell of the grid (FoV bounds / rows, cols) `[height, width]` in pixels.
    pub cell_px: [f32; 2],
    /// Centre of the FoV bounds `[y, x]`: the rotation centre.
    pub fov_centre: [f32; 2],
}

impl Layout {
    /// Whether zone `z`'s nominal centre (where its point is projected) lies inside the image.
    pub fn in_image(&self, z: usize) -> bool {
        let [y, x] = self.centres[z];
        y >= 0.0 && x >= 0.0 && y < self.height as f32 && x < self.width as f32
    }

    /// Sampling windows under `pose`: flat pixel indices, per-zone start offsets (`zones + 1`), and
    /// the moved window centres. Zones whose nominal centre is outside the image get no pixels.
    pub fn windows(&self, pose: &Pose) -> (Vec<u32>, Vec<u32>, Vec<[f32; 2]>) {
        let nh = (self.ifov_px[0].round() as usize).max(1);
        let nw = (self.ifov_px[1].round() as usize).max(1);
        let (step_y, step_x) = (self.ifov_px[0] / nh as f32, self.ifov_px[1] / nw as f32);
        let (sin, cos) = pose.angle_rad.sin_cos();
        let n = self.centres.len();
        let mut px = Vec::with_capacity(n * nh * nw);
        let mut start = Vec::with_capacity(n + 1);
        let mut moved = Vec::with_capacity(n);
        let [fy, fx] = self.fov_centre;
        let (h, w) = (self.height as f32, self.width as f32);
        // Rotated offsets of the window's columns, shared by every row and zone.
        let col_offsets: Vec<[f32; 2]> = (0..nw)
            .map(|v| {
                let ox = (v as f32 + 0.5) * step_x - self.ifov_px[1] / 2.0;
                [ox * sin, ox * cos]
            })
            .collect();
        for z in 0..n {
            start.push(px.len() as u32);
            let [y, x] = self.centres[z];
            let (dy, dx) = (y - fy, x - fx);
            let cy = fy + dx * sin + dy * cos + pose.translation_px[0];
            let cx = fx + dx * cos - dy * sin + pose.translation_px[1];
            moved.push([cy, cx]);
            if !self.in_image(z) {
                continue;
            }
            for u in 0..nh {
                let oy = (u as f32 + 0.5) * step_y - self.ifov_px[0] / 2.0;
                let (ry, rx) = (cy + oy * cos, cx - oy * sin);
                for &[dy, dx] in &col_offsets {
                    let (py, pxx) = (ry + dy, rx + dx);
                    // Truncation is floor here: both are ≥ 0.
                    if py >= 0.0 && pxx >= 0.0 && py < h && pxx < w {
                        px.push((py as usize * self.width + pxx as usize) as u32);
                    }
                }
            }
        }
        start.push(px.len() as u32);
        (px, start, moved)
    }
}

/// The frame's random rigid motion of the sampling windows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Pose {
    /// Translation `[dy, dx]` in pixels.
    pub translation_px: [f32; 2],
    /// Rotation about the FoV centre, radians.
    pub angle_rad: f32,
}

/// Overall-distribution aspect: random window motion and peak-of-histogram zone values.
///
/// Off (the paper's "w/o OD" ablation): windows stay at their nominal place and a zone reports
/// the ground-truth pixel at its nominal centre (what the public reference code does).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OverallDistribution {
    /// Switch.
    pub enabled: bool,
    /// Largest translation per axis as a fraction of the iFoV half-size (1 = up to half an iFoV;
    /// paper: "random translations … within the iFoV range").
    pub max_translation: f32,
    /// Largest rotation of the window grid about the FoV centre, degrees (paper: small, no figure).
    pub max_rotation_deg: f32,
    /// Histogram bin width in metres for the peak.
    pub bin_m: f32,
}

impl Default for OverallDistribution {
    /// Disabled; when enabled: translation up to the iFoV half-size, rotation up to 2° (our
    /// choice: it moves l5's corner zones by ≈ 11 px ≈ 0.2 iFoV), 5 cm bins.
    fn default() -> Self {
        OverallDistribution {
            enabled: false,
            max_translation: 1.0,
            max_rotation_deg: 2.0,
            bin_m: 0.05,
        }
    }
}

/// Name of the aspect (its config field and random stream).
pub(crate) const DISTRIBUTION: &str = "overall_distribution";

impl OverallDistribution {
    /// Checks the parameters; errors name the field as `overall_distribution.<field>`.
    pub fn validate(&self) -> Result<(), SimError> {
        check_in(
            DISTRIBUTION,
            "max_translation",
            self.max_translation,
            [0.0, 10.0],
            " iFoV half-sizes",
        )?;
        check_in(
            DISTRIBUTION,
            "max_rotation_deg",
            self.max_rotation_deg,
            [0.0, 45.0],
            "°",
        )?;
        check_above(DISTRIBUTION, "bin_m", self.bin_m, [0.0, 10.0], " m")
    }

    /// Draws the frame's window motion (identity when off).
    pub(crate) fn draw_pose(&self, layout: &Layout, rng: &mut Rng) -> Pose {
        if !self.enabled {
            return Pose::default();
        }
        let ty = self.max_translation * layout.ifov_px[0] / 2.0;
        let tx = self.max_translation * layout.ifov_px[1] / 2.0;
        let a = self.max_rotation_deg.to_radians();
        Pose {
            translation_px: [rng.range(-ty, ty), rng.range(-tx, tx)],
            angle_rad: rng.range(-a, a),
        }
    }

    /// Measures every zone's ground-truth value: `estimator`'s value over its window (on; the
    /// histogram peak by default) or the pixel at its centre (off): the nominal centre, or the
    /// moved one (`centres`) when `moved` (a rigid misregistration). Zones with no depth report no
    /// target.
    pub(crate) fn measure(
        &self,
        layout: &Layout,
        scene: &Scene<'_>,
        centres: &[[f32; 2]],
        estimator: &ZoneEstimator,
        moved: bool,
    ) -> ZoneGrid {
        let mut scratch = PeakScratch::default();
        let mut depths = Vec::new();
        let zones = (0..layout.centres.len())
            .map(|z| {
                let mut truth = ZoneTruth {
                    center_px: centres[z],
                    ..ZoneTruth::default()
                };
                let peak = if !layout.in_image(z) {
                    truth.events.insert(ZoneEvents::OUT_OF_IMAGE);
                    0.0
                } else if self.enabled {
                    depths.clear();
                    depths.extend(
                        scene
                            .window(z)
                            .iter()
                            .map(|&i| scene.depth(i as usize))
                            .filter(|&d| d > 0.0),
                    );
                    estimator.estimate(&mut depths, self.bin_m, &mut scratch)
                } else {
                    let [y, x] = if moved { centres[z] } else { layout.centres[z] };
                    let inside =
                        y >= 0.0 && x >= 0.0 && y < layout.height as f32 && x < layout.width as f32;
                    if inside {
                        scene.depth(y as usize * layout.width + x as usize)
                    } else {
                        0.0
                    }
                };
                if peak <= 0.0 && !truth.events.contains(ZoneEvents::OUT_OF_IMAGE) {
                    truth.events.insert(ZoneEvents::NO_DEPTH);
                }
                truth.peak_m = peak;
                Zone {
                    distance_m: peak,
                    truth,
                }
            })
            .collect();
        ZoneGrid {
            rows: layout.rows,
            cols: layout.cols,
            zones,
        }
    }
}

/// Reusable histogram buffers for [`histogram_peak`].
#[derive(Default)]
pub(crate) struct PeakScratch {
    counts: Vec<u32>,
    sums: Vec<f64>,
}

/// Most bins a histogram may have; wider spreads get proportionally wider bins.
const MAX_BINS: usize = 4096;

/// Peak (dominant mode) of the histogram of `depths` (all > 0) with bins `[k·bin_m, (k+1)·bin_m)`:
/// the mean of the depths in the fullest bin; ties go to the nearer bin. 0 when `depths` is empty.
pub(crate) fn histogram_peak(depths: &[f32], bin_m: f32, s: &mut PeakScratch) -> f32 {
    let Some(&first) = depths.first() else {
        return 0.0;
    };
    let (lo, hi) = depths
        .iter()
        .fold((first, first), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    let mut bw = bin_m;
    if (hi - lo) / bw > (MAX_BINS - 2) as f32 {
        bw = (hi - lo) / (MAX_BINS - 2) as f32;
    }
    // Depths are > 0, so truncation is floor.
    let base = (lo / bw) as usize;
    let n = (hi / bw) as usize - base + 1;
    s.counts.clear();
    s.counts.resize(n, 0);
    s.sums.clear();
    s.sums.resize(n, 0.0);
    for &d in depths {
        let k = ((d / bw) as usize).saturating_sub(base).min(n - 1);
        s.counts[k] += 1;
        s.sums[k] += f64::from(d);
    }
    let mut best = 0;
    for k in 1..n {
        if s.counts[k] > s.counts[best] {
            best = k;
        }
    }
    (s.sums[best] / f64::from(s.counts[best])) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn peak(d: &[f32], bin: f32) -> f32 {
        histogram_peak(d, bin, &mut PeakScratch::default())
    }

    #[test]
    fn peak_is_the_mode_not_the_mean() {
        // 7 pixels on a wall at 3.00–3.02 m, 3 on a box at 1.0 m: mean 2.41 m, peak 3.01 m.
        let d = [3.0, 3.01, 3.02, 3.0, 3.01, 3.02, 3.01, 1.0, 1.0, 1.0];
        assert!((peak(&d, 0.05) - 3.01).abs() < 1e-5);
    }

    #[test]
    fn ties_go_to_the_nearer_bin_and_empty_is_zero() {
        assert_eq!(peak(&[2.0, 2.01, 1.0, 1.01], 0.05), 1.005);
        assert_eq!(peak(&[], 0.05), 0.0);
        assert_eq!(peak(&[4.2], 0.05), 4.2);
    }

    #[test]
    fn huge_spread_widens_bins_instead_of_allocating() {
        let d = [0.1, 0.1, 1.0e6];
        assert!((peak(&d, 0.05) - 0.1).abs() < 1e-6);
    }

    #[test]
    fn layout_and_rects_hand_computed() {
        // 2×2 grid over rows [0.25, 0.75] and cols [0, 1] of a 100×200 (H×W) image, iFoV 0.2×0.1.
        let g = GridConfig {
            rows: 2,
            cols: 2,
            fov_bounds: [0.25, 0.75, 0.0, 1.0],
            ifov: [0.2, 0.1],
        };
        let r = g.zone_rects_px(200, 100);
        // Cells are 25×100 px; centres (37.5, 50), (37.5, 150), (62.5, 50), (62.5, 150); iFoV 20×20.
        assert_eq!(r[0], [27.5, 40.0, 47.5, 60.0]);
        assert_eq!(r[3], [52.5, 140.0, 72.5, 160.0]);
        let l = g.layout(200, 100);
        let (px, start, moved) = l.windows(&Pose::default());
        assert_eq!(start, vec![0, 400, 800, 1200, 1600]);
        assert_eq!(moved[1], [37.5, 150.0]);
        // Zone 0's first sample sits at (27.5 + 0.5, 40 + 0.5) = (28.0, 40.5): pixel row 28, col 40.
        assert_eq!(px[0], 28 * 200 + 40);
    }

    #[test]
    fn rotation_moves_corners_about_fov_centre() {
        let g = GridConfig {
            rows: 1,
            cols: 2,
            fov_bounds: [0.0, 1.0, 0.0, 1.0],
            ifov: [0.1, 0.1],
        };
        let l = g.layout(100, 100);
        // Zone centres (50, 25) and (50, 75); FoV centre (50, 50); rotate by 90°.
        let pose = Pose {
            translation_px: [1.0, 0.0],
            angle_rad: core::f32::consts::FRAC_PI_2,
        };
        let (_, _, moved) = l.windows(&pose);
        assert!(
            (moved[0][0] - 26.0).abs() < 1e-3 && (moved[0][1] - 50.0).abs() < 1e-3,
            "{moved:?}"
        );
        assert!(
            (moved[1][0] - 76.0).abs() < 1e-3 && (moved[1][1] - 50.0).abs() < 1e-3,
            "{moved:?}"
        );
    }
}
