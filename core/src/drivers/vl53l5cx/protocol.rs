//! Register map and wire formats of ST's VL53L5CX as spoken by ST's Ultra Lite Driver (ULD 1.3.0),
//! shared by the driver and the simulated device. Facts are taken from reading ST's sources; the
//! code and names here are ours.

/// 7-bit I2C address after power-up (ST writes it as the 8-bit `0x52`).
pub const ADDRESS: u8 = 0x29;
/// Page-select register, present on every page.
pub const PAGE_SELECT: u16 = 0x7FFF;

/// Page 0 register: device id, reads [`DEVICE_ID`].
pub const REG_DEVICE_ID: u16 = 0x0000;
/// Page 0 register: revision id, reads [`REVISION_ID`].
pub const REG_REVISION_ID: u16 = 0x0001;
/// Page 0 register: GO2 status 0 (bit 0 = booted, bit 7 = see GO2 status 1).
pub const REG_GO2_STATUS0: u16 = 0x0006;
/// Page 0 register: GO2 status 1 (an error or state code when status 0 has bit 7 set).
pub const REG_GO2_STATUS1: u16 = 0x0007;
/// Page 1 register: bit 4 is set once the host may access the firmware memory.
pub const REG_FW_ACCESS: u16 = 0x0021;

/// Value of [`REG_DEVICE_ID`].
pub const DEVICE_ID: u8 = 0xF0;
/// Value of [`REG_REVISION_ID`].
pub const REVISION_ID: u8 = 0x02;

/// Firmware image length: 86 016 bytes.
pub const FIRMWARE_LEN: usize = 0x15000;
/// Firmware upload: (page, bytes) in order; each part is written from index 0 of its page.
pub const FIRMWARE_PAGES: [(u8, usize); 3] = [(0x09, 0x8000), (0x0A, 0x8000), (0x0B, 0x5000)];
/// Length of ST's default configuration buffer (`VL53L5CX_DEFAULT_CONFIGURATION`).
pub const DEFAULT_CONFIG_LEN: usize = 972;
/// Length of ST's default crosstalk buffer (`VL53L5CX_DEFAULT_XTALK`).
pub const XTALK_LEN: usize = 776;
/// Length of ST's NVM read command (`VL53L5CX_GET_NVM_CMD`).
pub const NVM_CMD_LEN: usize = 40;
/// Bytes the host reads back after the NVM command.
pub const NVM_DATA_LEN: usize = 492;
/// Bytes of the NVM answer kept as offset calibration.
pub const OFFSET_LEN: usize = 488;

/// Page 2: command status word (4 bytes).
pub const UI_CMD_STATUS: u16 = 0x2C00;
/// Page 2: start of the command answer area.
pub const UI_CMD_START: u16 = 0x2C04;
/// Page 2: last byte of the command area; a write whose last byte lands here is a command.
pub const UI_CMD_END: u16 = 0x2FFF;
/// Page 2: where the offset calibration is written (ends at [`UI_CMD_END`]).
pub const OFFSET_INDEX: u16 = 0x2E18;
/// Page 2: where the crosstalk calibration is written.
pub const XTALK_INDEX: u16 = 0x2CF8;
/// Page 2: where the default configuration is written.
pub const DEFAULT_CONFIG_INDEX: u16 = 0x2C34;
/// Page 2: where the NVM read command is written.
pub const NVM_CMD_INDEX: u16 = 0x2FD8;
/// Page 2: the last command word; also read by `stop_ranging` as the auto-stop flag.
pub const LAST_CMD_WORD: u16 = 0x2FFC;
/// The auto-stop flag value meaning the device already stopped by itself.
pub const AUTO_STOP_FLAG: u32 = 0x4FF;
/// The start-ranging command word, written at [`LAST_CMD_WORD`].
pub const START_CMD: [u8; 4] = [0x00, 0x03, 0x00, 0x00];
/// Page 2: results start at index 0 (16-byte preamble, blocks, 8-byte footer).
pub const RESULTS_INDEX: u16 = 0x0000;
/// Bytes of the results preamble before the first block header.
pub const RESULTS_PREAMBLE: usize = 16;
/// Bytes of the results footer after the last block.
pub const RESULTS_FOOTER: usize = 8;

/// Footer word that ends a command written to the command area (big-endian on the wire).
pub const CMD_FOOTER_WORD: [u8; 4] = [0x00, 0x00, 0x00, 0x0F];

/// Firmware data items ("DCI") the driver reads or writes, by index.
pub mod dci {
    /// Zone configuration: bytes 0, 1 = zones per row/column; 4, 5 = zone size.
    pub const ZONE_CONFIG: u16 = 0x5450;
    /// Ranging frequency: byte 1 = Hz.
    pub const FREQ_HZ: u16 = 0x5458;
    /// Integration time: bytes 0..4 = microseconds, `u32` LE.
    pub const INT_TIME: u16 = 0x545C;
    /// Results layout as the firmware computed it: bytes 8..10 = results size, `u16` LE.
    pub const RANGE_DATA_INFO: u16 = 0x5440;
    /// Ranging mode: byte 1 = 1 continuous / 3 autonomous; byte 3 = 3 / 2.
    pub const RANGING_MODE: u16 = 0xAD30;
    /// SPAD selection configuration, patched per resolution.
    pub const DSS_CONFIG: u16 = 0xAD38;
    /// Single-range flag, `u32` LE.
    pub const SINGLE_RANGE: u16 = 0xCD5C;
    /// Output configuration: results size and number of outputs, two `u32` LE.
    pub const OUTPUT_CONFIG: u16 = 0xCD60;
    /// Output enables: four `u32` LE bit sets over the output list.
    pub const OUTPUT_ENABLES: u16 = 0xCD68;
    /// Output list: twelve block headers, `u32` LE.
    pub const OUTPUT_LIST: u16 = 0xCD78;
    /// Pipe control: targets per zone, 0, 1, 0.
    pub const PIPE_CONTROL: u16 = 0xCF78;
}

