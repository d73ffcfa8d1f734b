//! Helpers shared by the fuzz targets (included with `#[path]`, not a crate of its own).
#![allow(dead_code)]

/// Reads fields from the fuzz input front to back; past the end every read is zero, so any
/// prefix of a seed is still a meaningful input.
pub struct Bytes<'a> {
    rest: &'a [u8],
}

impl<'a> Bytes<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        Bytes { rest: data }
    }
    pub fn u8(&mut self) -> u8 {
        match self.rest.split_first() {
            Some((&b, rest)) => {
                self.rest = rest;
                b
            }
            None => 0,
        }
    }
    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
    /// Any `f32` bit pattern: NaN, ±inf, subnormals, −0 included.
    pub fn f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }
    /// Up to `n` bytes (fewer at the end of the input).
    pub fn take(&mut self, n: usize) -> &'a [u8] {
        let (head, rest) = self.rest.split_at(n.min(self.rest.len()));
        self.rest = rest;
        head
    }
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }
    pub fn rest(&self) -> &'a [u8] {
        self.rest
    }
}

/// The test network at 4×4 with few channels (`core/tests/common`'s `Widths::MICRO`: every op
/// of the blob vocabulary, 8 KB), written by `DEPTHOR_WRITE_FUZZ_SEEDS=1 cargo test -p
/// depthor-core --test blob fuzz_seed`.
pub static MICRO_BLOB: &[u8] = include_bytes!("../seeds/micro_net.dblob");

/// A delay that does not wait (the drivers' polling loops are bounded by their own counts).
pub struct NoDelay;

impl embedded_hal::delay::DelayNs for NoDelay {
    fn delay_ns(&mut self, _ns: u32) {}
}
