//! graph.json → [`Net`]: folds every `batch_norm` into the conv before it, fuses the ReLU /
//! LeakyReLU that follows into the conv when nothing else reads the intermediate values, splits
//! a conv's `sigmoid` activation into its own op (the blob has no fused sigmoid), infers shapes at
//! the native size and picks the blob storage of every value.

use super::graph::{Graph, GraphActivation, Node, NodeOp, Tensor};
use super::net::{Net, Op, OpKind, Storage, UpsampleSize, Value};
use depthor_core::kernels::conv::{Activation, ConvGeometry};
use depthor_core::kernels::float::Broadcast;
use depthor_core::kernels::Shape;
use std::collections::HashMap;

/// Why a graph cannot be turned into a blob network.
#[derive(Debug, thiserror::Error)]
pub enum FoldError {
    /// The graph's inputs are not `rgb` (3 channels) and `sparse` (1 channel).
    #[error("graph inputs must be rgb (3 channels) and sparse (1 channel), found {0:?}")]
    Inputs(Vec<(String, usize)>),
    /// The graph has not exactly one output.
    #[error("graph must have exactly one output, found {0}")]
    Outputs(usize),
    /// A node's operands do not fit it.
    #[error("node {node}: {what}")]
    Node {
        /// Node name.
        node: String,
        /// What is wrong.
        what: String,
    },
}

/// Folds `y = γ (x − μ)/√(σ² + ε) + β` into a conv with weights `weight` (`[O, …]`, `O =
/// gamma.len()`) and `bias`: returns the new weights and bias.
pub fn fold_batch_norm(
    weight: &[f32],
    bias: &[f32],
    gamma: &[f32],
    beta: &[f32],
    mean: &[f32],
    var: &[f32],
    eps: f32,
) -> (Vec<f32>, Vec<f32>) {
    let o = gamma.len();
    let per = weight.len() / o.max(1);
    let mut w = weight.to_vec();
    let mut b = vec![0f32; o];
    for c in 0..o {
        let s = (gamma[c] as f64 / (var[c] as f64 + eps as f64).sqrt()) as f32;
        for v in &mut w[c * per..(c + 1) * per] {
            *v *= s;
        }
        b[c] = (bias[c] - mean[c]) * s + beta[c];
    }
    (w, b)
}

struct Builder {
    values: Vec<Value>,
    ops: Vec<Op>,
    ids: HashMap<String, usize>,
}

impl Builder {
    fn err(node: &Node, what: impl Into<String>) -> FoldError {
        FoldError::Node {
            node: node.name.clone(),
            what: what.into(),
        }
    }

    fn input(&self, node: &Node, k: usize) -> Result<usize, FoldError> {
        let name = &node.inputs[k];
        self.ids
            .get(name.as_str())
            .copied()
            .ok_or_else(|| Self::err(node, format!("input {name:?} was fused away or is unknown")))
    }

    /// Errors unless input `k` of `node` is int8 (not an f32 depth map).
    fn need_i8(&self, node: &Node, k: usize) -> Result<(), FoldError> {
        let v = self.input(node, k)?;
        if self.values[v].storage != Storage::I8 {
            return Err(Self::err(
                node,
                format!("input {k} is an f32 depth map; this op needs int8"),
            ));
        }
        Ok(())
    }

    fn push(
        &mut self,
        name: &str,
        kind: OpKind,
        inputs: Vec<usize>,
        shape: Shape,
        storage: Storage,
    ) -> usize {
        let output = self.values.len();
        self.values.push(Value {
            name: name.to_string(),
            shape,
            storage,
            params_of: None,
        });
        self.ops.push(Op {
            kind,
            inputs,
            output,
        });
        self.ids.insert(name.to_string(), output);
        output
    }
}

fn activation(a: GraphActivation) -> Activation {
    match a {
        GraphActivation::Relu => Activation::Relu,
        GraphActivation::LeakyRelu(x) => Activation::LeakyRelu(x),
        GraphActivation::None | GraphActivation::Sigmoid => Activation::None,
    }
}

