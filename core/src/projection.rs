//! Zones → sparse depth map at camera resolution (paper supplement, "Project dToF to Sparse Depth
//! Map"; docs/design.md, pipeline step 1).
//!
//! Each valid zone becomes one point at the projection of its centre ray:
//!
//! 1. **Zone ray.** Zone `(r, c)` of a `rows × cols` grid looks along the unit-z ray
//!    `(tx, ty, 1)` of a uniform tangent grid over the full field of view `fov_deg = [h, v]`:
//!    `tx = tan(h/2) · (2(c + ½)/cols − 1)`, `ty = tan(v/2) · (2(r + ½)/rows − 1)`
//!    (row 0 at the top, `y` pointing down, like the camera).
//! 2. **3-D point** in the dToF frame, metres (`d = distance_mm / 1000`):
//!    [`DistanceKind::Z`] `P = d · (tx, ty, 1)`; [`DistanceKind::Radial`] `P = d · ray / |ray|`.
//! 3. **To the camera**: `P_rgb = R · P + t` ([`Extrinsics`], the paper's `T_dToF→RGB`).
//! 4. **Perspective division** with `K_rgb`: `u = fx · X/Z + cx`, `v = fy · Y/Z + cy`; the depth is
//!    `Z_rgb` (planar, like the reference depth maps).
//! 5. **Pixel**: pixel centres sit at integer coordinates, so the point lands on
//!    `x = floor(u + ½)`, `y = floor(v + ½)`.
//!
//! When the calibration carries `zone_rects_px` (ZJU-L5 style, already registered to the camera),
//! steps 1–4 are replaced by: `(u, v)` is the rectangle's centre `((x0 + x1)/2, (y0 + y1)/2)` and
//! the depth is the distance itself (for [`DistanceKind::Radial`], converted to planar depth with
//! the camera ray through that centre: `Z = d / |((u − cx)/fx, (v − cy)/fy, 1)|`); extrinsics and
//! field of view are not used.
//!
//! A zone leaves no point, and is counted in [`ProjectionStats`] under its [`Skip`] reason, when
//! its status is not valid ([`status_is_valid`]), its distance is NaN, infinite or ≤ 0, the point
//! lies at or behind the camera plane, or its pixel falls outside the image. Distances are not
//! clipped at `max_range_m` here. Nothing here panics on any input.
//!
//! Arithmetic is done in `f64` (a few dozen operations per zone; soft-float on a Cortex-M4F,
//! which is acceptable for 64 zones per frame), so pixel coordinates are exact to well below
//! 1e-4 px (checked against hand-computed cases in `tests/projection.rs`).

use crate::calibration::{Calibration, DistanceKind, Extrinsics};
use crate::fmath;
use crate::hal::{status_is_valid, ZoneView};

/// Why a zone left no point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skip {
    /// The zone's status is not a valid range (see [`status_is_valid`]).
    InvalidStatus,
    /// The distance is NaN, infinite or ≤ 0 (or its depth does not fit an `f32`).
    BadDistance,
    /// The point lies at or behind the camera plane (`Z_rgb ≤ 0`).
    BehindCamera,
    /// The point's pixel is outside the image (or a calibration value made it undefined).
    OutOfImage,
}

/// One zone projected onto the camera image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectedPoint {
    /// Row-major zone index.
    pub zone: u16,
    /// Sub-pixel column (pixel centres at integers).
    pub u: f32,
    /// Sub-pixel row (pixel centres at integers).
    pub v: f32,
    /// Pixel column, `floor(u + 0.5)`, inside the image.
    pub x: u32,
    /// Pixel row, `floor(v + 0.5)`, inside the image.
    pub y: u32,
    /// Planar depth in the camera frame (`Z_rgb`), metres, > 0.
    pub depth_m: f32,
}

/// What a projection pass did with the zones: `projected` plus the four skip counts equal `zones`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProjectionStats {
    /// Zones looked at (`rows * cols`).
    pub zones: u32,
    /// Zones that produced a point.
    pub projected: u32,
    /// Zones skipped for [`Skip::InvalidStatus`].
    pub invalid_status: u32,
    /// Zones skipped for [`Skip::BadDistance`].
    pub bad_distance: u32,
    /// Zones skipped for [`Skip::BehindCamera`].
    pub behind_camera: u32,
    /// Zones skipped for [`Skip::OutOfImage`].
    pub out_of_image: u32,
    /// Points that landed on a pixel already holding one ([`project_to_sparse`] only; the nearer
    /// point is kept). Collided points still count as `projected`.
    pub collisions: u32,
}

impl ProjectionStats {
    /// Total zones skipped, for any reason.
    pub fn skipped(&self) -> u32 {
        self.invalid_status + self.bad_distance + self.behind_camera + self.out_of_image
    }

