//! "depthor zone bridge": a small I2C protocol for a multizone dToF sensor, with the host-side
//! driver [`ZoneBridgeSensor`] (implements [`DtofSensor`]) and the device side
//! [`ZoneBridgeDevice`] (implements [`embedded_hal::i2c::I2c`] over borrowed zone data), so host
//! tests and QEMU firmware run the real driver path over a simulated bus.
//!
//! The protocol is ours (defined here, not a vendor's); it carries what the pipeline needs from a
//! VL53L5CX-class sensor behind a microcontroller bridge.
//!
//! # Bus
//!
//! 7-bit address [`ADDRESS`] (`0x29`), standard/fast mode. Register indices are 16 bits, sent big
//! endian. A **read** is `START, addr+W, idx_hi, idx_lo, RESTART, addr+R, data…, STOP`
//! ([`I2c::write_read`]); the index auto-increments with every byte, across register boundaries.
//! A **write** is `START, addr+W, idx_hi, idx_lo, data…, STOP`. Unmapped indices read as `0x00`;
//! writes to anything but `STATUS` are not acknowledged.
//!
//! # Register map
//!
//! | index | name | access | content |
//! |---|---|---|---|
//! | `0x0000` | `ID` | R | [`CHIP_ID`] = `0xDB` |
//! | `0x0001` | `VERSION` | R | protocol version, [`VERSION`] = 1 |
//! | `0x0002` | `ROWS` | R | zone rows, 1–255 |
//! | `0x0003` | `COLS` | R | zone columns, 1–255 |
//! | `0x0004` | `FOV_H` | R | horizontal FoV, `u16` LE, 0.01° units, 1–17999 |
//! | `0x0006` | `FOV_V` | R | vertical FoV, `u16` LE, 0.01° units, 1–17999 |
//! | `0x0008` | `KIND` | R | 0 = z distance, 1 = radial distance |
//! | `0x0009` | `MAX_RANGE` | R | largest reported distance, `u16` LE, mm |
//! | `0x000B` | `STATUS` | R/W | bit 0 `DATA_READY`; write `0x01` to release the frame |
//! | `0x000C` | `FRAME_COUNT` | R | frames latched so far, `u8`, wraps |
//! | `0x0100` | `FRAME` | R | `ROWS·COLS` records of 3 bytes, row-major (row 0 at the top) |
//!
//! A `FRAME` record is `distance_mm: i16` (little endian, millimetres) followed by
//! `target_status: u8` (ST codes: 5 and 9 valid, 255 no target; see [`crate::hal`]). The frame
//! must fit below index `0x10000`, so `ROWS·COLS ≤` [`MAX_ZONES`] (21 760).
//!
//! # Frame handshake
//!
//! The device latches a frame and sets `DATA_READY`. The latched frame does not change until the
//! host writes `0x01` to `STATUS`, so the host may read `FRAME` in as many chunks as it likes.
//! After the release `DATA_READY` reads 0 until the next frame is latched.
//!
//! # Example: the driver over the simulated device
//!
//! ```
//! use depthor_core::calibration::{DistanceKind, DtofGeometry};
//! use depthor_core::drivers::zone_bridge::{ZoneBridgeDevice, ZoneBridgeSensor};
//! use depthor_core::hal::{DtofSensor, ZoneFrame};
//!
//! struct NoDelay;
//! impl embedded_hal::delay::DelayNs for NoDelay {
//!     fn delay_ns(&mut self, _ns: u32) {}
//! }
//!
//! let geometry = DtofGeometry {
//!     rows: 2, cols: 2, fov_deg: [45.0, 45.0], distance: DistanceKind::Z, max_range_m: 4.0,
//! };
//! let distance_mm = [1000.0, 1200.0, 0.0, 3999.0];
//! let status = [5, 9, 255, 5];
//! let device = ZoneBridgeDevice::new(&geometry, &distance_mm, &status).unwrap();
//! let mut sensor = ZoneBridgeSensor::new(device, NoDelay);
//! let mut frame = ZoneFrame::<64>::new();
//! sensor.read_frame(&mut frame).unwrap();
//! assert_eq!((frame.rows, frame.cols), (2, 2));
//! assert_eq!(frame.view().distance_mm, &distance_mm[..]);
//! assert_eq!(frame.view().status, &status[..]);
//! assert_eq!(sensor.geometry(), geometry);
//! ```