/// Builds the deployable network from `graph` (see the module doc).
pub fn fold(graph: &Graph) -> Result<Net, FoldError> {
    let find = |n: &str| {
        graph
            .inputs
            .iter()
            .find(|(name, _)| name == n)
            .map(|(_, c)| *c)
    };
    if graph.inputs.len() != 2 || find("rgb") != Some(3) || find("sparse") != Some(1) {
        return Err(FoldError::Inputs(graph.inputs.clone()));
    }
    if graph.outputs.len() != 1 {
        return Err(FoldError::Outputs(graph.outputs.len()));
    }
    let (h, w) = (graph.height, graph.width);
    // Readers of each value (a graph output counts as one more reader).
    let mut readers: HashMap<&str, Vec<usize>> = HashMap::new();
    for (i, n) in graph.nodes.iter().enumerate() {
        for inp in &n.inputs {
            readers.entry(inp.as_str()).or_default().push(i);
        }
    }
    for o in &graph.outputs {
        readers.entry(o.as_str()).or_default().push(usize::MAX);
    }
    let mut b = Builder {
        values: vec![
            Value {
                name: "rgb".into(),
                shape: Shape::new(3, h, w),
                storage: Storage::I8,
                params_of: None,
            },
            Value {
                name: "sparse".into(),
                shape: Shape::new(1, h, w),
                storage: Storage::I8,
                params_of: None,
            },
        ],
        ops: Vec::new(),
        ids: HashMap::from([("rgb".to_string(), 0), ("sparse".to_string(), 1)]),
    };
    let mut fused = vec![false; graph.nodes.len()];
    for (i, node) in graph.nodes.iter().enumerate() {
        if !fused[i] {
            lower(&mut b, graph, &readers, &mut fused, node)?;
        }
    }
    let out_name = &graph.outputs[0];
    let output = *b.ids.get(out_name.as_str()).ok_or(FoldError::Outputs(0))?;
    if b.values[output].shape != Shape::new(1, h, w) || b.values[output].storage != Storage::F32 {
        return Err(FoldError::Node {
            node: out_name.clone(),
            what: "the output must be a [1,H,W] f32 depth map".into(),
        });
    }
    Ok(Net {
        variant: graph.variant.clone(),
        height: h,
        width: w,
        values: b.values,
        ops: b.ops,
        output,
    })
}

/// The only reader of `value`, when exactly one node (and not the graph output) reads it.
fn sole_reader(readers: &HashMap<&str, Vec<usize>>, value: &str) -> Option<usize> {
    match readers.get(value).map(Vec::as_slice) {
        Some([r]) if *r != usize::MAX => Some(*r),
        _ => None,
    }
}

