//! Offset and crosstalk calibration payloads as the ULD sends them per resolution. In 4×4 mode the
//! 8×8 grids are reduced to 4×4 (each 4×4 zone is the mean of its 2×2 block of 8×8 zones, the
//! rest zeroed) and a few constants are patched in; in 8×8 mode the buffers go out as they are.
//! Bytes are produced word by word so no copy of the 488/776-byte buffers is needed.

use super::protocol::{OFFSET_LEN, XTALK_LEN};

/// Patched into the NVM offset buffer at 0x10 for 4×4.
const OFFSET_DSS_4X4: [u8; 8] = [0x0F, 0x04, 0x04, 0x00, 0x08, 0x10, 0x10, 0x07];
/// Footer of the offset command (replaces the last 8 bytes).
const OFFSET_FOOTER: [u8; 8] = [0x00, 0x00, 0x00, 0x0F, 0x03, 0x01, 0x01, 0xE4];
/// Offset buffer: signal grid (64 × `u32`) and range grid (64 × `i16`) positions.
const OFFSET_SIGNAL: usize = 0x3C;
const OFFSET_RANGE: usize = 0x140;
/// Crosstalk patches for 4×4 (before the grid reduction).
const XTALK_RES_4X4: [u8; 8] = [0x0F, 0x04, 0x04, 0x17, 0x08, 0x10, 0x10, 0x07];
const XTALK_DSS_4X4: [u8; 8] = [0x00, 0x78, 0x00, 0x08, 0x00, 0x00, 0x00, 0x08];
/// Crosstalk patch for 4×4 (after the reduction) at 0x134, and the word zeroed at 0x78.
const XTALK_PROFILE_4X4: [u8; 4] = [0xA0, 0xFC, 0x01, 0x00];
const XTALK_SIGNAL: usize = 0x34;

/// Number of payload bytes of the offset command.
pub const OFFSET_PAYLOAD_LEN: usize = OFFSET_LEN;
/// Number of payload bytes of the crosstalk command.
pub const XTALK_PAYLOAD_LEN: usize = XTALK_LEN;

/// Raw byte `i` of `buf` with `patch` laid over it at `at`.
fn patched(buf: &[u8], i: usize, at: usize, patch: &[u8]) -> u8 {
    match i.checked_sub(at).and_then(|k| patch.get(k)) {
        Some(&b) => b,
        None => buf.get(i).copied().unwrap_or(0),
    }
}

/// The word (wire bytes) at `q` (a multiple of 4) of `raw` after reducing the `u32` grid at
/// `sig` to 4×4; `raw(i)` gives raw byte `i`.
fn reduced_u32_word(raw: &dyn Fn(usize) -> u8, sig: usize, q: usize) -> Option<[u8; 4]> {
    if !(sig..sig + 256).contains(&q) {
        return None;
    }
    let j = (q - sig) / 4;
    if j >= 16 {
        return Some([0; 4]);
    }
    let cell = |k: usize| {
        let b = sig + 4 * k;
        u32::from_be_bytes([raw(b), raw(b + 1), raw(b + 2), raw(b + 3)])
    };
    let (row, col) = (j / 4, j % 4);
    let base = 2 * col + 16 * row;
    let sum = cell(base)
        .wrapping_add(cell(base + 1))
        .wrapping_add(cell(base + 8))
        .wrapping_add(cell(base + 9));
    Some((sum / 4).to_be_bytes())
}

/// Offset payload byte `p` (`p < OFFSET_PAYLOAD_LEN`) for the given resolution, from the first
/// [`OFFSET_LEN`] bytes of the NVM answer.
pub fn offset_payload_byte(nvm: &[u8], four_by_four: bool, p: usize) -> u8 {
    if let Some(&b) = p
        .checked_sub(OFFSET_LEN - 8)
        .and_then(|k| OFFSET_FOOTER.get(k))
    {
        return b;
    }
    let i = p + 8;
    let raw = |i: usize| {
        if four_by_four {
            patched(nvm, i, 0x10, &OFFSET_DSS_4X4)
        } else {
            nvm.get(i).copied().unwrap_or(0)
        }
    };
    if !four_by_four {
        return raw(i);
    }
    let q = i & !3;
    if let Some(w) = reduced_u32_word(&raw, OFFSET_SIGNAL, q) {
        return w[i & 3];
    }
    if (OFFSET_RANGE..OFFSET_RANGE + 128).contains(&q) {
        // Word m holds range cells 2m (low half) and 2m + 1 (high half) of the swapped view.
        let cell = |n: usize| {
            let b = OFFSET_RANGE + 4 * (n / 2);
            let w = u32::from_be_bytes([raw(b), raw(b + 1), raw(b + 2), raw(b + 3)]);
            let half = if n.is_multiple_of(2) { w } else { w >> 16 };
            i32::from(half as u16 as i16)
        };
        let reduced = |n: usize| -> u16 {
            if n >= 16 {
                return 0;
            }
            let base = 2 * (n % 4) + 16 * (n / 4);
            let sum = cell(base) + cell(base + 1) + cell(base + 8) + cell(base + 9);
            (sum / 4) as i16 as u16
        };
        let m = (q - OFFSET_RANGE) / 4;
        let w = (u32::from(reduced(2 * m + 1)) << 16) | u32::from(reduced(2 * m));
        return w.to_be_bytes()[i & 3];
    }
    raw(i)
}

