//! A simulated VL53L5CX: an [`embedded_hal::i2c::I2c`] device that answers ST's ULD protocol,
//! for host tests and the QEMU firmware. `no_std`, no allocation.
//!
//! What it models (and checks):
//!
//! - Pages (`0x7FFF` select), device/revision ids, GO2 status registers, the firmware-access
//!   flag (page 1, `0x21`), a soft reset (page 0 `0x0F` ← `0x43`).
//! - The firmware upload: pages 9, 10, 11 written from index 0, in order, exactly
//!   `0x8000`/`0x8000`/`0x5000` bytes (a write past a page's part is not acknowledged). The MCU
//!   boot (page 0 `0x0B` ← `0x01`) fails with GO2 status `0x80`/`0x60` unless the upload was
//!   complete; [`SimVl53l5cx::firmware_hash`] is an FNV-1a 64 of the uploaded bytes. The
//!   content is not interpreted (a stand-in image of the right size boots).
//! - The command area (page 2, `0x2C00..0x3000`): a write whose last byte lands on `0x2FFF` is a
//!   command, framed by an 8-byte footer (`00 00 00 0F`, kind, 1 = write blocks / 2 = read
//!   blocks, length − 4). Written blocks (default configuration, offset, crosstalk, DCI writes)
//!   are parsed; the data items the firmware uses are kept. Read requests are answered at
//!   `0x2C04` (NVM calibration is synthetic). The start command (`00 03 00 00` at `0x2FFC`)
//!   checks the output list against the zone configuration and publishes the results size.
//!   The status word at `0x2C00` reads `[kind, 3, 0, 0]` when done, `[kind, 3, 0x80, 0]` when
//!   the command was malformed.
//! - Results: after `start` the sensor runs free: every data-ready read (4 bytes at index 0)
//!   counts one tick, and a new frame is published on the tick after
//!   [`SimVl53l5cx::set_latency_polls`] ticks without one (so a host that stops reading still
//!   sees the stream count move on). Blocks follow the programmed output list,
//!   built from the zones given to [`SimVl53l5cx::set_zones`] in the sensor's units and byte
//!   order.
//!
//! What it does not model: timing, power modes, the sensor's optics or noise.

use embedded_hal::i2c::{ErrorKind as I2cErrorKind, I2c, NoAcknowledgeSource, Operation};

use super::protocol::{self, block, dci, BlockHeader, *};
use super::UldBuffers;

/// One zone as the simulated sensor should report it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimZone {
    /// Distance, mm (sent × 4; clamped to the `i16` range).
    pub distance_mm: i16,
    /// ST target status; 255 = no target (sent as 0 targets detected).
    pub status: u8,
    /// Range sigma, mm (sent × 128).
    pub sigma_mm: u16,
    /// Signal per SPAD, kcps (sent × 2048).
    pub signal_kcps: u32,
    /// Ambient per SPAD, kcps (sent × 2048).
    pub ambient_kcps: u32,
}

impl SimZone {
    /// No target, everything 0.
    pub const NONE: SimZone = SimZone {
        distance_mm: 0,
        status: 255,
        sigma_mm: 0,
        signal_kcps: 0,
        ambient_kcps: 0,
    };
}

/// Largest results buffer the simulation serves (8×8, every ULD output).
pub const MAX_RESULTS: usize = 1440;

const UI_BASE: usize = UI_CMD_STATUS as usize;
const UI_LEN: usize = 0x3000 - UI_BASE;
const TRACKED: [u16; 14] = [
    dci::ZONE_CONFIG,
    dci::FREQ_HZ,
    dci::INT_TIME,
    dci::RANGE_DATA_INFO,
    0x5478,
    dci::RANGING_MODE,
    dci::DSS_CONFIG,
    0xAE64,
    0xAED8,
    dci::SINGLE_RANGE,
    dci::OUTPUT_CONFIG,
    dci::OUTPUT_ENABLES,
    dci::OUTPUT_LIST,
    dci::PIPE_CONTROL,
];
const DCI_MAX: usize = 48;
/// GO2 status 1 code the simulation reports when the firmware upload was incomplete.
pub const BOOT_ERROR_CODE: u8 = 0x60;