    fn record(&mut self, result: &Result<ProjectedPoint, Skip>) {
        match result {
            Ok(_) => self.projected += 1,
            Err(Skip::InvalidStatus) => self.invalid_status += 1,
            Err(Skip::BadDistance) => self.bad_distance += 1,
            Err(Skip::BehindCamera) => self.behind_camera += 1,
            Err(Skip::OutOfImage) => self.out_of_image += 1,
        }
    }
}

/// Why a projection pass could not run at all.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ProjectionError {
    /// The zone data does not match the calibration's `rows * cols` grid: `got` is the length of
    /// the offending distance or status slice, or the view's own `rows * cols` (a view whose rows
    /// and columns differ from the calibration's is reported here even when the counts agree).
    ZoneCountMismatch {
        /// Zones the calibration describes.
        expected: usize,
        /// Zones the data has.
        got: usize,
    },
    /// The output buffer is not `width * height` long.
    OutputSize {
        /// `width * height` of the camera.
        expected: usize,
        /// Length of the caller's buffer.
        got: usize,
    },
    /// A calibration value is unusable; the text says which.
    BadCalibration(&'static str),
}

impl core::fmt::Display for ProjectionError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ProjectionError::ZoneCountMismatch { expected, got } => write!(
                f,
                "zone data does not match the calibrated grid: expected {expected} zones, got {got}"
            ),
            ProjectionError::OutputSize { expected, got } => write!(
                f,
                "sparse depth buffer has {got} pixels, the camera needs {expected}"
            ),
            ProjectionError::BadCalibration(what) => write!(f, "bad calibration: {what}"),
        }
    }
}

impl core::error::Error for ProjectionError {}

/// The largest grid a [`ProjectedPoint::zone`] (`u16`) can index.
const MAX_ZONES: usize = u16::MAX as usize + 1;

/// How zones map to pixels, after validation.
#[derive(Clone, Copy)]
enum Mode<'a> {
    /// Tangent-grid rays through the extrinsics.
    Rays {
        tan_half_h: f64,
        tan_half_v: f64,
        rotation: [[f64; 3]; 3],
        translation: [f64; 3],
    },
    /// Registered per-zone rectangles `[y0, x0, y1, x1]`.
    Rects(&'a [[f32; 4]]),
}

/// A validated calibration with its constants in `f64`.
#[derive(Clone, Copy)]
struct Prepared<'a> {
    width: f64,
    height: f64,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    rows: usize,
    cols: usize,
    radial: bool,
    mode: Mode<'a>,
}

/// Half-FoV tangents from `fov_deg`, or `None` unless both are finite and in (0°, 180°).
fn tan_half_fov(fov_deg: [f32; 2]) -> Option<(f64, f64)> {
    let half = |deg: f32| {
        let deg = f64::from(deg);
        if deg.is_finite() && deg > 0.0 && deg < 180.0 {
            let t = fmath::tan_half_fov(deg.to_radians() * 0.5);
            t.is_finite().then_some(t)
        } else {
            None
        }
    };
    Some((half(fov_deg[0])?, half(fov_deg[1])?))
}

fn extrinsics_f64(e: &Extrinsics) -> Option<([[f64; 3]; 3], [f64; 3])> {
    let mut rotation = [[0.0; 3]; 3];
    for (dst, src) in rotation.iter_mut().zip(e.rotation.iter()) {
        for (d, s) in dst.iter_mut().zip(src.iter()) {
            *d = f64::from(*s);
        }
    }
    let translation = e.translation_m.map(f64::from);
    let finite = rotation.iter().flatten().all(|v| v.is_finite())
        && translation.iter().all(|v| v.is_finite());
    finite.then_some((rotation, translation))
}

