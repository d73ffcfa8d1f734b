//! Serde types mirroring `recording.json` and `dtof.json` of `depthor-recording/1` (docs/recording.md),
//! their checked parsing, their validation (shared by the reader and the writer) and their
//! conversions to the core's calibration types.

use super::error::Invalid;
use super::json::At;
use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};
use depthor_core::hal::ZoneView;
use serde::Serialize;
use std::collections::HashSet;

/// The value of `format` this crate reads and writes.
pub const FORMAT: &str = "depthor-recording/1";

/// Largest ST `target_status` code of the VL53L5CX range-status table (ST UM2884, "Target
/// status"): codes 0–13 are defined, 255 means no target. Anything else is rejected.
pub const MAX_ST_STATUS: u8 = 13;

/// Largest material class in `labels.png` (0 diffuse/unknown, 1 transparent, 2 specular/mirror,
/// 3 dark/absorbing; docs/recording.md).
pub const MAX_LABEL: u8 = 3;

fn is_true(b: &bool) -> bool {
    *b
}

/// `recording.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecordingMeta {
    /// Always [`FORMAT`].
    pub format: String,
    /// The RGB camera (frames may override it). In a recording without colour images
    /// (`rgb: false`) it is the virtual camera the zones are projected into.
    #[serde(serialize_with = "serialize_camera")]
    pub camera: CameraMeta,
    /// Whether the frames have `rgb.png` (`"rgb": false` only in zone-only recordings such as
    /// imported VL53L5CX logs; absent = true). Readers then hand out a black image of the
    /// camera's size.
    #[serde(skip_serializing_if = "is_true")]
    pub rgb: bool,
    /// The dToF sensor, absent for recordings with reference depth only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dtof: Option<DtofMeta>,
    /// dToF → camera transform; absent means identity.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dtof_to_camera: Option<ExtrinsicsMeta>,
    /// Frames in time order.
    pub frames: Vec<FrameMeta>,
}

/// The `camera` object: pinhole intrinsics in pixels, the core's own struct (one type from the
/// file to the projection; its fields are the object's keys).
pub type CameraMeta = CameraIntrinsics;

/// The `camera` object as serde writes it: the fields of [`CameraIntrinsics`] in their order.
struct CameraJson<'a>(&'a CameraIntrinsics);

impl Serialize for CameraJson<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let c = self.0;
        let mut o = s.serialize_struct("CameraMeta", 6)?;
        o.serialize_field("width", &c.width)?;
        o.serialize_field("height", &c.height)?;
        o.serialize_field("fx", &c.fx)?;
        o.serialize_field("fy", &c.fy)?;
        o.serialize_field("cx", &c.cx)?;
        o.serialize_field("cy", &c.cy)?;
        o.end()
    }
}

fn serialize_camera<S: serde::Serializer>(c: &CameraMeta, s: S) -> Result<S::Ok, S::Error> {
    CameraJson(c).serialize(s)
}

fn serialize_frame_camera<S: serde::Serializer>(
    c: &Option<CameraMeta>,
    s: S,
) -> Result<S::Ok, S::Error> {
    c.as_ref().map(CameraJson).serialize(s)
}

/// `"distance"`: how the sensor measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DistanceMeta {
    /// Perpendicular distance (`"z"`).
    Z,
    /// Along the zone's ray (`"radial"`).
    Radial,
}

/// The `dtof` object: zone grid.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DtofMeta {
    /// Zone rows.
    pub rows: u16,
    /// Zone columns.
    pub cols: u16,
    /// Full field of view `[horizontal, vertical]`, degrees.
    pub fov_deg: [f32; 2],
    /// Distance kind.
    pub distance: DistanceMeta,
    /// Largest reported distance, metres.
    pub max_range_m: f32,
    /// Per-zone rectangles `[y0, x0, y1, x1]` in camera pixels (serialised as `null` when absent).
    pub zone_rects_px: Option<Vec<[f32; 4]>>,
}

/// The `dtof_to_camera` object: `P_rgb = R · P_dtof + t`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ExtrinsicsMeta {
    /// Row-major rotation.
    pub rotation: [[f32; 3]; 3],
    /// Translation, metres.
    pub translation_m: [f32; 3],
}

