//! Sensor hardware abstraction: the traits a board's dToF and RGB camera drivers implement, in the
//! style of embedded-hal 1.0 (an `ErrorType` with an associated error whose `kind()` maps onto a
//! small, `#[non_exhaustive]` [`ErrorKind`]). Every frame buffer is provided by the caller.
//!
//! # Writing a driver
//!
//! A driver owns its embedded-hal bus and delay (embassy style), keeps its precise error and maps
//! it onto [`ErrorKind`]. A complete example is [`crate::drivers::zone_bridge`]; the skeleton for
//! a made-up one-zone ranger (register `0x00` = ready flag, `0x01..=0x02` = distance, `u16` LE mm):
//!
//! ```
//! use depthor_core::calibration::{DistanceKind, DtofGeometry};
//! use depthor_core::hal::{self, DtofSensor, ErrorKind, ZoneFrame};
//! use embedded_hal::{delay::DelayNs, i2c::I2c};
//!
//! #[derive(Debug)]
//! enum RangerError<E> { Bus(E), Timeout, Shape }
//! impl<E: embedded_hal::i2c::Error> hal::Error for RangerError<E> {
//!     fn kind(&self) -> ErrorKind {
//!         match self {
//!             RangerError::Bus(_) => ErrorKind::Bus,
//!             RangerError::Timeout => ErrorKind::Timeout,
//!             RangerError::Shape => ErrorKind::BufferShape,
//!         }
//!     }
//! }
//!
//! struct Ranger<I, D> { i2c: I, delay: D }
//! impl<I: I2c, D: DelayNs> hal::ErrorType for Ranger<I, D> { type Error = RangerError<I::Error>; }
//! impl<I: I2c, D: DelayNs> DtofSensor for Ranger<I, D> {
//!     fn geometry(&self) -> DtofGeometry {
//!         DtofGeometry { rows: 1, cols: 1, fov_deg: [27.0, 27.0], distance: DistanceKind::Z,
//!                        max_range_m: 4.0 }
//!     }
//!     fn read_frame<const N: usize>(&mut self, frame: &mut ZoneFrame<N>) -> Result<(), Self::Error> {
//!         frame.set_shape(1, 1).map_err(|_| RangerError::Shape)?;
//!         let mut ready = [0u8];
//!         for _ in 0..100 {            // poll up to 100 ms
//!             self.i2c.write_read(0x52, &[0x00], &mut ready).map_err(RangerError::Bus)?;
//!             if ready[0] & 1 != 0 { break; }
//!             self.delay.delay_ms(1);
//!         }
//!         if ready[0] & 1 == 0 { return Err(RangerError::Timeout); }
//!         let mut mm = [0u8; 2];
//!         self.i2c.write_read(0x52, &[0x01], &mut mm).map_err(RangerError::Bus)?;
//!         frame.distance_mm[0] = f32::from(u16::from_le_bytes(mm));  // N >= 1 after set_shape
//!         frame.status[0] = hal::STATUS_VALID;
//!         Ok(())
//!     }
//! }
//! ```

/// Generic sensor error categories, so pipeline code can react without knowing the driver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The bus (I2C, SPI, DCMI…) failed.
    Bus,
    /// The sensor did not produce a frame in time.
    Timeout,
    /// The caller's buffer does not match the sensor's frame shape.
    BufferShape,
    /// The sensor returned data that cannot be decoded.
    BadData,
    /// No more frames (replayed recordings).
    EndOfStream,
    /// Anything else.
    Other,
}

impl core::fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ErrorKind::Bus => "bus error",
            ErrorKind::Timeout => "timeout",
            ErrorKind::BufferShape => "buffer shape mismatch",
            ErrorKind::BadData => "undecodable sensor data",
            ErrorKind::EndOfStream => "end of stream",
            ErrorKind::Other => "sensor error",
        })
    }
}

/// A sensor error: drivers keep their precise error and expose its [`ErrorKind`].
pub trait Error: core::fmt::Debug {
    /// The generic category of this error.
    fn kind(&self) -> ErrorKind;
}

impl Error for ErrorKind {
    fn kind(&self) -> ErrorKind {
        *self
    }
}

/// Associates an error type with a sensor driver.
pub trait ErrorType {
    /// The driver's error type.
    type Error: Error;
}

/// ST `target_status` value for a valid range (docs/recording.md: 5 and 9 are valid, 255 is no target).
pub const STATUS_VALID: u8 = 5;
/// ST `target_status` value for a valid range with a larger sigma (still used).
pub const STATUS_VALID_LARGE_SIGMA: u8 = 9;
/// ST `target_status` value for "no target detected".
pub const STATUS_NO_TARGET: u8 = 255;

