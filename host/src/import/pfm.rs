//! Portable Float Map reader (greyscale `Pf` only), as Middlebury stores disparities.
//!
//! Layout (Middlebury's PFM page): `Pf` ⏎ `width height` ⏎ `scale` ⏎, then `width·height`
//! 32-bit floats, rows stored **bottom to top**. `scale < 0` means little-endian samples,
//! `scale > 0` big-endian; `|scale|` is not applied to the samples. Exactly one whitespace
//! character separates the scale from the data.

use std::path::Path;

use super::{decode::read_bytes, ImportError};

/// A decoded greyscale PFM, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct Pfm {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples, row-major, row 0 at the top (already flipped from the file's bottom-up order).
    pub data: Vec<f32>,
}

/// What is wrong with a PFM file: which header field, or how much data.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PfmError {
    /// No bytes at all.
    #[error("empty file, expected PFM magic 'Pf'")]
    Empty,
    /// A colour PFM.
    #[error("colour PFM ('PF') not supported, expected greyscale 'Pf'")]
    Colour,
    /// Another magic.
    #[error("not a PFM file: magic {magic:?}, expected 'Pf'")]
    NotPfm {
        /// The first token, as text.
        magic: String,
    },
    /// The header ends before `field`.
    #[error("header: missing {field}")]
    Missing {
        /// `width`, `height` or `scale`.
        field: &'static str,
    },
    /// A size that is not a positive integer.
    #[error("header: {field} {text:?} is not a positive integer")]
    Size {
        /// `width` or `height`.
        field: &'static str,
        /// The token.
        text: String,
    },
    /// A scale that is not a number.
    #[error("header: scale {text:?} is not a number")]
    ScaleNotNumber {
        /// The token.
        text: String,
    },
    /// A zero or non-finite scale.
    #[error("header: scale {text:?} must be finite and non-zero (its sign gives the byte order)")]
    ScaleZero {
        /// The token.
        text: String,
    },
    /// Nothing after the scale.
    #[error("header: no data after the scale")]
    NoData,
    /// More samples than memory can address.
    #[error("header: {width}×{height} is too large")]
    TooLarge {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// Fewer or more data bytes than `width · height` floats.
    #[error("{}: {width}×{height} floats need {need} data bytes, found {found}", length_kind(*.found, *.need))]
    Length {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Bytes needed.
        need: usize,
        /// Bytes found.
        found: usize,
    },
}

fn length_kind(found: usize, need: usize) -> &'static str {
    if found < need {
        "truncated"
    } else {
        "trailing bytes"
    }
}

/// Reads a greyscale PFM file.
pub fn read_pfm(path: &Path) -> Result<Pfm, ImportError> {
    let bytes = read_bytes(path)?;
    parse_pfm(&bytes).map_err(|e| ImportError::invalid(path, e.to_string()))
}

/// The next whitespace-separated header token at or after `pos`, and the index just past it.
fn token(bytes: &[u8], pos: usize) -> Option<(&[u8], usize)> {
    let start = pos
        + bytes
            .get(pos..)?
            .iter()
            .position(|b| !b.is_ascii_whitespace())?;
    let len = bytes[start..]
        .iter()
        .position(|b| b.is_ascii_whitespace())
        .unwrap_or(bytes.len() - start);
    Some((&bytes[start..start + len], start + len))
}

