//! Bilinear interpolation of the zone grid (the host's `bilinear_zones` baseline, and the third
//! candidate of [`crate::zone_gate`]): zones without a point take the depth of the nearest
//! zone that has one (squared grid distance, the first in zone order among equals); the zone
//! centres are the points' mean positions per zone row and column (in `f64`, in point order),
//! missing rows and columns placed linearly from the known ones; each pixel interpolates the
//! four surrounding centres, and pixels outside the centres take the nearest edge's values.
//! Points whose zone is outside the grid are ignored.
//!
//! No allocation: [`BilinearZones::prepare`] fills the caller's [`scratch_floats`] values, then
//! [`BilinearZones::rows`] writes any band of output rows.

use super::InterpError;
use crate::projection::ProjectedPoint;
use core::ops::Range;

/// `f64` values of scratch [`BilinearZones::prepare`] needs for a `rows × cols` grid: each
/// zone's measured and filled depth, and each zone row's and column's mean position and centre
/// (saturating).
pub fn scratch_floats(rows: usize, cols: usize) -> usize {
    rows.saturating_mul(cols)
        .saturating_mul(2)
        .saturating_add(rows.saturating_add(cols).saturating_mul(2))
}

/// The prepared interpolation of one frame.
#[derive(Debug)]
pub struct BilinearZones<'a> {
    width: usize,
    height: usize,
    cols: usize,
    /// Each zone's depth after the nearest-zone fill (empty without any point).
    filled: &'a [f64],
    /// Centre of each zone row (pixel rows) and column (pixel columns), `f32` values.
    row_v: &'a [f64],
    col_u: &'a [f64],
}

impl<'a> BilinearZones<'a> {
    /// Fills the tables in `scratch` for `points` on a `rows × cols` grid over a `width ×
    /// height` image.
    pub fn prepare(
        points: &[ProjectedPoint],
        (width, height): (usize, usize),
        (rows, cols): (usize, usize),
        scratch: &'a mut [f64],
    ) -> Result<Self, InterpError> {
        if rows == 0 || cols == 0 || rows > 0xffff || cols > 0xffff || rows * cols > 1 << 16 {
            return Err(InterpError::Grid);
        }
        if width == 0 || height == 0 || width.checked_mul(height).is_none() {
            return Err(InterpError::OutputSize);
        }
        let zones = rows * cols;
        let need = scratch_floats(rows, cols);
        if scratch.len() < need {
            return Err(InterpError::ScratchSize);
        }
        let (grid, rest) = scratch[..need].split_at_mut(zones);
        let (filled, rest) = rest.split_at_mut(zones);
        let (means, centres) = rest.split_at_mut(rows + cols);
        // NaN marks a zone without a point (a point's depth of NaN counts as none).
        grid.fill(f64::NAN);
        let mut any = false;
        for p in points {
            if let Some(g) = grid.get_mut(usize::from(p.zone)) {
                *g = f64::from(p.depth_m);
                any = true;
            }
        }
        let (row_v, col_u) = centres.split_at_mut(rows);
        if !any {
            return Ok(BilinearZones {
                width,
                height,
                cols,
                filled: &[],
                row_v,
                col_u,
            });
        }
        for (z, f) in filled.iter_mut().enumerate() {
            *f = if grid[z].is_nan() {
                nearest_valid(grid, cols, z)
            } else {
                grid[z]
            };
        }
        // Mean position per zone row, then per column (f64 sums in point order; NaN: none).
        let (row_mean, col_mean) = means.split_at_mut(rows);
        for (mean, line_of, pos) in [
            (
                &mut *row_mean,
                &(|z: usize| z / cols) as &dyn Fn(usize) -> usize,
                &(|p: &ProjectedPoint| p.v) as &dyn Fn(&ProjectedPoint) -> f32,
            ),
            (
                &mut *col_mean,
                &|z: usize| z % cols,
                &|p: &ProjectedPoint| p.u,
            ),
        ] {
            for (line, m) in mean.iter_mut().enumerate() {
                let (mut sum, mut n) = (0.0f64, 0u32);
                for p in points {
                    let z = usize::from(p.zone);
                    if z < zones && line_of(z) == line {
                        sum += f64::from(pos(p));
                        n += 1;
                    }
                }
                *m = if n > 0 { sum / f64::from(n) } else { f64::NAN };
            }
        }
        place_lines(row_mean, row_v);
        place_lines(col_mean, col_u);
        Ok(BilinearZones {
            width,
            height,
            cols,
            filled,
            row_v,
            col_u,
        })
    }