/// Returns true when an ST `target_status` code marks a usable range (5 or 9).
pub fn status_is_valid(status: u8) -> bool {
    status == STATUS_VALID || status == STATUS_VALID_LARGE_SIGMA
}

/// One dToF frame in caller-provided storage for up to `N` zones (row-major, row 0 at the top).
///
/// `N` is the capacity: `ZoneFrame<64>` holds an 8×8 VL53L5CX frame, `ZoneFrame<1200>` a 40×30
/// phone frame. Only the first `rows * cols` entries are meaningful. The optional channels are
/// meaningful only when their `has_*` flag is set. Size: `N * 17 + 8` bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct ZoneFrame<const N: usize> {
    /// Zone rows of the frame.
    pub rows: u16,
    /// Zone columns of the frame.
    pub cols: u16,
    /// Distance per zone in millimetres.
    pub distance_mm: [f32; N],
    /// ST `target_status` per zone.
    pub status: [u8; N],
    /// Range sigma per zone in millimetres (valid when `has_sigma`).
    pub sigma_mm: [f32; N],
    /// Signal rate per zone in kcps (valid when `has_signal`).
    pub signal_kcps: [f32; N],
    /// Ambient rate per zone in kcps (valid when `has_ambient`).
    pub ambient_kcps: [f32; N],
    /// Whether `sigma_mm` was filled.
    pub has_sigma: bool,
    /// Whether `signal_kcps` was filled.
    pub has_signal: bool,
    /// Whether `ambient_kcps` was filled.
    pub has_ambient: bool,
}

impl<const N: usize> ZoneFrame<N> {
    /// An empty frame (0×0 zones, everything zero).
    pub const fn new() -> Self {
        ZoneFrame {
            rows: 0,
            cols: 0,
            distance_mm: [0.0; N],
            status: [STATUS_NO_TARGET; N],
            sigma_mm: [0.0; N],
            signal_kcps: [0.0; N],
            ambient_kcps: [0.0; N],
            has_sigma: false,
            has_signal: false,
            has_ambient: false,
        }
    }

    /// Number of zones in use, clamped to the capacity `N`.
    pub fn len(&self) -> usize {
        (self.rows as usize * self.cols as usize).min(N)
    }

    /// True when the frame holds no zones.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sets the shape; fails with [`ErrorKind::BufferShape`] when `rows * cols > N`.
    pub fn set_shape(&mut self, rows: u16, cols: u16) -> Result<(), ErrorKind> {
        if rows as usize * cols as usize > N {
            return Err(ErrorKind::BufferShape);
        }
        self.rows = rows;
        self.cols = cols;
        Ok(())
    }

    /// Borrowed view of the zones in use (distances and statuses).
    pub fn view(&self) -> ZoneView<'_> {
        let n = self.len();
        ZoneView {
            rows: self.rows,
            cols: self.cols,
            distance_mm: &self.distance_mm[..n],
            status: &self.status[..n],
        }
    }
}

impl<const N: usize> Default for ZoneFrame<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// Borrowed zone distances and statuses, row-major; what projection consumes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZoneView<'a> {
    /// Zone rows.
    pub rows: u16,
    /// Zone columns.
    pub cols: u16,
    /// Distance per zone in millimetres.
    pub distance_mm: &'a [f32],
    /// ST `target_status` per zone.
    pub status: &'a [u8],
}

/// A direct time-of-flight multizone ranging sensor.
///
/// Implementations must fill `frame` completely (shape, distances, statuses; the optional channels
/// when they have them, setting the `has_*` flags) or return an error; they must not panic on
/// anything the device sends. A capacity too small for the sensor is [`ErrorKind::BufferShape`].
pub trait DtofSensor: ErrorType {
    /// Zone grid of this sensor (rows, cols, FoV, distance kind, range).
    fn geometry(&self) -> crate::calibration::DtofGeometry;

    /// Blocks until the next frame is ready and writes it into `frame`.
    fn read_frame<const N: usize>(&mut self, frame: &mut ZoneFrame<N>) -> Result<(), Self::Error>;
}

/// A caller-provided 8-bit RGB frame buffer (interleaved `R, G, B`, row-major, no padding).
#[derive(Debug)]
pub struct RgbFrame<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 3` bytes.
    pub data: &'a mut [u8],
}

/// An RGB camera.
///
/// Implementations must fill `frame.data` with exactly `width * height * 3` bytes at the
/// frame's size or return [`ErrorKind::BufferShape`] when the size does not match theirs.
pub trait RgbCamera: ErrorType {
    /// Width and height the camera delivers.
    fn resolution(&self) -> (u32, u32);

    /// Captures the next frame into `frame`.
    fn capture(&mut self, frame: &mut RgbFrame<'_>) -> Result<(), Self::Error>;
}
