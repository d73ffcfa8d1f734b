//! Zone interpolations without a network: [`bilinear`] interpolation of the zone grid, and
//! (this module) joint bilateral upsampling of the projected zones guided by the RGB image (Kopf
//! et al., SIGGRAPH 2007), on the device: the classical completion that wins where the zones are clean
//! (issue 39), and the edge-aware candidate of the learned zone gate
//! (docs/results/models_zone_gate.md).
//!
//! Each pixel averages the points within two point spacings (`spacing = sqrt(w·h / points)`),
//! weighted by `exp(−d²/2σs² − r²/2σr²)`: a spatial Gaussian (σs = one spacing) times a range
//! Gaussian on the RGB difference between the pixel and the point's pixel (σr = 20 levels), the
//! points summed in zone order; a pixel with no point in reach (or whose weights all underflow)
//! takes the nearest point (the first of equals), and with no point at all every pixel is 0.
//! This is the definition of the host's `joint_bilateral` baseline, with `exp` from the core's
//! own `f32` routine, so the bits are the same on every target.
//!
//! The points must come in increasing zone order (as [`crate::projection::for_each_point`]
//! gives them). A pixel then visits only the zones of the rectangle of zone rows and columns
//! whose points can lie within reach, in zone order, so the sums are those of a pass over every
//! point: about 25 candidates per pixel instead of all of them (1 200 on a 40×30 phone sensor).
//!
//! No allocation: [`JointBilateral::prepare`] lays its tables in the caller's words
//! ([`scratch_words`]), then [`JointBilateral::rows`] fills any band of output rows (bands are
//! independent, so a host may run them in parallel).

pub mod bilinear;

use crate::fmath::exp_f32_lanes;
use crate::projection::ProjectedPoint;
use core::ops::Range;

/// Range σ of the colour term, RGB levels.
pub const SIGMA_RGB: f32 = 20.0;
/// Pixels of a row filled together (the lanes of one SIMD register of `f32` on NEON and SSE2;
/// each lane runs the scalar definition's operations in its order).
pub(crate) const LANES: usize = 4;
/// The frame's constants of the weight `exp(−d²/spacing − r²/colour)`, taken within `reach2`.
pub(crate) struct Terms {
    /// `2σs²`, pixels².
    pub spacing: f32,
    /// `2σr²`, levels².
    pub colour: f32,
    /// `(2σs)²`, pixels²: farther points are not taken.
    pub reach2: f32,
}

/// `LANES` adjacent pixels of one row, filled together.
pub(crate) struct Group {
    /// The row.
    pub y: usize,
    /// Each lane's column as `f32`.
    pub xf: [f32; LANES],
    /// Each lane's R, G and B (planes).
    pub rgb: [[f32; LANES]; 3],
    /// Each lane's zone columns `col_lo..col_hi` (empty past the row's end).
    pub col_lo: [u32; LANES],
    /// See `col_lo`.
    pub col_hi: [u32; LANES],
    /// The zone rows in reach of the row.
    pub zone_rows: (u32, u32),
    /// The union of the lanes' zone columns (`(u32::MAX, 0)`: none).
    pub zone_cols: (u32, u32),
}

/// `[f(0), …, f(LANES − 1)]`.
#[inline(always)]
fn lanes(mut f: impl FnMut(usize) -> f32) -> [f32; LANES] {
    let mut v = [0.0; LANES];
    for (l, x) in v.iter_mut().enumerate() {
        *x = f(l);
    }
    v
}
/// No point in this zone (the zone table's empty slot).
const NONE: u32 = u32::MAX;

/// Why the interpolation refused its inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InterpError {
    /// `rgb` is not `3 · width · height` bytes (interleaved RGB), or the size is 0.
    RgbSize,
    /// The output slice is not the band's `width · rows` values.
    OutputSize,
    /// `scratch` holds fewer than [`scratch_words`] words.
    ScratchSize,
    /// A point's zone is not below `rows · cols`, or the zones do not increase.
    ZoneOrder,
    /// A point is not finite, not positive in depth, or outside the image.
    BadPoint,
    /// The band's rows are not inside the image.
    Rows,
    /// The zone grid is empty, holds more than 65 536 zones (zone indices are `u16`) or has more
    /// than 65 535 rows or columns.
    Grid,
}

