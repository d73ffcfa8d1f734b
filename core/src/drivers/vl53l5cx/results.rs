//! Result blocks: validation and decoding of the bytes read from index 0 of page 2.
//!
//! Layout (wire order): a 16-byte preamble (byte 0 = stream count), block after block (a 4-byte
//! header, then its payload), an 8-byte footer. Every 32-bit word is byte-swapped on the wire.
//! The decoder checks the whole buffer before it writes anything.

use super::protocol::{block, swapped, BlockHeader, RESULTS_FOOTER, RESULTS_PREAMBLE};

/// Largest zone count (8×8).
pub const MAX_ZONES: usize = 64;

/// One frame of results in ST's units (the fields and conversions of ST's
/// `VL53L5CX_ResultsData`, one target per zone). Entries beyond [`ResultsData::zones`] are 0.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResultsData {
    /// Zones in use: 16 (4×4) or 64 (8×8).
    pub zones: u8,
    /// Stream count of the frame (byte 0 of the preamble).
    pub stream_count: u8,
    /// Silicon temperature, °C.
    pub silicon_temp_degc: i8,
    /// Ambient rate per SPAD, kcps (raw ÷ 2048, truncated).
    pub ambient_per_spad: [u32; MAX_ZONES],
    /// Targets detected per zone.
    pub nb_target_detected: [u8; MAX_ZONES],
    /// Enabled SPADs per zone.
    pub nb_spads_enabled: [u32; MAX_ZONES],
    /// Signal rate per SPAD, kcps (raw ÷ 2048, truncated).
    pub signal_per_spad: [u32; MAX_ZONES],
    /// Range sigma, mm (raw ÷ 128, truncated).
    pub range_sigma_mm: [u16; MAX_ZONES],
    /// Distance, mm (raw ÷ 4 truncated towards zero, negatives clamped to 0).
    pub distance_mm: [i16; MAX_ZONES],
    /// Reflectance estimate, % (raw ÷ 2).
    pub reflectance: [u8; MAX_ZONES],
    /// ST target status; 255 where no target was detected.
    pub target_status: [u8; MAX_ZONES],
    /// Which optional blocks were present: ambient, signal, sigma.
    pub has: Present,
}

/// Optional blocks present in a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Present {
    /// Ambient rate block.
    pub ambient: bool,
    /// Signal rate block.
    pub signal: bool,
    /// Range sigma block.
    pub sigma: bool,
}

impl ResultsData {
    /// All zeros, 0 zones.
    pub const fn new() -> Self {
        ResultsData {
            zones: 0,
            stream_count: 0,
            silicon_temp_degc: 0,
            ambient_per_spad: [0; MAX_ZONES],
            nb_target_detected: [0; MAX_ZONES],
            nb_spads_enabled: [0; MAX_ZONES],
            signal_per_spad: [0; MAX_ZONES],
            range_sigma_mm: [0; MAX_ZONES],
            distance_mm: [0; MAX_ZONES],
            reflectance: [0; MAX_ZONES],
            target_status: [0; MAX_ZONES],
            has: Present {
                ambient: false,
                signal: false,
                sigma: false,
            },
        }
    }
}

impl Default for ResultsData {
    fn default() -> Self {
        Self::new()
    }
}

/// Why a results buffer was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResultsError {
    /// Shorter than preamble + footer.
    TooShort,
    /// A block's payload runs past the footer (`at` = header offset).
    Truncated {
        /// Offset of the block header.
        at: usize,
    },
    /// A block's payload is not a whole number of words (`at` = header offset).
    Misaligned {
        /// Offset of the block header.
        at: usize,
    },
    /// A known per-zone block has the wrong element type or zone count.
    BadBlock {
        /// Block index.
        idx: u16,
    },
    /// A block the driver needs (distance, target status) is missing.
    Missing {
        /// Block index.
        idx: u16,
    },
}

/// Element bytes and per-zone flag of the blocks we decode.
fn expected_kind(idx: u16) -> Option<u8> {
    match idx {
        block::AMBIENT | block::SPAD_COUNT | block::SIGNAL => Some(4),
        block::SIGMA | block::DISTANCE => Some(2),
        block::NB_TARGET | block::REFLECTANCE | block::TARGET_STATUS => Some(1),
        _ => None,
    }
}

