//! Per-zone covariates shared by the sim-to-real effects and the gap tool: what a zone's window
//! holds (brightness, materials, depth spread) and where the zone sits on the grid. The simulator
//! computes them over a frame's (moved) sampling windows; the gap tool over the nominal windows of
//! a recording, so both speak about the same quantities.

use super::dark::LABEL_DARK;
use super::surfaces::{LABEL_SPECULAR, LABEL_TRANSPARENT};
use super::SimInput;

/// HSV V below which a pixel counts as dark (the supplement's V < 40).
pub const DARK_V: u8 = 40;

/// What one zone's window holds and where the zone sits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ZoneCovariates {
    /// Mean HSV V / 255 over the window (a reflectance proxy), in [0, 1].
    pub brightness: f32,
    /// Fraction of the window that is dark (V < [`DARK_V`] or label 3).
    pub dark_fraction: f32,
    /// Fraction of the window that is transparent or specular (labels 1, 2).
    pub nonlambertian_fraction: f32,
    /// Mean known depth over the window, metres (0 when none).
    pub mean_m: f32,
    /// Depth spread over the window: 90th minus 10th percentile, metres.
    pub spread_m: f32,
    /// Distance of the zone's centre from the grid centre, 0 at the centre and 1 at a corner.
    pub radius: f32,
    /// Zone centre's normalised grid coordinates `[row, col]` in `[-1, 1]` (−1 top / left).
    pub grid_pos: [f32; 2],
}

/// Covariates along which the gap tool localises residuals (and the stratum of each effect,
/// [`super::effects::EffectFit::stratum`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Covariate {
    /// Simulated/reference range of the zone, metres.
    Range,
    /// In-zone depth spread (p90 − p10), metres: edges.
    Spread,
    /// Mean brightness (V / 255): reflectance proxy.
    Brightness,
    /// Fraction of transparent/specular pixels.
    Material,
    /// Normalised distance from the grid centre.
    Radius,
    /// Zone row.
    Row,
    /// Zone column.
    Col,
    /// Frame time.
    Time,
}

impl Covariate {
    /// Every covariate, in report order.
    pub const ALL: [Covariate; 8] = [
        Covariate::Range,
        Covariate::Spread,
        Covariate::Brightness,
        Covariate::Material,
        Covariate::Radius,
        Covariate::Row,
        Covariate::Col,
        Covariate::Time,
    ];

    /// Short name (file names, report).
    pub fn name(self) -> &'static str {
        match self {
            Covariate::Range => "range_m",
            Covariate::Spread => "depth_spread_m",
            Covariate::Brightness => "brightness",
            Covariate::Material => "transparent_specular_fraction",
            Covariate::Radius => "grid_radius",
            Covariate::Row => "zone_row",
            Covariate::Col => "zone_col",
            Covariate::Time => "time_s",
        }
    }
}

/// Normalised position `[row, col]` in `[-1, 1]` of zone `(row, col)` on a `rows × cols` grid and
/// its radius (1 at the corners).
pub fn grid_position(row: usize, col: usize, rows: usize, cols: usize) -> ([f32; 2], f32) {
    let r = 2.0 * (row as f32 + 0.5) / rows.max(1) as f32 - 1.0;
    let c = 2.0 * (col as f32 + 0.5) / cols.max(1) as f32 - 1.0;
    ([r, c], ((r * r + c * c) / 2.0).sqrt())
}

/// Covariates of zone `z` of a `rows × cols` grid over the pixels `window` of `input`, depths
/// multiplied by `depth_scale`.
pub fn zone_covariates(
    input: &SimInput<'_>,
    window: &[u32],
    depth_scale: f32,
    z: usize,
    rows: usize,
    cols: usize,
) -> ZoneCovariates {
    let (grid_pos, radius) = grid_position(z / cols.max(1), z % cols.max(1), rows, cols);
    let mut out = ZoneCovariates {
        grid_pos,
        radius,
        ..ZoneCovariates::default()
    };
    if window.is_empty() {
        return out;
    }
    let (mut v_sum, mut dark, mut nl) = (0u64, 0usize, 0usize);
    let mut depths = Vec::with_capacity(window.len());
    for &i in window {
        let i = i as usize;
        let p = &input.rgb[3 * i..3 * i + 3];
        let v = p[0].max(p[1]).max(p[2]);
        v_sum += u64::from(v);
        let label = input.labels.map_or(0, |l| l[i]);
        dark += usize::from(v < DARK_V || label == LABEL_DARK);
        nl += usize::from(label == LABEL_TRANSPARENT || label == LABEL_SPECULAR);
        let d = input.depth_m[i];
        if d.is_finite() && d > 0.0 {
            depths.push(d * depth_scale);
        }
    }
    let n = window.len() as f32;
    out.brightness = v_sum as f32 / (255.0 * n);
    out.dark_fraction = dark as f32 / n;
    out.nonlambertian_fraction = nl as f32 / n;
    if !depths.is_empty() {
        out.mean_m = depths.iter().sum::<f32>() / depths.len() as f32;
        depths.sort_by(f32::total_cmp);
        let q = |p: f32| {
            depths[((p * (depths.len() - 1) as f32).round() as usize).min(depths.len() - 1)]
        };
        out.spread_m = q(0.9) - q(0.1);
    }
    out
}

/// Covariates of every zone of `zones` over the scene's sampling windows.
pub(crate) fn scene_covariates(
    scene: &super::frame::Scene<'_>,
    zones: &super::frame::ZoneGrid,
) -> Vec<ZoneCovariates> {
    (0..zones.zones.len())
        .map(|z| {
            zone_covariates(
                scene.input,
                scene.window(z),
                scene.depth_scale,
                z,
                zones.rows,
                zones.cols,
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covariates_hand_computed() {
        // 2×2 image: pixel 0 dark (V 20) at 1 m, pixel 1 bright (V 200) glass at 3 m,
        // pixel 2 label-dark at 2 m, pixel 3 unknown depth, V 100.
        let rgb = [20, 10, 0, 200, 0, 0, 90, 90, 90, 100, 0, 0];
        let depth = [1.0, 3.0, 2.0, 0.0];
        let labels = [0, 1, 3, 0];
        let input = SimInput {
            width: 2,
            height: 2,
            depth_m: &depth,
            rgb: &rgb,
            labels: Some(&labels),
            reflectance: None,
            second_depth_m: None,
        };
        let c = zone_covariates(&input, &[0, 1, 2, 3], 1.0, 0, 2, 2);
        assert!((c.brightness - 410.0 / 1020.0).abs() < 1e-6);
        assert_eq!(c.dark_fraction, 0.5);
        assert_eq!(c.nonlambertian_fraction, 0.25);
        assert!((c.mean_m - 2.0).abs() < 1e-6);
        // Sorted 1, 2, 3: p10 at index round(0.2) = 0, p90 at round(1.8) = 2.
        assert!((c.spread_m - 2.0).abs() < 1e-6);
        assert_eq!(c.grid_pos, [-0.5, -0.5]);
        assert!((c.radius - 0.5).abs() < 1e-6);
        let (_, corner) = grid_position(0, 0, 1, 1);
        assert_eq!(corner, 0.0);
    }
}
