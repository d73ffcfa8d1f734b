//! CRC-32 as used by zlib, PNG and Ethernet (reflected polynomial `0xEDB88320`, initial value and
//! final XOR `0xFFFFFFFF`; the check value of `b"123456789"` is `0xCBF43926`).
//!
//! A 256-entry table built at compile time (1 KiB of flash), no allocation.

const POLY: u32 = 0xEDB8_8320;

const fn make_table() -> [u32; 256] {
    let mut table = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { POLY ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
}

static TABLE: [u32; 256] = make_table();

/// CRC-32 (IEEE 802.3) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        // The index is masked to 0..=255, so it is always inside the table.
        c = TABLE[((c ^ u32::from(b)) & 0xFF) as usize] ^ (c >> 8);
    }
    c ^ 0xFFFF_FFFF
}

#[cfg(test)]
mod tests {
    use super::crc32;

    #[test]
    fn check_value() {
        // The standard check value of the CRC-32/ISO-HDLC catalogue entry.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn empty_and_single_byte() {
        assert_eq!(crc32(b""), 0);
        // zlib: crc32(b"a") == 0xe8b7be43.
        assert_eq!(crc32(b"a"), 0xE8B7_BE43);
    }
}
