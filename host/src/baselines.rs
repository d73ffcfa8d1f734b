//! Classical baselines for dToF depth completion, run on the same projected points as the model:
//! nearest-zone fill, bilinear interpolation of the zone grid, and joint bilateral upsampling
//! guided by the RGB (Kopf et al., SIGGRAPH 2007). Outputs are dense depth maps in metres.

use depthor_core::interp;
use depthor_core::projection::ProjectedPoint;
use rayon::prelude::*;

/// The projected dToF points of one frame at camera resolution.
#[derive(Clone, Debug)]
pub struct SparseFrame<'a> {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Zone grid rows.
    pub rows: u16,
    /// Zone grid columns.
    pub cols: u16,
    /// Valid projected points (zone index, sub-pixel position, depth).
    pub points: &'a [ProjectedPoint],
}

/// Every pixel takes the depth of the nearest projected point (0 everywhere without points).
pub fn nearest_fill(s: &SparseFrame<'_>) -> Vec<f32> {
    let w = s.width as usize;
    let mut out = vec![0.0f32; w * s.height as usize];
    if s.points.is_empty() {
        return out;
    }
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let mut best = (f32::INFINITY, 0.0);
                for p in s.points {
                    let d = (p.u - x as f32).powi(2) + (p.v - y as f32).powi(2);
                    if d < best.0 {
                        best = (d, p.depth_m);
                    }
                }
                *o = best.1;
            }
        });
    out
}

/// Bilinear interpolation of the zone grid: zones without a point take the value of the nearest
/// valid zone (grid distance), zone centres come from the points (mean position per row and
/// column, linearly extended where a row or column has no point), and pixels outside the grid
/// of centres take the value at the nearest edge. The core's
/// [`depthor_core::interp::bilinear::BilinearZones`] (the same bits as on a device), bands of
/// rows in parallel; 0 everywhere without points or zones.
pub fn bilinear_zones(s: &SparseFrame<'_>) -> Vec<f32> {
    use depthor_core::interp::bilinear::{scratch_floats, BilinearZones};
    let (w, h) = (s.width as usize, s.height as usize);
    let grid = (usize::from(s.rows), usize::from(s.cols));
    let mut out = vec![0.0f32; w * h];
    let mut scratch = vec![0.0f64; scratch_floats(grid.0, grid.1)];
    let Ok(b) = BilinearZones::prepare(s.points, (w, h), grid, &mut scratch) else {
        return out;
    };
    let band = 16;
    out.par_chunks_mut((w * band).max(1))
        .enumerate()
        .for_each(|(i, chunk)| {
            let y0 = i * band;
            // A band inside the image with its own width: cannot fail.
            let _ = b.rows(y0..y0 + chunk.len() / w.max(1), chunk);
        });
    out
}

