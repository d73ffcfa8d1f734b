//! The replay flash image, format `DPTHRPLY` version 1: recorded frames (RGB + dToF zones) and
//! the calibration, in one blob the firmware embeds in flash and replays through its HAL.
//!
//! All integers and floats are little endian; floats are IEEE-754 `f32`. Offsets in bytes.
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | `[u8; 8]` | magic `b"DPTHRPLY"` ([`MAGIC`]) |
//! | 8 | `u16` | version, [`VERSION`] = 1 |
//! | 10 | `u16` | header length, [`HEADER_LEN`] = 104 (offset of the first frame) |
//! | 12 | `u32` | frame count, ≥ 1 |
//! | 16 | `u16` | image height H, 1–[`MAX_SIDE`] |
//! | 18 | `u16` | image width W, 1–[`MAX_SIDE`] |
//! | 20 | `u16` | zone rows, 1–255 |
//! | 22 | `u16` | zone cols, 1–255 |
//! | 24 | `u8` | distance kind: 0 = z, 1 = radial |
//! | 25 | `[u8; 3]` | reserved, 0 |
//! | 28 | `f32 × 4` | camera `fx, fy, cx, cy` (pixels) |
//! | 44 | `f32 × 3` | dToF `fov_h_deg, fov_v_deg, max_range_m` |
//! | 56 | `f32 × 9` | dToF → camera rotation, row-major |
//! | 92 | `f32 × 3` | dToF → camera translation, metres |
//! | 104 | frames | `frame count` records, back to back (below) |
//! | end − 4 | `u32` | CRC-32 (`depthor_core::blob::checksum::crc32`) of every byte before it |
//!
//! A frame record, `Z = rows · cols`; padding keeps every record and its RGB 4-byte aligned
//! (relative to the image start), so the firmware copies RGB with word moves:
//!
//! | type | field |
//! |---|---|
//! | `u16` | zone count; must equal `Z` |
//! | `u16` | reserved, 0 |
//! | `i16 × Z` | zone distance, millimetres, row-major, row 0 at the top |
//! | `u8 × Z` | ST `target_status` per zone (5, 9 valid; 255 no target) |
//! | `u8 × 0–3` | zero padding to a multiple of 4 bytes since the record start |
//! | `u8 × 3·H·W` | RGB888, interleaved, row-major, no padding between rows |
//! | `u8 × 0–3` | zero padding to a multiple of 4 bytes |
//!
//! [`Image::parse`] validates everything (header, exact length, CRC, every frame's zone count)
//! before the image is used, returns an [`ImageError`] for any defect and never panics.

use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};

use depthor_core::blob::checksum::crc32;

/// First eight bytes of every image.
pub const MAGIC: [u8; 8] = *b"DPTHRPLY";
/// Format version this crate reads and writes.
pub const VERSION: u16 = 1;
/// Bytes before the first frame record.
pub const HEADER_LEN: usize = 104;
/// Bytes of the trailing CRC-32.
pub const CRC_LEN: usize = 4;
/// Largest image height or width accepted.
pub const MAX_SIDE: u16 = 4096;
/// Zone rows and columns are limited to 255, as in the zone bridge protocol.
pub const MAX_ZONE_SIDE: u16 = 255;

/// Why an image cannot be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ImageError {
    /// The first eight bytes are not [`MAGIC`].
    BadMagic,
    /// The version field is not [`VERSION`].
    UnsupportedVersion(u16),
    /// A header field is out of range; the text says which.
    BadHeader(&'static str),
    /// The image is shorter than its header says.
    Truncated {
        /// Bytes the header implies.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// The image is longer than its header says.
    TrailingBytes {
        /// Bytes the header implies.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// The stored CRC-32 does not match the data.
    Crc {
        /// CRC stored in the image.
        stored: u32,
        /// CRC of the data.
        computed: u32,
    },
    /// A frame's zone count differs from the header's `rows · cols`.
    ZoneCount {
        /// Frame index.
        frame: u32,
        /// `rows · cols`.
        expected: usize,
        /// The frame's zone count.
        got: usize,
    },
}

impl ImageError {
    /// The firmware's exit status for this error (see the crate doc's table).
    pub fn exit_code(&self) -> u8 {
        match self {
            ImageError::BadMagic => 2,
            ImageError::UnsupportedVersion(_) => 3,
            ImageError::BadHeader(_) => 4,
            ImageError::Truncated { .. } => 5,
            ImageError::TrailingBytes { .. } => 6,
            ImageError::Crc { .. } => 7,
            ImageError::ZoneCount { .. } => 8,
        }
    }
}

impl core::fmt::Display for ImageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ImageError::BadMagic => f.write_str("not a replay image (bad magic)"),
            ImageError::UnsupportedVersion(v) => {
                write!(f, "replay image version {v}, this build reads {VERSION}")
            }
            ImageError::BadHeader(what) => write!(f, "bad replay image header: {what}"),
            ImageError::Truncated { expected, got } => {
                write!(
                    f,
                    "replay image truncated: {got} bytes, header implies {expected}"
                )
            }
            ImageError::TrailingBytes { expected, got } => {
                write!(f, "replay image has {got} bytes, header implies {expected}")
            }
            ImageError::Crc { stored, computed } => write!(
                f,
                "replay image CRC mismatch: stored {stored:#010x}, computed {computed:#010x}"
            ),
            ImageError::ZoneCount {
                frame,
                expected,
                got,
            } => write!(
                f,
                "replay frame {frame} has {got} zones, the header's grid has {expected}"
            ),
        }
    }
}

