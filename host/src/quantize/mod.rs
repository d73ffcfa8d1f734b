//! The int8 quantizer: graph.json + weights.bin (the Python export) → the core's model blob.
//!
//! 1. [`graph`] reads the export; [`fold`] folds batch norm into the convs and maps the graph
//!    onto the blob's ops ([`net::Net`]), which [`net::Net::run_f32`] executes with the core's
//!    f32 reference kernels.
//! 2. [`calibrate`] renders simulated frames (scene generator → dToF simulator → projection),
//!    records every value's min/max (and, for MSE clipping, a histogram) over them and chooses
//!    int8 asymmetric per-tensor parameters.
//! 3. [`blob_writer`] quantises weights (symmetric int8 per output channel, int32 bias), bakes
//!    the LUTs and writes blob format v1 through [`blob_format`] (the format's one writer); values
//!    chosen with [`widen`] are stored as int16 (16×8); the
//!    engine derives its Q31 multipliers from the stored f32 scales when it prepares the blob.
//! 4. [`check`] compares the engine on the blob with the float network, per frame and per op.
//!
//! ```no_run
//! use depthor_host::quantize::{graph::Graph, fold::fold, calibrate::simulated_frames, quantize};
//! let g = Graph::load("models/mcu/graph.json".as_ref(), None).unwrap();
//! let net = fold(&g).unwrap();
//! let frames = simulated_frames("mcu", net.height, net.width, 16, 0).unwrap();
//! let q = quantize(&net, &frames).unwrap();
//! std::fs::write("models/mcu/depthor.dblob", &q.blob).unwrap();
//! ```

pub mod blob_format;
#[cfg(test)]
mod blob_format_tests;
pub mod blob_writer;
pub mod calibrate;
pub mod check;
pub mod fold;
pub mod golden;
pub mod graph;
pub mod net;
pub mod upsample_scale;
pub mod widen;

use calibrate::{
    choose_qparams, override_ranges, Frame, Histograms, RangeFileError, RangeRule, Ranges,
};
use depthor_core::kernels::requant::QParams;
use net::{Net, RunError};

/// A quantised model.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantized {
    /// Blob bytes (format v1).
    pub blob: Vec<u8>,
    /// Parameters of every value.
    pub qparams: Vec<QParams>,
    /// Calibrated ranges of every value.
    pub ranges: Ranges,
}

/// Why quantisation failed.
#[derive(Debug, thiserror::Error)]
pub enum QuantizeError {
    /// The float run on a calibration frame failed.
    #[error("calibration run: {0}")]
    Run(#[from] RunError),
    /// The network does not fit the blob format.
    #[error("blob: {0}")]
    Blob(#[from] blob_writer::BlobError),
    /// No calibration frames were given.
    #[error("no calibration frames")]
    NoFrames,
    /// A given range names no value or is not a range.
    #[error("ranges file: {0}")]
    Ranges(#[from] RangeFileError),
}

/// Min/max of every value of `net` over `frames` (float runs).
pub fn calibrate_ranges(net: &Net, frames: &[Frame]) -> Result<Ranges, RunError> {
    let mut r = Ranges::new(net.values.len());
    for f in frames {
        r.observe(&net.run_f32(&f.rgb_planar(), &f.sparse_m)?);
    }
    Ok(r)
}

/// The range of every value of `net` over `frames` under `rule`: min/max, or MSE-clipped from
/// a histogram filled by a second pass over the frames (int16 values keep min/max).
pub fn calibrate_ranges_with(
    net: &Net,
    frames: &[Frame],
    rule: RangeRule,
) -> Result<Ranges, RunError> {
    let full = calibrate_ranges(net, frames)?;
    if rule == RangeRule::MinMax {
        return Ok(full);
    }
    let mut h = Histograms::new(&full);
    for f in frames {
        h.observe(&net.run_f32(&f.rgb_planar(), &f.sparse_m)?);
    }
    let mut clipped = h.mse_ranges();
    // int16 values keep min/max: their rounding is too fine for clipping to pay.
    for (v, value) in net.values.iter().enumerate() {
        if value.storage == net::Storage::I16 {
            clipped.min[v] = full.min[v];
            clipped.max[v] = full.max[v];
        }
    }
    Ok(clipped)
}

/// Calibrates `net` on `frames` with the default [`RangeRule`] and writes its blob.
pub fn quantize(net: &Net, frames: &[Frame]) -> Result<Quantized, QuantizeError> {
    quantize_with(net, frames, RangeRule::default())
}

/// Calibrates `net` on `frames` with `rule` and writes its blob.
pub fn quantize_with(
    net: &Net,
    frames: &[Frame],
    rule: RangeRule,
) -> Result<Quantized, QuantizeError> {
    quantize_with_ranges(net, frames, rule, &[])
}

/// As [`quantize_with`], then the ranges of the values named in `given` (name → `[lo, hi]`)
/// replaced before the parameters are chosen (e.g. those a quantisation-aware run trained with).
pub fn quantize_with_ranges(
    net: &Net,
    frames: &[Frame],
    rule: RangeRule,
    given: &[(String, [f32; 2])],
) -> Result<Quantized, QuantizeError> {
    if frames.is_empty() {
        return Err(QuantizeError::NoFrames);
    }
    let mut ranges = calibrate_ranges_with(net, frames, rule)?;
    override_ranges(net, &mut ranges, given)?;
    let qparams = choose_qparams(net, &ranges);
    let blob = blob_writer::write_blob(net, &qparams)?;
    Ok(Quantized {
        blob,
        qparams,
        ranges,
    })
}