/// The simulated sensor (see the module docs).
#[derive(Clone, Debug)]
pub struct SimVl53l5cx {
    address: u8,
    ids: (u8, u8),
    page: u8,
    regs0: [u8; 0x20],
    fw_access: bool,
    fw_written: [usize; 3],
    fw_in_order: bool,
    fw_hash: u64,
    booted: bool,
    boot_error: bool,
    mcu_stopped: bool,
    ui: [u8; UI_LEN],
    dci: [(u16, u8, [u8; DCI_MAX]); TRACKED.len()],
    ranging: bool,
    results_len: usize,
    results: [u8; MAX_RESULTS],
    stream: u8,
    latency_polls: u32,
    polls_left: u32,
    zones: [SimZone; 64],
    frames: u32,
    commands: u32,
}

impl Default for SimVl53l5cx {
    fn default() -> Self {
        Self::new()
    }
}

fn fnv(mut h: u64, b: u8) -> u64 {
    h ^= u64::from(b);
    h.wrapping_mul(0x0000_0100_0000_01B3)
}

/// [`fnv`] over `data`, read eight bytes at a time (one load per word, so the 86 KB upload
/// stays cheap under AddressSanitizer's per-load checks in the fuzz targets).
fn fnv_bytes(mut h: u64, data: &[u8]) -> u64 {
    let mut words = data.chunks_exact(8);
    for w in &mut words {
        let w = u64::from_le_bytes([w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7]]);
        for k in 0..8 {
            h = fnv(h, (w >> (8 * k)) as u8);
        }
    }
    words.remainder().iter().fold(h, |h, &b| fnv(h, b))
}

impl SimVl53l5cx {
    /// A powered-up sensor at [`ADDRESS`], no firmware, every zone [`SimZone::NONE`].
    pub const fn new() -> Self {
        SimVl53l5cx {
            address: ADDRESS,
            ids: (DEVICE_ID, REVISION_ID),
            page: 0,
            regs0: [0; 0x20],
            fw_access: false,
            fw_written: [0; 3],
            fw_in_order: true,
            fw_hash: 0xCBF2_9CE4_8422_2325,
            booted: false,
            boot_error: false,
            mcu_stopped: false,
            ui: [0; UI_LEN],
            dci: [(0, 0, [0; DCI_MAX]); TRACKED.len()],
            ranging: false,
            results_len: 0,
            results: [0; MAX_RESULTS],
            stream: 255,
            latency_polls: 0,
            polls_left: 0,
            zones: [SimZone::NONE; 64],
            frames: 0,
            commands: 0,
        }
    }

    /// Reports other device/revision ids (a different chip).
    pub fn set_ids(&mut self, device: u8, revision: u8) {
        self.ids = (device, revision);
    }

    /// The zones of the next frames (ULD order; the first 16 in 4×4 mode).
    pub fn set_zones(&mut self, zones: &[SimZone]) {
        for (d, s) in self.zones.iter_mut().zip(zones) {
            *d = *s;
        }
    }

    /// Data-ready reads that report "not ready" before each frame.
    pub fn set_latency_polls(&mut self, polls: u32) {
        self.latency_polls = polls;
        self.polls_left = polls;
    }

    /// True once the firmware booted.
    pub fn booted(&self) -> bool {
        self.booted
    }

    /// True while ranging.
    pub fn ranging(&self) -> bool {
        self.ranging
    }

    /// Frames published so far.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Commands processed so far.
    pub fn commands(&self) -> u32 {
        self.commands
    }

    /// FNV-1a 64 over the firmware bytes uploaded since the last reset.
    pub fn firmware_hash(&self) -> u64 {
        self.fw_hash
    }

    /// The results size published at start (0 before).
    pub fn results_len(&self) -> usize {
        self.results_len
    }

    /// The value of a kept firmware data item (logical byte order), if the device has it.
    pub fn dci(&self, index: u16) -> Option<&[u8]> {
        self.dci
            .iter()
            .find(|e| e.0 == index && e.1 > 0)
            .map(|e| e.2.get(..usize::from(e.1)).unwrap_or(&[]))
    }

