//! The scalar f32 functions every path shares (the float reference in [`super::float`], the
//! bins head, the refinement): deterministic IEEE operations only, so host and Cortex-M give
//! the same bits. A leaf module: it imports no kernel.

/// `e^x` to about 2 ULP from deterministic IEEE f32 operations (called explicitly so a host
/// build with `std` linked never picks the platform `expf`, whose bits differ between libms).
#[inline]
pub fn exp(x: f32) -> f32 {
    crate::fmath::exp_f32(x)
}

/// A softmax's weight `e^x` for `x = l − max ≤ 0`: a 32-entry table of `2^(j/32)` and a
/// cubic, within `3·10⁻⁷ + |x|·1.2·10⁻⁷` relative of `e^x`, 0 below −80 (`fmath::softmax_exp`).
#[inline(always)]
pub fn softmax_exp(x: f32) -> f32 {
    crate::fmath::softmax_exp(x)
}

/// `max(x, 0)`.
pub fn relu(x: f32) -> f32 {
    if x > 0.0 {
        x
    } else {
        0.0
    }
}

/// `x` for `x ≥ 0`, `alpha·x` otherwise.
pub fn leaky_relu(x: f32, alpha: f32) -> f32 {
    if x >= 0.0 {
        x
    } else {
        alpha * x
    }
}

/// `1/(1 + e^−x)`, saturating cleanly for large |x|.
pub fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        1.0 / (1.0 + exp(-x))
    } else {
        let e = exp(x);
        e / (1.0 + e)
    }
}

/// `1/(x + eps)`.
pub fn reciprocal(x: f32, eps: f32) -> f32 {
    1.0 / (x + eps)
}