    /// Fills `out` (`width · rows.len()` values, metres; all 0 without any point) with the
    /// output rows `rows`.
    pub fn rows(&self, rows: Range<usize>, out: &mut [f32]) -> Result<(), InterpError> {
        if rows.start > rows.end || rows.end > self.height {
            return Err(InterpError::Rows);
        }
        if out.len() != self.width * rows.len() {
            return Err(InterpError::OutputSize);
        }
        if self.filled.is_empty() {
            out.fill(0.0);
            return Ok(());
        }
        let cols = self.cols;
        for (y, row) in rows.zip(out.chunks_exact_mut(self.width)) {
            let (r0, r1, fy) = locate(self.row_v, y as f32);
            for (x, o) in row.iter_mut().enumerate() {
                let (c0, c1, fx) = locate(self.col_u, x as f32);
                let v = |r: usize, c: usize| self.filled[r * cols + c] as f32;
                let top = v(r0, c0) * (1.0 - fx) + v(r0, c1) * fx;
                let bottom = v(r1, c0) * (1.0 - fx) + v(r1, c1) * fx;
                *o = top * (1.0 - fy) + bottom * fy;
            }
        }
        Ok(())
    }
}

/// The depth of the valid zone nearest to zone `z` (squared grid distance; the first in zone
/// order among equals).
fn nearest_valid(grid: &[f64], cols: usize, z: usize) -> f64 {
    let (r, c) = ((z / cols) as i64, (z % cols) as i64);
    let mut best = (i64::MAX, 0.0);
    for (k, &d) in grid.iter().enumerate() {
        if d.is_nan() {
            continue;
        }
        let dist = (r - (k / cols) as i64).pow(2) + (c - (k % cols) as i64).pow(2);
        if dist < best.0 {
            best = (dist, d);
        }
    }
    best.1
}

/// Each grid line's centre from the lines' mean positions (`NaN`: no point): a known line
/// placed by the two nearest known lines around it, a missing one linearly between the nearest
/// known lines on each side (extrapolated from the two nearest at an end); one known line
/// gives a spacing of 1 px, none the line's index. Centres are stored as `f32` values.
fn place_lines(mean: &[f64], out: &mut [f64]) {
    let lines = mean.len();
    let known = |range: &mut dyn Iterator<Item = usize>| first_known(mean, range);
    let first = known(&mut (0..lines));
    let second = first.and_then(|(k, _)| known(&mut (k + 1..lines)));
    let last = known(&mut (0..lines).rev());
    let before_last = last.and_then(|(k, _)| known(&mut (0..k).rev()));
    for (i, o) in out.iter_mut().enumerate() {
        let p = match (first, second, last, before_last) {
            (None, ..) => i as f64,
            (Some((k, m)), None, ..) => m + (i as f64 - k as f64),
            (Some(f), Some(s), Some(l), Some(bl)) => {
                let (a, b) = match known(&mut (i..lines)) {
                    // The first known line at or after `i` and the known line before it.
                    Some(right) => match known(&mut (0..right.0).rev()) {
                        Some(left) => (left, right),
                        None => (f, s),
                    },
                    None => (bl, l),
                };
                a.1 + (b.1 - a.1) * (i as f64 - a.0 as f64) / (b.0 as f64 - a.0 as f64)
            }
            // Two known lines always have a last and one before it.
            _ => i as f64,
        };
        *o = f64::from(p as f32);
    }
}

/// The first line of `range` with a mean position, and that mean.
fn first_known(mean: &[f64], range: &mut dyn Iterator<Item = usize>) -> Option<(usize, f64)> {
    for k in range {
        if !mean[k].is_nan() {
            return Some((k, mean[k]));
        }
    }
    None
}

