//! ST VL53L5CX 8×8 multizone dToF sensor on embedded-hal 1.0 ([`I2c`] + [`DelayNs`]): a
//! `no_std`, allocation-free driver speaking the protocol of ST's Ultra Lite Driver (ULD 1.3.0),
//! written from reading ST's sources, with a simulated device ([`sim::SimVl53l5cx`]) for tests
//! and the QEMU firmware.
//!
//! The contract (buffers, what is read, units) is `docs/vl53l5cx.md`. In short:
//!
//! - The caller supplies ST's four buffers from `vl53l5cx_buffers.h` of ST's ULD (STSW-IMG023,
//!   or the PyPI sdist `vl53l5cx-ctypes`) as [`UldBuffers`]: firmware (86 016 B), default
//!   configuration (972 B), default crosstalk (776 B), NVM command (40 B). The project ships none.
//! - The caller supplies an I/O buffer: every I2C write is built in it (so writes are chunked to
//!   its length, or [`Config::max_write_len`]) and results are read into it (≥ 528 B for 4×4,
//!   ≥ 1 440 B for 8×8; [`results_len`]). 32 bytes are enough to initialise.
//! - Bus traffic matches ST's ULD transaction for transaction (`core/tests/st_uld_crosscheck.rs`
//!   compares the traces), except that long writes are split into chunks at consecutive indices.
//!
//! ```
//! use depthor_core::drivers::vl53l5cx::{sim, Config, Resolution, UldBuffers, Vl53l5cx};
//! use depthor_core::hal::{DtofSensor, ZoneFrame};
//!
//! struct NoDelay;
//! impl embedded_hal::delay::DelayNs for NoDelay {
//!     fn delay_ns(&mut self, _ns: u32) {}
//! }
//! // Stand-in buffers of the right sizes (a real board passes ST's).
//! let mut device = sim::SimVl53l5cx::new();
//! let zones = [sim::SimZone { distance_mm: 1234, status: 5, ..sim::SimZone::NONE }; 64];
//! device.set_zones(&zones);
//! let mut io = [0u8; 1452];
//! let mut tof = Vl53l5cx::new(device, NoDelay, sim::stand_in_buffers(), &mut io, Config::default());
//! tof.init().unwrap();
//! tof.set_resolution(Resolution::R8x8).unwrap();
//! tof.start_ranging().unwrap();
//! let mut frame = ZoneFrame::<64>::new();
//! tof.read_frame(&mut frame).unwrap();
//! assert_eq!((frame.rows, frame.cols), (8, 8));
//! assert_eq!(frame.distance_mm[0], 1234.0);
//! ```

mod calib;
pub mod protocol;
mod results;
pub mod sim;

use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;

use crate::calibration::{DistanceKind, DtofGeometry};
use crate::hal::{DtofSensor, ErrorKind, ErrorType, ZoneFrame};

use protocol::{dci, *};
pub use results::{Present, ResultsData, ResultsError, MAX_ZONES};

/// ST's binary buffers (from ST's `vl53l5cx_buffers.h`), borrowed for the driver's life.
#[derive(Clone, Copy, Debug)]
pub struct UldBuffers<'a> {
    /// `VL53L5CX_FIRMWARE`, [`FIRMWARE_LEN`] bytes.
    pub firmware: &'a [u8],
    /// `VL53L5CX_DEFAULT_CONFIGURATION`, [`DEFAULT_CONFIG_LEN`] bytes.
    pub default_configuration: &'a [u8],
    /// `VL53L5CX_DEFAULT_XTALK`, [`XTALK_LEN`] bytes.
    pub default_xtalk: &'a [u8],
    /// `VL53L5CX_GET_NVM_CMD`, [`NVM_CMD_LEN`] bytes.
    pub get_nvm_cmd: &'a [u8],
}

/// Zone grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resolution {
    /// 4×4 zones, up to 60 Hz.
    R4x4,
    /// 8×8 zones, up to 15 Hz.
    R8x8,
}

impl Resolution {
    /// Zones per row (= per column).
    pub const fn side(self) -> u16 {
        match self {
            Resolution::R4x4 => 4,
            Resolution::R8x8 => 8,
        }
    }

    /// Zone count.
    pub const fn zones(self) -> u16 {
        self.side() * self.side()
    }
}

/// Ranging mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangingMode {
    /// Back-to-back ranging, integration time = frame period.
    Continuous,
    /// Ranging at the frequency with the programmed integration time (ST's default).
    Autonomous,
}

/// Validates a results buffer (wire bytes as read from index 0 of page 2) for `zones` zones and
/// decodes it into `out`; `out` is untouched on error.
pub fn decode_results(buf: &[u8], zones: usize, out: &mut ResultsData) -> Result<(), ResultsError> {
    results::decode(buf, zones, out)
}

/// Bytes of results for a resolution with every output on (ULD's default).
pub fn results_len(resolution: Resolution) -> usize {
    protocol::results_len(&output_list(resolution.zones()), &OUTPUT_ENABLES)
}

