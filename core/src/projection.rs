//! Zones → sparse depth map at camera resolution.
//!
//! Minimal implementation written by the host-recording branch so the host compiles; the
//! projection branch owns this module and replaces it on merge (same API).

use crate::calibration::{Calibration, DistanceKind};
use crate::hal::{status_is_valid, ZoneView};
use micromath::F32Ext;

/// Why a zone produced no point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skip {
    /// The zone's status is not 5 or 9.
    InvalidStatus,
    /// The distance is not finite or not positive.
    BadDistance,
    /// The point lies at or behind the camera plane.
    BehindCamera,
    /// The point projects outside the image.
    OutOfImage,
}

/// One zone projected onto the camera image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectedPoint {
    /// Row-major zone index.
    pub zone: u16,
    /// Sub-pixel column (pixel `x` covers `[x, x + 1)`).
    pub u: f32,
    /// Sub-pixel row.
    pub v: f32,
    /// Pixel column, `floor(u)`.
    pub x: u32,
    /// Pixel row, `floor(v)`.
    pub y: u32,
    /// Depth along the camera axis, metres.
    pub depth_m: f32,
}

/// Counts of what happened to the zones of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProjectionStats {
    /// Zones in the frame.
    pub zones: u32,
    /// Zones that produced a point.
    pub projected: u32,
    /// Zones skipped for their status.
    pub invalid_status: u32,
    /// Zones skipped for a non-finite or non-positive distance.
    pub bad_distance: u32,
    /// Zones whose point lies behind the camera.
    pub behind_camera: u32,
    /// Zones whose point falls outside the image.
    pub out_of_image: u32,
    /// Points that landed on a pixel already holding one (the nearer is kept).
    pub collisions: u32,
}

/// Inconsistent inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProjectionError {
    /// The zone view does not hold `rows * cols` of the calibration.
    ZoneCountMismatch {
        /// Zones the calibration describes.
        expected: usize,
        /// Zones the view holds.
        got: usize,
    },
    /// The output buffer is not `width * height`.
    OutputSize {
        /// `width * height`.
        expected: usize,
        /// Buffer length.
        got: usize,
    },
    /// The calibration cannot be used.
    BadCalibration(&'static str),
}

fn check(cal: &Calibration, zones: &ZoneView) -> Result<usize, ProjectionError> {
    let expected = cal.dtof.zones();
    let got = zones.rows as usize * zones.cols as usize;
    if got != expected || zones.distance_mm.len() != expected || zones.status.len() != expected {
        return Err(ProjectionError::ZoneCountMismatch {
            expected,
            got: zones.distance_mm.len().min(zones.status.len()).min(got),
        });
    }
    let c = &cal.camera;
    if c.width == 0 || c.height == 0 {
        return Err(ProjectionError::BadCalibration("camera size is zero"));
    }
    if !(c.fx.is_finite() && c.fy.is_finite() && c.cx.is_finite() && c.cy.is_finite()) {
        return Err(ProjectionError::BadCalibration(
            "camera intrinsics not finite",
        ));
    }
    if let Some(rects) = cal.zone_rects_px {
        if rects.len() != expected {
            return Err(ProjectionError::BadCalibration("zone_rects_px length"));
        }
    }
    Ok(expected)
}

fn project_zone(cal: &Calibration, i: usize, d_mm: f32) -> Result<(f32, f32, f32), Skip> {
    if !d_mm.is_finite() || d_mm <= 0.0 {
        return Err(Skip::BadDistance);
    }
    let d = d_mm / 1000.0;
    let (u, v, z) = match cal.zone_rects_px.and_then(|r| r.get(i)) {
        Some(r) => ((r[1] + r[3]) * 0.5, (r[0] + r[2]) * 0.5, d),
        None => {
            let cols = cal.dtof.cols as usize;
            let (row, col) = (i / cols, i % cols);
            let half_h = F32Ext::tan(cal.dtof.fov_deg[0].to_radians() * 0.5);
            let half_v = F32Ext::tan(cal.dtof.fov_deg[1].to_radians() * 0.5);
            let tx = half_h * ((2 * col + 1) as f32 / cols as f32 - 1.0);
            let ty = half_v * ((2 * row + 1) as f32 / cal.dtof.rows as f32 - 1.0);
            let zs = match cal.dtof.distance {
                DistanceKind::Z => d,
                DistanceKind::Radial => d / F32Ext::sqrt(1.0 + tx * tx + ty * ty),
            };
            let q = cal.dtof_to_camera.apply([tx * zs, ty * zs, zs]);
            if q[2].is_nan() || q[2] <= 0.0 {
                return Err(Skip::BehindCamera);
            }
            let c = &cal.camera;
            (c.fx * q[0] / q[2] + c.cx, c.fy * q[1] / q[2] + c.cy, q[2])
        }
    };
    let (w, h) = (cal.camera.width as f32, cal.camera.height as f32);
    if !(u >= 0.0 && u < w && v >= 0.0 && v < h) {
        return Err(Skip::OutOfImage);
    }
    Ok((u, v, z))
}

/// Projects every valid zone and calls `f` with its point, in zone order.
pub fn for_each_point(
    cal: &Calibration,
    zones: &ZoneView,
    mut f: impl FnMut(ProjectedPoint),
) -> Result<ProjectionStats, ProjectionError> {
    let n = check(cal, zones)?;
    let mut stats = ProjectionStats {
        zones: n as u32,
        ..ProjectionStats::default()
    };
    for (i, (&d, &s)) in zones.distance_mm.iter().zip(zones.status).enumerate() {
        let r = if status_is_valid(s) {
            project_zone(cal, i, d)
        } else {
            Err(Skip::InvalidStatus)
        };
        match r {
            Ok((u, v, z)) => {
                stats.projected += 1;
                f(ProjectedPoint {
                    zone: i as u16,
                    u,
                    v,
                    x: u as u32,
                    y: v as u32,
                    depth_m: z,
                });
            }
            Err(Skip::InvalidStatus) => stats.invalid_status += 1,
            Err(Skip::BadDistance) => stats.bad_distance += 1,
            Err(Skip::BehindCamera) => stats.behind_camera += 1,
            Err(Skip::OutOfImage) => stats.out_of_image += 1,
        }
    }
    Ok(stats)
}

/// Writes the sparse depth map (metres, 0 where no point) into `out_depth_m` (`width * height`).
pub fn project_to_sparse(
    cal: &Calibration,
    zones: &ZoneView,
    out_depth_m: &mut [f32],
) -> Result<ProjectionStats, ProjectionError> {
    let expected = cal.camera.width as usize * cal.camera.height as usize;
    if out_depth_m.len() != expected {
        return Err(ProjectionError::OutputSize {
            expected,
            got: out_depth_m.len(),
        });
    }
    out_depth_m.fill(0.0);
    let w = cal.camera.width as usize;
    let mut collisions = 0;
    let mut stats = for_each_point(cal, zones, |p| {
        if let Some(px) = out_depth_m.get_mut(p.y as usize * w + p.x as usize) {
            if *px > 0.0 {
                collisions += 1;
                *px = px.min(p.depth_m);
            } else {
                *px = p.depth_m;
            }
        }
    })?;
    stats.collisions = collisions;
    Ok(stats)
}