/// Joint bilateral upsampling of the points guided by the RGB: each pixel averages the points
/// within two point spacings, weighted by a spatial Gaussian (σ = one spacing) times a range
/// Gaussian on the RGB difference between the pixel and the point's pixel (σ = 20 levels); a
/// pixel with no point in reach takes the nearest point. The core's
/// [`depthor_core::interp::JointBilateral`] (the same bits as on a device), bands of rows in
/// parallel; points out of zone order or a wrong-sized `rgb` give [`nearest_fill`].
pub fn joint_bilateral(s: &SparseFrame<'_>, rgb: &[u8]) -> Vec<f32> {
    let (w, h) = (s.width as usize, s.height as usize);
    let grid = (usize::from(s.rows), usize::from(s.cols));
    let mut scratch = vec![0u32; interp::scratch_words(w, h, grid.0, grid.1)];
    let Ok(jb) = interp::JointBilateral::prepare(s.points, rgb, (w, h), grid, &mut scratch) else {
        return nearest_fill(s);
    };
    let mut out = vec![0.0f32; w * h];
    const BAND: usize = 16;
    let filled = out
        .par_chunks_mut((w * BAND).max(1))
        .enumerate()
        .all(|(i, band)| {
            let y0 = i * BAND;
            jb.rows(y0..y0 + band.len() / w.max(1), band).is_ok()
        });
    if filled {
        out
    } else {
        nearest_fill(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(zone: u16, u: f32, v: f32, d: f32) -> ProjectedPoint {
        ProjectedPoint {
            zone,
            u,
            v,
            x: u.round() as u32,
            y: v.round() as u32,
            depth_m: d,
        }
    }

    #[test]
    fn nearest_and_bilinear_on_a_2x2_grid() {
        // Zones at (u, v) = (2, 1), (6, 1), (2, 5), (6, 5) with depths 1, 2, 3, 4 on an 9×7 image.
        let pts = [
            pt(0, 2.0, 1.0, 1.0),
            pt(1, 6.0, 1.0, 2.0),
            pt(2, 2.0, 5.0, 3.0),
            pt(3, 6.0, 5.0, 4.0),
        ];
        let s = SparseFrame {
            width: 9,
            height: 7,
            rows: 2,
            cols: 2,
            points: &pts,
        };
        let n = nearest_fill(&s);
        assert_eq!(n[0], 1.0);
        assert_eq!(n[6 * 9 + 8], 4.0);
        let b = bilinear_zones(&s);
        // Centre (4, 3): mean of the four = 2.5; (4, 1): halfway between 1 and 2; outside: edge.
        assert!((b[3 * 9 + 4] - 2.5).abs() < 1e-6);
        assert!((b[9 + 4] - 1.5).abs() < 1e-6);
        assert_eq!(b[0], 1.0);
        assert_eq!(b[6 * 9 + 8], 4.0);
    }

    #[test]
    fn missing_zone_takes_its_nearest_valid_neighbour() {
        let pts = [
            pt(0, 2.0, 1.0, 1.0),
            pt(1, 6.0, 1.0, 2.0),
            pt(2, 2.0, 5.0, 3.0),
        ];
        let s = SparseFrame {
            width: 9,
            height: 7,
            rows: 2,
            cols: 2,
            points: &pts,
        };
        let b = bilinear_zones(&s);
        // Zone 3 is filled from zone 1 or 2 (both at grid distance 1; the first found, zone 1 = 2.0).
        assert!((b[5 * 9 + 6] - 2.0).abs() < 1e-6);
    }

    #[test]
    fn joint_bilateral_in_bands_is_the_cores_whole_frame() {
        // Colour edges and the definition are the core's tests (core/src/interp.rs); here the
        // parallel bands (16 rows each) must give the core's one-call result.
        let (w, h) = (24usize, 40usize);
        let rgb: Vec<u8> = (0..3 * w * h).map(|i| (i * 37 % 251) as u8).collect();
        let pts: Vec<ProjectedPoint> = (0..12u16)
            .map(|z| {
                pt(
                    z,
                    2.0 + 6.0 * f32::from(z % 4),
                    3.0 + 12.0 * f32::from(z / 4),
                    1.0 + f32::from(z) / 4.0,
                )
            })
            .collect();
        let s = SparseFrame {
            width: w as u32,
            height: h as u32,
            rows: 3,
            cols: 4,
            points: &pts,
        };
        let mut scratch = vec![0u32; interp::scratch_words(w, h, 3, 4)];
        let jb = interp::JointBilateral::prepare(&pts, &rgb, (w, h), (3, 4), &mut scratch).unwrap();
        let mut whole = vec![0.0f32; w * h];
        jb.rows(0..h, &mut whole).unwrap();
        let banded = joint_bilateral(&s, &rgb);
        assert!(whole
            .iter()
            .zip(&banded)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        // Points out of zone order: the nearest fill.
        let mut shuffled = pts.clone();
        shuffled.swap(0, 5);
        let s = SparseFrame {
            points: &shuffled,
            ..s
        };
        assert_eq!(joint_bilateral(&s, &rgb), nearest_fill(&s));
    }
}