/// One entry of `frames`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameMeta {
    /// Directory name under `frames/`.
    pub id: String,
    /// Capture time, seconds.
    pub t_s: f64,
    /// Per-frame camera overriding the recording's.
    #[serde(
        skip_serializing_if = "Option::is_none",
        serialize_with = "serialize_frame_camera"
    )]
    pub camera: Option<CameraMeta>,
}

/// `dtof.json`: one frame of zone measurements, row-major, `rows * cols` each.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DtofFrame {
    /// Distance per zone, millimetres.
    pub distance_mm: Vec<f32>,
    /// ST `target_status` per zone (5, 9 valid; 255 no target).
    pub status: Vec<u8>,
    /// Range sigma, millimetres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_mm: Option<Vec<f32>>,
    /// Signal rate, kcps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub signal_kcps: Option<Vec<f32>>,
    /// Ambient rate, kcps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ambient_kcps: Option<Vec<f32>>,
}

// ---------------------------------------------------------------------------------------------
// Parsing (types only; semantic checks are in `validate`).

/// Reads a `camera` object.
fn parse_camera(at: At<'_>) -> Result<CameraMeta, Invalid> {
    at.object(&["width", "height", "fx", "fy", "cx", "cy"])?;
    Ok(CameraMeta {
        width: at.req("width")?.at().uint(u32::MAX as u64)? as u32,
        height: at.req("height")?.at().uint(u32::MAX as u64)? as u32,
        fx: at.req("fx")?.at().f32()?,
        fy: at.req("fy")?.at().f32()?,
        cx: at.req("cx")?.at().f32()?,
        cy: at.req("cy")?.at().f32()?,
    })
}

impl DtofMeta {
    fn parse(at: At<'_>) -> Result<Self, Invalid> {
        at.object(&[
            "rows",
            "cols",
            "fov_deg",
            "distance",
            "max_range_m",
            "zone_rects_px",
        ])?;
        let d = at.req("distance")?;
        let distance = match d.at().str()? {
            "z" => DistanceMeta::Z,
            "radial" => DistanceMeta::Radial,
            other => {
                return Err(d.at().invalid(format_args!(
                    "expected \"z\" or \"radial\", found {other:?}"
                )))
            }
        };
        let zone_rects_px = match at.get("zone_rects_px") {
            None => None,
            Some(r) => Some(
                r.at()
                    .array()?
                    .iter()
                    .map(|c| c.at().fixed::<f32, 4>(|x| x.f32()))
                    .collect::<Result<Vec<_>, _>>()?,
            ),
        };
        Ok(DtofMeta {
            rows: at.req("rows")?.at().uint(u16::MAX as u64)? as u16,
            cols: at.req("cols")?.at().uint(u16::MAX as u64)? as u16,
            fov_deg: at.req("fov_deg")?.at().fixed::<f32, 2>(|x| x.f32())?,
            distance,
            max_range_m: at.req("max_range_m")?.at().f32()?,
            zone_rects_px,
        })
    }
}

impl ExtrinsicsMeta {
    fn parse(at: At<'_>) -> Result<Self, Invalid> {
        at.object(&["rotation", "translation_m"])?;
        Ok(ExtrinsicsMeta {
            rotation: at
                .req("rotation")?
                .at()
                .fixed::<[f32; 3], 3>(|row| row.fixed::<f32, 3>(|x| x.f32()))?,
            translation_m: at.req("translation_m")?.at().fixed::<f32, 3>(|x| x.f32())?,
        })
    }
}

impl FrameMeta {
    fn parse(at: At<'_>) -> Result<Self, Invalid> {
        at.object(&["id", "t_s", "camera"])?;
        Ok(FrameMeta {
            id: at.req("id")?.at().str()?.to_string(),
            t_s: at.req("t_s")?.at().f64()?,
            camera: at.get("camera").map(|c| parse_camera(c.at())).transpose()?,
        })
    }
}