impl core::error::Error for ImageError {}

/// A validated replay image borrowing its bytes (in the firmware: flash).
#[derive(Clone, Copy, Debug)]
pub struct Image<'a> {
    bytes: &'a [u8],
    frame_count: u32,
    height: u16,
    width: u16,
    rows: u16,
    cols: u16,
    record_len: usize,
    calibration: Calibration<'static>,
}

/// One frame of an [`Image`]: borrowed zone and RGB bytes.
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    distance_le: &'a [u8],
    /// ST `target_status` per zone, row-major.
    pub status: &'a [u8],
    /// RGB888 pixels, `3 · H · W` bytes.
    pub rgb: &'a [u8],
}

impl<'a> Frame<'a> {
    /// Number of zones.
    pub fn zones(&self) -> usize {
        self.status.len()
    }

    /// Zone distances in millimetres, row-major.
    pub fn distance_mm(&self) -> impl Iterator<Item = i16> + 'a {
        self.distance_le.chunks_exact(2).map(|b| match *b {
            [lo, hi] => i16::from_le_bytes([lo, hi]),
            _ => 0, // chunks_exact(2) yields only pairs
        })
    }
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    match b.get(at..at + 2) {
        Some(&[x, y]) => u16::from_le_bytes([x, y]),
        _ => 0,
    }
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    match b.get(at..at + 4) {
        Some(&[a, b1, c, d]) => u32::from_le_bytes([a, b1, c, d]),
        _ => 0,
    }
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

/// Rounds `n` up to a multiple of 4, `None` on overflow.
fn pad4(n: usize) -> Option<usize> {
    Some(n.checked_add(3)? & !3)
}

/// Byte offset of the RGB inside a frame record with `zones` zones, `None` on overflow.
pub fn rgb_offset(zones: usize) -> Option<usize> {
    pad4(zones.checked_mul(3)?.checked_add(4)?)
}

/// Bytes of one frame record for `zones` zones and an `h × w` image, `None` on overflow.
pub fn record_len(zones: usize, height: usize, width: usize) -> Option<usize> {
    let rgb = height.checked_mul(width)?.checked_mul(3)?;
    pad4(rgb_offset(zones)?.checked_add(rgb)?)
}