/// Driver settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Config {
    /// 7-bit bus address (default [`ADDRESS`]).
    pub address: u8,
    /// Largest I2C write, bytes including the 2 index bytes (0 = the I/O buffer's length);
    /// at least 4.
    pub max_write_len: usize,
    /// Wait between two data-ready polls in [`DtofSensor::read_frame`], microseconds
    /// (default 1 000).
    pub poll_interval_us: u32,
    /// Give up waiting for a frame after this long, microseconds (default 1 100 000: one frame
    /// period at 1 Hz plus margin).
    pub frame_timeout_us: u32,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            address: ADDRESS,
            max_write_len: 0,
            poll_interval_us: 1_000,
            frame_timeout_us: 1_100_000,
        }
    }
}

/// Which part of the protocol an error happened in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Device and revision id check.
    Presence,
    /// Software reboot sequence.
    Reboot,
    /// Waiting for the boot flag.
    Boot,
    /// Enabling firmware access.
    FirmwareAccess,
    /// Power-on and MCU wake-up writes.
    PowerOn,
    /// Writing the firmware to pages 9–11.
    FirmwareUpload,
    /// Checking the upload and resetting the MCU.
    McuBoot,
    /// Reading the NVM calibration.
    Nvm,
    /// Sending the offset calibration.
    Offset,
    /// Sending the crosstalk calibration.
    Xtalk,
    /// Sending the default configuration.
    DefaultConfig,
    /// A firmware data item read or write.
    Dci,
    /// Starting a ranging session.
    Start,
    /// Stopping the ranging session.
    Stop,
    /// Polling for a new frame.
    DataReady,
    /// Reading the results.
    Results,
}

/// What went wrong; `E` is the bus's error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Vl53l5cxError<E> {
    /// An I2C transaction failed.
    Bus {
        /// Where.
        step: Step,
        /// The bus's error.
        error: E,
    },
    /// The device did not answer in time (2 s for commands, 0.5 s for the MCU boot,
    /// [`Config::frame_timeout_us`] for frames).
    Timeout(Step),
    /// Device/revision id were not 0xF0/0x02.
    WrongChipId {
        /// Read device id.
        device: u8,
        /// Read revision id.
        revision: u8,
    },
    /// One of ST's buffers has the wrong length.
    BufferSize {
        /// Which buffer.
        which: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// The I/O buffer is shorter than what the step needs.
    IoBufferTooSmall {
        /// Bytes needed.
        needed: usize,
        /// Bytes given.
        got: usize,
    },
    /// The device's MCU reported an error status (GO2 status or command status ≥ 0x7F).
    Mcu {
        /// Where.
        step: Step,
        /// The status byte.
        code: u8,
    },
    /// A parameter is out of range.
    InvalidParam(&'static str),
    /// The firmware's results size differs from the driver's.
    ResultsSizeMismatch {
        /// The driver's size.
        driver: usize,
        /// The device's size.
        device: usize,
    },
    /// A read was attempted before [`Vl53l5cx::start_ranging`].
    NotRanging,
    /// The device's zone configuration is neither 4×4 nor 8×8.
    BadResolution(u8),
    /// The results bytes are corrupt.
    BadResults(ResultsError),
    /// The caller's [`ZoneFrame`] holds fewer zones than the sensor sends.
    BufferShape {
        /// Zones per frame.
        zones: usize,
        /// Capacity of the caller's frame.
        capacity: usize,
    },
}

impl<E: core::fmt::Debug> core::fmt::Display for Vl53l5cxError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "VL53L5CX: {self:?}")
    }
}

impl<E: core::fmt::Debug> core::error::Error for Vl53l5cxError<E> {}

impl<E: embedded_hal::i2c::Error> crate::hal::Error for Vl53l5cxError<E> {
    fn kind(&self) -> ErrorKind {
        match self {
            Vl53l5cxError::Bus { .. } => ErrorKind::Bus,
            Vl53l5cxError::Timeout(_) => ErrorKind::Timeout,
            Vl53l5cxError::BufferShape { .. } | Vl53l5cxError::IoBufferTooSmall { .. } => {
                ErrorKind::BufferShape
            }
            Vl53l5cxError::WrongChipId { .. }
            | Vl53l5cxError::Mcu { .. }
            | Vl53l5cxError::ResultsSizeMismatch { .. }
            | Vl53l5cxError::BadResolution(_)
            | Vl53l5cxError::BadResults(_) => ErrorKind::BadData,
            _ => ErrorKind::Other,
        }
    }
}

/// Poll limit of command answers: 200 × 10 ms.
const CMD_POLLS: u32 = 200;
/// Poll limit of the MCU boot: 500 × 1 ms.
const BOOT_POLLS: u32 = 500;
/// Poll limit of the MCU stop: 500 × 10 ms.
const STOP_POLLS: u32 = 500;
/// Largest DCI item the driver reads (integration time, 20 B) plus the 12 framing bytes.
const MIN_IO: usize = 32;