/// Lowers one graph node (not already fused into an earlier one) onto the blob network.
fn lower(
    b: &mut Builder,
    graph: &Graph,
    readers: &HashMap<&str, Vec<usize>>,
    fused: &mut [bool],
    node: &Node,
) -> Result<(), FoldError> {
    let x = b.input(node, 0)?;
    let xs = b.values[x].shape;
    let xst = b.values[x].storage;
    match &node.op {
        NodeOp::Conv2d { .. } => lower_conv(b, graph, readers, fused, node, x)?,
        NodeOp::BatchNorm { .. } => {
            return Err(Builder::err(
                node,
                "batch_norm does not directly follow a conv2d read only by it",
            ));
        }
        NodeOp::Linear { .. } => lower_linear(b, node, x)?,
        NodeOp::Relu
        | NodeOp::LeakyRelu(_)
        | NodeOp::Sigmoid
        | NodeOp::Reciprocal(_)
        | NodeOp::MinMaxNorm(_) => {
            b.need_i8(node, 0)?;
            let kind = match node.op {
                NodeOp::Relu => OpKind::Relu,
                NodeOp::LeakyRelu(a) => OpKind::LeakyRelu(a),
                NodeOp::Sigmoid => OpKind::Sigmoid,
                NodeOp::Reciprocal(e) => OpKind::Reciprocal(e),
                NodeOp::MinMaxNorm(e) => OpKind::MinMaxNorm(e),
                _ => unreachable!("matched above"),
            };
            b.push(&node.output, kind, vec![x], xs, Storage::I8);
        }
        NodeOp::Add | NodeOp::Mul => {
            b.need_i8(node, 0)?;
            b.need_i8(node, 1)?;
            let y = b.input(node, 1)?;
            let ys = b.values[y].shape;
            let kind = if ys == xs {
                if matches!(node.op, NodeOp::Add) {
                    OpKind::Add
                } else {
                    OpKind::Mul(Broadcast::None)
                }
            } else if matches!(node.op, NodeOp::Mul) && ys == Shape::new(1, xs.h, xs.w) {
                OpKind::Mul(Broadcast::OverChannels)
            } else if matches!(node.op, NodeOp::Mul) && ys == Shape::new(xs.c, 1, 1) {
                OpKind::Mul(Broadcast::OverSpace)
            } else {
                return Err(Builder::err(
                    node,
                    format!("shapes {xs:?} and {ys:?} do not broadcast"),
                ));
            };
            b.push(&node.output, kind, vec![x, y], xs, Storage::I8);
        }
        NodeOp::Concat => {
            let mut ids = Vec::new();
            let mut c = 0;
            for k in 0..node.inputs.len() {
                b.need_i8(node, k)?;
                let v = b.input(node, k)?;
                let s = b.values[v].shape;
                if (s.h, s.w) != (xs.h, xs.w) {
                    return Err(Builder::err(
                        node,
                        format!("input {k} is {s:?}, input 0 is {xs:?}"),
                    ));
                }
                c += s.c;
                ids.push(v);
            }
            b.push(
                &node.output,
                OpKind::Concat,
                ids,
                Shape::new(c, xs.h, xs.w),
                Storage::I8,
            );
        }
        NodeOp::UpsampleBilinear { out_h, out_w } => {
            // Prefer an earlier value of the same size, so the blob runs at any input size.
            let like = b
                .values
                .iter()
                .position(|v| (v.shape.h, v.shape.w) == (*out_h, *out_w));
            let size = like.map_or(UpsampleSize::Fixed(*out_h, *out_w), UpsampleSize::Like);
            b.push(
                &node.output,
                OpKind::Upsample(size),
                vec![x],
                Shape::new(xs.c, *out_h, *out_w),
                xst,
            );
        }
        NodeOp::PixelShuffle(r) => {
            if *r == 0 || !xs.c.is_multiple_of(r * r) {
                return Err(Builder::err(
                    node,
                    format!("{} channels do not divide by factor² ({r}²)", xs.c),
                ));
            }
            let os = Shape::new(xs.c / (r * r), xs.h * r, xs.w * r);
            b.push(&node.output, OpKind::PixelShuffle(*r), vec![x], os, xst);
        }
        NodeOp::GlobalAvgPool | NodeOp::GlobalMaxPool => {
            b.need_i8(node, 0)?;
            let kind = if matches!(node.op, NodeOp::GlobalAvgPool) {
                OpKind::GlobalAvgPool
            } else {
                OpKind::GlobalMaxPool
            };
            b.push(
                &node.output,
                kind,
                vec![x],
                Shape::new(xs.c, 1, 1),
                Storage::I8,
            );
        }
        NodeOp::ChannelMean | NodeOp::ChannelMax => {
            b.need_i8(node, 0)?;
            let kind = if matches!(node.op, NodeOp::ChannelMean) {
                OpKind::ChannelMean
            } else {
                OpKind::ChannelMax
            };
            b.push(
                &node.output,
                kind,
                vec![x],
                Shape::new(1, xs.h, xs.w),
                Storage::I8,
            );
        }
        NodeOp::BinsHead { .. } => lower_bins_head(b, node, x)?,
        NodeOp::Refine(attrs) => {
            let n = |k| attrs.neighbours(k);
            let want = [1, n(0), n(1), n(2), 3, 3];
            let mut ids = Vec::new();
            for (k, c) in want.iter().enumerate() {
                let v = b.input(node, k)?;
                let s = b.values[v].shape;
                let st = if k == 0 { Storage::F32 } else { Storage::I8 };
                if s != Shape::new(*c, xs.h, xs.w) || b.values[v].storage != st {
                    return Err(Builder::err(
                        node,
                        format!(
                            "input {k} is {s:?}, expected {c} channels at {}×{}",
                            xs.h, xs.w
                        ),
                    ));
                }
                ids.push(v);
            }
            b.push(
                &node.output,
                OpKind::Refine(*attrs),
                ids,
                Shape::new(1, xs.h, xs.w),
                Storage::F32,
            );
        }
    }
    Ok(())
}

