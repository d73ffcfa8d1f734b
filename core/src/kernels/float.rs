//! f32 reference of every graph op (docs/graph.md semantics), for calibration by the host quantizer
//! and as ground truth in tests. Plain loops, CHW layout, `no_std`; the one transcendental
//! function, [`exp`], is the crate's own (about 2 ULP, plain IEEE operations), so results are the
//! same on the host and on a Cortex-M4F.

use super::bins::{self, BinsAttrs};
use super::conv::{Activation, ConvGeometry};
use super::refine::{self, F32Map, RefineAttrs};
use super::{need, KernelError, Shape};

pub use super::scalar::{exp, leaky_relu, reciprocal, relu, sigmoid};

/// Applies an activation.
pub fn activate(x: f32, act: Activation) -> f32 {
    match act {
        Activation::None => x,
        Activation::Relu => relu(x),
        Activation::LeakyRelu(a) => leaky_relu(x, a),
    }
}

/// Conv2d, weights `[O, I/groups, kh, kw]`, optional bias, fused activation.
#[allow(clippy::too_many_arguments)]
pub fn conv2d(
    g: &ConvGeometry,
    input: &[f32],
    in_shape: Shape,
    weights: &[f32],
    bias: Option<&[f32]>,
    act: Activation,
    output: &mut [f32],
    out_shape: Shape,
) -> Result<(), KernelError> {
    let out = g
        .output_shape(in_shape, out_shape.c)
        .ok_or(KernelError::Attr)?;
    if out != out_shape || Some(weights.len()) != g.weight_len(in_shape.c, out.c) {
        return Err(KernelError::Shape);
    }
    if bias.is_some_and(|b| b.len() < out.c) {
        return Err(KernelError::Shape);
    }
    need(input, in_shape)?;
    need(output, out)?;
    let icg = in_shape.c / g.groups;
    let ocg = out.c / g.groups;
    for o in 0..out.c {
        for oy in 0..out.h {
            for ox in 0..out.w {
                let mut acc = bias.map_or(0.0, |b| b[o]);
                for i in 0..icg {
                    let ic = (o / ocg) * icg + i;
                    for ky in 0..g.kernel[0] {
                        for kx in 0..g.kernel[1] {
                            let iy = (oy * g.stride[0] + ky * g.dilation[0]) as isize
                                - g.padding[0] as isize;
                            let ix = (ox * g.stride[1] + kx * g.dilation[1]) as isize
                                - g.padding[1] as isize;
                            if iy < 0
                                || ix < 0
                                || iy >= in_shape.h as isize
                                || ix >= in_shape.w as isize
                            {
                                continue;
                            }
                            let x =
                                input[(ic * in_shape.h + iy as usize) * in_shape.w + ix as usize];
                            acc +=
                                weights[((o * icg + i) * g.kernel[0] + ky) * g.kernel[1] + kx] * x;
                        }
                    }
                }
                output[(o * out.h + oy) * out.w + ox] = activate(acc, act);
            }
        }
    }
    Ok(())
}

/// `linear`: weights `[O, I]`, input `[I,1,1]` → `[O,1,1]`.
pub fn linear(
    input: &[f32],
    weights: &[f32],
    bias: Option<&[f32]>,
    act: Activation,
    output: &mut [f32],
) -> Result<(), KernelError> {
    let o = output.len();
    let i = input.len();
    conv2d(
        &ConvGeometry::POINTWISE,
        input,
        Shape::new(i, 1, 1),
        weights,
        bias,
        act,
        output,
        Shape::new(o, 1, 1),
    )
}

pub use super::broadcast::{broadcast_index, broadcast_len, Broadcast};

/// Elementwise `a + b` (same shape).
pub fn add(a: &[f32], b: &[f32], out: &mut [f32]) -> Result<(), KernelError> {
    if a.len() != b.len() || out.len() < a.len() {
        return Err(KernelError::Shape);
    }
    for ((o, &x), &y) in out.iter_mut().zip(a).zip(b) {
        *o = x + y;
    }
    Ok(())
}

