//! Errors of the simulator: bad configurations (naming the offending field) and bad inputs.

/// Why a configuration or an input was rejected.
///
/// Configuration errors display as one line `field: what is wrong (allowed …)`; the command
/// line puts the file in front (`cfg.json: grid.rows: 65535 is out of range (allowed 1 to 128
/// zones)`).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A configuration value is out of range; `field` is its JSON path, e.g. `dark.p_loss`.
    #[error("{field}: {reason}")]
    InvalidConfig {
        /// JSON path of the field, e.g. `anomalies.noise_fraction`.
        field: String,
        /// What is wrong with it, with the allowed range.
        reason: String,
    },
    /// The configuration JSON does not parse or has a field of the wrong type or name; `field`
    /// is its JSON path where one could be found, else `JSON`.
    #[error("{field}: {message}")]
    Json {
        /// JSON path of the offending field (`grid.rows`, `dark.p_losss`), or `JSON`.
        field: String,
        /// serde's message, one line.
        message: String,
    },
    /// `preset` was given a name it does not know.
    #[error("unknown sim preset `{0}` (expected `l5`, `phone` or `mcu`)")]
    UnknownPreset(String),
    /// An input array does not match `width × height` (× 3 for RGB).
    #[error("sim input: `{field}` has {got} values, expected {expected}")]
    InputSize {
        /// Name of the [`super::SimInput`] field.
        field: &'static str,
        /// Expected number of values.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
    /// The input image has zero width or height.
    #[error("sim input: empty image ({width}×{height})")]
    EmptyImage {
        /// Given width.
        width: u32,
        /// Given height.
        height: u32,
    },
    /// A run would need more memory than the limit allows (see [`super::MemoryEstimate`]).
    #[error(
        "{field}: the run needs about {need_mib} MiB (allowed at most {limit_mib} MiB; {what})"
    )]
    TooMuchMemory {
        /// The setting that drives the estimate (`grid.ifov`, `--width/--height`).
        field: String,
        /// Estimated peak bytes, in MiB.
        need_mib: u64,
        /// The limit, in MiB.
        limit_mib: u64,
        /// What the estimate is made of.
        what: String,
    },
}

/// An [`SimError::InvalidConfig`] for `aspect.field`.
pub(crate) fn invalid(aspect: &str, field: &str, reason: impl Into<String>) -> SimError {
    SimError::InvalidConfig {
        field: format!("{aspect}.{field}"),
        reason: reason.into(),
    }
}

/// Checks `lo ≤ v ≤ hi` (NaN and infinities fail); the message names the allowed range and
/// `unit` (empty, or e.g. ` m`).
pub(crate) fn check_in(
    aspect: &str,
    field: &str,
    v: f32,
    [lo, hi]: [f32; 2],
    unit: &str,
) -> Result<(), SimError> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(invalid(
            aspect,
            field,
            format!("{v} is out of range (allowed {lo} to {hi}{unit})"),
        ))
    }
}

/// Checks `lo < v ≤ hi` (a strictly positive quantity has `lo = 0`).
pub(crate) fn check_above(
    aspect: &str,
    field: &str,
    v: f32,
    [lo, hi]: [f32; 2],
    unit: &str,
) -> Result<(), SimError> {
    if v.is_finite() && v > lo && v <= hi {
        Ok(())
    } else {
        Err(invalid(
            aspect,
            field,
            format!("{v} is out of range (allowed above {lo} up to {hi}{unit})"),
        ))
    }
}

/// Checks that `v` is a probability in `[0, 1]`.
pub(crate) fn check_prob(aspect: &str, field: &str, v: f32) -> Result<(), SimError> {
    check_in(aspect, field, v, [0.0, 1.0], "")
}

/// Checks that `[lo, hi]` is ordered (`lo ≤ hi`) with both ends in `bounds`.
pub(crate) fn check_ordered(
    aspect: &str,
    field: &str,
    r: [f32; 2],
    bounds: [f32; 2],
    unit: &str,
) -> Result<(), SimError> {
    let ok = |v: f32| v.is_finite() && (bounds[0]..=bounds[1]).contains(&v);
    if ok(r[0]) && ok(r[1]) && r[0] <= r[1] {
        Ok(())
    } else {
        Err(invalid(
            aspect,
            field,
            format!(
                "[{}, {}] is not an ordered range (allowed {} ≤ lo ≤ hi ≤ {}{unit})",
                r[0], r[1], bounds[0], bounds[1]
            ),
        ))
    }
}