impl RecordingMeta {
    /// Reads a parsed `recording.json` and validates it; errors name the field.
    pub fn from_json(value: &serde_json::Value) -> Result<Self, Invalid> {
        let at = At::root(value);
        at.object(&[
            "format",
            "camera",
            "rgb",
            "dtof",
            "dtof_to_camera",
            "frames",
        ])?;
        let meta = RecordingMeta {
            format: at.req("format")?.at().str()?.to_string(),
            camera: parse_camera(at.req("camera")?.at())?,
            rgb: at
                .get("rgb")
                .map(|c| c.at().bool())
                .transpose()?
                .unwrap_or(true),
            dtof: at
                .get("dtof")
                .map(|c| DtofMeta::parse(c.at()))
                .transpose()?,
            dtof_to_camera: at
                .get("dtof_to_camera")
                .map(|c| ExtrinsicsMeta::parse(c.at()))
                .transpose()?,
            frames: at
                .req("frames")?
                .at()
                .array()?
                .iter()
                .map(|c| FrameMeta::parse(c.at()))
                .collect::<Result<_, _>>()?,
        };
        meta.validate()?;
        Ok(meta)
    }
}

impl DtofFrame {
    /// Reads a parsed `dtof.json` and validates it against the zone grid; errors name the field.
    pub fn from_json(value: &serde_json::Value, geometry: &DtofMeta) -> Result<Self, Invalid> {
        let at = At::root(value);
        at.object(&[
            "distance_mm",
            "status",
            "sigma_mm",
            "signal_kcps",
            "ambient_kcps",
        ])?;
        let opt = |key: &str| at.get(key).map(|c| c.at().f32_vec()).transpose();
        let frame = DtofFrame {
            distance_mm: at.req("distance_mm")?.at().f32_vec()?,
            status: at
                .req("status")?
                .at()
                .array()?
                .iter()
                .map(|c| c.at().uint(u8::MAX as u64).map(|s| s as u8))
                .collect::<Result<_, _>>()?,
            sigma_mm: opt("sigma_mm")?,
            signal_kcps: opt("signal_kcps")?,
            ambient_kcps: opt("ambient_kcps")?,
        };
        frame.validate(geometry)?;
        Ok(frame)
    }
}

// ---------------------------------------------------------------------------------------------
// Validation.

fn finite(field: impl FnOnce() -> String, x: f64) -> Result<(), Invalid> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(Invalid::new(
            field(),
            format_args!("must be finite, found {x}"),
        ))
    }
}

fn positive(field: impl FnOnce() -> String, x: f64) -> Result<(), Invalid> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(Invalid::new(
            field(),
            format_args!("must be finite and > 0, found {x}"),
        ))
    }
}

fn all_finite(field: &str, xs: &[f32]) -> Result<(), Invalid> {
    match xs.iter().position(|x| !x.is_finite()) {
        None => Ok(()),
        Some(i) => finite(|| format!("{field}[{i}]"), xs[i] as f64),
    }
}

/// True when `id` can name a directory under `frames/` on every platform.
pub fn frame_id_is_valid(id: &str) -> bool {
    !id.is_empty()
        && id != "."
        && id != ".."
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-' || b == b'.')
}

/// Checks a camera's sizes are positive and intrinsics finite (focal lengths positive); errors
/// name `field`.
pub fn validate_camera(c: &CameraMeta, field: &str) -> Result<(), Invalid> {
    if c.width == 0 {
        return Err(Invalid::new(format!("{field}.width"), "must be > 0"));
    }
    if c.height == 0 {
        return Err(Invalid::new(format!("{field}.height"), "must be > 0"));
    }
    positive(|| format!("{field}.fx"), c.fx as f64)?;
    positive(|| format!("{field}.fy"), c.fy as f64)?;
    finite(|| format!("{field}.cx"), c.cx as f64)?;
    finite(|| format!("{field}.cy"), c.cy as f64)
}

impl DtofMeta {
    /// Number of zones (`rows * cols`).
    pub fn zones(&self) -> usize {
        self.rows as usize * self.cols as usize
    }