use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::{I2c, NoAcknowledgeSource, Operation};

use crate::calibration::{DistanceKind, DtofGeometry};
use crate::hal::{DtofSensor, ErrorKind, ErrorType, ZoneFrame};

/// 7-bit I2C address of the bridge.
pub const ADDRESS: u8 = 0x29;
/// Value of the `ID` register.
pub const CHIP_ID: u8 = 0xDB;
/// Protocol version in the `VERSION` register.
pub const VERSION: u8 = 1;
/// Bytes per `FRAME` record (`i16` distance + `u8` status).
pub const RECORD_BYTES: usize = 3;
/// Largest zone count whose frame fits the 16-bit register space above `FRAME`.
pub const MAX_ZONES: usize = (0x1_0000 - reg::FRAME as usize) / RECORD_BYTES;

/// Register indices (see the module's register map).
pub mod reg {
    /// Chip identifier, reads [`super::CHIP_ID`].
    pub const ID: u16 = 0x0000;
    /// Protocol version.
    pub const VERSION: u16 = 0x0001;
    /// Zone rows.
    pub const ROWS: u16 = 0x0002;
    /// Zone columns.
    pub const COLS: u16 = 0x0003;
    /// Horizontal FoV, `u16` LE, 0.01°.
    pub const FOV_H: u16 = 0x0004;
    /// Vertical FoV, `u16` LE, 0.01°.
    pub const FOV_V: u16 = 0x0006;
    /// Distance kind: 0 = z, 1 = radial.
    pub const KIND: u16 = 0x0008;
    /// Largest reported distance, `u16` LE, mm.
    pub const MAX_RANGE: u16 = 0x0009;
    /// Bit 0 = data ready; write `0x01` to release the frame.
    pub const STATUS: u16 = 0x000B;
    /// Latched frame counter, `u8`.
    pub const FRAME_COUNT: u16 = 0x000C;
    /// Start of the frame records.
    pub const FRAME: u16 = 0x0100;
    /// Bytes from `ID` through `MAX_RANGE`, read in one transaction at init.
    pub const HEADER_LEN: usize = STATUS as usize;
}

/// `STATUS` bit 0: a frame is latched and ready to read.
pub const STATUS_DATA_READY: u8 = 0x01;
/// Value written to `STATUS` to release the latched frame.
pub const STATUS_RELEASE: u8 = 0x01;

/// Zones read per `FRAME` transaction by the driver (16 · 3 = 48 bytes of stack).
const CHUNK_ZONES: usize = 16;

/// Driver settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Config {
    /// 7-bit bus address (default [`ADDRESS`]).
    pub address: u8,
    /// Wait between two `STATUS` polls, microseconds (default 1000).
    pub poll_interval_us: u32,
    /// Give up waiting for `DATA_READY` after this long, microseconds (default 200 000, i.e.
    /// several frame periods of a 15 Hz sensor).
    pub timeout_us: u32,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            address: ADDRESS,
            poll_interval_us: 1_000,
            timeout_us: 200_000,
        }
    }
}

/// What went wrong talking to the bridge; `E` is the bus's error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ZoneBridgeError<E> {
    /// The I2C transaction failed.
    Bus(E),
    /// `DATA_READY` did not rise within [`Config::timeout_us`].
    Timeout,
    /// The `ID` register did not read [`CHIP_ID`].
    WrongId(u8),
    /// The header registers hold an unsupported value; the text says which.
    BadHeader(&'static str),
    /// The caller's [`ZoneFrame`] holds fewer zones than the sensor sends.
    BufferShape {
        /// Zones per frame of the sensor.
        zones: usize,
        /// Capacity of the caller's frame.
        capacity: usize,
    },
}

impl<E: core::fmt::Debug> core::fmt::Display for ZoneBridgeError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ZoneBridgeError::Bus(e) => write!(f, "zone bridge bus error: {e:?}"),
            ZoneBridgeError::Timeout => f.write_str("zone bridge: no frame before the timeout"),
            ZoneBridgeError::WrongId(id) => {
                write!(
                    f,
                    "zone bridge: ID reads {id:#04x}, expected {CHIP_ID:#04x}"
                )
            }
            ZoneBridgeError::BadHeader(what) => write!(f, "zone bridge: bad header: {what}"),
            ZoneBridgeError::BufferShape { zones, capacity } => write!(
                f,
                "zone bridge sends {zones} zones, the frame buffer holds {capacity}"
            ),
        }
    }
}