fn word_at(buf: &[u8], at: usize) -> u32 {
    match buf.get(at..at + 4) {
        Some(&[a, b, c, d]) => u32::from_be_bytes([a, b, c, d]),
        _ => 0,
    }
}

/// Logical (unswapped) byte `o` of the buffer.
fn logical(buf: &[u8], o: usize) -> u8 {
    buf.get(swapped(o)).copied().unwrap_or(0)
}

/// Checks the block structure of `buf` for `zones` zones.
pub fn validate(buf: &[u8], zones: usize) -> Result<(), ResultsError> {
    if buf.len() < RESULTS_PREAMBLE + RESULTS_FOOTER {
        return Err(ResultsError::TooShort);
    }
    let end = buf.len() - RESULTS_FOOTER;
    let (mut distance, mut status) = (false, false);
    let mut at = RESULTS_PREAMBLE;
    while at + 4 <= end {
        let h = BlockHeader::from_word(word_at(buf, at));
        let n = h.payload_len();
        if !n.is_multiple_of(4) {
            return Err(ResultsError::Misaligned { at });
        }
        if at + 4 + n > end {
            return Err(ResultsError::Truncated { at });
        }
        if let Some(kind) = expected_kind(h.idx) {
            if h.kind != kind || usize::from(h.size) != zones {
                return Err(ResultsError::BadBlock { idx: h.idx });
            }
        }
        distance |= h.idx == block::DISTANCE;
        status |= h.idx == block::TARGET_STATUS;
        at += 4 + n;
    }
    if !distance {
        return Err(ResultsError::Missing {
            idx: block::DISTANCE,
        });
    }
    if !status {
        return Err(ResultsError::Missing {
            idx: block::TARGET_STATUS,
        });
    }
    Ok(())
}

/// Validates `buf` and decodes it into `out` (untouched on error).
pub fn decode(buf: &[u8], zones: usize, out: &mut ResultsData) -> Result<(), ResultsError> {
    validate(buf, zones)?;
    *out = ResultsData::new();
    out.zones = zones as u8;
    out.stream_count = buf.first().copied().unwrap_or(0);
    let end = buf.len() - RESULTS_FOOTER;
    let mut nb_target_seen = false;
    let mut at = RESULTS_PREAMBLE;
    while at + 4 <= end {
        let h = BlockHeader::from_word(word_at(buf, at));
        let data = at + 4;
        let u8_at = |k: usize| logical(buf, data + k);
        let u16_at = |k: usize| u16::from_le_bytes([u8_at(2 * k), u8_at(2 * k + 1)]);
        let u32_at = |k: usize| {
            u32::from_le_bytes([
                u8_at(4 * k),
                u8_at(4 * k + 1),
                u8_at(4 * k + 2),
                u8_at(4 * k + 3),
            ])
        };
        let z = zones.min(MAX_ZONES);
        match h.idx {
            block::METADATA => out.silicon_temp_degc = u8_at(8) as i8,
            block::AMBIENT => {
                out.has.ambient = true;
                for k in 0..z {
                    out.ambient_per_spad[k] = u32_at(k) / 2048;
                }
            }
            block::SPAD_COUNT => {
                for k in 0..z {
                    out.nb_spads_enabled[k] = u32_at(k);
                }
            }
            block::NB_TARGET => {
                nb_target_seen = true;
                for k in 0..z {
                    out.nb_target_detected[k] = u8_at(k);
                }
            }
            block::SIGNAL => {
                out.has.signal = true;
                for k in 0..z {
                    out.signal_per_spad[k] = u32_at(k) / 2048;
                }
            }
            block::SIGMA => {
                out.has.sigma = true;
                for k in 0..z {
                    out.range_sigma_mm[k] = u16_at(k) / 128;
                }
            }
            block::DISTANCE => {
                for k in 0..z {
                    out.distance_mm[k] = (u16_at(k) as i16 / 4).max(0);
                }
            }
            block::REFLECTANCE => {
                for k in 0..z {
                    out.reflectance[k] = u8_at(k) / 2;
                }
            }
            block::TARGET_STATUS => {
                for k in 0..z {
                    out.target_status[k] = u8_at(k);
                }
            }
            _ => {}
        }
        at = data + h.payload_len();
    }
    if nb_target_seen {
        for k in 0..zones.min(MAX_ZONES) {
            if out.nb_target_detected[k] == 0 {
                out.target_status[k] = 255;
            }
        }
    }
    Ok(())
}