/// The VL53L5CX driver; owns its bus and delay, borrows ST's buffers and the I/O buffer.
#[derive(Debug)]
pub struct Vl53l5cx<'a, I2C, D> {
    i2c: I2C,
    delay: D,
    config: Config,
    st: UldBuffers<'a>,
    io: &'a mut [u8],
    nvm: [u8; NVM_DATA_LEN],
    resolution: Resolution,
    stream_count: u8,
    data_read_size: usize,
    ranging: bool,
    results: ResultsData,
}

type Res<T, E> = Result<T, Vl53l5cxError<E>>;

/// Writes `len` bytes produced by `fill(offset, chunk)` at `index`, split into writes of at most
/// `chunk_max` bytes (index included) built in `io`. No chunk but the first starts at the page
/// register [`PAGE_SELECT`].
#[allow(clippy::too_many_arguments)]
fn write_chunked<I: I2c>(
    i2c: &mut I,
    address: u8,
    io: &mut [u8],
    chunk_max: usize,
    step: Step,
    index: u16,
    len: usize,
    mut fill: impl FnMut(usize, &mut [u8]),
) -> Result<(), Vl53l5cxError<I::Error>> {
    let room = chunk_max.min(io.len());
    // Two payload bytes at least, so that no chunk has to start on the page register.
    if room < 4 {
        return Err(Vl53l5cxError::IoBufferTooSmall {
            needed: 4,
            got: room,
        });
    }
    let mut done = 0usize;
    while done < len {
        let mut n = (room - 2).min(len - done);
        let at = usize::from(index) + done;
        if done + n < len && at + n == usize::from(PAGE_SELECT) {
            n -= 1; // the next chunk would start on the page register
        }
        let (head, rest) = io.split_at_mut(2);
        head.copy_from_slice(&(at as u16).to_be_bytes());
        let body = rest.get_mut(..n).unwrap_or(&mut []);
        fill(done, body);
        let frame = io.get(..n + 2).unwrap_or(&[]);
        i2c.write(address, frame)
            .map_err(|error| Vl53l5cxError::Bus { step, error })?;
        done += n;
    }
    Ok(())
}

impl<'a, I2C: I2c, D: DelayNs> Vl53l5cx<'a, I2C, D> {
    /// A driver; does no bus traffic. `io` is the I/O buffer (see the module docs).
    pub fn new(i2c: I2C, delay: D, st: UldBuffers<'a>, io: &'a mut [u8], config: Config) -> Self {
        Vl53l5cx {
            i2c,
            delay,
            config,
            st,
            io,
            nvm: [0; NVM_DATA_LEN],
            resolution: Resolution::R4x4,
            stream_count: 255,
            data_read_size: 0,
            ranging: false,
            results: ResultsData::new(),
        }
    }

    /// Gives the bus and delay back.
    pub fn release(self) -> (I2C, D) {
        (self.i2c, self.delay)
    }

    /// Borrow of the bus (e.g. to inspect a simulated device).
    pub fn i2c(&self) -> &I2C {
        &self.i2c
    }

    /// Mutable borrow of the bus (e.g. to latch a frame on a simulated device).
    pub fn i2c_mut(&mut self) -> &mut I2C {
        &mut self.i2c
    }

    /// The resolution last set (4×4 after [`Vl53l5cx::init`], the device's default).
    pub fn resolution(&self) -> Resolution {
        self.resolution
    }

    /// The last frame decoded by [`DtofSensor::read_frame`].
    pub fn last_results(&self) -> &ResultsData {
        &self.results
    }

    fn chunk_max(&self) -> usize {
        match self.config.max_write_len {
            0 => self.io.len(),
            n => n,
        }
    }

    fn wr(&mut self, step: Step, index: u16, value: u8) -> Res<(), I2C::Error> {
        let [hi, lo] = index.to_be_bytes();
        self.i2c
            .write(self.config.address, &[hi, lo, value])
            .map_err(|error| Vl53l5cxError::Bus { step, error })
    }

    fn rd(&mut self, step: Step, index: u16, buf: &mut [u8]) -> Res<(), I2C::Error> {
        self.i2c
            .write_read(self.config.address, &index.to_be_bytes(), buf)
            .map_err(|error| Vl53l5cxError::Bus { step, error })
    }

    fn rd_byte(&mut self, step: Step, index: u16) -> Res<u8, I2C::Error> {
        let mut b = [0u8];
        self.rd(step, index, &mut b)?;
        Ok(b[0])
    }

    fn wr_slice(&mut self, step: Step, index: u16, data: &[u8]) -> Res<(), I2C::Error> {
        let chunk = self.chunk_max();
        write_chunked(
            &mut self.i2c,
            self.config.address,
            self.io,
            chunk,
            step,
            index,
            data.len(),
            |off, out| {
                if let Some(src) = data.get(off..off + out.len()) {
                    out.copy_from_slice(src);
                }
            },
        )
    }

