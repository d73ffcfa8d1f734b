//! Classical baselines for dToF depth completion, run on the same projected points as the model:
//! nearest-zone fill, bilinear interpolation of the zone grid, and joint bilateral upsampling
//! guided by the RGB (Kopf et al., SIGGRAPH 2007). Outputs are dense depth maps in metres.

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
/// of centres take the value at the nearest edge.
pub fn bilinear_zones(s: &SparseFrame<'_>) -> Vec<f32> {
    let (rows, cols) = (s.rows as usize, s.cols as usize);
    let w = s.width as usize;
    let mut out = vec![0.0f32; w * s.height as usize];
    if s.points.is_empty() || rows == 0 || cols == 0 {
        return out;
    }
    // Zone values and centre positions.
    let mut grid = vec![None::<f32>; rows * cols];
    let (mut col_u, mut row_v) = (vec![(0.0f64, 0u32); cols], vec![(0.0f64, 0u32); rows]);
    for p in s.points {
        let z = p.zone as usize;
        if z >= rows * cols {
            continue;
        }
        grid[z] = Some(p.depth_m);
        col_u[z % cols].0 += f64::from(p.u);
        col_u[z % cols].1 += 1;
        row_v[z / cols].0 += f64::from(p.v);
        row_v[z / cols].1 += 1;
    }
    let col_u = fill_positions(&col_u);
    let row_v = fill_positions(&row_v);
    let filled: Vec<f32> = (0..rows * cols)
        .map(|z| {
            grid[z].unwrap_or_else(|| {
                let (r, c) = ((z / cols) as i64, (z % cols) as i64);
                let mut best = (i64::MAX, 0.0);
                for (k, g) in grid.iter().enumerate() {
                    if let Some(d) = g {
                        let dist = (r - (k / cols) as i64).pow(2) + (c - (k % cols) as i64).pow(2);
                        if dist < best.0 {
                            best = (dist, *d);
                        }
                    }
                }
                best.1
            })
        })
        .collect();
    let locate = |centres: &[f32], x: f32| -> (usize, usize, f32) {
        if centres.len() == 1 || x <= centres[0] {
            return (0, 0, 0.0);
        }
        let last = centres.len() - 1;
        if x >= centres[last] {
            return (last, last, 0.0);
        }
        let i = centres.iter().position(|&c| c > x).unwrap_or(last).max(1) - 1;
        let span = (centres[i + 1] - centres[i]).max(1e-6);
        (i, i + 1, (x - centres[i]) / span)
    };
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let (r0, r1, fy) = locate(&row_v, y as f32);
            for (x, o) in row.iter_mut().enumerate() {
                let (c0, c1, fx) = locate(&col_u, x as f32);
                let v = |r: usize, c: usize| filled[r * cols + c];
                let top = v(r0, c0) * (1.0 - fx) + v(r0, c1) * fx;
                let bottom = v(r1, c0) * (1.0 - fx) + v(r1, c1) * fx;
                *o = top * (1.0 - fy) + bottom * fy;
            }
        });
    out
}

/// Mean positions per grid line, with missing lines extended linearly from the known ones
/// (monotone increasing result; one known line gives a constant spacing of 1 px).
fn fill_positions(acc: &[(f64, u32)]) -> Vec<f32> {
    let known: Vec<(usize, f64)> = acc
        .iter()
        .enumerate()
        .filter(|(_, (_, n))| *n > 0)
        .map(|(i, (s, n))| (i, s / f64::from(*n)))
        .collect();
    (0..acc.len())
        .map(|i| {
            let pos = match known.as_slice() {
                [] => i as f64,
                [(k, p)] => p + (i as f64 - *k as f64),
                _ => {
                    // Interpolate between the nearest known lines on each side (or extrapolate
                    // from the two nearest at an end).
                    let right = known.iter().position(|(k, _)| *k >= i);
                    let (a, b) = match right {
                        Some(0) => (known[0], known[1]),
                        Some(j) => (known[j - 1], known[j]),
                        None => (known[known.len() - 2], known[known.len() - 1]),
                    };
                    a.1 + (b.1 - a.1) * (i as f64 - a.0 as f64) / (b.0 as f64 - a.0 as f64)
                }
            };
            pos as f32
        })
        .collect()
}

/// Joint bilateral upsampling of the points guided by the RGB: each pixel averages the points
/// within two point spacings, weighted by a spatial Gaussian (σ = one spacing) times a range
/// Gaussian on the RGB difference between the pixel and the point's pixel (σ = 20 levels); a
/// pixel with no point in reach takes the nearest point.
pub fn joint_bilateral(s: &SparseFrame<'_>, rgb: &[u8]) -> Vec<f32> {
    let (w, h) = (s.width as usize, s.height as usize);
    if s.points.is_empty() || rgb.len() != 3 * w * h {
        return nearest_fill(s);
    }
    let spacing = ((w * h) as f32 / s.points.len() as f32).sqrt();
    let (sigma_s, sigma_r) = (spacing, 20.0f32);
    let reach2 = (2.0 * spacing).powi(2);
    let colour = |x: usize, y: usize| -> [f32; 3] {
        let i = 3 * (y.min(h - 1) * w + x.min(w - 1));
        [rgb[i] as f32, rgb[i + 1] as f32, rgb[i + 2] as f32]
    };
    let point_colour: Vec<[f32; 3]> = s
        .points
        .iter()
        .map(|p| colour(p.x as usize, p.y as usize))
        .collect();
    let nearest = nearest_fill(s);
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let c = colour(x, y);
                let (mut num, mut den) = (0.0f32, 0.0f32);
                for (p, pc) in s.points.iter().zip(&point_colour) {
                    let d2 = (p.u - x as f32).powi(2) + (p.v - y as f32).powi(2);
                    if d2 > reach2 {
                        continue;
                    }
                    let r2 =
                        (c[0] - pc[0]).powi(2) + (c[1] - pc[1]).powi(2) + (c[2] - pc[2]).powi(2);
                    let wgt =
                        (-d2 / (2.0 * sigma_s * sigma_s) - r2 / (2.0 * sigma_r * sigma_r)).exp();
                    num += wgt * p.depth_m;
                    den += wgt;
                }
                *o = if den > 1e-12 {
                    num / den
                } else {
                    nearest[y * w + x]
                };
            }
        });
    out
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
    fn joint_bilateral_respects_colour_edges() {
        // Left half black at 1 m, right half white at 3 m: a pixel next to the edge on the black
        // side stays near 1 m although the white point is almost as close.
        let (w, h) = (16usize, 4usize);
        let mut rgb = vec![0u8; 3 * w * h];
        for y in 0..h {
            for x in 8..w {
                rgb[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[255, 255, 255]);
            }
        }
        let pts = [pt(0, 4.0, 2.0, 1.0), pt(1, 12.0, 2.0, 3.0)];
        let s = SparseFrame {
            width: w as u32,
            height: h as u32,
            rows: 1,
            cols: 2,
            points: &pts,
        };
        let j = joint_bilateral(&s, &rgb);
        assert!((j[2 * w + 7] - 1.0).abs() < 0.01, "{}", j[2 * w + 7]);
        assert!((j[2 * w + 8] - 3.0).abs() < 0.01, "{}", j[2 * w + 8]);
    }
}