/// Validates everything about `cal` that projection uses.
fn prepare<'a>(cal: &Calibration<'a>) -> Result<Prepared<'a>, ProjectionError> {
    let cam = &cal.camera;
    if cam.width == 0 || cam.height == 0 {
        return Err(ProjectionError::BadCalibration(
            "camera width or height is zero",
        ));
    }
    let (fx, fy, cx, cy) = (
        f64::from(cam.fx),
        f64::from(cam.fy),
        f64::from(cam.cx),
        f64::from(cam.cy),
    );
    if !(fx.is_finite() && fy.is_finite() && fx > 0.0 && fy > 0.0) {
        return Err(ProjectionError::BadCalibration(
            "camera fx and fy must be finite and > 0",
        ));
    }
    if !(cx.is_finite() && cy.is_finite()) {
        return Err(ProjectionError::BadCalibration(
            "camera cx and cy must be finite",
        ));
    }
    let rows = usize::from(cal.dtof.rows);
    let cols = usize::from(cal.dtof.cols);
    let zones = cal.dtof.zones();
    if zones > MAX_ZONES {
        return Err(ProjectionError::BadCalibration(
            "more than 65536 zones (zone indices are u16)",
        ));
    }
    let mode = match cal.zone_rects_px {
        Some(rects) => {
            if rects.len() != zones {
                return Err(ProjectionError::BadCalibration(
                    "zone_rects_px length differs from rows * cols",
                ));
            }
            Mode::Rects(rects)
        }
        None => {
            let (tan_half_h, tan_half_v) = tan_half_fov(cal.dtof.fov_deg).ok_or(
                ProjectionError::BadCalibration("fov_deg must be finite and in (0, 180) degrees"),
            )?;
            let (rotation, translation) = extrinsics_f64(&cal.dtof_to_camera).ok_or(
                ProjectionError::BadCalibration("dtof_to_camera has a non-finite value"),
            )?;
            Mode::Rays {
                tan_half_h,
                tan_half_v,
                rotation,
                translation,
            }
        }
    };
    Ok(Prepared {
        width: f64::from(cam.width),
        height: f64::from(cam.height),
        fx,
        fy,
        cx,
        cy,
        rows,
        cols,
        radial: cal.dtof.distance == DistanceKind::Radial,
        mode,
    })
}

/// Checks the zone data against the calibrated grid.
fn check_zones(cal: &Calibration<'_>, zones: &ZoneView<'_>) -> Result<(), ProjectionError> {
    let expected = cal.dtof.zones();
    let view = usize::from(zones.rows) * usize::from(zones.cols);
    for got in [zones.distance_mm.len(), zones.status.len(), view] {
        if got != expected {
            return Err(ProjectionError::ZoneCountMismatch { expected, got });
        }
    }
    if zones.rows != cal.dtof.rows || zones.cols != cal.dtof.cols {
        return Err(ProjectionError::ZoneCountMismatch {
            expected,
            got: view,
        });
    }
    Ok(())
}

/// `(tx, ty)` of zone `zone` on the tangent grid (caller ensures `zone < rows * cols`).
fn ray(rows: usize, cols: usize, tan_half_h: f64, tan_half_v: f64, zone: usize) -> (f64, f64) {
    let (r, c) = (zone / cols, zone % cols);
    let tx = tan_half_h * ((2.0 * (c as f64 + 0.5)) / cols as f64 - 1.0);
    let ty = tan_half_v * ((2.0 * (r as f64 + 0.5)) / rows as f64 - 1.0);
    (tx, ty)
}

impl Prepared<'_> {
    /// Projects one zone; `zone < rows * cols` is the caller's to ensure.
    fn project(&self, zone: usize, distance_mm: f32) -> Result<ProjectedPoint, Skip> {
        let d = f64::from(distance_mm);
        if !(d.is_finite() && d > 0.0) {
            return Err(Skip::BadDistance);
        }
        let d = d / 1000.0;
        let (u, v, depth) = match self.mode {
            Mode::Rays {
                tan_half_h,
                tan_half_v,
                rotation: r,
                translation: t,
            } => {
                let (tx, ty) = ray(self.rows, self.cols, tan_half_h, tan_half_v, zone);
                let scale = if self.radial {
                    d / fmath::sqrt(tx * tx + ty * ty + 1.0)
                } else {
                    d
                };
                let p = [scale * tx, scale * ty, scale];
                let q = [0, 1, 2].map(|i| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + t[i]);
                if q[2].is_nan() || q[2] <= 0.0 {
                    return Err(Skip::BehindCamera);
                }
                let u = self.fx * q[0] / q[2] + self.cx;
                let v = self.fy * q[1] / q[2] + self.cy;
                (u, v, q[2])
            }
            Mode::Rects(rects) => {
                let [y0, x0, y1, x1] = rects.get(zone).ok_or(Skip::OutOfImage)?.map(f64::from);
                let u = 0.5 * (x0 + x1);
                let v = 0.5 * (y0 + y1);
                let depth = if self.radial {
                    let a = (u - self.cx) / self.fx;
                    let b = (v - self.cy) / self.fy;
                    d / fmath::sqrt(a * a + b * b + 1.0)
                } else {
                    d
                };
                (u, v, depth)
            }
        };
        let depth_m = depth as f32;
        if depth_m.is_infinite() {
            return Err(Skip::BadDistance);
        }
        if depth_m.is_nan() || depth_m <= 0.0 {
            return Err(Skip::BehindCamera);
        }
        let (px, py) = (u + 0.5, v + 0.5);
        // `contains` is false for NaN, so undefined coordinates land here too.
        if !((0.0..self.width).contains(&px) && (0.0..self.height).contains(&py)) {
            return Err(Skip::OutOfImage);
        }
        Ok(ProjectedPoint {
            // `prepare` limits the grid to 65536 zones, so this never saturates.
            zone: u16::try_from(zone).unwrap_or(u16::MAX),
            u: u as f32,
            v: v as f32,
            // In [0, width) and [0, height): truncation is floor and fits u32.
            x: px as u32,
            y: py as u32,
            depth_m,
        })
    }
}

