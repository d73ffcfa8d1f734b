//! Errors of the simulator: bad configurations (naming the offending field) and bad inputs.

/// Why a configuration or an input was rejected.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A configuration value is out of range; `field` is its JSON path, e.g. `dark.p_loss`.
    #[error("sim config: `{field}` {reason}")]
    InvalidConfig {
        /// JSON path of the field, e.g. `anomalies.noise_fraction`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The configuration JSON does not parse (unknown field, wrong type…); serde names the field.
    #[error("sim config JSON: {0}")]
    Json(String),
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
}

/// An [`SimError::InvalidConfig`] for `aspect.field`.
pub(crate) fn invalid(aspect: &str, field: &str, reason: impl Into<String>) -> SimError {
    SimError::InvalidConfig {
        field: format!("{aspect}.{field}"),
        reason: reason.into(),
    }
}

/// Checks that `v` is a probability in `[0, 1]`.
pub(crate) fn check_prob(aspect: &str, field: &str, v: f32) -> Result<(), SimError> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(invalid(
            aspect,
            field,
            format!("must be a probability in [0, 1], got {v}"),
        ))
    }
}

/// Checks that `v` is finite and strictly positive.
pub(crate) fn check_positive(aspect: &str, field: &str, v: f32) -> Result<(), SimError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            aspect,
            field,
            format!("must be finite and > 0, got {v}"),
        ))
    }
}

/// Checks that `[lo, hi]` is finite and ordered (`lo <= hi`).
pub(crate) fn check_ordered(aspect: &str, field: &str, r: [f32; 2]) -> Result<(), SimError> {
    if r[0].is_finite() && r[1].is_finite() && r[0] <= r[1] {
        Ok(())
    } else {
        Err(invalid(
            aspect,
            field,
            format!(
                "must be an ordered finite range [lo, hi], got [{}, {}]",
                r[0], r[1]
            ),
        ))
    }
}