/// Words of scratch [`JointBilateral::prepare`] needs for an image of `width × height` and a
/// zone grid of `rows × cols` (4 bytes each): the zone table, each zone row's and column's span
/// of positions, and each pixel row's and column's range of zones (saturating: sizes no buffer
/// can hold give `usize::MAX`).
pub fn scratch_words(width: usize, height: usize, rows: usize, cols: usize) -> usize {
    [
        rows.saturating_mul(cols),
        rows,
        rows,
        cols,
        cols,
        height,
        height,
        width,
        width,
    ]
    .iter()
    .fold(0usize, |a, &b| a.saturating_add(b))
}

/// The prepared interpolation of one frame (borrows its inputs and tables).
#[derive(Debug)]
pub struct JointBilateral<'a> {
    points: &'a [ProjectedPoint],
    rgb: &'a [u8],
    width: usize,
    height: usize,
    cols: usize,
    /// Point index of each zone, or [`NONE`].
    table: &'a [u32],
    /// Per pixel row, the zone rows `lo..hi` (packed `lo << 16 | hi`) whose points may be in reach.
    row_zones: &'a [u32],
    /// Per pixel column, the zone columns likewise.
    col_zones: &'a [u32],
    /// Per zone row, the smallest and largest `v` of its points (f32 bits; +inf, −inf: none).
    row_span: &'a [u32],
    /// Per zone column, the same of `u`.
    col_span: &'a [u32],
    spacing: f32,
}

impl<'a> JointBilateral<'a> {
    /// Checks the inputs and builds the tables in `scratch`: `points` in increasing zone order
    /// on a `rows × cols` grid, `rgb` interleaved `3 · width · height` bytes.
    pub fn prepare(
        points: &'a [ProjectedPoint],
        rgb: &'a [u8],
        (width, height): (usize, usize),
        (rows, cols): (usize, usize),
        scratch: &'a mut [u32],
    ) -> Result<Self, InterpError> {
        if width == 0
            || height == 0
            || width.checked_mul(height).and_then(|n| n.checked_mul(3)) != Some(rgb.len())
        {
            return Err(InterpError::RgbSize);
        }
        let bounded = rows <= 0xffff && cols <= 0xffff && rows * cols <= 1 << 16;
        if rows == 0 || cols == 0 || !bounded {
            return Err(InterpError::Grid);
        }
        let need = scratch_words(width, height, rows, cols);
        if scratch.len() < need || width > u16::MAX as usize || height > u16::MAX as usize {
            return Err(InterpError::ScratchSize);
        }
        let zones = rows * cols;
        let mut last = None;
        for p in points {
            let zone = usize::from(p.zone);
            if zone >= zones || last.is_some_and(|l| zone <= l) {
                return Err(InterpError::ZoneOrder);
            }
            last = Some(zone);
            let inside = (p.x as usize) < width && (p.y as usize) < height;
            let finite = p.u.is_finite() && p.v.is_finite() && p.depth_m.is_finite();
            if !(finite && p.depth_m > 0.0 && inside) {
                return Err(InterpError::BadPoint);
            }
        }
        let scratch: &'a mut [u32] = &mut scratch[..need];
        let (table, rest) = scratch.split_at_mut(zones);
        let (row_span, rest) = rest.split_at_mut(2 * rows);
        let (col_span, rest) = rest.split_at_mut(2 * cols);
        let (row_zones, col_zones) = rest.split_at_mut(2 * height);
        let col_zones = &mut col_zones[..2 * width];
        table.fill(NONE);
        // Spans as f32 bits: min in the even word, max in the odd (empty: +inf, −inf).
        for span in [&mut *row_span, &mut *col_span] {
            for mm in span.chunks_exact_mut(2) {
                mm[0] = f32::INFINITY.to_bits();
                mm[1] = f32::NEG_INFINITY.to_bits();
            }
        }
        for (i, p) in points.iter().enumerate() {
            let zone = usize::from(p.zone);
            table[zone] = i as u32;
            for (span, at, pos) in [
                (&mut *row_span, zone / cols, p.v),
                (&mut *col_span, zone % cols, p.u),
            ] {
                let mm = &mut span[2 * at..2 * at + 2];
                mm[0] = f32::from_bits(mm[0]).min(pos).to_bits();
                mm[1] = f32::from_bits(mm[1]).max(pos).to_bits();
            }
        }
        let spacing = if points.is_empty() {
            0.0
        } else {
            crate::fmath::sqrt((width * height) as f64 / points.len() as f64) as f32
        };
        let reach = 2.0 * spacing;
        // The hull of the zone rows (columns) whose span comes within `reach` of the pixel row
        // (column): every point in reach lies in one of them (a superset, in zone order).
        let hull = |span: &[u32], at: f32| -> u32 {
            let (mut lo, mut hi) = (u32::MAX, 0u32);
            for (k, mm) in span.chunks_exact(2).enumerate() {
                let (a, b) = (f32::from_bits(mm[0]), f32::from_bits(mm[1]));
                if a - reach <= at && at <= b + reach {
                    lo = lo.min(k as u32);
                    hi = k as u32 + 1;
                }
            }
            if lo == u32::MAX {
                0
            } else {
                lo << 16 | hi
            }
        };
        for (y, z) in row_zones.iter_mut().enumerate() {
            *z = hull(row_span, y as f32);
        }
        for (x, z) in col_zones.iter_mut().enumerate() {
            *z = hull(col_span, x as f32);
        }
        Ok(Self {
            points,
            rgb,
            width,
            height,
            cols,
            table,
            row_zones,
            col_zones,
            row_span,
            col_span,
            spacing,
        })
    }