/// Parses PFM bytes; the error says which header field or how much data is wrong.
pub(crate) fn parse_pfm(bytes: &[u8]) -> Result<Pfm, PfmError> {
    let (magic, pos) = token(bytes, 0).ok_or(PfmError::Empty)?;
    match magic {
        b"Pf" => {}
        b"PF" => return Err(PfmError::Colour),
        _ => {
            return Err(PfmError::NotPfm {
                magic: String::from_utf8_lossy(magic).into_owned(),
            })
        }
    }
    let field = |field: &'static str, pos: usize| -> Result<(String, usize), PfmError> {
        let (t, end) = token(bytes, pos).ok_or(PfmError::Missing { field })?;
        Ok((String::from_utf8_lossy(t).into_owned(), end))
    };
    let (w, pos) = field("width", pos)?;
    let (h, pos) = field("height", pos)?;
    let (s, pos) = field("scale", pos)?;
    let dim = |field: &'static str, t: &str| match t.parse::<u32>() {
        Ok(v) if v > 0 => Ok(v),
        _ => Err(PfmError::Size {
            field,
            text: t.to_string(),
        }),
    };
    let (width, height) = (dim("width", &w)?, dim("height", &h)?);
    let scale: f32 = s
        .parse()
        .map_err(|_| PfmError::ScaleNotNumber { text: s.clone() })?;
    if !scale.is_finite() || scale == 0.0 {
        return Err(PfmError::ScaleZero { text: s });
    }
    let little = scale < 0.0;
    let data = bytes.get(pos + 1..).ok_or(PfmError::NoData)?;
    let n = (width as usize)
        .checked_mul(height as usize)
        .filter(|n| n.checked_mul(4).is_some());
    let n = n.ok_or(PfmError::TooLarge { width, height })?;
    if data.len() != n * 4 {
        return Err(PfmError::Length {
            width,
            height,
            need: n * 4,
            found: data.len(),
        });
    }
    let w = width as usize;
    let mut out = vec![0.0f32; n];
    for (i, chunk) in data.chunks_exact(4).enumerate() {
        let b = [chunk[0], chunk[1], chunk[2], chunk[3]];
        let v = if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        };
        let (file_row, x) = (i / w, i % w);
        out[(height as usize - 1 - file_row) * w + x] = v;
    }
    Ok(Pfm {
        width,
        height,
        data: out,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand-made 2×2 PFM: the file lists the bottom row first.
    fn file(scale: &str, little: bool) -> Vec<u8> {
        let mut b = format!("Pf\n2 2\n{scale}\n").into_bytes();
        // Bottom row (image row 1): 3.0, +inf; top row (image row 0): 1.0, -2.5.
        for v in [3.0f32, f32::INFINITY, 1.0, -2.5] {
            b.extend_from_slice(&if little {
                v.to_le_bytes()
            } else {
                v.to_be_bytes()
            });
        }
        b
    }

    #[test]
    fn both_byte_orders_and_row_flip() {
        let want = Pfm {
            width: 2,
            height: 2,
            data: vec![1.0, -2.5, 3.0, f32::INFINITY],
        };
        assert_eq!(parse_pfm(&file("-1.0", true)), Ok(want.clone()));
        assert_eq!(parse_pfm(&file("1.0", false)), Ok(want.clone()));
        // The wrong byte order gives other numbers: the sign of scale matters.
        assert_ne!(parse_pfm(&file("1.0", true)), Ok(want.clone()));
        // Through a real file too.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.pfm");
        std::fs::write(&p, file("-0.003922", true)).unwrap();
        assert_eq!(read_pfm(&p).unwrap(), want);
    }

    #[test]
    fn malformed_headers_and_data() {
        let full = file("-1.0", true);
        let e = parse_pfm(&full[..full.len() - 1]).unwrap_err().to_string();
        assert!(
            e.starts_with("truncated: 2×2 floats need 16 data bytes, found 15"),
            "{e}"
        );
        let mut long = full.clone();
        long.push(0);
        let e = |b: &[u8]| parse_pfm(b).unwrap_err().to_string();
        assert!(e(&long).starts_with("trailing bytes"));
        assert!(e(b"PF\n2 2\n-1\n").contains("colour"));
        assert!(e(b"P5\n2 2\n-1\n").contains("not a PFM"));
        assert!(e(b"Pf\n2 x\n-1\n").contains("height \"x\""));
        assert!(e(b"Pf\n2 2\n0\n").contains("scale"));
        assert!(e(b"Pf\n2 2\n").contains("missing scale"));
        assert!(parse_pfm(b"").is_err());
    }
}