    /// Runs a list of single-byte writes and ignored reads (`None` = read that index).
    fn script(&mut self, step: Step, ops: &[(u16, Option<u8>)]) -> Res<(), I2C::Error> {
        for &(index, value) in ops {
            match value {
                Some(v) => self.wr(step, index, v)?,
                None => {
                    self.rd_byte(step, index)?;
                }
            }
        }
        Ok(())
    }

    /// ULD's poll: read `size` bytes at `index`, wait 10 ms, until `buf[pos] & mask == expected`.
    fn poll(
        &mut self,
        step: Step,
        index: u16,
        size: usize,
        pos: usize,
        mask: u8,
        expected: u8,
    ) -> Res<(), I2C::Error> {
        for _ in 0..=CMD_POLLS {
            let mut buf = [0u8; 4];
            let buf = buf.get_mut(..size).unwrap_or(&mut []);
            self.rd(step, index, buf)?;
            self.delay.delay_ms(10);
            if let Some(&code) = buf.get(2).filter(|&&c| size >= 4 && c >= 0x7F) {
                return Err(Vl53l5cxError::Mcu { step, code });
            }
            if buf.get(pos).is_some_and(|&b| b & mask == expected) {
                return Ok(());
            }
        }
        Err(Vl53l5cxError::Timeout(step))
    }

    fn poll_cmd(&mut self, step: Step) -> Res<(), I2C::Error> {
        self.poll(step, UI_CMD_STATUS, 4, 1, 0xFF, 0x03)
    }

    /// Checks the device and revision ids (page 0, then back to page 2).
    pub fn is_alive(&mut self) -> Res<(), I2C::Error> {
        let step = Step::Presence;
        self.wr(step, PAGE_SELECT, 0x00)?;
        let device = self.rd_byte(step, REG_DEVICE_ID)?;
        let revision = self.rd_byte(step, REG_REVISION_ID)?;
        self.wr(step, PAGE_SELECT, 0x02)?;
        if device != DEVICE_ID || revision != REVISION_ID {
            return Err(Vl53l5cxError::WrongChipId { device, revision });
        }
        Ok(())
    }

    fn check_buffers(&self) -> Res<(), I2C::Error> {
        let checks = [
            ("firmware", FIRMWARE_LEN, self.st.firmware.len()),
            (
                "default configuration",
                DEFAULT_CONFIG_LEN,
                self.st.default_configuration.len(),
            ),
            ("default xtalk", XTALK_LEN, self.st.default_xtalk.len()),
            ("NVM command", NVM_CMD_LEN, self.st.get_nvm_cmd.len()),
        ];
        for (which, expected, got) in checks {
            if got != expected {
                return Err(Vl53l5cxError::BufferSize {
                    which,
                    expected,
                    got,
                });
            }
        }
        if self.io.len() < MIN_IO {
            return Err(Vl53l5cxError::IoBufferTooSmall {
                needed: MIN_IO,
                got: self.io.len(),
            });
        }
        Ok(())
    }