    fn reset(&mut self) {
        let (ids, zones, latency, address) =
            (self.ids, self.zones, self.latency_polls, self.address);
        *self = Self::new();
        self.ids = ids;
        self.zones = zones;
        self.latency_polls = latency;
        self.polls_left = latency;
        self.address = address;
    }

    fn dci_store(&mut self, index: u16, data: &[u8]) {
        if !TRACKED.contains(&index) || data.len() > DCI_MAX {
            return;
        }
        let slot = match self.dci.iter().position(|e| e.0 == index && e.1 > 0) {
            Some(s) => s,
            None => match self.dci.iter().position(|e| e.1 == 0) {
                Some(s) => s,
                None => return,
            },
        };
        let e = &mut self.dci[slot];
        e.0 = index;
        e.1 = data.len() as u8;
        e.2[..data.len()].copy_from_slice(data);
    }

    fn ui_byte(&self, index: usize) -> u8 {
        index
            .checked_sub(UI_BASE)
            .and_then(|k| self.ui.get(k))
            .copied()
            .unwrap_or(0)
    }

    fn read_byte(&mut self, index: u16) -> u8 {
        if index == PAGE_SELECT {
            return self.page;
        }
        let i = usize::from(index);
        match self.page {
            0 => match index {
                REG_DEVICE_ID => self.ids.0,
                REG_REVISION_ID => self.ids.1,
                REG_GO2_STATUS0 => {
                    if self.boot_error {
                        0x80
                    } else if self.mcu_stopped {
                        0x81
                    } else {
                        0x01
                    }
                }
                REG_GO2_STATUS1 => {
                    if self.boot_error {
                        BOOT_ERROR_CODE
                    } else if self.mcu_stopped {
                        0x84
                    } else {
                        0
                    }
                }
                _ => self.regs0.get(i).copied().unwrap_or(0),
            },
            1 if index == REG_FW_ACCESS => u8::from(self.fw_access) << 4,
            2 if i < MAX_RESULTS => self.results[i],
            2 => self.ui_byte(i),
            _ => 0,
        }
    }

    /// Reads `buf` from `start` of the current page; returns the index after it. A read inside
    /// the results is one copy (the data-ready polls and frame reads are most of the traffic).
    fn read(&mut self, start: u16, buf: &mut [u8]) -> u16 {
        let s = usize::from(start);
        if self.page == 2 && s + buf.len() <= MAX_RESULTS {
            buf.copy_from_slice(&self.results[s..s + buf.len()]);
            return start + buf.len() as u16;
        }
        let mut p = start;
        for b in buf.iter_mut() {
            *b = self.read_byte(p);
            p = p.wrapping_add(1);
        }
        p
    }

    fn nack() -> I2cErrorKind {
        I2cErrorKind::NoAcknowledge(NoAcknowledgeSource::Data)
    }

    /// One write transaction: `data` at `index` of the current page.
    fn write(&mut self, index: u16, data: &[u8]) -> Result<(), I2cErrorKind> {
        if index == PAGE_SELECT {
            return match data {
                [p] => {
                    self.page = *p;
                    Ok(())
                }
                _ => Err(Self::nack()),
            };
        }
        let start = usize::from(index);
        match self.page {
            0 => {
                for (k, &v) in data.iter().enumerate() {
                    self.page0_write(start + k, v);
                }
                Ok(())
            }
            1 => Ok(()),
            2 => {
                if start == 0x0003 && data == [0x0D] {
                    self.fw_access = true;
                    return Ok(());
                }
                let end = start + data.len();
                if start >= UI_BASE + 4 && end <= 0x3000 {
                    // Writing a command clears the status word.
                    self.ui[..4].fill(0);
                    self.ui[start - UI_BASE..end - UI_BASE].copy_from_slice(data);
                    if end == 0x3000 {
                        self.command();
                    }
                    return Ok(());
                }
                Err(Self::nack())
            }
            p @ 0x09..=0x0B => {
                let part = usize::from(p - 0x09);
                let limit = FIRMWARE_PAGES[part].1;
                if start + data.len() > limit {
                    return Err(Self::nack());
                }
                let earlier_done = (0..part).all(|k| self.fw_written[k] == FIRMWARE_PAGES[k].1);
                if start != self.fw_written[part] || !earlier_done {
                    self.fw_in_order = false;
                }
                self.fw_written[part] = start + data.len();
                self.fw_hash = fnv_bytes(self.fw_hash, data);
                Ok(())
            }
            _ => Err(Self::nack()),
        }
    }