/// Lowers a `conv2d` with the `batch_norm` and ReLU / LeakyReLU folded into it when nothing
/// else reads its output, and a `sigmoid` activation split into its own op.
fn lower_conv(
    b: &mut Builder,
    graph: &Graph,
    readers: &HashMap<&str, Vec<usize>>,
    fused: &mut [bool],
    node: &Node,
    x: usize,
) -> Result<(), FoldError> {
    let NodeOp::Conv2d {
        geometry,
        out_channels,
        activation: act,
        weight,
        bias,
    } = &node.op
    else {
        return Err(Builder::err(node, "lower_conv: wrong op"));
    };
    let xs = b.values[x].shape;
    b.need_i8(node, 0)?;
    if weight.shape[1] * geometry.groups != xs.c || !xs.c.is_multiple_of(geometry.groups) {
        return Err(Builder::err(
            node,
            format!(
                "weight {:?} does not fit {} input channels, groups {}",
                weight.shape, xs.c, geometry.groups
            ),
        ));
    }
    let os = geometry
        .output_shape(xs, *out_channels)
        .ok_or_else(|| Builder::err(node, format!("geometry does not fit input {xs:?}")))?;
    let mut wv = weight.data.clone();
    let mut bv = bias
        .as_ref()
        .map_or(vec![0.0; *out_channels], |t| t.data.clone());
    let mut act = *act;
    let mut name = node.output.as_str();
    // batch_norm directly after, read by nothing else?
    if let Some(j) = sole_reader(readers, name)
        .filter(|&j| matches!(graph.nodes[j].op, NodeOp::BatchNorm { .. }))
    {
        let bn = &graph.nodes[j];
        if let NodeOp::BatchNorm {
            eps,
            gamma,
            beta,
            mean,
            var,
        } = &bn.op
        {
            if act != GraphActivation::None {
                return Err(Builder::err(
                    bn,
                    "batch_norm after a conv with an activation",
                ));
            }
            if gamma.data.len() != *out_channels {
                return Err(Builder::err(
                    bn,
                    format!("{} channels, conv has {out_channels}", gamma.data.len()),
                ));
            }
            (wv, bv) = fold_batch_norm(
                &wv,
                &bv,
                &gamma.data,
                &beta.data,
                &mean.data,
                &var.data,
                *eps,
            );
            fused[j] = true;
            name = bn.output.as_str();
        }
    }
    // A ReLU / LeakyReLU reading only this conv is fused into it.
    if act == GraphActivation::None {
        if let Some(j) = sole_reader(readers, name) {
            let a = match graph.nodes[j].op {
                NodeOp::Relu => Some(GraphActivation::Relu),
                NodeOp::LeakyRelu(s) => Some(GraphActivation::LeakyRelu(s)),
                _ => None,
            };
            if let Some(a) = a {
                act = a;
                fused[j] = true;
                name = graph.nodes[j].output.as_str();
            }
        }
    }
    let conv = |act| OpKind::Conv {
        geometry: *geometry,
        act,
        weight: wv.clone(),
        bias: bv.clone(),
        linear: false,
    };
    if act == GraphActivation::Sigmoid {
        let pre = format!("{name}.pre");
        let p = b.push(&pre, conv(Activation::None), vec![x], os, Storage::I8);
        b.push(name, OpKind::Sigmoid, vec![p], os, Storage::I8);
    } else {
        b.push(name, conv(activation(act)), vec![x], os, Storage::I8);
    }
    Ok(())
}