    /// Checks presence, reboots the sensor, uploads the firmware, reads the NVM calibration and
    /// sends the offset, crosstalk and default configuration (4×4, ST's `vl53l5cx_is_alive`
    /// followed by `vl53l5cx_init`). Buffer sizes are checked before any bus traffic.
    pub fn init(&mut self) -> Res<(), I2C::Error> {
        self.check_buffers()?;
        self.ranging = false;
        self.is_alive()?;
        const W: fn(u16, u8) -> (u16, Option<u8>) = |i, v| (i, Some(v));
        const R: fn(u16) -> (u16, Option<u8>) = |i| (i, None);
        self.script(
            Step::Reboot,
            &[
                W(0x7FFF, 0x00),
                W(0x0009, 0x04),
                W(0x000F, 0x40),
                W(0x000A, 0x03),
                R(0x7FFF),
                W(0x000C, 0x01),
                W(0x0101, 0x00),
                W(0x0102, 0x00),
                W(0x010A, 0x01),
                W(0x4002, 0x01),
                W(0x4002, 0x00),
                W(0x010A, 0x03),
                W(0x0103, 0x01),
                W(0x000C, 0x00),
                W(0x000F, 0x43),
            ],
        )?;
        self.delay.delay_ms(1);
        self.script(Step::Reboot, &[W(0x000F, 0x40), W(0x000A, 0x01)])?;
        self.delay.delay_ms(100);

        self.wr(Step::Boot, PAGE_SELECT, 0x00)?;
        self.poll(Step::Boot, REG_GO2_STATUS0, 1, 0, 0xFF, 0x01)?;
        self.script(Step::Boot, &[W(0x000E, 0x01), W(0x7FFF, 0x02)])?;

        self.script(Step::FirmwareAccess, &[W(0x0003, 0x0D), W(0x7FFF, 0x01)])?;
        self.poll(Step::FirmwareAccess, REG_FW_ACCESS, 1, 0, 0x10, 0x10)?;
        self.wr(Step::FirmwareAccess, PAGE_SELECT, 0x00)?;

        self.script(
            Step::PowerOn,
            &[
                R(0x7FFF),
                W(0x000C, 0x01),
                W(0x7FFF, 0x00),
                W(0x0101, 0x00),
                W(0x0102, 0x00),
                W(0x010A, 0x01),
                W(0x4002, 0x01),
                W(0x4002, 0x00),
                W(0x010A, 0x03),
                W(0x0103, 0x01),
                W(0x400F, 0x00),
                W(0x021A, 0x43),
                W(0x021A, 0x03),
                W(0x021A, 0x01),
                W(0x021A, 0x00),
                W(0x0219, 0x00),
                W(0x021B, 0x00),
                // Wake up the MCU.
                W(0x7FFF, 0x00),
                R(0x7FFF),
                W(0x000C, 0x00),
                W(0x7FFF, 0x01),
                W(0x0020, 0x07),
                W(0x0020, 0x06),
            ],
        )?;

        let firmware = self.st.firmware;
        let mut start = 0usize;
        for (page, len) in FIRMWARE_PAGES {
            self.wr(Step::FirmwareUpload, PAGE_SELECT, page)?;
            let part = firmware.get(start..start + len).unwrap_or(&[]);
            self.wr_slice(Step::FirmwareUpload, 0x0000, part)?;
            start += len;
        }
        self.wr(Step::FirmwareUpload, PAGE_SELECT, 0x01)?;

        self.script(
            Step::McuBoot,
            &[W(0x7FFF, 0x02), W(0x0003, 0x0D), W(0x7FFF, 0x01)],
        )?;
        self.poll(Step::McuBoot, REG_FW_ACCESS, 1, 0, 0x10, 0x10)?;
        self.script(
            Step::McuBoot,
            &[
                W(0x7FFF, 0x00),
                R(0x7FFF),
                W(0x000C, 0x01),
                W(0x7FFF, 0x00),
                W(0x0114, 0x00),
                W(0x0115, 0x00),
                W(0x0116, 0x42),
                W(0x0117, 0x00),
                W(0x000B, 0x00),
                R(0x7FFF),
                W(0x000C, 0x00),
                W(0x000B, 0x01),
            ],
        )?;
        self.poll_mcu_boot()?;
        self.wr(Step::McuBoot, PAGE_SELECT, 0x02)?;

        let cmd = self.st.get_nvm_cmd;
        self.wr_slice(Step::Nvm, NVM_CMD_INDEX, cmd)?;
        self.poll(Step::Nvm, UI_CMD_STATUS, 4, 0, 0xFF, 0x02)?;
        let mut nvm = [0u8; NVM_DATA_LEN];
        self.rd(Step::Nvm, UI_CMD_START, &mut nvm)?;
        self.nvm = nvm;
        self.send_offset(Resolution::R4x4)?;
        self.send_xtalk(Resolution::R4x4)?;

        let config = self.st.default_configuration;
        self.wr_slice(Step::DefaultConfig, DEFAULT_CONFIG_INDEX, config)?;
        self.poll_cmd(Step::DefaultConfig)?;
        // One target per zone; single range on (autonomous).
        self.dci_write(dci::PIPE_CONTROL, &[1, 0, 1, 0])?;
        self.dci_write(dci::SINGLE_RANGE, &1u32.to_le_bytes())?;
        self.resolution = Resolution::R4x4;
        Ok(())
    }

    fn poll_mcu_boot(&mut self) -> Res<(), I2C::Error> {
        let step = Step::McuBoot;
        for _ in 0..BOOT_POLLS {
            let s0 = self.rd_byte(step, REG_GO2_STATUS0)?;
            if s0 & 0x80 != 0 {
                let code = self.rd_byte(step, REG_GO2_STATUS1)?;
                return match code {
                    0 => Ok(()),
                    code => Err(Vl53l5cxError::Mcu { step, code }),
                };
            }
            self.delay.delay_ms(1);
            if s0 & 0x01 != 0 {
                return Ok(());
            }
        }
        Err(Vl53l5cxError::Timeout(step))
    }

    fn send_offset(&mut self, resolution: Resolution) -> Res<(), I2C::Error> {
        let four = resolution == Resolution::R4x4;
        let chunk = self.chunk_max();
        let nvm = &self.nvm[..OFFSET_LEN];
        write_chunked(
            &mut self.i2c,
            self.config.address,
            self.io,
            chunk,
            Step::Offset,
            OFFSET_INDEX,
            calib::OFFSET_PAYLOAD_LEN,
            |off, out| {
                for (k, b) in out.iter_mut().enumerate() {
                    *b = calib::offset_payload_byte(nvm, four, off + k);
                }
            },
        )?;
        self.poll_cmd(Step::Offset)
    }

    fn send_xtalk(&mut self, resolution: Resolution) -> Res<(), I2C::Error> {
        let four = resolution == Resolution::R4x4;
        let chunk = self.chunk_max();
        let xtalk = self.st.default_xtalk;
        write_chunked(
            &mut self.i2c,
            self.config.address,
            self.io,
            chunk,
            Step::Xtalk,
            XTALK_INDEX,
            calib::XTALK_PAYLOAD_LEN,
            |off, out| {
                for (k, b) in out.iter_mut().enumerate() {
                    *b = calib::xtalk_payload_byte(xtalk, four, off + k);
                }
            },
        )?;
        self.poll_cmd(Step::Xtalk)
    }