/// The unit-z ray `(tx, ty, 1)` of `zone` (row-major) in the dToF frame, from the tangent grid
/// over `fov_deg` (see the module doc). `None` when `zone ≥ rows * cols` or the field of view is
/// not finite and in (0°, 180°). Ignores `zone_rects_px`.
pub fn zone_ray(cal: &Calibration, zone: usize) -> Option<[f32; 3]> {
    let rows = usize::from(cal.dtof.rows);
    let cols = usize::from(cal.dtof.cols);
    if zone >= rows * cols {
        return None;
    }
    let (th, tv) = tan_half_fov(cal.dtof.fov_deg)?;
    let (tx, ty) = ray(rows, cols, th, tv, zone);
    Some([tx as f32, ty as f32, 1.0])
}

/// Projects one zone with distance `distance_mm` (its status is the caller's business).
///
/// Returns the skip reason when the zone leaves no point. An invalid calibration or a zone index
/// outside the grid also gives [`Skip::OutOfImage`] here (there is no pixel to give);
/// [`for_each_point`] and [`project_to_sparse`] report those as [`ProjectionError`] instead.
pub fn project_zone(
    cal: &Calibration,
    zone: usize,
    distance_mm: f32,
) -> Result<ProjectedPoint, Skip> {
    let prepared = prepare(cal).map_err(|_| Skip::OutOfImage)?;
    if zone >= cal.dtof.zones() {
        return Err(Skip::OutOfImage);
    }
    prepared.project(zone, distance_mm)
}

/// Projects every zone of `zones` and calls `f` with each point, in zone order.
///
/// Zones with an invalid status are [`Skip::InvalidStatus`] before their distance is looked at.
/// Fails, before calling `f`, when the calibration is unusable or the zone data does not have the
/// calibration's `rows × cols` shape. `collisions` stays 0 (points are not rasterised here).
pub fn for_each_point(
    cal: &Calibration,
    zones: &ZoneView,
    mut f: impl FnMut(ProjectedPoint),
) -> Result<ProjectionStats, ProjectionError> {
    let prepared = prepare(cal)?;
    check_zones(cal, zones)?;
    let mut stats = ProjectionStats::default();
    for (zone, (&distance, &status)) in zones
        .distance_mm
        .iter()
        .zip(zones.status.iter())
        .enumerate()
    {
        let result = if status_is_valid(status) {
            prepared.project(zone, distance)
        } else {
            Err(Skip::InvalidStatus)
        };
        stats.zones += 1;
        stats.record(&result);
        if let Ok(point) = result {
            f(point);
        }
    }
    Ok(stats)
}

/// Rasterises the zones into `out_depth_m`, the sparse depth map `S` (row-major,
/// `width * height`, metres, 0 = no point).
///
/// The buffer is zero-filled first. When two points land on one pixel the nearer is kept (a tie
/// keeps the earlier zone) and `collisions` counts it. Fails without touching `out_depth_m` when
/// the calibration or zone shape is unusable or the buffer has the wrong length.
pub fn project_to_sparse(
    cal: &Calibration,
    zones: &ZoneView,
    out_depth_m: &mut [f32],
) -> Result<ProjectionStats, ProjectionError> {
    prepare(cal)?;
    check_zones(cal, zones)?;
    let width = cal.camera.width as usize;
    let expected =
        width
            .checked_mul(cal.camera.height as usize)
            .ok_or(ProjectionError::BadCalibration(
                "camera width * height overflows usize",
            ))?;
    if out_depth_m.len() != expected {
        return Err(ProjectionError::OutputSize {
            expected,
            got: out_depth_m.len(),
        });
    }
    out_depth_m.fill(0.0);
    let mut collisions = 0u32;
    let mut stats = for_each_point(cal, zones, |p| {
        let index = p.y as usize * width + p.x as usize;
        if let Some(slot) = out_depth_m.get_mut(index) {
            if *slot > 0.0 {
                collisions += 1;
                if p.depth_m < *slot {
                    *slot = p.depth_m;
                }
            } else {
                *slot = p.depth_m;
            }
        }
    })?;
    stats.collisions = collisions;
    Ok(stats)
}