impl<E: core::fmt::Debug> core::error::Error for ZoneBridgeError<E> {}

impl<E: embedded_hal::i2c::Error> crate::hal::Error for ZoneBridgeError<E> {
    fn kind(&self) -> ErrorKind {
        match self {
            ZoneBridgeError::Bus(_) => ErrorKind::Bus,
            ZoneBridgeError::Timeout => ErrorKind::Timeout,
            ZoneBridgeError::WrongId(_) | ZoneBridgeError::BadHeader(_) => ErrorKind::BadData,
            ZoneBridgeError::BufferShape { .. } => ErrorKind::BufferShape,
        }
    }
}

/// Decodes the header registers (`ID` through `MAX_RANGE`) into a geometry.
fn parse_header<E>(h: &[u8; reg::HEADER_LEN]) -> Result<DtofGeometry, ZoneBridgeError<E>> {
    let [id, version, rows, cols, fh0, fh1, fv0, fv1, kind, mr0, mr1] = *h;
    if id != CHIP_ID {
        return Err(ZoneBridgeError::WrongId(id));
    }
    if version != VERSION {
        return Err(ZoneBridgeError::BadHeader("unsupported protocol version"));
    }
    if rows == 0 || cols == 0 {
        return Err(ZoneBridgeError::BadHeader("zero rows or columns"));
    }
    if usize::from(rows) * usize::from(cols) > MAX_ZONES {
        return Err(ZoneBridgeError::BadHeader(
            "frame larger than the register space",
        ));
    }
    let fov = |lo: u8, hi: u8| {
        let centi = u16::from_le_bytes([lo, hi]);
        (1..18_000)
            .contains(&centi)
            .then(|| f32::from(centi) / 100.0)
    };
    let (Some(fov_h), Some(fov_v)) = (fov(fh0, fh1), fov(fv0, fv1)) else {
        return Err(ZoneBridgeError::BadHeader(
            "field of view outside (0, 180) degrees",
        ));
    };
    let distance = match kind {
        0 => DistanceKind::Z,
        1 => DistanceKind::Radial,
        _ => return Err(ZoneBridgeError::BadHeader("unknown distance kind")),
    };
    Ok(DtofGeometry {
        rows: u16::from(rows),
        cols: u16::from(cols),
        fov_deg: [fov_h, fov_v],
        distance,
        max_range_m: f32::from(u16::from_le_bytes([mr0, mr1])) / 1000.0,
    })
}

/// Host-side driver of a zone bridge; owns its bus and delay (embassy style).
///
/// The header is read once, by [`ZoneBridgeSensor::init`] or lazily by the first
/// [`DtofSensor::read_frame`]; until then [`DtofSensor::geometry`] reports a 0×0 grid.
#[derive(Debug)]
pub struct ZoneBridgeSensor<I2C, D> {
    i2c: I2C,
    delay: D,
    config: Config,
    geometry: Option<DtofGeometry>,
}

impl<I2C: I2c, D: DelayNs> ZoneBridgeSensor<I2C, D> {
    /// A driver with the default [`Config`]; does no bus traffic.
    pub fn new(i2c: I2C, delay: D) -> Self {
        Self::with_config(i2c, delay, Config::default())
    }

    /// A driver with explicit settings; does no bus traffic.
    pub fn with_config(i2c: I2C, delay: D, config: Config) -> Self {
        ZoneBridgeSensor {
            i2c,
            delay,
            config,
            geometry: None,
        }
    }

    /// Gives the bus and delay back.
    pub fn release(self) -> (I2C, D) {
        (self.i2c, self.delay)
    }

    /// Checks `ID` and `VERSION` and reads the zone geometry (again, if already read).
    pub fn init(&mut self) -> Result<DtofGeometry, ZoneBridgeError<I2C::Error>> {
        let mut header = [0u8; reg::HEADER_LEN];
        self.read_regs(reg::ID, &mut header)?;
        let geometry = parse_header(&header)?;
        self.geometry = Some(geometry);
        Ok(geometry)
    }