/// The two centres around `x` and the weight of the second (clamped at both ends).
fn locate(centres: &[f64], x: f32) -> (usize, usize, f32) {
    let c = |i: usize| centres[i] as f32;
    if centres.len() == 1 || x <= c(0) {
        return (0, 0, 0.0);
    }
    let last = centres.len() - 1;
    if x >= c(last) {
        return (last, last, 0.0);
    }
    let i = (0..centres.len())
        .position(|k| c(k) > x)
        .unwrap_or(last)
        .max(1)
        - 1;
    let span = (c(i + 1) - c(i)).max(1e-6);
    (i, i + 1, (x - c(i)) / span)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    fn pt(zone: u16, u: f32, v: f32, depth_m: f32) -> ProjectedPoint {
        ProjectedPoint {
            zone,
            u,
            v,
            x: u as u32,
            y: v as u32,
            depth_m,
        }
    }

    fn run(points: &[ProjectedPoint], size: (usize, usize), grid: (usize, usize)) -> Vec<f32> {
        let mut scratch = vec![0.0; scratch_floats(grid.0, grid.1)];
        let b = BilinearZones::prepare(points, size, grid, &mut scratch).unwrap();
        let mut out = vec![0.0; size.0 * size.1];
        b.rows(0..size.1, &mut out).unwrap();
        out
    }

    #[test]
    fn a_2x2_grid_interpolates_between_centres_and_clamps_outside() {
        let pts = [
            pt(0, 2.0, 2.0, 1.0),
            pt(1, 6.0, 2.0, 2.0),
            pt(2, 2.0, 6.0, 3.0),
            pt(3, 6.0, 6.0, 4.0),
        ];
        let out = run(&pts, (8, 8), (2, 2));
        assert_eq!(out[0], 1.0); // outside the centres: the corner zone
        assert_eq!(out[2 * 8 + 4], 1.5); // halfway along the top row of centres
        assert_eq!(out[4 * 8 + 4], 2.5); // the middle
        assert_eq!(out[7 * 8 + 7], 4.0);
    }

    #[test]
    fn a_missing_zone_takes_the_nearest_and_a_missing_row_is_placed_linearly() {
        // 3×1 grid, the middle zone without a point: it takes the first of its two equally
        // near neighbours, and its row's centre lies halfway.
        let pts = [pt(0, 1.0, 1.0, 1.0), pt(2, 1.0, 9.0, 3.0)];
        let out = run(&pts, (2, 11), (3, 1));
        assert_eq!(out[5 * 2], 1.0); // at the middle centre (v = 5): zone 1 filled with 1.0
        assert_eq!(out[7 * 2], 2.0); // between v = 5 (1.0) and v = 9 (3.0)
    }

    #[test]
    fn bands_equal_the_whole_frame_and_bad_inputs_are_refused() {
        let pts: Vec<_> = (0..12u16)
            .filter(|z| z % 5 != 2)
            .map(|z| {
                pt(
                    z,
                    3.0 + 8.0 * f32::from(z % 4),
                    4.0 + 9.0 * f32::from(z / 4),
                    1.0 + f32::from(z) * 0.3,
                )
            })
            .collect();
        let whole = run(&pts, (32, 27), (3, 4));
        let mut scratch = vec![0.0; scratch_floats(3, 4)];
        let b = BilinearZones::prepare(&pts, (32, 27), (3, 4), &mut scratch).unwrap();
        let mut band = vec![0.0; 32 * 5];
        b.rows(10..15, &mut band).unwrap();
        assert_eq!(&band[..], &whole[10 * 32..15 * 32]);
        assert_eq!(b.rows(20..28, &mut band), Err(InterpError::Rows));
        assert_eq!(b.rows(0..4, &mut band), Err(InterpError::OutputSize));
        assert!(run(&[], (4, 4), (2, 2)).iter().all(|&d| d == 0.0));
        let mut short = vec![0.0; scratch_floats(3, 4) - 1];
        assert_eq!(
            BilinearZones::prepare(&pts, (32, 27), (3, 4), &mut short).unwrap_err(),
            InterpError::ScratchSize
        );
        assert_eq!(
            BilinearZones::prepare(&pts, (32, 27), (0, 4), &mut scratch).unwrap_err(),
            InterpError::Grid
        );
    }
}