/// `a · b` with `b` broadcast per [`Broadcast`].
pub fn mul(
    a: &[f32],
    shape: Shape,
    b: &[f32],
    bc: Broadcast,
    out: &mut [f32],
) -> Result<(), KernelError> {
    let n = need(a, shape)?;
    if Some(b.len()) != broadcast_len(bc, shape) || out.len() < n {
        return Err(KernelError::Shape);
    }
    for i in 0..n {
        out[i] = a[i] * b[broadcast_index(bc, shape, i)];
    }
    Ok(())
}

/// Bilinear resize with `align_corners = true`, per channel.
pub fn upsample_bilinear(
    input: &[f32],
    in_shape: Shape,
    out: &mut [f32],
    out_shape: Shape,
) -> Result<(), KernelError> {
    super::resize::upsample_bilinear_f32(input, in_shape, out, out_shape)
}

/// PyTorch `pixel_shuffle`: `[C·r², H, W] → [C, H·r, W·r]`.
pub fn pixel_shuffle(
    input: &[f32],
    in_shape: Shape,
    r: usize,
    out: &mut [f32],
) -> Result<Shape, KernelError> {
    super::elementwise::pixel_shuffle(input, in_shape, r, out)
}

/// Global average pool `[C,H,W] → [C]`.
pub fn global_avg_pool(input: &[f32], shape: Shape, out: &mut [f32]) -> Result<(), KernelError> {
    need(input, shape)?;
    let p = shape.plane().ok_or(KernelError::Shape)?;
    if out.len() < shape.c || p == 0 {
        return Err(KernelError::Shape);
    }
    for c in 0..shape.c {
        out[c] = input[c * p..(c + 1) * p].iter().sum::<f32>() / p as f32;
    }
    Ok(())
}

/// Global max pool `[C,H,W] → [C]`.
pub fn global_max_pool(input: &[f32], shape: Shape, out: &mut [f32]) -> Result<(), KernelError> {
    need(input, shape)?;
    let p = shape.plane().ok_or(KernelError::Shape)?;
    if out.len() < shape.c || p == 0 {
        return Err(KernelError::Shape);
    }
    for c in 0..shape.c {
        out[c] = input[c * p..(c + 1) * p]
            .iter()
            .fold(f32::NEG_INFINITY, |m, &v| m.max(v));
    }
    Ok(())
}

/// Mean over channels `[C,H,W] → [1,H,W]`.
pub fn channel_mean(input: &[f32], shape: Shape, out: &mut [f32]) -> Result<(), KernelError> {
    need(input, shape)?;
    let p = shape.plane().ok_or(KernelError::Shape)?;
    if out.len() < p || shape.c == 0 {
        return Err(KernelError::Shape);
    }
    for i in 0..p {
        out[i] = (0..shape.c).map(|c| input[c * p + i]).sum::<f32>() / shape.c as f32;
    }
    Ok(())
}

/// Max over channels `[C,H,W] → [1,H,W]`.
pub fn channel_max(input: &[f32], shape: Shape, out: &mut [f32]) -> Result<(), KernelError> {
    need(input, shape)?;
    let p = shape.plane().ok_or(KernelError::Shape)?;
    if out.len() < p || shape.c == 0 {
        return Err(KernelError::Shape);
    }
    for i in 0..p {
        out[i] = (0..shape.c)
            .map(|c| input[c * p + i])
            .fold(f32::NEG_INFINITY, f32::max);
    }
    Ok(())
}

/// `(x − min x)/(max x − min x + eps)` over the whole tensor.
pub fn minmax_norm(input: &[f32], eps: f32, out: &mut [f32]) -> Result<(), KernelError> {
    if out.len() < input.len() || input.is_empty() {
        return Err(KernelError::Shape);
    }
    let lo = input.iter().fold(f32::INFINITY, |m, &v| m.min(v));
    let hi = input.iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v));
    let d = hi - lo + eps;
    for (o, &x) in out.iter_mut().zip(input) {
        *o = (x - lo) / d;
    }
    Ok(())
}

