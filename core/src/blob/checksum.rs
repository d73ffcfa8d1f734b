//! CRC-32 (IEEE 802.3: reflected polynomial `0xEDB88320`, initial value and final XOR
//! `0xFFFFFFFF`, the same as zlib's `crc32` and Python's `zlib.crc32`), bitwise so it needs no
//! table in flash; run once per `Engine::new`.

/// CRC-32 of `data`.
pub fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc ^= b as u32;
        // The eight bit steps written out: no loop counter to compare (the fuzz build traces
        // every comparison, and the blob's CRC is checked on each parse).
        crc = bit(bit(bit(bit(bit(bit(bit(bit(crc))))))));
    }
    !crc
}

/// One bit of the reflected CRC: shift right, XOR the polynomial if the bit out was set.
#[inline(always)]
fn bit(crc: u32) -> u32 {
    (crc >> 1) ^ (0xEDB8_8320 & (crc & 1).wrapping_neg())
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