    /// Reads firmware data item `index` into `out` (`out.len()` a multiple of 4, ≤ 20).
    pub fn dci_read(&mut self, index: u16, out: &mut [u8]) -> Res<(), I2C::Error> {
        let size = out.len();
        if !size.is_multiple_of(4) || size + 12 > self.io.len() || size > 0xFFF {
            return Err(Vl53l5cxError::InvalidParam("DCI size"));
        }
        let [ih, il] = index.to_be_bytes();
        let cmd = [
            ih,
            il,
            ((size & 0xFF0) >> 4) as u8,
            ((size & 0xF) << 4) as u8,
            0x00,
            0x00,
            0x00,
            0x0F,
            0x00,
            0x02,
            0x00,
            0x08,
        ];
        self.wr_slice(Step::Dci, UI_CMD_END - 11, &cmd)?;
        self.poll_cmd(Step::Dci)?;
        let step = Step::Dci;
        let buf = self.io.get_mut(..size + 12).unwrap_or(&mut []);
        self.i2c
            .write_read(self.config.address, &UI_CMD_START.to_be_bytes(), buf)
            .map_err(|error| Vl53l5cxError::Bus { step, error })?;
        for (i, o) in out.iter_mut().enumerate() {
            *o = buf.get(4 + swapped(i)).copied().unwrap_or(0);
        }
        Ok(())
    }

    /// Writes firmware data item `index` from `data` (`data.len()` a multiple of 4).
    pub fn dci_write(&mut self, index: u16, data: &[u8]) -> Res<(), I2C::Error> {
        let size = data.len();
        if !size.is_multiple_of(4) || size > 0xFFF - 8 {
            return Err(Vl53l5cxError::InvalidParam("DCI size"));
        }
        let [ih, il] = index.to_be_bytes();
        let head = [
            ih,
            il,
            ((size & 0xFF0) >> 4) as u8,
            ((size & 0xF) << 4) as u8,
        ];
        let [fh, fl] = ((size + 8) as u16).to_be_bytes();
        let foot = [0x00, 0x00, 0x00, 0x0F, 0x05, 0x01, fh, fl];
        let at = (usize::from(UI_CMD_END) + 1 - (size + 12)) as u16;
        let chunk = self.chunk_max();
        write_chunked(
            &mut self.i2c,
            self.config.address,
            self.io,
            chunk,
            Step::Dci,
            at,
            size + 12,
            |off, out| {
                for (k, b) in out.iter_mut().enumerate() {
                    let p = off + k;
                    *b = if p < 4 {
                        head[p]
                    } else if p < 4 + size {
                        data.get(swapped(p - 4)).copied().unwrap_or(0)
                    } else {
                        foot.get(p - 4 - size).copied().unwrap_or(0)
                    };
                }
            },
        )?;
        self.poll_cmd(Step::Dci)
    }

    /// Sets 4×4 or 8×8 (SPAD selection, zone configuration, then offset and crosstalk again).
    pub fn set_resolution(&mut self, resolution: Resolution) -> Res<(), I2C::Error> {
        let (dss, zone, size) = match resolution {
            Resolution::R4x4 => (64, 4, 8),
            Resolution::R8x8 => (16, 8, 4),
        };
        let mut d = [0u8; 16];
        self.dci_read(dci::DSS_CONFIG, &mut d)?;
        d[4] = dss;
        d[6] = dss;
        d[9] = if resolution == Resolution::R4x4 { 4 } else { 1 };
        self.dci_write(dci::DSS_CONFIG, &d)?;
        let mut z = [0u8; 8];
        self.dci_read(dci::ZONE_CONFIG, &mut z)?;
        z[0] = zone;
        z[1] = zone;
        z[4] = size;
        z[5] = size;
        self.dci_write(dci::ZONE_CONFIG, &z)?;
        self.send_offset(resolution)?;
        self.send_xtalk(resolution)?;
        self.resolution = resolution;
        Ok(())
    }

    /// Sets the ranging frequency: 1–60 Hz in 4×4, 1–15 Hz in 8×8 (ST's limits; checked against
    /// the resolution last set).
    pub fn set_ranging_frequency_hz(&mut self, hz: u8) -> Res<(), I2C::Error> {
        let max = match self.resolution {
            Resolution::R4x4 => 60,
            Resolution::R8x8 => 15,
        };
        if !(1..=max).contains(&hz) {
            return Err(Vl53l5cxError::InvalidParam("ranging frequency"));
        }
        let mut d = [0u8; 4];
        self.dci_read(dci::FREQ_HZ, &mut d)?;
        d[1] = hz;
        self.dci_write(dci::FREQ_HZ, &d)
    }

    /// Reads the ranging frequency, Hz.
    pub fn ranging_frequency_hz(&mut self) -> Res<u8, I2C::Error> {
        let mut d = [0u8; 4];
        self.dci_read(dci::FREQ_HZ, &mut d)?;
        Ok(d[1])
    }

