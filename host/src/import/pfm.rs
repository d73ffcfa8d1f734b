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

/// Reads a greyscale PFM file.
pub fn read_pfm(path: &Path) -> Result<Pfm, ImportError> {
    let bytes = read_bytes(path)?;
    parse_pfm(&bytes).map_err(|what| ImportError::invalid(path, what))
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
pub(crate) fn parse_pfm(bytes: &[u8]) -> Result<Pfm, String> {
    let (magic, pos) = token(bytes, 0).ok_or("empty file, expected PFM magic 'Pf'")?;
    match magic {
        b"Pf" => {}
        b"PF" => return Err("colour PFM ('PF') not supported, expected greyscale 'Pf'".into()),
        _ => {
            return Err(format!(
                "not a PFM file: magic {:?}, expected 'Pf'",
                String::from_utf8_lossy(magic)
            ))
        }
    }
    let field = |name: &str, pos: usize| -> Result<(String, usize), String> {
        let (t, end) = token(bytes, pos).ok_or_else(|| format!("header: missing {name}"))?;
        Ok((String::from_utf8_lossy(t).into_owned(), end))
    };
    let (w, pos) = field("width", pos)?;
    let (h, pos) = field("height", pos)?;
    let (s, pos) = field("scale", pos)?;
    let dim = |name: &str, t: &str| match t.parse::<u32>() {
        Ok(v) if v > 0 => Ok(v),
        _ => Err(format!("header: {name} {t:?} is not a positive integer")),
    };
    let (width, height) = (dim("width", &w)?, dim("height", &h)?);
    let scale: f32 = s
        .parse()
        .map_err(|_| format!("header: scale {s:?} is not a number"))?;
    if !scale.is_finite() || scale == 0.0 {
        return Err(format!(
            "header: scale {s:?} must be finite and non-zero (its sign gives the byte order)"
        ));
    }
    let little = scale < 0.0;
    let data = bytes
        .get(pos + 1..)
        .ok_or("header: no data after the scale")?;
    let n = (width as usize)
        .checked_mul(height as usize)
        .filter(|n| n.checked_mul(4).is_some());
    let n = n.ok_or_else(|| format!("header: {width}×{height} is too large"))?;
    if data.len() != n * 4 {
        let kind = if data.len() < n * 4 {
            "truncated"
        } else {
            "trailing bytes"
        };
        return Err(format!(
            "{kind}: {width}×{height} floats need {} data bytes, found {}",
            n * 4,
            data.len()
        ));
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
        let e = parse_pfm(&full[..full.len() - 1]).unwrap_err();
        assert!(
            e.starts_with("truncated: 2×2 floats need 16 data bytes, found 15"),
            "{e}"
        );
        let mut long = full.clone();
        long.push(0);
        assert!(parse_pfm(&long).unwrap_err().starts_with("trailing bytes"));
        assert!(parse_pfm(b"PF\n2 2\n-1\n").unwrap_err().contains("colour"));
        assert!(parse_pfm(b"P5\n2 2\n-1\n")
            .unwrap_err()
            .contains("not a PFM"));
        assert!(parse_pfm(b"Pf\n2 x\n-1\n")
            .unwrap_err()
            .contains("height \"x\""));
        assert!(parse_pfm(b"Pf\n2 2\n0\n").unwrap_err().contains("scale"));
        assert!(parse_pfm(b"Pf\n2 2\n")
            .unwrap_err()
            .contains("missing scale"));
        assert!(parse_pfm(b"").is_err());
    }
}