    /// Fills `out` (`width · rows.len()` values, metres) with the output rows `rows`.
    pub fn rows(&self, rows: Range<usize>, out: &mut [f32]) -> Result<(), InterpError> {
        if rows.start > rows.end || rows.end > self.height {
            return Err(InterpError::Rows);
        }
        if out.len() != self.width * rows.len() {
            return Err(InterpError::OutputSize);
        }
        if self.points.is_empty() {
            out.fill(0.0);
            return Ok(());
        }
        let w = self.width;
        let terms = Terms {
            spacing: 2.0 * self.spacing * self.spacing,
            colour: 2.0 * SIGMA_RGB * SIGMA_RGB,
            reach2: (2.0 * self.spacing) * (2.0 * self.spacing),
        };
        for (y, row) in rows.clone().zip(out.chunks_exact_mut(w)) {
            for (x0, pixels) in (0..w).step_by(LANES).zip(row.chunks_mut(LANES)) {
                let group = self.group(y, x0, pixels.len());
                let (num, den) = self.group_sums(&group, &terms);
                for (l, o) in pixels.iter_mut().enumerate() {
                    *o = if den[l] > 1e-12 {
                        num[l] / den[l]
                    } else {
                        self.nearest(x0 + l, y)
                    };
                }
            }
        }
        Ok(())
    }

    /// The RGB of pixel `(x, y)` (clamped into the image) as `f32` levels.
    #[inline(always)]
    fn colour(&self, x: usize, y: usize) -> [f32; 3] {
        let i = 3 * (y.min(self.height - 1) * self.width + x.min(self.width - 1));
        [
            f32::from(self.rgb[i]),
            f32::from(self.rgb[i + 1]),
            f32::from(self.rgb[i + 2]),
        ]
    }

    /// The `n ≤ LANES` pixels of row `y` from column `x0`.
    fn group(&self, y: usize, x0: usize, n: usize) -> Group {
        let span = |z: u32| ((z >> 16), (z & 0xffff));
        let mut g = Group {
            y,
            xf: [0.0; LANES],
            rgb: [[0.0; LANES]; 3],
            col_lo: [0; LANES],
            col_hi: [0; LANES],
            zone_rows: span(self.row_zones[y]),
            zone_cols: (u32::MAX, 0),
        };
        for l in 0..LANES {
            let c = self.colour(x0 + l, y);
            for (plane, v) in g.rgb.iter_mut().zip(c) {
                plane[l] = v;
            }
            g.xf[l] = (x0 + l) as f32;
            // Lanes past the row's end keep no zone columns: they add nothing.
            if l < n {
                (g.col_lo[l], g.col_hi[l]) = span(self.col_zones[x0 + l]);
                if g.col_lo[l] < g.col_hi[l] {
                    g.zone_cols.0 = g.zone_cols.0.min(g.col_lo[l]);
                    g.zone_cols.1 = g.zone_cols.1.max(g.col_hi[l]);
                }
            }
        }
        g
    }