impl<'a> Image<'a> {
    /// Validates `bytes` (header, exact length, CRC, zone counts) and returns the image.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, ImageError> {
        let min = HEADER_LEN + CRC_LEN;
        if bytes.len() < min {
            // Say "truncated" only for something that starts like an image.
            if bytes.len() >= MAGIC.len() && bytes.get(..MAGIC.len()) != Some(&MAGIC[..]) {
                return Err(ImageError::BadMagic);
            }
            return Err(ImageError::Truncated {
                expected: min,
                got: bytes.len(),
            });
        }
        if bytes.get(..MAGIC.len()) != Some(&MAGIC[..]) {
            return Err(ImageError::BadMagic);
        }
        let version = u16_at(bytes, 8);
        if version != VERSION {
            return Err(ImageError::UnsupportedVersion(version));
        }
        if usize::from(u16_at(bytes, 10)) != HEADER_LEN {
            return Err(ImageError::BadHeader("header length is not 104"));
        }
        let frame_count = u32_at(bytes, 12);
        let (height, width) = (u16_at(bytes, 16), u16_at(bytes, 18));
        let (rows, cols) = (u16_at(bytes, 20), u16_at(bytes, 22));
        if frame_count == 0 {
            return Err(ImageError::BadHeader("zero frames"));
        }
        if !(1..=MAX_SIDE).contains(&height) || !(1..=MAX_SIDE).contains(&width) {
            return Err(ImageError::BadHeader(
                "image height or width outside 1-4096",
            ));
        }
        if !(1..=MAX_ZONE_SIDE).contains(&rows) || !(1..=MAX_ZONE_SIDE).contains(&cols) {
            return Err(ImageError::BadHeader("zone rows or cols outside 1-255"));
        }
        let distance = match bytes.get(24) {
            Some(0) => DistanceKind::Z,
            Some(1) => DistanceKind::Radial,
            _ => return Err(ImageError::BadHeader("unknown distance kind")),
        };
        if bytes.get(25..28) != Some(&[0, 0, 0][..]) {
            return Err(ImageError::BadHeader("reserved bytes are not zero"));
        }
        let zones = usize::from(rows) * usize::from(cols);
        let too_big = ImageError::BadHeader("image size overflows the address space");
        let record = record_len(zones, usize::from(height), usize::from(width)).ok_or(too_big)?;
        let expected = usize::try_from(frame_count)
            .ok()
            .and_then(|n| n.checked_mul(record))
            .and_then(|n| n.checked_add(HEADER_LEN + CRC_LEN))
            .ok_or(too_big)?;
        if bytes.len() < expected {
            return Err(ImageError::Truncated {
                expected,
                got: bytes.len(),
            });
        }
        if bytes.len() > expected {
            return Err(ImageError::TrailingBytes {
                expected,
                got: bytes.len(),
            });
        }
        let body = expected - CRC_LEN;
        let stored = u32_at(bytes, body);
        let computed = crc32(bytes.get(..body).unwrap_or(&[]));
        if stored != computed {
            return Err(ImageError::Crc { stored, computed });
        }
        for frame in 0..frame_count {
            let at = HEADER_LEN + frame as usize * record;
            if u16_at(bytes, at + 2) != 0 {
                return Err(ImageError::BadHeader("frame reserved field is not zero"));
            }
            let got = usize::from(u16_at(bytes, at));
            if got != zones {
                return Err(ImageError::ZoneCount {
                    frame,
                    expected: zones,
                    got,
                });
            }
        }
        let f = |i: usize| f32_at(bytes, 28 + 4 * i);
        let calibration = Calibration {
            camera: CameraIntrinsics {
                width: u32::from(width),
                height: u32::from(height),
                fx: f(0),
                fy: f(1),
                cx: f(2),
                cy: f(3),
            },
            dtof: DtofGeometry {
                rows,
                cols,
                fov_deg: [f(4), f(5)],
                distance,
                max_range_m: f(6),
            },
            dtof_to_camera: Extrinsics {
                rotation: [
                    [f(7), f(8), f(9)],
                    [f(10), f(11), f(12)],
                    [f(13), f(14), f(15)],
                ],
                translation_m: [f(16), f(17), f(18)],
            },
            zone_rects_px: None,
        };
        Ok(Image {
            bytes,
            frame_count,
            height,
            width,
            rows,
            cols,
            record_len: record,
            calibration,
        })
    }

    /// Number of frames.
    pub fn frame_count(&self) -> u32 {
        self.frame_count
    }

    /// Image height and width in pixels.
    pub fn size(&self) -> (u16, u16) {
        (self.height, self.width)
    }

    /// Zone rows and columns.
    pub fn zone_grid(&self) -> (u16, u16) {
        (self.rows, self.cols)
    }

    /// The recorded calibration (no zone rectangles: the format stores the tangent-grid model).
    pub fn calibration(&self) -> Calibration<'static> {
        self.calibration
    }

    /// Total bytes of the image, CRC included.
    pub fn len_bytes(&self) -> usize {
        self.bytes.len()
    }

    /// Frame `index`, or `None` past the end.
    pub fn frame(&self, index: u32) -> Option<Frame<'a>> {
        if index >= self.frame_count {
            return None;
        }
        let zones = usize::from(self.rows) * usize::from(self.cols);
        let rgb_len = 3 * usize::from(self.height) * usize::from(self.width);
        let start = HEADER_LEN + index as usize * self.record_len;
        let record = self.bytes.get(start..start + self.record_len)?;
        let distance_le = record.get(4..4 + 2 * zones)?;
        let status = record.get(4 + 2 * zones..4 + 3 * zones)?;
        let rgb_at = rgb_offset(zones)?;
        let rgb = record.get(rgb_at..rgb_at + rgb_len)?;
        Some(Frame {
            distance_le,
            status,
            rgb,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{frame, mcu_calibration};
    use crate::writer::{image_bytes, reseal};

    fn small() -> Vec<u8> {
        // 2×3 image, 2×2 zones, 2 frames.
        let mut cal = mcu_calibration();
        cal.camera.width = 3;
        cal.camera.height = 2;
        cal.dtof.rows = 2;
        cal.dtof.cols = 2;
        let frames: Vec<_> = (0..2).map(|i| frame(i, 2, 2, 2, 3)).collect();
        image_bytes(&cal, &frames).unwrap()
    }

    #[test]
    fn layout_worked_by_hand() {
        // Record: 2 (count) + 2 (reserved) + 2·4 (distances) + 4 (status) = 16, already a
        // multiple of 4; RGB 3·2·3 = 18 → 34 → padded to 36. Image: 104 + 2·36 + 4 = 180.
        assert_eq!(rgb_offset(4), Some(16));
        assert_eq!(record_len(4, 2, 3), Some(36));
        assert_eq!(rgb_offset(64), Some(196)); // 4 + 192
        assert_eq!(record_len(64, 120, 160), Some(196 + 57_600));
        let bytes = small();
        assert_eq!(bytes.len(), 180);
        assert_eq!(&bytes[..8], b"DPTHRPLY");
        assert_eq!(&bytes[104..106], &4u16.to_le_bytes());
    }

    #[test]
    fn round_trip() {
        let bytes = small();
        let image = Image::parse(&bytes).unwrap();
        assert_eq!(image.frame_count(), 2);
        assert_eq!(image.size(), (2, 3));
        assert_eq!(image.zone_grid(), (2, 2));
        assert_eq!(image.calibration().camera.fx, 140.0);
        let want = frame(1, 2, 2, 2, 3);
        let f = image.frame(1).unwrap();
        assert_eq!(f.distance_mm().collect::<Vec<_>>(), want.distance_mm);
        assert_eq!(f.status, &want.status[..]);
        assert_eq!(f.rgb, &want.rgb[..]);
        assert!(image.frame(2).is_none());
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let bytes = small();
        for n in 0..bytes.len() {
            let err = Image::parse(&bytes[..n]).unwrap_err();
            assert!(
                matches!(err, ImageError::Truncated { got, .. } if got == n),
                "{n}: {err}"
            );
        }
    }

    #[test]
    fn defects_map_to_their_errors() {
        let good = small();
        let edit = |at: usize, v: u8, seal: bool| {
            let mut b = good.clone();
            b[at] = v;
            if seal {
                reseal(&mut b);
            }
            Image::parse(&b).unwrap_err()
        };
        assert_eq!(edit(0, b'X', true), ImageError::BadMagic);
        assert_eq!(edit(8, 2, true), ImageError::UnsupportedVersion(2));
        assert_eq!(
            edit(24, 7, true),
            ImageError::BadHeader("unknown distance kind")
        );
        // A flipped RGB byte without resealing: CRC.
        assert!(matches!(edit(130, 0xFF, false), ImageError::Crc { .. }));
        // Frame 1's zone count 5 instead of 4.
        assert_eq!(
            edit(104 + 36, 5, true),
            ImageError::ZoneCount {
                frame: 1,
                expected: 4,
                got: 5
            }
        );
        let mut long = good.clone();
        long.push(0);
        assert_eq!(
            Image::parse(&long).unwrap_err(),
            ImageError::TrailingBytes {
                expected: 180,
                got: 181
            }
        );
        // Codes are distinct.
        let codes = [
            ImageError::BadMagic.exit_code(),
            ImageError::UnsupportedVersion(0).exit_code(),
            ImageError::BadHeader("").exit_code(),
            ImageError::Truncated {
                expected: 0,
                got: 0,
            }
            .exit_code(),
            ImageError::TrailingBytes {
                expected: 0,
                got: 0,
            }
            .exit_code(),
            ImageError::Crc {
                stored: 0,
                computed: 0,
            }
            .exit_code(),
            ImageError::ZoneCount {
                frame: 0,
                expected: 0,
                got: 0,
            }
            .exit_code(),
        ];
        assert_eq!(codes, [2, 3, 4, 5, 6, 7, 8]);
    }

    #[test]
    fn huge_header_sizes_do_not_overflow() {
        let mut b = small();
        b[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        b[16..18].copy_from_slice(&4096u16.to_le_bytes());
        b[18..20].copy_from_slice(&4096u16.to_le_bytes());
        reseal(&mut b);
        assert!(matches!(
            Image::parse(&b).unwrap_err(),
            ImageError::Truncated { .. } | ImageError::BadHeader(_)
        ));
    }
}
