//! How `mul`'s second operand broadcasts over the first (CBAM's attention maps), shared by the
//! int8 kernel ([`super::elementwise::mul`]), the float reference and the planner. A leaf
//! module.

use super::Shape;

/// How the second operand of `mul` broadcasts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Broadcast {
    /// Same shape as the first operand.
    None,
    /// `[1, H, W]`: one map applied to every channel (CBAM spatial attention).
    OverChannels,
    /// `[C, 1, 1]`: one value per channel (CBAM channel attention).
    OverSpace,
}

/// Index into the second operand for element `i` of a `shape` tensor.
#[inline]
pub fn broadcast_index(b: Broadcast, shape: Shape, i: usize) -> usize {
    let plane = shape.h * shape.w;
    match b {
        Broadcast::None => i,
        Broadcast::OverChannels => i % plane,
        Broadcast::OverSpace => i / plane,
    }
}

/// Length the second operand must have.
pub fn broadcast_len(b: Broadcast, shape: Shape) -> Option<usize> {
    match b {
        Broadcast::None => shape.len(),
        Broadcast::OverChannels => shape.plane(),
        Broadcast::OverSpace => Some(shape.c),
    }
}
