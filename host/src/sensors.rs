//! File-backed sensors: a recording replayed through the core's HAL traits, so the pipeline runs
//! on recorded data exactly as on a board.

use crate::recording::{Recording, RecordingError};
use depthor_core::calibration::DtofGeometry;
use depthor_core::hal::{self, DtofSensor, ErrorKind, ErrorType, RgbCamera, RgbFrame, ZoneFrame};
use std::fmt;

/// Error of a replayed sensor: a HAL [`ErrorKind`] plus the recording error behind it.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplayError {
    /// Generic category (`EndOfStream` after the last frame, `BufferShape`, `BadData`).
    pub kind: ErrorKind,
    /// The file problem, when the error came from the recording.
    pub source: Option<RecordingError>,
}

impl ReplayError {
    fn kind(kind: ErrorKind) -> Self {
        ReplayError { kind, source: None }
    }
}

impl From<RecordingError> for ReplayError {
    fn from(e: RecordingError) -> Self {
        ReplayError {
            kind: ErrorKind::BadData,
            source: Some(e),
        }
    }
}

impl fmt::Display for ReplayError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.source {
            Some(e) => write!(f, "{}: {e}", self.kind),
            None => write!(f, "{}", self.kind),
        }
    }
}

impl std::error::Error for ReplayError {}

impl hal::Error for ReplayError {
    fn kind(&self) -> ErrorKind {
        self.kind
    }
}

/// Replays a recording's `dtof.json` files in frame order.
#[derive(Clone, Debug)]
pub struct ReplayDtof {
    rec: Recording,
    geometry: DtofGeometry,
    next: usize,
}

impl ReplayDtof {
    /// A sensor over `rec`; fails when the recording has no dToF.
    pub fn new(rec: Recording) -> Result<Self, RecordingError> {
        let geometry = match &rec.meta().dtof {
            Some(d) => d.into(),
            None => {
                return Err(RecordingError::new(
                    rec.dir().join(crate::recording::files::RECORDING_JSON),
                    "dtof",
                    "the recording has no dToF sensor to replay",
                ))
            }
        };
        Ok(ReplayDtof {
            rec,
            geometry,
            next: 0,
        })
    }

    /// Index of the frame the next read returns.
    pub fn position(&self) -> usize {
        self.next
    }

    /// The replayed recording.
    pub fn recording(&self) -> &Recording {
        &self.rec
    }
}

impl ErrorType for ReplayDtof {
    type Error = ReplayError;
}

impl DtofSensor for ReplayDtof {
    fn geometry(&self) -> DtofGeometry {
        self.geometry
    }

    /// Fills `frame` from the next `dtof.json`. A capacity below `rows * cols` is `BufferShape`
    /// and does not advance; a bad file is `BadData` and skips that frame.
    fn read_frame<const N: usize>(&mut self, frame: &mut ZoneFrame<N>) -> Result<(), ReplayError> {
        if self.next >= self.rec.len() {
            return Err(ReplayError::kind(ErrorKind::EndOfStream));
        }
        frame
            .set_shape(self.geometry.rows, self.geometry.cols)
            .map_err(ReplayError::kind)?;
        let i = self.next;
        self.next += 1;
        let z = self
            .rec
            .read_dtof(i)?
            .ok_or(ReplayError::kind(ErrorKind::BadData))?;
        let n = frame.len();
        frame.distance_mm[..n].copy_from_slice(&z.distance_mm);
        frame.status[..n].copy_from_slice(&z.status);
        let fill = |dst: &mut [f32; N], src: &Option<Vec<f32>>| {
            match src {
                Some(s) => dst[..n].copy_from_slice(s),
                None => dst[..n].fill(0.0),
            }
            src.is_some()
        };
        frame.has_sigma = fill(&mut frame.sigma_mm, &z.sigma_mm);
        frame.has_signal = fill(&mut frame.signal_kcps, &z.signal_kcps);
        frame.has_ambient = fill(&mut frame.ambient_kcps, &z.ambient_kcps);
        Ok(())
    }
}

/// Replays a recording's `rgb.png` files in frame order.
#[derive(Clone, Debug)]
pub struct ReplayCamera {
    rec: Recording,
    next: usize,
}

impl ReplayCamera {
    /// A camera over `rec`.
    pub fn new(rec: Recording) -> Self {
        ReplayCamera { rec, next: 0 }
    }

    /// Index of the frame the next capture returns.
    pub fn position(&self) -> usize {
        self.next
    }

    /// The replayed recording.
    pub fn recording(&self) -> &Recording {
        &self.rec
    }
}

impl ErrorType for ReplayCamera {
    type Error = ReplayError;
}

impl RgbCamera for ReplayCamera {
    /// Size of the next frame (frames may override the camera); the recording's after the end.
    fn resolution(&self) -> (u32, u32) {
        let cam = if self.next < self.rec.len() {
            self.rec.camera(self.next)
        } else {
            self.rec.meta().camera
        };
        (cam.width, cam.height)
    }

    /// Copies the next `rgb.png` into `frame`. A frame of another size is `BufferShape` and does
    /// not advance; a bad file is `BadData` and skips that frame.
    fn capture(&mut self, frame: &mut RgbFrame<'_>) -> Result<(), ReplayError> {
        if self.next >= self.rec.len() {
            return Err(ReplayError::kind(ErrorKind::EndOfStream));
        }
        let (w, h) = self.resolution();
        if (frame.width, frame.height) != (w, h) || frame.data.len() != w as usize * h as usize * 3
        {
            return Err(ReplayError::kind(ErrorKind::BufferShape));
        }
        let i = self.next;
        self.next += 1;
        let rgb = self.rec.read_rgb(i)?;
        frame.data.copy_from_slice(rgb.as_raw());
        Ok(())
    }
}