    fn page0_write(&mut self, index: usize, value: u8) {
        if let Some(r) = self.regs0.get_mut(index) {
            *r = value;
        }
        match (index, value) {
            (0x0F, 0x43) => self.reset(),
            (0x0B, 0x01) => {
                let complete = self
                    .fw_written
                    .iter()
                    .zip(FIRMWARE_PAGES)
                    .all(|(&w, (_, len))| w == len);
                self.booted = complete && self.fw_in_order;
                self.boot_error = !self.booted;
            }
            (0x14, 0x01) => {
                self.mcu_stopped = true;
                self.ranging = false;
            }
            (0x14, 0x00) => self.mcu_stopped = false,
            _ => {}
        }
    }

    fn set_status(&mut self, kind: u8, ok: bool) {
        self.ui[..4].copy_from_slice(&[kind, 0x03, if ok { 0 } else { 0x80 }, 0]);
    }

    /// A command ended at 0x2FFF.
    fn command(&mut self) {
        if !self.booted || self.mcu_stopped {
            return; // no firmware to answer: the status stays 0 and the host times out
        }
        self.commands += 1;
        let tail = |s: &Self, k: usize| s.ui_byte(0x3000 - k);
        // A framed command ends in `[kind, 1 | 2, len]`, never in the start word.
        if (1..=4).rev().map(|k| tail(self, k)).eq(START_CMD) {
            let ok = self.start();
            self.set_status(0, ok);
            return;
        }
        let footer: [u8; 8] = core::array::from_fn(|k| tail(self, 8 - k));
        let kind = footer[4];
        let len = usize::from(u16::from_be_bytes([footer[6], footer[7]])) + 4;
        if footer[..4] != CMD_FOOTER_WORD || !(8..=UI_LEN - 4).contains(&len) {
            self.set_status(kind, false);
            return;
        }
        let begin = 0x3000 - len;
        let body_end = 0x3000 - 8;
        let ok = match footer[5] {
            0x01 => self.write_blocks(begin, body_end),
            0x02 => self.read_blocks(begin, body_end),
            _ => false,
        };
        self.set_status(kind, ok);
    }

    fn word(&self, at: usize) -> u32 {
        u32::from_be_bytes(core::array::from_fn(|k| self.ui_byte(at + k)))
    }

    fn write_blocks(&mut self, mut at: usize, end: usize) -> bool {
        while at + 4 <= end {
            let h = BlockHeader::from_word(self.word(at));
            let n = h.payload_len();
            if at + 4 + n > end {
                return false;
            }
            if n <= DCI_MAX && TRACKED.contains(&h.idx) {
                let mut data = [0u8; DCI_MAX];
                for (i, d) in data.iter_mut().enumerate().take(n) {
                    *d = self.ui_byte(at + 4 + swapped(i));
                }
                self.dci_store(h.idx, &data[..n]);
            }
            at += 4 + n;
        }
        at == end
    }

    /// Synthetic NVM calibration byte `k` of item `idx` (logical order).
    fn nvm_byte(idx: u16, k: usize) -> u8 {
        let x = (u32::from(idx) << 12) ^ (k as u32).wrapping_mul(0x9E37_79B9);
        (x ^ (x >> 15)).wrapping_mul(0x2C1B_3C6D).to_le_bytes()[3] >> 1
    }

