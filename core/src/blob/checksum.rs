//! CRC-32 (IEEE 802.3: reflected polynomial `0xEDB88320`, initial value and final XOR
//! `0xFFFFFFFF`, the same as zlib's `crc32` and Python's `zlib.crc32`), bitwise so it needs no
//! table in flash; run once per `Engine::new`.

/// CRC-32 of `data`.
pub fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            // A multiply, not a mask: LLVM turns the mask into a comparison, which the fuzz
            // build traces (8 calls per byte; each parse checks the CRC).
            crc = (crc >> 1) ^ 0xEDB8_8320u32.wrapping_mul(crc & 1);
        }
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_vectors() {
        assert_eq!(crc32(b""), 0);
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926); // the standard check value
        assert_eq!(crc32(b"a"), 0xE8B7_BE43);
    }
}
