//! The gap tool's input: "real" frames (reference depth, RGB, labels and the zones the sensor
//! reported), read from a recording with clear errors for what the tool cannot use.

use std::path::Path;

use crate::recording::Recording;
use crate::sim::SimInput;
use depthor_core::hal::status_is_valid;

/// Why a recording cannot be compared with the simulator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GapError {
    /// The recording could not be read.
    #[error(transparent)]
    Recording(#[from] crate::recording::RecordingError),
    /// The recording has no frames.
    #[error("recording {0} has no frames: nothing to compare")]
    Empty(String),
    /// The recording has no dToF zones.
    #[error(
        "recording {0} has no dToF (no \"dtof\" in recording.json): the gap tool compares zones"
    )]
    NoDtof(String),
    /// A frame has no reference depth to simulate from.
    #[error("frame {frame} of {recording} has no reference depth (depth.png): the simulator needs it to predict the zones")]
    NoDepth {
        /// Recording directory.
        recording: String,
        /// Frame id.
        frame: String,
    },
    /// The simulator's zone grid does not match the recording's.
    #[error("zone grid mismatch: the recording has {real:?} (rows, cols) zones, the sim config {sim:?}; pass a --sim-config with the recording's grid")]
    GridMismatch {
        /// Recording's rows and cols.
        real: (u16, u16),
        /// Simulator's rows and cols.
        sim: (u16, u16),
    },
    /// Frames differ in image size.
    #[error(
        "frame {frame} is {got:?} (w, h), the first frame {first:?}: one recording per image size"
    )]
    SizeMismatch {
        /// Frame id.
        frame: String,
        /// Its size.
        got: (u32, u32),
        /// The first frame's size.
        first: (u32, u32),
    },
    /// Too few frames to split into a training and a held-out half.
    #[error("{0} frames are too few: the gap tool fits on half the frames and tests on the other half (need ≥ 4)")]
    TooFewFrames(usize),
    /// The simulator rejected its configuration or input.
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
    /// A name that is not an effect of the library.
    #[error(transparent)]
    UnknownEffect(#[from] crate::sim::effects::UnknownEffect),
}

/// One frame to compare: the simulator's input and the zones the real sensor reported.
#[derive(Clone, Debug)]
pub struct GapFrame {
    /// Frame id.
    pub id: String,
    /// Capture time, seconds.
    pub t_s: f64,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Reference planar depth, metres, 0 = unknown.
    pub depth_m: Vec<f32>,
    /// Interleaved 8-bit RGB.
    pub rgb: Vec<u8>,
    /// Material labels, if the recording has them.
    pub labels: Option<Vec<u8>>,
    /// Whether each zone reported a target (row-major).
    pub real_valid: Vec<bool>,
    /// Reported distance per zone, metres (meaningful where valid).
    pub real_m: Vec<f32>,
}

impl GapFrame {
    /// The simulator input of this frame.
    pub fn sim_input(&self) -> SimInput<'_> {
        SimInput::observed(
            self.width,
            self.height,
            &self.depth_m,
            &self.rgb,
            self.labels.as_deref(),
        )
    }
}

/// Frames of one real recording plus what the tool needs of its header.
#[derive(Clone, Debug)]
pub struct GapData {
    /// Frames in time order.
    pub frames: Vec<GapFrame>,
    /// Zone rows and columns.
    pub grid: (u16, u16),
    /// Largest distance the sensor reports, metres (support of the outlier density).
    pub max_range_m: f32,
}

/// Reads every frame of the recording at `dir` (calling `progress` after each).
pub fn load_recording(dir: &Path, mut progress: impl FnMut()) -> Result<GapData, GapError> {
    let name = dir.display().to_string();
    let rec = Recording::open(dir)?;
    if rec.is_empty() {
        return Err(GapError::Empty(name));
    }
    let Some(dtof) = rec.meta().dtof.clone() else {
        return Err(GapError::NoDtof(name));
    };
    let mut frames = Vec::with_capacity(rec.len());
    for i in 0..rec.len() {
        let f = rec.read_frame(i)?;
        let Some(depth_m) = f.depth_m else {
            return Err(GapError::NoDepth {
                recording: name,
                frame: f.id,
            });
        };
        let z = f.dtof.unwrap_or_default();
        let (width, height) = f.rgb.dimensions();
        if let Some(first) = frames.first().map(|g: &GapFrame| (g.width, g.height)) {
            if first != (width, height) {
                return Err(GapError::SizeMismatch {
                    frame: f.id,
                    got: (width, height),
                    first,
                });
            }
        }
        frames.push(GapFrame {
            id: f.id,
            t_s: rec.meta().frames[i].t_s,
            width,
            height,
            depth_m,
            rgb: f.rgb.into_raw(),
            labels: f.labels,
            real_valid: z.status.iter().map(|&s| status_is_valid(s)).collect(),
            real_m: z.distance_mm.iter().map(|&d| d / 1000.0).collect(),
        });
        progress();
    }
    Ok(GapData {
        frames,
        grid: (dtof.rows, dtof.cols),
        max_range_m: dtof.max_range_m,
    })
}