/// Result block indices (upper 16 bits of a block header), one target per zone.
pub mod block {
    /// Metadata (12 bytes; byte 8 = silicon temperature, °C, `i8`).
    pub const METADATA: u16 = 0x54B4;
    /// Common data (4 bytes).
    pub const COMMON: u16 = 0x54C0;
    /// Ambient rate per SPAD, `u32` per zone, kcps × 2048.
    pub const AMBIENT: u16 = 0x54D0;
    /// Enabled SPADs, `u32` per zone.
    pub const SPAD_COUNT: u16 = 0x55D0;
    /// Targets detected, `u8` per zone.
    pub const NB_TARGET: u16 = 0xCF7C;
    /// Signal rate per SPAD, `u32` per zone, kcps × 2048.
    pub const SIGNAL: u16 = 0xCFBC;
    /// Range sigma, `u16` per zone, mm × 128.
    pub const SIGMA: u16 = 0xD2BC;
    /// Distance, `i16` per zone, mm × 4.
    pub const DISTANCE: u16 = 0xD33C;
    /// Reflectance estimate, `u8` per zone, % × 2.
    pub const REFLECTANCE: u16 = 0xD43C;
    /// Target status, `u8` per zone (ST codes).
    pub const TARGET_STATUS: u16 = 0xD47C;
    /// Motion indicator (140 bytes).
    pub const MOTION: u16 = 0xCC50;
}

/// The output list the driver programs (ULD's defaults, every output on), with the per-zone
/// blocks' sizes still 0: [`output_list`] fills them for a zone count.
const OUTPUT_LIST_TEMPLATE: [u32; 12] = [
    0x0000_000D, // start marker
    0x54B4_00C0, // metadata, 12 B
    0x54C0_0040, // common data, 4 B
    0x54D0_0004, // ambient, 4 B × zones
    0x55D0_0004, // SPAD count, 4 B × zones
    0xCF7C_0001, // targets detected, 1 B × zones
    0xCFBC_0004, // signal, 4 B × zones
    0xD2BC_0002, // sigma, 2 B × zones
    0xD33C_0002, // distance, 2 B × zones
    0xD43C_0001, // reflectance, 1 B × zones
    0xD47C_0001, // target status, 1 B × zones
    0xCC50_08C0, // motion indicator, 140 B
];

/// Output enables programmed with [`output_list`]: all twelve outputs.
pub const OUTPUT_ENABLES: [u32; 4] = [0x0000_0FFF, 0, 0, 0xC000_0000];

/// A decoded block header: `type` (bits 0..4), `size` (bits 4..16), `idx` (bits 16..32).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockHeader {
    /// Element type: 1..=12 = bytes per element of a per-zone array, else a raw block.
    pub kind: u8,
    /// Element count (per-zone blocks) or byte count.
    pub size: u16,
    /// Block index.
    pub idx: u16,
}

impl BlockHeader {
    /// Decodes a header word.
    pub const fn from_word(w: u32) -> Self {
        BlockHeader {
            kind: (w & 0xF) as u8,
            size: ((w >> 4) & 0xFFF) as u16,
            idx: (w >> 16) as u16,
        }
    }

    /// Encodes the header word.
    pub const fn word(self) -> u32 {
        ((self.idx as u32) << 16) | (((self.size & 0xFFF) as u32) << 4) | (self.kind as u32 & 0xF)
    }

    /// Payload bytes that follow the header (ULD rule: `type × size` for types 2..=12).
    pub const fn payload_len(self) -> usize {
        if self.kind > 1 && self.kind < 0xD {
            self.kind as usize * self.size as usize
        } else {
            self.size as usize
        }
    }
}

/// The output list for `zones` zones (16 or 64), as `u32` headers.
pub fn output_list(zones: u16) -> [u32; 12] {
    let mut list = OUTPUT_LIST_TEMPLATE;
    for w in list.iter_mut() {
        let mut h = BlockHeader::from_word(*w);
        if h.kind >= 1 && h.kind < 0xD {
            h.size = zones;
            *w = h.word();
        }
    }
    list
}

/// Results size in bytes for an output list and its enables (ULD's rule: every enabled,
/// non-zero entry adds its header and payload; plus 20 bytes of preamble and footer).
pub fn results_len(list: &[u32], enables: &[u32; 4]) -> usize {
    let mut total = 0usize;
    for (i, &w) in list.iter().enumerate() {
        let enabled = enables
            .get(i / 32)
            .is_some_and(|e| e & (1 << (i % 32)) != 0);
        if w == 0 || !enabled {
            continue;
        }
        let h = BlockHeader::from_word(w);
        total += if h.kind >= 1 && h.kind < 0xD {
            h.kind as usize * h.size as usize
        } else {
            h.size as usize
        } + 4;
    }
    total + 20
}

/// Byte `i` of a buffer whose 32-bit words are byte-swapped (the wire order of DCI data and
/// results): logical byte `i` sits at wire byte `i ^ 3`.
#[inline]
pub const fn swapped(i: usize) -> usize {
    i ^ 3
}