    fn read_blocks(&mut self, begin: usize, end: usize) -> bool {
        let mut out = UI_BASE + 4;
        let mut at = begin;
        while at + 4 <= end {
            let word = self.word(at);
            let h = BlockHeader::from_word(word);
            let n = h.payload_len();
            if out + 4 + n + 8 > begin {
                return false; // the answer would overwrite the request
            }
            let mut data = [0u8; DCI_MAX];
            if let Some(d) = self.dci(h.idx) {
                let m = d.len().min(DCI_MAX);
                data[..m].copy_from_slice(&d[..m]);
            }
            for (k, b) in word.to_be_bytes().into_iter().enumerate() {
                self.ui[out - UI_BASE + k] = b;
            }
            for i in 0..n {
                let v = if TRACKED.contains(&h.idx) {
                    data.get(i).copied().unwrap_or(0)
                } else {
                    Self::nvm_byte(h.idx, i)
                };
                self.ui[out + 4 + swapped(i) - UI_BASE] = v;
            }
            out += 4 + n;
            at += 4;
        }
        let foot = [0x00, 0x00, 0x00, 0x0F, 0x00, 0x01, 0x00, 0x00];
        self.ui[out - UI_BASE..out - UI_BASE + 8].copy_from_slice(&foot);
        at == end
    }