/// `bins_head` on f32 features: weights `[N, C]`, bias `[N]`, `bin_logits` `[N]` → `[h·w]` metres.
pub fn bins_head(
    features: &[f32],
    shape: Shape,
    bin_logits: &[f32],
    weights: &[f32],
    bias: &[f32],
    attrs: &BinsAttrs,
    out: &mut [f32],
) -> Result<(), KernelError> {
    bins::bins_head_f32(features, shape, bin_logits, weights, bias, attrs, out)
}

/// `refine` on f32 maps (all `H×W` planes, CHW): see [`refine::refine`]; `scratch` holds ≥
/// [`refine::scratch_len`] f32.
#[allow(clippy::too_many_arguments)]
pub fn refine(
    d0: &[f32],
    h: usize,
    w: usize,
    aff: [&[f32]; 3],
    kmix: &[f32],
    tmix: &[f32],
    attrs: &RefineAttrs,
    out: &mut [f32],
    scratch: &mut [f32],
) -> Result<(), KernelError> {
    let p = h.checked_mul(w).ok_or(KernelError::Shape)?;
    let a3 = F32Map::new(aff[0], attrs.neighbours(0), p)?;
    let a5 = F32Map::new(aff[1], attrs.neighbours(1), p)?;
    let a7 = F32Map::new(aff[2], attrs.neighbours(2), p)?;
    let km = F32Map::new(kmix, 3, p)?;
    let tm = F32Map::new(tmix, 3, p)?;
    refine::refine(d0, h, w, [&a3, &a5, &a7], &km, &tm, attrs, out, scratch)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_functions() {
        assert_eq!(relu(-2.0), 0.0);
        assert_eq!(leaky_relu(-2.0, 0.1), -0.2);
        assert!((sigmoid(0.0) - 0.5).abs() < 1e-6);
        assert!((sigmoid(4.0) - 0.98201376).abs() < 1e-4);
        assert!((sigmoid(-4.0) - 0.01798621).abs() < 1e-4);
        assert!((exp(1.5) - 4.481_689).abs() < 1e-6);
        assert_eq!(reciprocal(0.999, 1e-3), 1.0);
    }

    #[test]
    fn small_ops_by_hand() {
        let s = Shape::new(2, 1, 2);
        let x = [1.0, 2.0, 3.0, 5.0];
        let mut o = [0.0; 4];
        mul(&x, s, &[2.0, 10.0], Broadcast::OverSpace, &mut o).unwrap();
        assert_eq!(o, [2.0, 4.0, 30.0, 50.0]);
        mul(&x, s, &[2.0, 10.0], Broadcast::OverChannels, &mut o).unwrap();
        assert_eq!(o, [2.0, 20.0, 6.0, 50.0]);
        let mut p = [0.0; 2];
        global_avg_pool(&x, s, &mut p).unwrap();
        assert_eq!(p, [1.5, 4.0]);
        global_max_pool(&x, s, &mut p).unwrap();
        assert_eq!(p, [2.0, 5.0]);
        channel_mean(&x, s, &mut p).unwrap();
        assert_eq!(p, [2.0, 3.5]);
        channel_max(&x, s, &mut p).unwrap();
        assert_eq!(p, [3.0, 5.0]);
        minmax_norm(&x, 0.0, &mut o).unwrap();
        assert_eq!(o, [0.0, 0.25, 0.5, 1.0]);
        let mut y = [0.0; 1];
        linear(
            &[1.0, 2.0],
            &[3.0, 4.0],
            Some(&[0.5]),
            Activation::None,
            &mut y,
        )
        .unwrap();
        assert_eq!(y, [11.5]);
    }
}