    /// Checks the grid is non-empty, the FoV in (0°, 180°), the range positive and the optional
    /// rectangles one finite, ordered rectangle per zone.
    pub fn validate(&self, field: &str) -> Result<(), Invalid> {
        if self.rows == 0 {
            return Err(Invalid::new(format!("{field}.rows"), "must be > 0"));
        }
        if self.cols == 0 {
            return Err(Invalid::new(format!("{field}.cols"), "must be > 0"));
        }
        for (i, &a) in self.fov_deg.iter().enumerate() {
            if !(a.is_finite() && a > 0.0 && a < 180.0) {
                return Err(Invalid::new(
                    format!("{field}.fov_deg[{i}]"),
                    format_args!("must be in (0, 180) degrees, found {a}"),
                ));
            }
        }
        positive(|| format!("{field}.max_range_m"), self.max_range_m as f64)?;
        if let Some(rects) = &self.zone_rects_px {
            let name = format!("{field}.zone_rects_px");
            if rects.len() != self.zones() {
                return Err(Invalid::new(
                    name,
                    format_args!(
                        "expected {} rectangles, found {}",
                        self.zones(),
                        rects.len()
                    ),
                ));
            }
            for (i, r) in rects.iter().enumerate() {
                all_finite(&format!("{name}[{i}]"), r)?;
                if r[0] > r[2] || r[1] > r[3] {
                    return Err(Invalid::new(
                        format!("{name}[{i}]"),
                        format_args!(
                            "expected [y0, x0, y1, x1] with y0 <= y1 and x0 <= x1, found {r:?}"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

impl ExtrinsicsMeta {
    /// Checks every entry is finite.
    pub fn validate(&self, field: &str) -> Result<(), Invalid> {
        for (i, row) in self.rotation.iter().enumerate() {
            all_finite(&format!("{field}.rotation[{i}]"), row)?;
        }
        all_finite(&format!("{field}.translation_m"), &self.translation_m)
    }
}

impl RecordingMeta {
    /// A recording header with no frames yet.
    pub fn new(
        camera: CameraMeta,
        dtof: Option<DtofMeta>,
        dtof_to_camera: Option<ExtrinsicsMeta>,
    ) -> Self {
        RecordingMeta {
            format: FORMAT.to_string(),
            camera,
            rgb: true,
            dtof,
            dtof_to_camera,
            frames: Vec::new(),
        }
    }

    /// Checks the format string, every number, the frame ids (valid directory names, unique)
    /// and the per-frame cameras.
    pub fn validate(&self) -> Result<(), Invalid> {
        if self.format != FORMAT {
            return Err(Invalid::new(
                "format",
                format_args!("expected {FORMAT:?}, found {:?}", self.format),
            ));
        }
        validate_camera(&self.camera, "camera")?;
        if let Some(d) = &self.dtof {
            d.validate("dtof")?;
        }
        if let Some(e) = &self.dtof_to_camera {
            e.validate("dtof_to_camera")?;
        }
        let mut seen = HashSet::new();
        for (i, f) in self.frames.iter().enumerate() {
            f.validate(&format!("frames[{i}]"))?;
            if !seen.insert(f.id.as_str()) {
                return Err(Invalid::new(
                    format!("frames[{i}].id"),
                    format_args!("duplicate frame id {:?}", f.id),
                ));
            }
        }
        Ok(())
    }

    /// Intrinsics of frame `i`: its own camera or the recording's. Panics if `i >= frames.len()`.
    pub fn frame_camera(&self, i: usize) -> &CameraMeta {
        self.frames[i].camera.as_ref().unwrap_or(&self.camera)
    }
}

impl FrameMeta {
    /// Checks the id, the time and the optional camera.
    pub fn validate(&self, field: &str) -> Result<(), Invalid> {
        if !frame_id_is_valid(&self.id) {
            return Err(Invalid::new(
                format!("{field}.id"),
                format_args!(
                    "{:?} is not a valid directory name (use A-Z a-z 0-9 _ - .)",
                    self.id
                ),
            ));
        }
        finite(|| format!("{field}.t_s"), self.t_s)?;
        if let Some(c) = &self.camera {
            validate_camera(c, &format!("{field}.camera"))?;
        }
        Ok(())
    }
}

impl DtofFrame {
    /// Checks every array holds `rows * cols` finite values and every status is an ST code.
    pub fn validate(&self, geometry: &DtofMeta) -> Result<(), Invalid> {
        let n = geometry.zones();
        let len = |field: &str, got: usize| {
            if got == n {
                Ok(())
            } else {
                Err(Invalid::new(
                    field,
                    format_args!(
                        "expected {n} values ({}×{} zones), found {got}",
                        geometry.rows, geometry.cols
                    ),
                ))
            }
        };
        len("distance_mm", self.distance_mm.len())?;
        all_finite("distance_mm", &self.distance_mm)?;
        len("status", self.status.len())?;
        if let Some(i) = self
            .status
            .iter()
            .position(|&s| s > MAX_ST_STATUS && s != depthor_core::hal::STATUS_NO_TARGET)
        {
            return Err(Invalid::new(
                format!("status[{i}]"),
                format_args!(
                    "{} is not an ST target_status code (0..={MAX_ST_STATUS} or 255)",
                    self.status[i]
                ),
            ));
        }
        for (name, arr) in [
            ("sigma_mm", &self.sigma_mm),
            ("signal_kcps", &self.signal_kcps),
            ("ambient_kcps", &self.ambient_kcps),
        ] {
            if let Some(a) = arr {
                len(name, a.len())?;
                all_finite(name, a)?;
            }
        }
        Ok(())
    }

    /// Borrowed view for projection (`rows`, `cols` from the recording's grid).
    pub fn view(&self, geometry: &DtofMeta) -> ZoneView<'_> {
        ZoneView {
            rows: geometry.rows,
            cols: geometry.cols,
            distance_mm: &self.distance_mm,
            status: &self.status,
        }
    }

    /// Number of zones whose status is valid (5 or 9).
    pub fn valid_zones(&self) -> usize {
        self.status
            .iter()
            .filter(|&&s| depthor_core::hal::status_is_valid(s))
            .count()
    }
}

// ---------------------------------------------------------------------------------------------
// Conversions to and from the core.

impl From<DistanceMeta> for DistanceKind {
    fn from(d: DistanceMeta) -> Self {
        match d {
            DistanceMeta::Z => DistanceKind::Z,
            DistanceMeta::Radial => DistanceKind::Radial,
        }
    }
}

impl From<DistanceKind> for DistanceMeta {
    fn from(d: DistanceKind) -> Self {
        match d {
            DistanceKind::Z => DistanceMeta::Z,
            DistanceKind::Radial => DistanceMeta::Radial,
        }
    }
}

impl From<&DtofMeta> for DtofGeometry {
    fn from(d: &DtofMeta) -> Self {
        DtofGeometry {
            rows: d.rows,
            cols: d.cols,
            fov_deg: d.fov_deg,
            distance: d.distance.into(),
            max_range_m: d.max_range_m,
        }
    }
}

impl DtofMeta {
    /// The `dtof` object for a core geometry, with optional zone rectangles.
    pub fn from_geometry(g: &DtofGeometry, zone_rects_px: Option<Vec<[f32; 4]>>) -> Self {
        DtofMeta {
            rows: g.rows,
            cols: g.cols,
            fov_deg: g.fov_deg,
            distance: g.distance.into(),
            max_range_m: g.max_range_m,
            zone_rects_px,
        }
    }
}

impl From<ExtrinsicsMeta> for Extrinsics {
    fn from(e: ExtrinsicsMeta) -> Self {
        Extrinsics {
            rotation: e.rotation,
            translation_m: e.translation_m,
        }
    }
}

impl From<Extrinsics> for ExtrinsicsMeta {
    fn from(e: Extrinsics) -> Self {
        ExtrinsicsMeta {
            rotation: e.rotation,
            translation_m: e.translation_m,
        }
    }
}

/// Owned calibration of one frame; [`CalibrationData::as_core`] lends the core's
/// [`Calibration`].
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationData {
    /// Camera intrinsics of the frame.
    pub camera: CameraIntrinsics,
    /// Zone grid.
    pub dtof: DtofGeometry,
    /// dToF → camera (identity when the recording has none).
    pub dtof_to_camera: Extrinsics,
    /// Per-zone rectangles in camera pixels.
    pub zone_rects_px: Option<Vec<[f32; 4]>>,
}

impl CalibrationData {
    /// Builds the calibration of a frame with camera `camera` in a recording with dToF `dtof`.
    pub fn new(
        camera: &CameraMeta,
        dtof: &DtofMeta,
        dtof_to_camera: Option<&ExtrinsicsMeta>,
    ) -> Self {
        CalibrationData {
            camera: *camera,
            dtof: dtof.into(),
            dtof_to_camera: dtof_to_camera.map_or(Extrinsics::IDENTITY, |&e| e.into()),
            zone_rects_px: dtof.zone_rects_px.clone(),
        }
    }

    /// The core's borrowed calibration.
    pub fn as_core(&self) -> Calibration<'_> {
        Calibration {
            camera: self.camera,
            dtof: self.dtof,
            dtof_to_camera: self.dtof_to_camera,
            zone_rects_px: self.zone_rects_px.as_deref(),
        }
    }
}