    /// Each point a group's pixels may take, in zone order, with its zone column and colour.
    #[inline(always)]
    fn candidates<'g>(
        &'g self,
        g: &'g Group,
    ) -> impl Iterator<Item = (u32, &'g ProjectedPoint, [f32; 3])> + 'g {
        (g.zone_rows.0..g.zone_rows.1).flat_map(move |zr| {
            (g.zone_cols.0..g.zone_cols.1).filter_map(move |zc| {
                let i = self.table[zr as usize * self.cols + zc as usize];
                (i != NONE).then(|| {
                    let p = &self.points[i as usize];
                    (zc, p, self.colour(p.x as usize, p.y as usize))
                })
            })
        })
    }

    /// The weighted sums `(Σ w·depth, Σ w)` of a group's pixels, over its candidates in zone
    /// order: NEON where the CPU has it, else the portable lanes (the same bits).
    fn group_sums(&self, g: &Group, t: &Terms) -> ([f32; LANES], [f32; LANES]) {
        #[cfg(target_arch = "aarch64")]
        if crate::kernels::isa::Isa::Neon.available() {
            // SAFETY: NEON is available (checked just above).
            return unsafe {
                crate::kernels::aarch64::joint_bilateral::group_sums(self.candidates(g), g, t)
            };
        }
        let mut num = [0.0f32; LANES];
        let mut den = [0.0f32; LANES];
        let yf = g.y as f32;
        for (zc, p, pc) in self.candidates(g) {
            // Stage by stage over the lanes, each lane the definition's operations in order.
            let dv = p.v - yf;
            let dv2 = dv * dv;
            let du = lanes(|l| p.u - g.xf[l]);
            let d2 = lanes(|l| du[l] * du[l] + dv2);
            let r = lanes(|l| g.rgb[0][l] - pc[0]);
            let gr = lanes(|l| g.rgb[1][l] - pc[1]);
            let b = lanes(|l| g.rgb[2][l] - pc[2]);
            let r2 = lanes(|l| r[l] * r[l] + gr[l] * gr[l] + b[l] * b[l]);
            let arg = lanes(|l| -d2[l] / t.spacing - r2[l] / t.colour);
            // 1 where the lane takes the point: its zone column and within reach.
            let take = lanes(|l| {
                let inside = g.col_lo[l] <= zc && zc < g.col_hi[l] && d2[l] <= t.reach2;
                if inside {
                    1.0
                } else {
                    0.0
                }
            });
            if take == [0.0; LANES] {
                continue;
            }
            // A lane that does not take the point adds +0 (a weight times 0) to sums that are
            // ≥ +0: they keep their bits, as if it had been skipped.
            let wgt = exp_f32_lanes(arg);
            let wl = lanes(|l| wgt[l] * take[l]);
            num = lanes(|l| num[l] + wl[l] * p.depth_m);
            den = lanes(|l| den[l] + wl[l]);
        }
        (num, den)
    }

    /// The depth of the point nearest pixel `(x, y)` (the first of equals).
    ///
    /// Zone rows and columns whose points all lie farther than a point already found are
    /// skipped: a row's `|p.v − y|` is at least its span's distance from `y` (rounding is
    /// monotonic, so the f32 `d` of each of its points is at least that distance squared), and
    /// a skipped point is strictly farther than the nearest one, so neither the nearest point
    /// nor the first of equals changes. The first bound is the nearest of the pixel's reach
    /// rectangle.
    fn nearest(&self, x: usize, y: usize) -> f32 {
        let (xf, yf) = (x as f32, y as f32);
        let dist = |p: &ProjectedPoint| {
            let (du, dv) = (p.u - xf, p.v - yf);
            du * du + dv * dv
        };
        let point = |zr: usize, zc: usize| {
            let i = self.table[zr * self.cols + zc];
            (i != NONE).then(|| &self.points[i as usize])
        };
        let span = |z: u32| (z >> 16) as usize..(z & 0xffff) as usize;
        let mut bound = f32::INFINITY;
        for zr in span(self.row_zones[y]) {
            for zc in span(self.col_zones[x]) {
                if let Some(p) = point(zr, zc) {
                    bound = bound.min(dist(p));
                }
            }
        }
        // The square of `at`'s distance from the span `[lo, hi]` (f32 bits), in f32.
        let below = |span: &[u32], at: f32| {
            let (lo, hi) = (f32::from_bits(span[0]), f32::from_bits(span[1]));
            let gap = if at < lo {
                lo - at
            } else if at > hi {
                at - hi
            } else {
                0.0
            };
            gap * gap
        };
        let mut best = (f32::INFINITY, 0.0);
        for (zr, rs) in self.row_span.chunks_exact(2).enumerate() {
            if below(rs, yf) > bound {
                continue;
            }
            for (zc, cs) in self.col_span.chunks_exact(2).enumerate() {
                if below(cs, xf) > bound {
                    continue;
                }
                if let Some(p) = point(zr, zc) {
                    let d = dist(p);
                    if d < best.0 {
                        best = (d, p.depth_m);
                    }
                }
            }
        }
        best.1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmath::exp_f32;
    use std::vec;
    use std::vec::Vec;

    fn pt(zone: u16, u: f32, v: f32, d: f32) -> ProjectedPoint {
        ProjectedPoint {
            zone,
            u,
            v,
            x: (u + 0.5) as u32,
            y: (v + 0.5) as u32,
            depth_m: d,
        }
    }

    /// The definition, over every point (the pass [`JointBilateral::rows`] must equal).
    fn every_point(points: &[ProjectedPoint], rgb: &[u8], w: usize, h: usize) -> Vec<f32> {
        let spacing = crate::fmath::sqrt((w * h) as f64 / points.len() as f64) as f32;
        let reach2 = (2.0 * spacing) * (2.0 * spacing);
        let colour = |x: usize, y: usize| {
            let i = 3 * (y.min(h - 1) * w + x.min(w - 1));
            [
                f32::from(rgb[i]),
                f32::from(rgb[i + 1]),
                f32::from(rgb[i + 2]),
            ]
        };
        let mut out = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let c = colour(x, y);
                let (mut num, mut den) = (0.0f32, 0.0f32);
                let mut best = (f32::INFINITY, 0.0);
                for p in points {
                    let (du, dv) = (p.u - x as f32, p.v - y as f32);
                    let d2 = du * du + dv * dv;
                    if d2 < best.0 {
                        best = (d2, p.depth_m);
                    }
                    if d2 > reach2 {
                        continue;
                    }
                    let pc = colour(p.x as usize, p.y as usize);
                    let (r, g, b) = (c[0] - pc[0], c[1] - pc[1], c[2] - pc[2]);
                    let wgt = exp_f32(
                        -d2 / (2.0 * spacing * spacing)
                            - (r * r + g * g + b * b) / (2.0 * SIGMA_RGB * SIGMA_RGB),
                    );
                    num += wgt * p.depth_m;
                    den += wgt;
                }
                out[y * w + x] = if den > 1e-12 { num / den } else { best.1 };
            }
        }
        out
    }

    fn run(
        points: &[ProjectedPoint],
        rgb: &[u8],
        w: usize,
        h: usize,
        grid: (usize, usize),
    ) -> Vec<f32> {
        let mut scratch = vec![0u32; scratch_words(w, h, grid.0, grid.1)];
        let jb = JointBilateral::prepare(points, rgb, (w, h), grid, &mut scratch).unwrap();
        let mut out = vec![0.0; w * h];
        // In two bands, as a host running them in parallel would.
        let (a, b) = out.split_at_mut(w * (h / 2));
        jb.rows(0..h / 2, a).unwrap();
        jb.rows(h / 2..h, b).unwrap();
        out
    }

    /// A perturbed `rows × cols` grid of points with some zones missing, random colours.
    fn scene(
        w: usize,
        h: usize,
        rows: usize,
        cols: usize,
        seed: u32,
    ) -> (Vec<ProjectedPoint>, Vec<u8>) {
        let mut s = seed.wrapping_mul(2_654_435_761).max(1);
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        };
        let rgb: Vec<u8> = (0..3 * w * h)
            .map(|i| ((i / 3 % w) * 7 + (next() % 40) as usize) as u8)
            .collect();
        let mut points = Vec::new();
        for r in 0..rows {
            for c in 0..cols {
                if next() % 7 == 0 {
                    continue;
                }
                let jitter = |v: u32| (v % 100) as f32 / 100.0 - 0.5;
                let u = ((c as f32 + 0.5) * w as f32 / cols as f32 + 2.0 * jitter(next()))
                    .clamp(0.0, w as f32 - 1.0);
                let v = ((r as f32 + 0.5) * h as f32 / rows as f32 + 2.0 * jitter(next()))
                    .clamp(0.0, h as f32 - 1.0);
                points.push(pt(
                    (r * cols + c) as u16,
                    u,
                    v,
                    0.5 + (next() % 400) as f32 / 100.0,
                ));
            }
        }
        (points, rgb)
    }

    #[test]
    fn equals_the_pass_over_every_point_bit_for_bit() {
        for (w, h, rows, cols, seed) in [
            (48, 64, 10, 8, 1),
            (40, 30, 8, 8, 2),
            (33, 17, 3, 5, 3),
            (64, 48, 30, 40, 4),
        ] {
            let (points, rgb) = scene(w, h, rows, cols, seed);
            // Also with colours random over the whole range: most weights underflow, so most
            // pixels take the nearest point.
            let mut s = seed;
            let noisy: Vec<u8> = rgb
                .iter()
                .map(|_| {
                    s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    (s >> 24) as u8
                })
                .collect();
            for rgb in [rgb, noisy] {
                let got = run(&points, &rgb, w, h, (rows, cols));
                let want = every_point(&points, &rgb, w, h);
                for (i, (g, e)) in got.iter().zip(&want).enumerate() {
                    assert_eq!(g.to_bits(), e.to_bits(), "{w}x{h} pixel {i}: {g} vs {e}");
                }
            }
        }
    }

    #[test]
    fn respects_colour_edges_and_falls_back_to_the_nearest_point() {
        // Left half black at 1 m, right half white at 3 m (the host baseline's test).
        let (w, h) = (16usize, 4usize);
        let mut rgb = vec![0u8; 3 * w * h];
        for y in 0..h {
            for x in 8..w {
                rgb[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[255, 255, 255]);
            }
        }
        let points = [pt(0, 4.0, 2.0, 1.0), pt(1, 12.0, 2.0, 3.0)];
        let j = run(&points, &rgb, w, h, (1, 2));
        assert!((j[2 * w + 7] - 1.0).abs() < 0.01, "{}", j[2 * w + 7]);
        assert!((j[2 * w + 8] - 3.0).abs() < 0.01, "{}", j[2 * w + 8]);
        // One point in a wide image: pixels beyond two spacings take it as the nearest.
        let (w, h) = (200usize, 2usize);
        let one = [pt(0, 1.0, 0.0, 2.5)];
        let j = run(&one, &vec![9u8; 3 * w * h], w, h, (1, 1));
        assert!(j.iter().all(|&d| (d - 2.5).abs() < 1e-6));
        assert!(
            j[60..200].iter().all(|&d| d == 2.5),
            "beyond reach: the point itself"
        );
        // No point: zeros.
        assert!(run(&[], &[0u8; 3 * 4 * 4], 4, 4, (2, 2))
            .iter()
            .all(|&d| d == 0.0));
    }

    #[test]
    fn bad_inputs_are_errors() {
        let (w, h) = (8usize, 8usize);
        let rgb = vec![0u8; 3 * w * h];
        let mut scratch = vec![0u32; scratch_words(w, h, 2, 2)];
        let good = [pt(0, 1.0, 1.0, 1.0), pt(3, 6.0, 6.0, 2.0)];
        let e = |points: &[ProjectedPoint], rgb: &[u8], scratch: &mut [u32]| {
            JointBilateral::prepare(points, rgb, (w, h), (2, 2), scratch).err()
        };
        assert_eq!(
            e(&good, &rgb[1..], &mut scratch),
            Some(InterpError::RgbSize)
        );
        assert_eq!(
            e(&good, &rgb, &mut scratch[1..]),
            Some(InterpError::ScratchSize)
        );
        assert_eq!(
            e(&[good[1], good[0]], &rgb, &mut scratch),
            Some(InterpError::ZoneOrder)
        );
        assert_eq!(
            e(&[pt(4, 1.0, 1.0, 1.0)], &rgb, &mut scratch),
            Some(InterpError::ZoneOrder)
        );
        for grid in [(0, 2), (usize::MAX, 3), (1 << 17, 1), (1 << 16, 1)] {
            let got = JointBilateral::prepare(&good, &rgb, (w, h), grid, &mut scratch).err();
            assert_eq!(got, Some(InterpError::Grid), "{grid:?}");
        }
        assert_eq!(scratch_words(w, h, usize::MAX, 3), usize::MAX);
        assert_eq!(
            e(&[pt(0, f32::NAN, 1.0, 1.0)], &rgb, &mut scratch),
            Some(InterpError::BadPoint)
        );
        assert_eq!(
            e(&[pt(0, 1.0, 1.0, 0.0)], &rgb, &mut scratch),
            Some(InterpError::BadPoint)
        );
        assert_eq!(
            e(&[pt(0, 20.0, 1.0, 1.0)], &rgb, &mut scratch),
            Some(InterpError::BadPoint)
        );
        let jb = JointBilateral::prepare(&good, &rgb, (w, h), (2, 2), &mut scratch).unwrap();
        assert_eq!(jb.rows(0..9, &mut [0.0; 72]), Err(InterpError::Rows));
        assert_eq!(jb.rows(0..2, &mut [0.0; 15]), Err(InterpError::OutputSize));
    }
}