/// Crosstalk payload byte `p` (`p < XTALK_PAYLOAD_LEN`) for the given resolution, from ST's
/// default crosstalk buffer.
pub fn xtalk_payload_byte(xtalk: &[u8], four_by_four: bool, p: usize) -> u8 {
    if !four_by_four {
        return xtalk.get(p).copied().unwrap_or(0);
    }
    if let Some(&b) = p.checked_sub(0x134).and_then(|k| XTALK_PROFILE_4X4.get(k)) {
        return b;
    }
    if (0x78..0x7C).contains(&p) {
        return 0;
    }
    let raw = |i: usize| {
        let b = patched(xtalk, i, 0x08, &XTALK_RES_4X4);
        if (0x20..0x28).contains(&i) {
            patched(xtalk, i, 0x20, &XTALK_DSS_4X4)
        } else {
            b
        }
    };
    match reduced_u32_word(&raw, XTALK_SIGNAL, p & !3) {
        Some(w) => w[p & 3],
        None => raw(p),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_by_eight_offset_is_shifted_with_footer() {
        let nvm: [u8; OFFSET_LEN] = core::array::from_fn(|i| i as u8);
        assert_eq!(offset_payload_byte(&nvm, false, 0), 8);
        assert_eq!(offset_payload_byte(&nvm, false, 479), (479 + 8) as u8);
        assert_eq!(offset_payload_byte(&nvm, false, 483), 0x0F);
        assert_eq!(offset_payload_byte(&nvm, false, 487), 0xE4);
    }

    #[test]
    fn four_by_four_signal_is_the_mean_of_two_by_two() {
        let mut nvm = [0u8; OFFSET_LEN];
        // Signal cells 0, 1, 8, 9 (big-endian words) = 4, 8, 12, 16 → mean 10.
        for (k, v) in [(0usize, 4u32), (1, 8), (8, 12), (9, 16), (20, 99)] {
            nvm[OFFSET_SIGNAL + 4 * k..][..4].copy_from_slice(&v.to_be_bytes());
        }
        let word = |q: usize| {
            let b: [u8; 4] = core::array::from_fn(|k| offset_payload_byte(&nvm, true, q - 8 + k));
            u32::from_be_bytes(b)
        };
        assert_eq!(word(OFFSET_SIGNAL), 10);
        assert_eq!(word(OFFSET_SIGNAL + 4 * 20), 0, "cells ≥ 16 are zeroed");
        // The DSS patch lands at 0x10.
        assert_eq!(offset_payload_byte(&nvm, true, 0x10 - 8), 0x0F);
    }

    #[test]
    fn four_by_four_range_mean_truncates_towards_zero() {
        let mut nvm = [0u8; OFFSET_LEN];
        // Range cells are i16 halves of big-endian words: cell 2m = low half of word m.
        let put = |nvm: &mut [u8], n: usize, v: i16| {
            let b = OFFSET_RANGE + 4 * (n / 2);
            let mut w = u32::from_be_bytes([nvm[b], nvm[b + 1], nvm[b + 2], nvm[b + 3]]);
            if n.is_multiple_of(2) {
                w = (w & 0xFFFF_0000) | u32::from(v as u16);
            } else {
                w = (w & 0xFFFF) | (u32::from(v as u16) << 16);
            }
            nvm[b..b + 4].copy_from_slice(&w.to_be_bytes());
        };
        for (n, v) in [(0, -3i16), (1, -3), (8, -3), (9, 0)] {
            put(&mut nvm, n, v);
        }
        let b: [u8; 4] =
            core::array::from_fn(|k| offset_payload_byte(&nvm, true, OFFSET_RANGE - 8 + k));
        let w = u32::from_be_bytes(b);
        assert_eq!(
            (w & 0xFFFF) as u16 as i16,
            -2,
            "-9 / 4 truncates to -2 as in C"
        );
    }
}
