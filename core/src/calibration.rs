//! Calibration of the RGB camera and the dToF sensor: intrinsics, zone geometry and the rigid
//! transform from the dToF frame to the camera frame (paper supplement, "Project dToF to Sparse
//! Depth Map"). Mirrors the `camera`, `dtof` and `dtof_to_camera` objects of `recording.json`
//! (`depthor-recording/1`, see docs/recording.md).

/// Pinhole intrinsics of the RGB camera, in pixels (`K_rgb`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraIntrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
}

/// How a zone's distance is measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DistanceKind {
    /// Perpendicular distance along the sensor's optical axis (what the VL53L5CX reports).
    Z,
    /// Distance along the zone's ray.
    Radial,
}

/// Zone grid of a dToF sensor: `rows × cols` zones, row-major, row 0 at the top of the image as
/// the camera sees it, on a uniform tangent grid over `fov_deg` centred on the sensor's axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DtofGeometry {
    /// Number of zone rows.
    pub rows: u16,
    /// Number of zone columns.
    pub cols: u16,
    /// Full field of view `[horizontal, vertical]` in degrees.
    pub fov_deg: [f32; 2],
    /// How distances are measured.
    pub distance: DistanceKind,
    /// Largest distance the sensor reports, metres.
    pub max_range_m: f32,
}

impl DtofGeometry {
    /// Number of zones (`rows * cols`).
    pub fn zones(&self) -> usize {
        self.rows as usize * self.cols as usize
    }
}

/// Rigid transform `P_rgb = R · P_dtof + t` (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extrinsics {
    /// Row-major rotation matrix `R`.
    pub rotation: [[f32; 3]; 3],
    /// Translation `t` in metres.
    pub translation_m: [f32; 3],
}

impl Extrinsics {
    /// The identity transform (sensor and camera share one optical centre and axis).
    pub const IDENTITY: Extrinsics = Extrinsics {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation_m: [0.0; 3],
    };

    /// Applies the transform to a point.
    pub fn apply(&self, p: [f32; 3]) -> [f32; 3] {
        let r = &self.rotation;
        let t = &self.translation_m;
        [
            r[0][0] * p[0] + r[0][1] * p[1] + r[0][2] * p[2] + t[0],
            r[1][0] * p[0] + r[1][1] * p[1] + r[1][2] * p[2] + t[1],
            r[2][0] * p[0] + r[2][1] * p[1] + r[2][2] * p[2] + t[2],
        ]
    }
}

/// Everything projection needs to map zones onto camera pixels.
///
/// `zone_rects_px`, when present, gives each zone's rectangle `[y0, x0, y1, x1]` in camera pixels
/// (ZJU-L5 style, already registered to the camera): the zone's point is then the rectangle's
/// centre and the extrinsics and `fov_deg` are not used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration<'a> {
    /// RGB camera intrinsics.
    pub camera: CameraIntrinsics,
    /// dToF zone grid.
    pub dtof: DtofGeometry,
    /// dToF → camera transform.
    pub dtof_to_camera: Extrinsics,
    /// Optional per-zone rectangles in camera pixels, row-major, `rows * cols` entries.
    pub zone_rects_px: Option<&'a [[f32; 4]]>,
}