    /// Reads the `FRAME_COUNT` register.
    pub fn frame_count(&mut self) -> Result<u8, ZoneBridgeError<I2C::Error>> {
        let mut b = [0u8];
        self.read_regs(reg::FRAME_COUNT, &mut b)?;
        Ok(b[0])
    }

    fn read_regs(&mut self, index: u16, buf: &mut [u8]) -> Result<(), ZoneBridgeError<I2C::Error>> {
        self.i2c
            .write_read(self.config.address, &index.to_be_bytes(), buf)
            .map_err(ZoneBridgeError::Bus)
    }

    /// Polls `STATUS` until `DATA_READY`, sleeping `poll_interval_us` between polls.
    fn wait_ready(&mut self) -> Result<(), ZoneBridgeError<I2C::Error>> {
        let interval = self.config.poll_interval_us.max(1);
        let polls = self.config.timeout_us / interval + 1;
        for poll in 0..polls {
            let mut status = [0u8];
            self.read_regs(reg::STATUS, &mut status)?;
            if status[0] & STATUS_DATA_READY != 0 {
                return Ok(());
            }
            if poll + 1 < polls {
                self.delay.delay_us(interval);
            }
        }
        Err(ZoneBridgeError::Timeout)
    }
}

impl<I2C: I2c, D: DelayNs> ErrorType for ZoneBridgeSensor<I2C, D> {
    type Error = ZoneBridgeError<I2C::Error>;
}

impl<I2C: I2c, D: DelayNs> DtofSensor for ZoneBridgeSensor<I2C, D> {
    fn geometry(&self) -> DtofGeometry {
        self.geometry.unwrap_or(DtofGeometry {
            rows: 0,
            cols: 0,
            fov_deg: [0.0; 2],
            distance: DistanceKind::Z,
            max_range_m: 0.0,
        })
    }

    fn read_frame<const N: usize>(&mut self, frame: &mut ZoneFrame<N>) -> Result<(), Self::Error> {
        let geometry = match self.geometry {
            Some(g) => g,
            None => self.init()?,
        };
        let zones = geometry.zones();
        if zones > N {
            return Err(ZoneBridgeError::BufferShape { zones, capacity: N });
        }
        self.wait_ready()?;
        let (Some(distances), Some(statuses)) = (
            frame.distance_mm.get_mut(..zones),
            frame.status.get_mut(..zones),
        ) else {
            return Err(ZoneBridgeError::BufferShape { zones, capacity: N });
        };
        let mut index = reg::FRAME;
        let mut bytes = [0u8; CHUNK_ZONES * RECORD_BYTES];
        for (dist_chunk, status_chunk) in distances
            .chunks_mut(CHUNK_ZONES)
            .zip(statuses.chunks_mut(CHUNK_ZONES))
        {
            let len = dist_chunk.len() * RECORD_BYTES;
            let buf = bytes.get_mut(..len).unwrap_or(&mut []);
            self.i2c
                .write_read(self.config.address, &index.to_be_bytes(), buf)
                .map_err(ZoneBridgeError::Bus)?;
            for ((d, s), rec) in dist_chunk
                .iter_mut()
                .zip(status_chunk.iter_mut())
                .zip(buf.chunks_exact(RECORD_BYTES))
            {
                if let [lo, hi, st] = *rec {
                    *d = f32::from(i16::from_le_bytes([lo, hi]));
                    *s = st;
                }
            }
            // `MAX_ZONES` keeps the frame inside the 16-bit index space.
            index = index.wrapping_add(len as u16);
        }
        self.i2c
            .write(
                self.config.address,
                &[
                    reg::STATUS.to_be_bytes()[0],
                    reg::STATUS.to_be_bytes()[1],
                    STATUS_RELEASE,
                ],
            )
            .map_err(ZoneBridgeError::Bus)?;
        frame
            .set_shape(geometry.rows, geometry.cols)
            .map_err(|_| ZoneBridgeError::BufferShape { zones, capacity: N })?;
        frame.has_sigma = false;
        frame.has_signal = false;
        frame.has_ambient = false;
        Ok(())
    }
}