/// Lowers a `linear` (a 1×1 conv on a `[I,1,1]` vector; a `sigmoid` activation as its own op).
fn lower_linear(b: &mut Builder, node: &Node, x: usize) -> Result<(), FoldError> {
    let NodeOp::Linear {
        activation: act,
        weight,
        bias,
    } = &node.op
    else {
        return Err(Builder::err(node, "lower_linear: wrong op"));
    };
    let xs = b.values[x].shape;
    b.need_i8(node, 0)?;
    let (o, i_) = (weight.shape[0], weight.shape[1]);
    if xs.c * xs.h * xs.w != i_ || xs.h * xs.w != 1 {
        return Err(Builder::err(
            node,
            format!("weight [{o}, {i_}] does not fit input {xs:?}"),
        ));
    }
    let bv = bias
        .as_ref()
        .map_or(vec![0.0; o], |t: &Tensor| t.data.clone());
    let kind = |a| OpKind::Conv {
        geometry: ConvGeometry::POINTWISE,
        act: a,
        weight: weight.data.clone(),
        bias: bv.clone(),
        linear: true,
    };
    let os = Shape::new(o, 1, 1);
    if *act == GraphActivation::Sigmoid {
        let pre = format!("{}.pre", node.output);
        let p = b.push(&pre, kind(Activation::None), vec![x], os, Storage::I8);
        b.push(&node.output, OpKind::Sigmoid, vec![p], os, Storage::I8);
    } else {
        b.push(
            &node.output,
            kind(activation(*act)),
            vec![x],
            os,
            Storage::I8,
        );
    }
    Ok(())
}

/// Lowers a `bins_head`: int8 features and bin logits in, an f32 depth map out.
fn lower_bins_head(b: &mut Builder, node: &Node, x: usize) -> Result<(), FoldError> {
    let NodeOp::BinsHead {
        attrs,
        weight,
        bias,
    } = &node.op
    else {
        return Err(Builder::err(node, "lower_bins_head: wrong op"));
    };
    let xs = b.values[x].shape;
    b.need_i8(node, 0)?;
    let l = b.input(node, 1)?;
    if weight.shape[1] != xs.c || b.values[l].shape.len() != Some(attrs.n_bins) {
        return Err(Builder::err(
            node,
            "weight or bin-logit size does not fit the features",
        ));
    }
    let bv = bias
        .as_ref()
        .map_or(vec![0.0; attrs.n_bins], |t| t.data.clone());
    let kind = OpKind::BinsHead {
        attrs: *attrs,
        weight: weight.data.clone(),
        bias: bv,
    };
    b.push(
        &node.output,
        kind,
        vec![x, l],
        Shape::new(1, xs.h, xs.w),
        Storage::F32,
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batch_norm_folds_by_hand() {
        // Two output channels, two weights each. Channel 0: γ=2, β=1, μ=3, σ²=3, ε=1 → s = 1.
        // Channel 1: γ=1, β=0, μ=0, σ²=0.25, ε=0 → s = 2.
        let (w, b) = fold_batch_norm(
            &[1.0, 2.0, 3.0, 4.0],
            &[5.0, 1.0],
            &[2.0, 1.0],
            &[1.0, 0.0],
            &[3.0, 0.0],
            &[3.0, 0.25],
            1.0,
        );
        // ε = 1 applies to both: channel 1 has s = 1/√1.25.
        let s1 = 1.0 / 1.25f32.sqrt();
        assert_eq!(w[..2], [1.0, 2.0]);
        assert!((w[2] - 3.0 * s1).abs() < 1e-6 && (w[3] - 4.0 * s1).abs() < 1e-6);
        assert_eq!(b[0], (5.0 - 3.0) * 1.0 + 1.0);
        assert!((b[1] - s1).abs() < 1e-6);
    }
}