    /// Sets the integration time, 2–1000 ms (used in autonomous mode).
    pub fn set_integration_time_ms(&mut self, ms: u32) -> Res<(), I2C::Error> {
        if !(2..=1000).contains(&ms) {
            return Err(Vl53l5cxError::InvalidParam("integration time"));
        }
        let mut d = [0u8; 20];
        self.dci_read(dci::INT_TIME, &mut d)?;
        d[..4].copy_from_slice(&(ms * 1000).to_le_bytes());
        self.dci_write(dci::INT_TIME, &d)
    }

    /// Reads the integration time, ms.
    pub fn integration_time_ms(&mut self) -> Res<u32, I2C::Error> {
        let mut d = [0u8; 20];
        self.dci_read(dci::INT_TIME, &mut d)?;
        Ok(u32::from_le_bytes([d[0], d[1], d[2], d[3]]) / 1000)
    }

    /// Sets the ranging mode.
    pub fn set_ranging_mode(&mut self, mode: RangingMode) -> Res<(), I2C::Error> {
        let mut d = [0u8; 8];
        self.dci_read(dci::RANGING_MODE, &mut d)?;
        let single: u32 = match mode {
            RangingMode::Continuous => {
                d[1] = 1;
                d[3] = 3;
                0
            }
            RangingMode::Autonomous => {
                d[1] = 3;
                d[3] = 2;
                1
            }
        };
        self.dci_write(dci::RANGING_MODE, &d)?;
        self.dci_write(dci::SINGLE_RANGE, &single.to_le_bytes())
    }

    /// Reads the resolution from the device's zone configuration.
    pub fn read_resolution(&mut self) -> Res<Resolution, I2C::Error> {
        let mut z = [0u8; 8];
        self.dci_read(dci::ZONE_CONFIG, &mut z)?;
        match z[0].wrapping_mul(z[1]) {
            16 => Ok(Resolution::R4x4),
            64 => Ok(Resolution::R8x8),
            n => Err(Vl53l5cxError::BadResolution(n)),
        }
    }

    /// Programs the outputs (all of ULD's default outputs) and starts ranging.
    pub fn start_ranging(&mut self) -> Res<(), I2C::Error> {
        let resolution = self.read_resolution()?;
        let list = output_list(resolution.zones());
        let size = protocol::results_len(&list, &OUTPUT_ENABLES);
        if self.io.len() < size {
            return Err(Vl53l5cxError::IoBufferTooSmall {
                needed: size,
                got: self.io.len(),
            });
        }
        self.resolution = resolution;
        self.stream_count = 255;
        self.data_read_size = 0;
        let mut bytes = [0u8; 48];
        for (b, w) in bytes.chunks_exact_mut(4).zip(list) {
            b.copy_from_slice(&w.to_le_bytes());
        }
        self.dci_write(dci::OUTPUT_LIST, &bytes)?;
        let mut cfg = [0u8; 8];
        cfg[..4].copy_from_slice(&(size as u32).to_le_bytes());
        cfg[4..].copy_from_slice(&(list.len() as u32 + 1).to_le_bytes());
        self.dci_write(dci::OUTPUT_CONFIG, &cfg)?;
        let mut en = [0u8; 16];
        for (b, w) in en.chunks_exact_mut(4).zip(OUTPUT_ENABLES) {
            b.copy_from_slice(&w.to_le_bytes());
        }
        self.dci_write(dci::OUTPUT_ENABLES, &en)?;
        self.script(
            Step::Start,
            &[
                (0x7FFF, Some(0x00)),
                (0x0009, Some(0x05)),
                (0x7FFF, Some(0x02)),
            ],
        )?;
        self.wr_slice(Step::Start, LAST_CMD_WORD, &START_CMD)?;
        self.poll_cmd(Step::Start)?;
        let mut info = [0u8; 12];
        self.dci_read(dci::RANGE_DATA_INFO, &mut info)?;
        let device = usize::from(u16::from_le_bytes([info[8], info[9]]));
        if device != size {
            return Err(Vl53l5cxError::ResultsSizeMismatch {
                driver: size,
                device,
            });
        }
        self.data_read_size = size;
        self.ranging = true;
        Ok(())
    }