/// Why a [`ZoneBridgeDevice`] cannot serve the given geometry or data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceError {
    /// The geometry does not fit the protocol (rows/cols 1–255, FoV in (0°, 180°) at 0.01°,
    /// at most [`MAX_ZONES`] zones, range up to 65.535 m).
    UnsupportedGeometry(&'static str),
    /// The distance or status slice is not `rows * cols` long.
    ZoneCount {
        /// `rows * cols`.
        expected: usize,
        /// Length given.
        got: usize,
    },
}

impl core::fmt::Display for DeviceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DeviceError::UnsupportedGeometry(what) => write!(f, "unsupported geometry: {what}"),
            DeviceError::ZoneCount { expected, got } => {
                write!(f, "expected {expected} zones, got {got}")
            }
        }
    }
}

impl core::error::Error for DeviceError {}

/// Device side of the protocol: serves frames from borrowed zone data through
/// [`embedded_hal::i2c::I2c`], as the bridge firmware would.
///
/// Distances are sent as `i16` millimetres, rounded to nearest; NaN is sent as 0 and values
/// beyond the `i16` range saturate. Bus errors are [`embedded_hal::i2c::ErrorKind`]: a wrong
/// address or a write to a read-only register is not acknowledged.
#[derive(Clone, Debug)]
pub struct ZoneBridgeDevice<'a> {
    address: u8,
    header: [u8; reg::HEADER_LEN],
    distance_mm: &'a [f32],
    status: &'a [u8],
    pointer: u16,
    data_ready: bool,
    frame_count: u8,
    latency_polls: u32,
    polls_left: u32,
    repeat: bool,
    releases: u32,
}

impl<'a> ZoneBridgeDevice<'a> {
    /// A device at [`ADDRESS`] with `distance_mm`/`status` latched as its first frame
    /// (`DATA_READY` set, `FRAME_COUNT` 1).
    pub fn new(
        geometry: &DtofGeometry,
        distance_mm: &'a [f32],
        status: &'a [u8],
    ) -> Result<Self, DeviceError> {
        let unsupported = DeviceError::UnsupportedGeometry;
        let rows = u8::try_from(geometry.rows).map_err(|_| unsupported("rows above 255"))?;
        let cols = u8::try_from(geometry.cols).map_err(|_| unsupported("cols above 255"))?;
        if rows == 0 || cols == 0 {
            return Err(unsupported("zero rows or columns"));
        }
        if geometry.zones() > MAX_ZONES {
            return Err(unsupported("more zones than the register space holds"));
        }
        let centi = |deg: f32| {
            let c = deg * 100.0 + 0.5;
            (1.0..18_000.0).contains(&c).then_some(c as u16)
        };
        let (Some(fov_h), Some(fov_v)) = (centi(geometry.fov_deg[0]), centi(geometry.fov_deg[1]))
        else {
            return Err(unsupported("field of view outside (0, 180) degrees"));
        };
        let range_mm = geometry.max_range_m * 1000.0 + 0.5;
        if !(0.0..65_536.0).contains(&range_mm) {
            return Err(unsupported("max range outside 0-65.535 m"));
        }
        let [fh0, fh1] = fov_h.to_le_bytes();
        let [fv0, fv1] = fov_v.to_le_bytes();
        let [mr0, mr1] = (range_mm as u16).to_le_bytes();
        let kind = match geometry.distance {
            DistanceKind::Z => 0,
            DistanceKind::Radial => 1,
        };
        let mut device = ZoneBridgeDevice {
            address: ADDRESS,
            header: [
                CHIP_ID, VERSION, rows, cols, fh0, fh1, fv0, fv1, kind, mr0, mr1,
            ],
            distance_mm: &[],
            status: &[],
            pointer: 0,
            data_ready: false,
            frame_count: 0,
            latency_polls: 0,
            polls_left: 0,
            repeat: false,
            releases: 0,
        };
        device.set_frame(distance_mm, status)?;
        Ok(device)
    }

    /// Answers at another 7-bit address instead of [`ADDRESS`].
    pub fn with_address(mut self, address: u8) -> Self {
        self.address = address;
        self
    }

