//! Writes replay images ([`crate::format`]) on the host (`std` feature).

use std::io::{self, Write};

use depthor_core::calibration::{Calibration, DistanceKind};

use crate::format::{
    record_len, rgb_offset, CRC_LEN, HEADER_LEN, MAGIC, MAX_SIDE, MAX_ZONE_SIDE, VERSION,
};
use depthor_core::blob::checksum::crc32;

/// One frame to write: RGB888 at the calibration's camera size and the zones, row-major.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameData {
    /// `3 · width · height` bytes, interleaved RGB, row-major.
    pub rgb: Vec<u8>,
    /// Zone distances in millimetres (`rows · cols`).
    pub distance_mm: Vec<i16>,
    /// ST `target_status` per zone (`rows · cols`).
    pub status: Vec<u8>,
}

fn invalid(what: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, format!("replay image: {what}"))
}

/// The whole image as bytes; see [`write_image`] for what is checked.
pub fn image_bytes(cal: &Calibration, frames: &[FrameData]) -> io::Result<Vec<u8>> {
    let cam = &cal.camera;
    let geo = &cal.dtof;
    let side = |v: u32| u16::try_from(v).ok().filter(|v| (1..=MAX_SIDE).contains(v));
    let (Some(height), Some(width)) = (side(cam.height), side(cam.width)) else {
        return Err(invalid("camera height or width outside 1-4096"));
    };
    if !(1..=MAX_ZONE_SIDE).contains(&geo.rows) || !(1..=MAX_ZONE_SIDE).contains(&geo.cols) {
        return Err(invalid("zone rows or cols outside 1-255"));
    }
    if cal.zone_rects_px.is_some() {
        return Err(invalid(
            "zone rectangles cannot be stored (format version 1)",
        ));
    }
    let frame_count =
        u32::try_from(frames.len()).map_err(|_| invalid("more than 2^32 - 1 frames"))?;
    if frame_count == 0 {
        return Err(invalid("no frames"));
    }
    let zones = geo.zones();
    let pixels = usize::from(height) * usize::from(width);
    let record = record_len(zones, usize::from(height), usize::from(width))
        .ok_or_else(|| invalid("frame too large"))?;
    let mut out = Vec::with_capacity(HEADER_LEN + frames.len() * record + CRC_LEN);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(HEADER_LEN as u16).to_le_bytes());
    out.extend_from_slice(&frame_count.to_le_bytes());
    for v in [height, width, geo.rows, geo.cols] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.push(match geo.distance {
        DistanceKind::Z => 0,
        DistanceKind::Radial => 1,
    });
    out.extend_from_slice(&[0; 3]);
    let r = &cal.dtof_to_camera.rotation;
    let t = &cal.dtof_to_camera.translation_m;
    let floats = [
        cam.fx,
        cam.fy,
        cam.cx,
        cam.cy,
        geo.fov_deg[0],
        geo.fov_deg[1],
        geo.max_range_m,
    ]
    .into_iter()
    .chain(r.iter().flatten().copied())
    .chain(t.iter().copied());
    for v in floats {
        out.extend_from_slice(&v.to_le_bytes());
    }
    debug_assert_eq!(out.len(), HEADER_LEN);
    for (i, f) in frames.iter().enumerate() {
        if f.distance_mm.len() != zones || f.status.len() != zones {
            return Err(invalid(&format!(
                "frame {i} has {}/{} distances/statuses, the grid has {zones} zones",
                f.distance_mm.len(),
                f.status.len()
            )));
        }
        if f.rgb.len() != 3 * pixels {
            return Err(invalid(&format!(
                "frame {i} has {} RGB bytes, {height}x{width} needs {}",
                f.rgb.len(),
                3 * pixels
            )));
        }
        let start = out.len();
        out.extend_from_slice(&(zones as u16).to_le_bytes());
        out.extend_from_slice(&[0; 2]);
        for d in &f.distance_mm {
            out.extend_from_slice(&d.to_le_bytes());
        }
        out.extend_from_slice(&f.status);
        out.resize(start + rgb_offset(zones).unwrap_or(0), 0);
        out.extend_from_slice(&f.rgb);
        out.resize(start + record, 0);
    }
    out.extend_from_slice(&[0; CRC_LEN]);
    reseal(&mut out);
    Ok(out)
}

/// Writes a replay image of `frames` with calibration `cal` to `out`.
///
/// Fails with [`io::ErrorKind::InvalidInput`] when the calibration does not fit the format
/// (sizes out of range, zone rectangles) or a frame's RGB or zone arrays have the wrong length.
pub fn write_image<W: Write>(
    cal: &Calibration,
    frames: &[FrameData],
    mut out: W,
) -> io::Result<()> {
    out.write_all(&image_bytes(cal, frames)?)
}

/// Recomputes the trailing CRC-32 of an image in place (for tools and tests that edit images).
/// Does nothing to a buffer shorter than the CRC.
pub fn reseal(image: &mut [u8]) {
    if let Some(body) = image.len().checked_sub(CRC_LEN) {
        let crc = crc32(&image[..body]);
        image[body..].copy_from_slice(&crc.to_le_bytes());
    }
}
