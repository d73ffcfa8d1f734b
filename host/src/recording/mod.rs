//! Recordings in the `depthor-recording/1` format (docs/recording.md): the file-backed input of every
//! host tool and the output of the simulator and the importers.
//!
//! ```text
//! <dir>/recording.json
//! <dir>/frames/<id>/rgb.png      8-bit RGB, camera width × height
//! <dir>/frames/<id>/dtof.json    zone measurements (when the recording has a dToF)
//! <dir>/frames/<id>/depth.png    optional 16-bit millimetres, 0 = unknown
//! <dir>/frames/<id>/labels.png   optional 8-bit material classes 0..=3
//! ```
//! [`Recording::open`] validates the header and that every frame directory exists;
//! [`Recording::read_frame`] validates one frame. [`RecordingWriter`] writes atomically;
//! [`merge_shards`] joins the shards of a sharded run.

mod error;
mod json;
mod merge;
mod meta;
mod reader;
mod summary;
mod writer;

pub use error::{Invalid, RecordingError};
pub use merge::{merge_shards, Shard, ShardError};
pub use meta::{
    frame_id_is_valid, CalibrationData, CameraMeta, DistanceMeta, DtofFrame, DtofMeta,
    ExtrinsicsMeta, FrameMeta, RecordingMeta, FORMAT, MAX_LABEL, MAX_ST_STATUS,
};
pub use reader::{Frame, Recording};
pub use summary::{DepthSummary, FrameSummary};
pub use writer::{depth_m_to_mm, RecordingWriter, WriteOptions};

/// File names inside a frame directory.
pub mod files {
    /// The header.
    pub const RECORDING_JSON: &str = "recording.json";
    /// Directory holding one sub-directory per frame.
    pub const FRAMES: &str = "frames";
    /// 8-bit RGB image.
    pub const RGB: &str = "rgb.png";
    /// Zone measurements.
    pub const DTOF: &str = "dtof.json";
    /// 16-bit reference depth in millimetres.
    pub const DEPTH: &str = "depth.png";
    /// 8-bit material classes.
    pub const LABELS: &str = "labels.png";
}