    /// Latches a new frame: sets `DATA_READY` (after the configured latency) and increments
    /// `FRAME_COUNT`. A frame not yet released is replaced.
    pub fn set_frame(
        &mut self,
        distance_mm: &'a [f32],
        status: &'a [u8],
    ) -> Result<(), DeviceError> {
        let expected = usize::from(self.header[2]) * usize::from(self.header[3]);
        for got in [distance_mm.len(), status.len()] {
            if got != expected {
                return Err(DeviceError::ZoneCount { expected, got });
            }
        }
        self.distance_mm = distance_mm;
        self.status = status;
        self.latch();
        Ok(())
    }

    /// Makes `DATA_READY` read 0 for this many `STATUS` reads after each latch (simulated
    /// integration time).
    pub fn set_latency_polls(&mut self, polls: u32) {
        self.latency_polls = polls;
        self.polls_left = polls;
    }

    /// When on, releasing a frame latches the same data again at once (a free-running sensor
    /// watching a still scene).
    pub fn set_repeat(&mut self, repeat: bool) {
        self.repeat = repeat;
    }

    /// True while a latched frame waits to be released.
    pub fn data_ready(&self) -> bool {
        self.data_ready
    }

    /// How many times the host released a frame.
    pub fn releases(&self) -> u32 {
        self.releases
    }

    fn latch(&mut self) {
        self.data_ready = true;
        self.frame_count = self.frame_count.wrapping_add(1);
        self.polls_left = self.latency_polls;
    }

    /// The byte at register index `index` (reading `STATUS` consumes a latency poll).
    fn read_byte(&mut self, index: u16) -> u8 {
        let i = usize::from(index);
        if let Some(&b) = self.header.get(i) {
            return b;
        }
        match index {
            reg::STATUS => {
                if self.data_ready && self.polls_left == 0 {
                    STATUS_DATA_READY
                } else {
                    self.polls_left = self.polls_left.saturating_sub(1);
                    0
                }
            }
            reg::FRAME_COUNT => self.frame_count,
            _ if index >= reg::FRAME => {
                let offset = i - usize::from(reg::FRAME);
                let zone = offset / RECORD_BYTES;
                match (self.distance_mm.get(zone), self.status.get(zone)) {
                    (Some(&d), Some(&s)) => {
                        // Round to nearest; `as` saturates and maps NaN to 0.
                        let mm = (if d >= 0.0 { d + 0.5 } else { d - 0.5 }) as i16;
                        let [lo, hi] = mm.to_le_bytes();
                        [lo, hi, s].get(offset % RECORD_BYTES).copied().unwrap_or(0)
                    }
                    _ => 0,
                }
            }
            _ => 0,
        }
    }

    fn write_byte(&mut self, index: u16, value: u8) -> Result<(), embedded_hal::i2c::ErrorKind> {
        if index != reg::STATUS {
            return Err(embedded_hal::i2c::ErrorKind::NoAcknowledge(
                NoAcknowledgeSource::Data,
            ));
        }
        if value & STATUS_RELEASE != 0 && self.data_ready {
            self.data_ready = false;
            self.releases = self.releases.wrapping_add(1);
            if self.repeat {
                self.latch();
            }
        }
        Ok(())
    }
}

impl embedded_hal::i2c::ErrorType for ZoneBridgeDevice<'_> {
    type Error = embedded_hal::i2c::ErrorKind;
}

impl I2c for ZoneBridgeDevice<'_> {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        if address != self.address {
            return Err(embedded_hal::i2c::ErrorKind::NoAcknowledge(
                NoAcknowledgeSource::Address,
            ));
        }
        for op in operations {
            match op {
                Operation::Write(bytes) => {
                    let [hi, lo, data @ ..] = bytes else {
                        // An index is two bytes; a shorter write is refused.
                        return Err(embedded_hal::i2c::ErrorKind::NoAcknowledge(
                            NoAcknowledgeSource::Data,
                        ));
                    };
                    self.pointer = u16::from_be_bytes([*hi, *lo]);
                    for &b in data.iter() {
                        self.write_byte(self.pointer, b)?;
                        self.pointer = self.pointer.wrapping_add(1);
                    }
                }
                Operation::Read(buf) => {
                    for b in buf.iter_mut() {
                        *b = self.read_byte(self.pointer);
                        self.pointer = self.pointer.wrapping_add(1);
                    }
                }
            }
        }
        Ok(())
    }
}