    /// Stops ranging (MCU stop handshake unless the device stopped by itself).
    pub fn stop_ranging(&mut self) -> Res<(), I2C::Error> {
        let step = Step::Stop;
        self.ranging = false;
        let mut flag = [0u8; 4];
        self.rd(step, LAST_CMD_WORD, &mut flag)?;
        if u32::from_le_bytes(flag) != AUTO_STOP_FLAG {
            self.script(
                step,
                &[
                    (0x7FFF, Some(0x00)),
                    (0x0015, Some(0x16)),
                    (0x0014, Some(0x01)),
                ],
            )?;
            let mut stopped = false;
            for _ in 0..=STOP_POLLS {
                let s = self.rd_byte(step, REG_GO2_STATUS0)?;
                self.delay.delay_ms(10);
                if s & 0x80 != 0 {
                    stopped = true;
                    break;
                }
            }
            if !stopped {
                return Err(Vl53l5cxError::Timeout(step));
            }
        }
        let s = self.rd_byte(step, REG_GO2_STATUS0)?;
        if s & 0x80 != 0 {
            let code = self.rd_byte(step, REG_GO2_STATUS1)?;
            if code != 0x84 && code != 0x85 {
                return Err(Vl53l5cxError::Mcu { step, code });
            }
        }
        self.script(
            step,
            &[
                (0x7FFF, Some(0x00)),
                (0x0014, Some(0x00)),
                (0x0015, Some(0x00)),
                (0x0009, Some(0x04)),
                (0x7FFF, Some(0x02)),
            ],
        )
    }

    /// True when a new frame is ready (one 4-byte read of the results preamble).
    pub fn check_data_ready(&mut self) -> Res<bool, I2C::Error> {
        if !self.ranging {
            return Err(Vl53l5cxError::NotRanging);
        }
        let mut b = [0u8; 4];
        self.rd(Step::DataReady, RESULTS_INDEX, &mut b)?;
        if b[0] != self.stream_count
            && b[0] != 255
            && b[1] == 0x05
            && b[2] & 0x05 == 0x05
            && b[3] & 0x10 == 0x10
        {
            self.stream_count = b[0];
            return Ok(true);
        }
        if b[3] & 0x80 != 0 {
            return Err(Vl53l5cxError::Mcu {
                step: Step::DataReady,
                code: b[2],
            });
        }
        Ok(false)
    }

    /// Reads and decodes the results into `out` (untouched on error).
    pub fn get_ranging_data(&mut self, out: &mut ResultsData) -> Res<(), I2C::Error> {
        if !self.ranging {
            return Err(Vl53l5cxError::NotRanging);
        }
        let size = self.data_read_size;
        let step = Step::Results;
        let got = self.io.len();
        let buf = self
            .io
            .get_mut(..size)
            .ok_or(Vl53l5cxError::IoBufferTooSmall { needed: size, got })?;
        self.i2c
            .write_read(self.config.address, &RESULTS_INDEX.to_be_bytes(), buf)
            .map_err(|error| Vl53l5cxError::Bus { step, error })?;
        self.stream_count = buf.first().copied().unwrap_or(255);
        results::decode(buf, usize::from(self.resolution.zones()), out)
            .map_err(Vl53l5cxError::BadResults)
    }

    fn wait_frame(&mut self) -> Res<(), I2C::Error> {
        let interval = self.config.poll_interval_us.max(1);
        let polls = self.config.frame_timeout_us / interval + 1;
        for poll in 0..polls {
            if self.check_data_ready()? {
                return Ok(());
            }
            if poll + 1 < polls {
                self.delay.delay_us(interval);
            }
        }
        Err(Vl53l5cxError::Timeout(Step::DataReady))
    }
}

impl<I2C: I2c, D: DelayNs> ErrorType for Vl53l5cx<'_, I2C, D> {
    type Error = Vl53l5cxError<I2C::Error>;
}

impl<I2C: I2c, D: DelayNs> DtofSensor for Vl53l5cx<'_, I2C, D> {
    fn geometry(&self) -> DtofGeometry {
        let side = self.resolution.side();
        DtofGeometry {
            rows: side,
            cols: side,
            fov_deg: [45.0, 45.0],
            distance: DistanceKind::Z,
            max_range_m: 4.0,
        }
    }

    /// Waits for the next frame (after [`Vl53l5cx::start_ranging`]) and fills distance,
    /// ST status, sigma, signal and ambient (kcps per SPAD) in ULD zone order.
    fn read_frame<const N: usize>(&mut self, frame: &mut ZoneFrame<N>) -> Result<(), Self::Error> {
        if !self.ranging {
            return Err(Vl53l5cxError::NotRanging);
        }
        let zones = usize::from(self.resolution.zones());
        if zones > N {
            return Err(Vl53l5cxError::BufferShape { zones, capacity: N });
        }
        self.wait_frame()?;
        let mut results = core::mem::take(&mut self.results);
        let got = self.get_ranging_data(&mut results);
        self.results = results;
        got?;
        let r = &self.results;
        let side = self.resolution.side();
        frame
            .set_shape(side, side)
            .map_err(|_| Vl53l5cxError::BufferShape { zones, capacity: N })?;
        for k in 0..zones.min(N).min(MAX_ZONES) {
            frame.distance_mm[k] = f32::from(r.distance_mm[k]);
            frame.status[k] = r.target_status[k];
            frame.sigma_mm[k] = f32::from(r.range_sigma_mm[k]);
            frame.signal_kcps[k] = r.signal_per_spad[k] as f32;
            frame.ambient_kcps[k] = r.ambient_per_spad[k] as f32;
        }
        frame.has_sigma = r.has.sigma;
        frame.has_signal = r.has.signal;
        frame.has_ambient = r.has.ambient;
        Ok(())
    }
}