    /// The start command: checks the outputs against the zones, publishes the results size.
    fn start(&mut self) -> bool {
        let zones = match self.dci(dci::ZONE_CONFIG) {
            Some(z) if z.len() >= 2 => usize::from(z[0]) * usize::from(z[1]),
            _ => return false,
        };
        let (list, enables, config) = match (
            self.dci(dci::OUTPUT_LIST),
            self.dci(dci::OUTPUT_ENABLES),
            self.dci(dci::OUTPUT_CONFIG),
        ) {
            (Some(l), Some(e), Some(c)) if l.len() == 48 && e.len() == 16 && c.len() == 8 => {
                let mut list = [0u32; 12];
                for (w, b) in list.iter_mut().zip(l.chunks_exact(4)) {
                    *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
                let mut en = [0u32; 4];
                for (w, b) in en.iter_mut().zip(e.chunks_exact(4)) {
                    *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
                (list, en, u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            }
            _ => return false,
        };
        for &w in &list {
            let h = BlockHeader::from_word(w);
            if (1..0xD).contains(&h.kind) && usize::from(h.size) != zones {
                return false;
            }
        }
        let size = protocol::results_len(&list, &enables);
        if size > MAX_RESULTS || size as u32 != config || (zones != 16 && zones != 64) {
            return false;
        }
        let mut info = [0u8; 12];
        info[8..10].copy_from_slice(&(size as u16).to_le_bytes());
        self.dci_store(dci::RANGE_DATA_INFO, &info);
        self.results_len = size;
        self.ranging = true;
        self.polls_left = self.latency_polls;
        self.results = [0; MAX_RESULTS];
        self.results[0] = 255;
        true
    }

    /// Builds the results of the current zones into `self.results` (wire order).
    fn publish(&mut self) {
        self.stream = match self.stream.wrapping_add(1) {
            255 => 0,
            s => s,
        };
        self.frames += 1;
        let zones = self
            .dci(dci::ZONE_CONFIG)
            .and_then(|z| Some(usize::from(*z.first()?) * usize::from(*z.get(1)?)))
            .unwrap_or(0)
            .min(64);
        let mut list = [0u32; 12];
        let mut en = 0u32;
        if let (Some(l), Some(e)) = (self.dci(dci::OUTPUT_LIST), self.dci(dci::OUTPUT_ENABLES)) {
            for (w, b) in list.iter_mut().zip(l.chunks_exact(4)) {
                *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
            en = u32::from_le_bytes([e[0], e[1], e[2], e[3]]);
        }
        let mut buf = [0u8; MAX_RESULTS];
        let mut at = RESULTS_PREAMBLE;
        for (i, &w) in list.iter().enumerate() {
            let h = BlockHeader::from_word(w);
            if w == 0 || en & (1 << i) == 0 || h.kind == 0xD {
                continue;
            }
            let n = h.payload_len();
            if at + 4 + n > self.results_len.saturating_sub(RESULTS_FOOTER) {
                break;
            }
            buf[at..at + 4].copy_from_slice(&w.to_le_bytes());
            let data = &mut buf[at + 4..at + 4 + n];
            for (z, zone) in self.zones.iter().enumerate().take(zones) {
                let target = zone.status != 255;
                let put = |data: &mut [u8], bytes: &[u8]| {
                    let o = z * bytes.len();
                    if let Some(d) = data.get_mut(o..o + bytes.len()) {
                        d.copy_from_slice(bytes);
                    }
                };
                match h.idx {
                    block::AMBIENT => {
                        put(data, &zone.ambient_kcps.saturating_mul(2048).to_le_bytes())
                    }
                    block::SPAD_COUNT => put(data, &(1024u32 + z as u32).to_le_bytes()),
                    block::NB_TARGET => put(data, &[u8::from(target)]),
                    block::SIGNAL => {
                        put(data, &zone.signal_kcps.saturating_mul(2048).to_le_bytes())
                    }
                    block::SIGMA => put(data, &zone.sigma_mm.saturating_mul(128).to_le_bytes()),
                    block::DISTANCE => {
                        let raw = if target {
                            zone.distance_mm.saturating_mul(4)
                        } else {
                            0
                        };
                        put(data, &raw.to_le_bytes())
                    }
                    block::REFLECTANCE => put(data, &[if target { 40 } else { 0 }]),
                    block::TARGET_STATUS => put(data, &[if target { zone.status } else { 0 }]),
                    _ => {}
                }
            }
            if h.idx == block::METADATA {
                if let Some(t) = data.get_mut(8) {
                    *t = 31; // silicon temperature, °C
                }
            }
            at += 4 + n;
        }
        // Footer marker, then every word to wire order; the preamble is raw bytes.
        if let Some(f) = buf.get_mut(at..at + 4) {
            f.copy_from_slice(&0x0000_000Fu32.to_le_bytes());
        }
        for w in buf.chunks_exact_mut(4) {
            w.reverse();
        }
        buf[..4].copy_from_slice(&[self.stream, 0x05, 0x05, 0x10]);
        self.results = buf;
    }

    fn data_ready_poll(&mut self) {
        if !self.ranging {
            return;
        }
        if self.polls_left > 0 {
            self.polls_left -= 1;
            return;
        }
        self.publish();
        self.polls_left = self.latency_polls;
    }
}

impl embedded_hal::i2c::ErrorType for SimVl53l5cx {
    type Error = I2cErrorKind;
}

impl I2c for SimVl53l5cx {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        if address != self.address {
            return Err(I2cErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
        }
        let mut pointer: Option<u16> = None;
        for op in operations {
            match op {
                Operation::Write(bytes) => {
                    let (index, data) = match (pointer, &bytes[..]) {
                        (None, [hi, lo, data @ ..]) => (u16::from_be_bytes([*hi, *lo]), data),
                        (Some(p), data) => (p, data),
                        _ => return Err(Self::nack()),
                    };
                    if !data.is_empty() {
                        self.write(index, data)?;
                    }
                    pointer = Some(index.wrapping_add(data.len() as u16));
                }
                Operation::Read(buf) => {
                    let start = pointer.unwrap_or(0);
                    if self.page == 2 && start == RESULTS_INDEX && buf.len() == 4 {
                        self.data_ready_poll();
                    }
                    pointer = Some(self.read(start, buf));
                }
            }
        }
        Ok(())
    }
}

const fn block_bytes<const N: usize>(
    mut out: [u8; N],
    at: usize,
    idx: u16,
    kind: u8,
    size: u16,
) -> [u8; N] {
    let w = BlockHeader { kind, size, idx }.word().to_be_bytes();
    out[at] = w[0];
    out[at + 1] = w[1];
    out[at + 2] = w[2];
    out[at + 3] = w[3];
    out
}

/// Writes the logical bytes `data` as a block's payload at `at` (wire order).
const fn payload<const N: usize>(mut out: [u8; N], at: usize, data: &[u8]) -> [u8; N] {
    let mut i = 0;
    while i < data.len() {
        out[at + (i ^ 3)] = data[i];
        i += 1;
    }
    out
}

const fn footer<const N: usize>(mut out: [u8; N], kind: u8, read: bool) -> [u8; N] {
    let len = (N - 4) as u16;
    let f = [
        0,
        0,
        0,
        0x0F,
        kind,
        if read { 2 } else { 1 },
        (len >> 8) as u8,
        len as u8,
    ];
    let mut k = 0;
    while k < 8 {
        out[N - 8 + k] = f[k];
        k += 1;
    }
    out
}

/// A stand-in firmware image (a fixed pseudo-random pattern, not ST's firmware).
pub static STAND_IN_FIRMWARE: [u8; FIRMWARE_LEN] = {
    let mut fw = [0u8; FIRMWARE_LEN];
    let mut x: u32 = 0x6465_7074; // "dept"
    let mut i = 0;
    while i < FIRMWARE_LEN {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        fw[i] = x as u8;
        i += 1;
    }
    fw
};

/// A stand-in default configuration: the data items the simulation uses, at the device's
/// defaults (4×4, 1 Hz, 10 ms, autonomous), padded to ST's length.
pub static STAND_IN_DEFAULT_CONFIG: [u8; DEFAULT_CONFIG_LEN] = {
    let out = [0u8; DEFAULT_CONFIG_LEN];
    let out = block_bytes(out, 0, dci::ZONE_CONFIG, 0, 8);
    let out = payload(out, 4, &[4, 4, 4, 0, 8, 8, 0, 0]);
    let out = block_bytes(out, 12, dci::RANGING_MODE, 0, 8);
    let out = payload(out, 16, &[3, 3, 1, 2, 0, 3, 0, 0]);
    let out = block_bytes(out, 24, dci::DSS_CONFIG, 0, 16);
    let out = payload(
        out,
        28,
        &[0x40, 1, 0xE0, 1, 0x40, 0, 0x40, 0, 0, 4, 0, 1, 1, 0, 0, 0],
    );
    let out = block_bytes(out, 44, dci::FREQ_HZ, 0, 4);
    let out = payload(out, 48, &[0, 1, 0, 0]);
    let out = block_bytes(out, 52, dci::INT_TIME, 0, 20);
    let out = payload(out, 56, &[0x10, 0x27, 0, 0]);
    // Filler: one untracked item up to the footer.
    let out = block_bytes(out, 76, 0xB000, 0, (DEFAULT_CONFIG_LEN - 76 - 4 - 8) as u16);
    footer(out, 0, false)
};

/// A stand-in crosstalk buffer with the block layout the 4×4 reduction expects (grid at 0x34,
/// a 16-byte item at 0x134), zero data.
pub static STAND_IN_XTALK: [u8; XTALK_LEN] = {
    let out = [0u8; XTALK_LEN];
    let out = block_bytes(out, 0, 0x9000, 0, 12);
    let out = block_bytes(out, 0x10, 0x9010, 0, 20);
    let out = block_bytes(out, 0x28, 0x9020, 0, 4);
    let out = block_bytes(out, 0x30, 0x9024, 4, 64);
    let out = block_bytes(out, 0x134, 0xA0FC, 0, 16);
    let out = block_bytes(out, 0x148, 0x9200, 0, (XTALK_LEN - 0x148 - 4 - 8) as u16);
    footer(out, 5, false)
};

/// A stand-in NVM command: eight items laid out like the sensor's offset calibration (signal
/// grid at 0x3C, range grid at 0x140 of the answer).
pub static STAND_IN_NVM_CMD: [u8; NVM_CMD_LEN] = {
    let out = [0u8; NVM_CMD_LEN];
    let out = block_bytes(out, 0, 0x9100, 0, 4);
    let out = block_bytes(out, 4, 0x9104, 0, 12);
    let out = block_bytes(out, 8, 0x9110, 0, 20);
    let out = block_bytes(out, 12, 0x9124, 0, 4);
    let out = block_bytes(out, 16, 0x9128, 4, 64);
    let out = block_bytes(out, 20, 0x9228, 2, 64);
    let out = block_bytes(out, 24, 0x92A8, 0, 16);
    let out = block_bytes(out, 28, 0x92B8, 0, 16);
    footer(out, 2, true)
};

/// The four stand-in buffers as [`UldBuffers`].
pub fn stand_in_buffers() -> UldBuffers<'static> {
    UldBuffers {
        firmware: &STAND_IN_FIRMWARE,
        default_configuration: &STAND_IN_DEFAULT_CONFIG,
        default_xtalk: &STAND_IN_XTALK,
        get_nvm_cmd: &STAND_IN_NVM_CMD,
    }
}
