//! Reader of the Python export `graph.json` (`depthor-graph/1`, specified in `docs/graph.md`)
//! and its `weights.bin` (little-endian f32 tensors at 64-byte aligned offsets).
//! Every error names the file and the JSON field (`nodes[12].attrs.kernel`) or tensor at fault.

use depthor_core::kernels::bins::BinsAttrs;
use depthor_core::kernels::conv::ConvGeometry;
use depthor_core::kernels::refine::{Neighbourhood, RefineAttrs};
use serde_json::{Map, Value};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The only graph format this reader accepts.
pub const FORMAT: &str = "depthor-graph/1";
/// Alignment of tensor offsets in `weights.bin`.
pub const WEIGHT_ALIGN: usize = 64;

/// Why a graph could not be read.
#[derive(Debug, thiserror::Error)]
pub enum GraphError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// `graph.json` is not JSON.
    #[error("{path}: not JSON: {source}")]
    Json {
        /// File.
        path: PathBuf,
        /// Cause.
        source: serde_json::Error,
    },
    /// A field is missing or holds a bad value.
    #[error("{path}: {field}: {what}")]
    Field {
        /// File.
        path: PathBuf,
        /// JSON path of the field.
        field: String,
        /// What is wrong.
        what: String,
    },
}

/// A parameter tensor (f32, row-major).
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    /// Shape as exported.
    pub shape: Vec<usize>,
    /// Values.
    pub data: Vec<f32>,
}

/// Activation attribute of `conv2d` / `linear`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GraphActivation {
    /// Identity.
    None,
    /// `max(x, 0)`.
    Relu,
    /// Leaky ReLU with this slope.
    LeakyRelu(f32),
    /// Logistic sigmoid.
    Sigmoid,
}

/// A docs/graph.md op with its attributes and parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeOp {
    /// `conv2d`; weight `[O, I/groups, kh, kw]`.
    Conv2d {
        /// Kernel, stride, dilation, padding, groups.
        geometry: ConvGeometry,
        /// Output channels `O`.
        out_channels: usize,
        /// Fused activation.
        activation: GraphActivation,
        /// Weights.
        weight: Tensor,
        /// Bias `[O]`, absent = zeros.
        bias: Option<Tensor>,
    },
    /// `batch_norm` (inference statistics).
    BatchNorm {
        /// Variance epsilon.
        eps: f32,
        /// Scale γ.
        gamma: Tensor,
        /// Shift β.
        beta: Tensor,
        /// Running mean.
        mean: Tensor,
        /// Running variance.
        var: Tensor,
    },
    /// `relu`.
    Relu,
    /// `leaky_relu` with slope `alpha`.
    LeakyRelu(f32),
    /// `sigmoid`.
    Sigmoid,
    /// `add`.
    Add,
    /// `mul` (second input may broadcast).
    Mul,
    /// `concat` over channels.
    Concat,
    /// `upsample_bilinear` to `out_h × out_w` (align_corners = true).
    UpsampleBilinear {
        /// Output rows.
        out_h: usize,
        /// Output columns.
        out_w: usize,
    },
    /// `pixel_shuffle` by `factor`.
    PixelShuffle(usize),
    /// `global_avg_pool`.
    GlobalAvgPool,
    /// `global_max_pool`.
    GlobalMaxPool,
    /// `channel_mean`.
    ChannelMean,
    /// `channel_max`.
    ChannelMax,
    /// `linear`; weight `[O, I]`.
    Linear {
        /// Fused activation.
        activation: GraphActivation,
        /// Weights.
        weight: Tensor,
        /// Bias `[O]`, absent = zeros.
        bias: Option<Tensor>,
    },
    /// `minmax_norm` with `eps`.
    MinMaxNorm(f32),
    /// `reciprocal`: `1/(x + eps)`.
    Reciprocal(f32),
    /// `bins_head`; weight `[N, C]`, bias `[N]`.
    BinsHead {
        /// Bin count and depth range.
        attrs: BinsAttrs,
        /// Per-pixel logits weights.
        weight: Tensor,
        /// Logits bias.
        bias: Option<Tensor>,
    },
    /// `refine`.
    Refine(RefineAttrs),
}

impl NodeOp {
    /// Number of inputs the op takes (`None` = any number ≥ 1, for `concat`).
    pub fn arity(&self) -> Option<usize> {
        Some(match self {
            NodeOp::Concat => return None,
            NodeOp::Add | NodeOp::Mul | NodeOp::BinsHead { .. } => 2,
            NodeOp::Refine(_) => 6,
            _ => 1,
        })
    }
}

/// One node of graph.json.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Unique node name (`prior.` prefix for the monocular prior).
    pub name: String,
    /// Input value names.
    pub inputs: Vec<String>,
    /// Output value name.
    pub output: String,
    /// Op, attributes and parameters.
    pub op: NodeOp,
}

/// A parsed `graph.json` with its weights loaded.
#[derive(Clone, Debug, PartialEq)]
pub struct Graph {
    /// Variant name (`mcu`, `phone`).
    pub variant: String,
    /// Native input rows.
    pub height: usize,
    /// Native input columns.
    pub width: usize,
    /// Graph inputs (name, channels), in file order.
    pub inputs: Vec<(String, usize)>,
    /// Graph output value names.
    pub outputs: Vec<String>,
    /// Nodes in topological order.
    pub nodes: Vec<Node>,
}

/// Field access with errors that name the file and the JSON path.
struct Ctx<'p> {
    path: &'p Path,
}

impl Ctx<'_> {
    fn err(&self, field: &str, what: impl Into<String>) -> GraphError {
        GraphError::Field {
            path: self.path.to_path_buf(),
            field: field.to_string(),
            what: what.into(),
        }
    }
    fn get<'v>(
        &self,
        obj: &'v Map<String, Value>,
        at: &str,
        key: &str,
    ) -> Result<&'v Value, GraphError> {
        obj.get(key)
            .ok_or_else(|| self.err(&join(at, key), "missing"))
    }
    fn obj<'v>(&self, v: &'v Value, at: &str) -> Result<&'v Map<String, Value>, GraphError> {
        v.as_object()
            .ok_or_else(|| self.err(at, "expected an object"))
    }
    fn str<'v>(
        &self,
        obj: &'v Map<String, Value>,
        at: &str,
        key: &str,
    ) -> Result<&'v str, GraphError> {
        self.get(obj, at, key)?
            .as_str()
            .ok_or_else(|| self.err(&join(at, key), "expected a string"))
    }
    fn usize(&self, obj: &Map<String, Value>, at: &str, key: &str) -> Result<usize, GraphError> {
        let v = self.get(obj, at, key)?;
        v.as_u64()
            .and_then(|u| usize::try_from(u).ok())
            .ok_or_else(|| {
                self.err(
                    &join(at, key),
                    format!("expected a non-negative integer, got {v}"),
                )
            })
    }
    fn f32(&self, obj: &Map<String, Value>, at: &str, key: &str) -> Result<f32, GraphError> {
        let v = self.get(obj, at, key)?;
        v.as_f64()
            .map(|f| f as f32)
            .filter(|f| f.is_finite())
            .ok_or_else(|| self.err(&join(at, key), format!("expected a finite number, got {v}")))
    }
    fn f32_or(
        &self,
        obj: &Map<String, Value>,
        at: &str,
        key: &str,
        default: f32,
    ) -> Result<f32, GraphError> {
        if obj.contains_key(key) {
            self.f32(obj, at, key)
        } else {
            Ok(default)
        }
    }
    fn arr<'v>(
        &self,
        obj: &'v Map<String, Value>,
        at: &str,
        key: &str,
    ) -> Result<&'v Vec<Value>, GraphError> {
        self.get(obj, at, key)?
            .as_array()
            .ok_or_else(|| self.err(&join(at, key), "expected an array"))
    }
    fn usizes(
        &self,
        obj: &Map<String, Value>,
        at: &str,
        key: &str,
    ) -> Result<Vec<usize>, GraphError> {
        let f = join(at, key);
        self.arr(obj, at, key)?
            .iter()
            .map(|v| {
                v.as_u64()
                    .and_then(|u| usize::try_from(u).ok())
                    .ok_or_else(|| self.err(&f, format!("expected non-negative integers, got {v}")))
            })
            .collect()
    }
    fn pair(
        &self,
        obj: &Map<String, Value>,
        at: &str,
        key: &str,
    ) -> Result<[usize; 2], GraphError> {
        let v = self.usizes(obj, at, key)?;
        match v.as_slice() {
            [a, b] => Ok([*a, *b]),
            _ => Err(self.err(&join(at, key), "expected two integers")),
        }
    }
}

fn join(at: &str, key: &str) -> String {
    if at.is_empty() {
        key.to_string()
    } else {
        format!("{at}.{key}")
    }
}

fn read(path: &Path) -> Result<Vec<u8>, GraphError> {
    std::fs::read(path).map_err(|source| GraphError::Io {
        path: path.to_path_buf(),
        source,
    })
}

impl Graph {
    /// Reads `graph_path` and the weights file beside it (`weights.bin`), or `weights_path`.
    pub fn load(graph_path: &Path, weights_path: Option<&Path>) -> Result<Graph, GraphError> {
        let text = read(graph_path)?;
        let json: Value = serde_json::from_slice(&text).map_err(|source| GraphError::Json {
            path: graph_path.to_path_buf(),
            source,
        })?;
        let wpath = weights_path
            .map(Path::to_path_buf)
            .unwrap_or_else(|| graph_path.with_file_name("weights.bin"));
        let weights = read(&wpath)?;
        Graph::from_parts(graph_path, &json, &wpath, &weights)
    }

    /// Parses an already-read graph document and weights (the paths are only for messages).
    pub fn from_parts(
        graph_path: &Path,
        json: &Value,
        weights_path: &Path,
        weights: &[u8],
    ) -> Result<Graph, GraphError> {
        let c = Ctx { path: graph_path };
        let root = c.obj(json, "(root)")?;
        let format = c.str(root, "", "format")?;
        if format != FORMAT {
            return Err(c.err("format", format!("{format:?}, expected {FORMAT:?}")));
        }
        let variant = c.str(root, "", "variant")?.to_string();
        let height = c.usize(root, "", "height")?;
        let width = c.usize(root, "", "width")?;
        if height == 0 || width == 0 || height > u16::MAX as usize || width > u16::MAX as usize {
            return Err(c.err("height", "input size must be 1..=65535 in both dimensions"));
        }
        let mut inputs = Vec::new();
        for (i, v) in c.arr(root, "", "inputs")?.iter().enumerate() {
            let at = format!("inputs[{i}]");
            let o = c.obj(v, &at)?;
            inputs.push((
                c.str(o, &at, "name")?.to_string(),
                c.usize(o, &at, "channels")?,
            ));
        }
        let outputs = c
            .arr(root, "", "outputs")?
            .iter()
            .enumerate()
            .map(|(i, v)| {
                v.as_str()
                    .map(str::to_string)
                    .ok_or_else(|| c.err(&format!("outputs[{i}]"), "expected a string"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let tensors = load_tensors(
            &c,
            c.obj(c.get(root, "", "tensors")?, "tensors")?,
            weights_path,
            weights,
        )?;
        let mut nodes = Vec::new();
        let mut produced: HashMap<String, usize> = HashMap::new();
        for (name, _) in &inputs {
            produced.insert(name.clone(), 0);
        }
        for (i, v) in c.arr(root, "", "nodes")?.iter().enumerate() {
            let at = format!("nodes[{i}]");
            let node = parse_node(&c, c.obj(v, &at)?, &at, &tensors)?;
            for (k, inp) in node.inputs.iter().enumerate() {
                if !produced.contains_key(inp) {
                    return Err(c.err(
                        &format!("{at}.inputs[{k}]"),
                        format!("value {inp:?} is used before it is produced"),
                    ));
                }
            }
            if produced.insert(node.output.clone(), i).is_some() {
                return Err(c.err(
                    &format!("{at}.output"),
                    format!("value {:?} is produced twice", node.output),
                ));
            }
            nodes.push(node);
        }
        for (i, o) in outputs.iter().enumerate() {
            if !produced.contains_key(o) {
                return Err(c.err(&format!("outputs[{i}]"), format!("no node produces {o:?}")));
            }
        }
        Ok(Graph {
            variant,
            height,
            width,
            inputs,
            outputs,
            nodes,
        })
    }

    /// Number of parameters (f32 values) the graph's nodes hold.
    pub fn parameter_count(&self) -> usize {
        self.nodes
            .iter()
            .map(|n| match &n.op {
                NodeOp::Conv2d { weight, bias, .. }
                | NodeOp::Linear { weight, bias, .. }
                | NodeOp::BinsHead { weight, bias, .. } => {
                    weight.data.len() + bias.as_ref().map_or(0, |b| b.data.len())
                }
                NodeOp::BatchNorm { gamma, .. } => 4 * gamma.data.len(),
                _ => 0,
            })
            .sum()
    }
}

fn load_tensors(
    c: &Ctx,
    table: &Map<String, Value>,
    wpath: &Path,
    weights: &[u8],
) -> Result<HashMap<String, Tensor>, GraphError> {
    let mut out = HashMap::new();
    for (name, v) in table {
        let at = format!("tensors.{name}");
        let o = c.obj(v, &at)?;
        let shape = c.usizes(o, &at, "shape")?;
        let offset = c.usize(o, &at, "offset")?;
        let n = shape
            .iter()
            .try_fold(1usize, |a, &d| a.checked_mul(d))
            .ok_or_else(|| c.err(&join(&at, "shape"), "element count overflows"))?;
        if !offset.is_multiple_of(WEIGHT_ALIGN) {
            return Err(c.err(
                &join(&at, "offset"),
                format!("{offset} is not {WEIGHT_ALIGN}-byte aligned"),
            ));
        }
        let bytes = offset
            .checked_add(n * 4)
            .and_then(|end| weights.get(offset..end))
            .ok_or_else(|| GraphError::Field {
                path: wpath.to_path_buf(),
                field: at.clone(),
                what: format!(
                    "{n} f32 at offset {offset} run past the end of the file ({} bytes)",
                    weights.len()
                ),
            })?;
        let data: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        if let Some(k) = data.iter().position(|v| !v.is_finite()) {
            return Err(GraphError::Field {
                path: wpath.to_path_buf(),
                field: at,
                what: format!("element {k} is not finite"),
            });
        }
        out.insert(name.clone(), Tensor { shape, data });
    }
    Ok(out)
}

fn activation(
    c: &Ctx,
    attrs: &Map<String, Value>,
    at: &str,
) -> Result<GraphActivation, GraphError> {
    let alpha = c.f32_or(attrs, at, "alpha", 0.1)?;
    Ok(match c.str(attrs, at, "activation")? {
        "none" => GraphActivation::None,
        "relu" => GraphActivation::Relu,
        "leaky_relu" => GraphActivation::LeakyRelu(alpha),
        "sigmoid" => GraphActivation::Sigmoid,
        other => {
            return Err(c.err(
                &join(at, "activation"),
                format!("unknown activation {other:?}"),
            ))
        }
    })
}

/// One node's attributes and parameters, with errors that name their JSON path.
struct NodeFields<'a> {
    c: &'a Ctx<'a>,
    attrs: &'a Map<String, Value>,
    /// JSON path of `attrs`.
    aat: String,
    params: &'a Map<String, Value>,
    /// JSON path of `params`.
    pat: String,
    tensors: &'a HashMap<String, Tensor>,
}

impl NodeFields<'_> {
    fn param(&self, key: &str) -> Result<Tensor, GraphError> {
        let tname = self.c.str(self.params, &self.pat, key)?;
        self.tensors.get(tname).cloned().ok_or_else(|| {
            self.c.err(
                &join(&self.pat, key),
                format!("tensor {tname:?} is not in `tensors`"),
            )
        })
    }

    fn opt_param(&self, key: &str) -> Result<Option<Tensor>, GraphError> {
        if self.params.get(key).is_none_or(Value::is_null) {
            Ok(None)
        } else {
            self.param(key).map(Some)
        }
    }

    fn shape_err(&self, key: &str, what: String) -> GraphError {
        self.c.err(&join(&self.pat, key), what)
    }

    /// An optional bias of `n` values.
    fn bias(&self, n: usize) -> Result<Option<Tensor>, GraphError> {
        let bias = self.opt_param("bias")?;
        match &bias {
            Some(b) if b.data.len() != n => {
                Err(self.shape_err("bias", format!("{} values, expected {n}", b.data.len())))
            }
            _ => Ok(bias),
        }
    }

    fn usize(&self, key: &str) -> Result<usize, GraphError> {
        self.c.usize(self.attrs, &self.aat, key)
    }

    fn f32(&self, key: &str) -> Result<f32, GraphError> {
        self.c.f32(self.attrs, &self.aat, key)
    }

    fn f32_or(&self, key: &str, default: f32) -> Result<f32, GraphError> {
        self.c.f32_or(self.attrs, &self.aat, key, default)
    }

    fn conv2d(&self) -> Result<NodeOp, GraphError> {
        let (c, attrs, aat) = (self.c, self.attrs, self.aat.as_str());
        let kernel = c.pair(attrs, aat, "kernel")?;
        let stride = self.usize("stride")?;
        let dilation = self.usize("dilation")?;
        let padding = c.pair(attrs, aat, "padding")?;
        let groups = self.usize("groups")?;
        let out_channels = self.usize("out_channels")?;
        if kernel.contains(&0) || stride == 0 || dilation == 0 || groups == 0 || out_channels == 0 {
            return Err(c.err(aat, "zero kernel, stride, dilation, groups or out_channels"));
        }
        if !out_channels.is_multiple_of(groups) {
            return Err(c.err(&join(aat, "groups"), "does not divide out_channels"));
        }
        let weight = self.param("weight")?;
        if weight.shape.len() != 4
            || weight.shape[0] != out_channels
            || weight.shape[2..] != kernel[..]
        {
            return Err(self.shape_err(
                "weight",
                format!(
                    "shape {:?} does not match out_channels {out_channels}, kernel {kernel:?}",
                    weight.shape
                ),
            ));
        }
        let bias = self.bias(out_channels)?;
        Ok(NodeOp::Conv2d {
            geometry: ConvGeometry {
                kernel,
                stride: [stride; 2],
                dilation: [dilation; 2],
                padding,
                groups,
            },
            out_channels,
            activation: activation(c, attrs, aat)?,
            weight,
            bias,
        })
    }

    fn batch_norm(&self) -> Result<NodeOp, GraphError> {
        let (gamma, beta, mean, var) = (
            self.param("gamma")?,
            self.param("beta")?,
            self.param("mean")?,
            self.param("var")?,
        );
        let n = gamma.data.len();
        for (k, t) in [("beta", &beta), ("mean", &mean), ("var", &var)] {
            if t.data.len() != n {
                return Err(self.shape_err(k, format!("{} values, gamma has {n}", t.data.len())));
            }
        }
        if var.data.iter().any(|&v| v < 0.0) {
            return Err(self.shape_err("var", "negative variance".into()));
        }
        Ok(NodeOp::BatchNorm {
            eps: self.f32("eps")?,
            gamma,
            beta,
            mean,
            var,
        })
    }

    fn linear(&self) -> Result<NodeOp, GraphError> {
        let weight = self.param("weight")?;
        if weight.shape.len() != 2 {
            return Err(self.shape_err(
                "weight",
                format!("shape {:?}, expected [O, I]", weight.shape),
            ));
        }
        let bias = self.bias(weight.shape[0])?;
        Ok(NodeOp::Linear {
            activation: activation(self.c, self.attrs, &self.aat)?,
            weight,
            bias,
        })
    }

    fn bins_head(&self) -> Result<NodeOp, GraphError> {
        let n_bins = self.usize("n_bins")?;
        let min_depth = self.f32("min_depth_m")?;
        let max_depth = self.f32("max_depth_m")?;
        if n_bins == 0 || min_depth >= max_depth {
            return Err(self.c.err(
                &self.aat,
                "n_bins must be > 0 and min_depth_m < max_depth_m",
            ));
        }
        let weight = self.param("weight")?;
        if weight.shape.len() != 2 || weight.shape[0] != n_bins {
            return Err(self.shape_err(
                "weight",
                format!("shape {:?}, expected [{n_bins}, C]", weight.shape),
            ));
        }
        let bias = self.bias(n_bins)?;
        Ok(NodeOp::BinsHead {
            attrs: BinsAttrs {
                n_bins,
                min_depth,
                max_depth,
            },
            weight,
            bias,
        })
    }

    fn refine(&self) -> Result<NodeOp, GraphError> {
        let iterations = self.usize("iterations")?;
        let s = self.c.arr(self.attrs, &self.aat, "sigma")?;
        let sig: Vec<f32> = s
            .iter()
            .filter_map(|v| v.as_f64().map(|f| f as f32))
            .collect();
        if sig.len() != 3 || sig.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(self
                .c
                .err(&join(&self.aat, "sigma"), "expected three positive numbers"));
        }
        if !iterations.is_multiple_of(2) {
            return Err(self.c.err(&join(&self.aat, "iterations"), "must be even"));
        }
        let at = join(&self.aat, "neighbourhood");
        let neighbourhood = match self.attrs.get("neighbourhood") {
            None => Neighbourhood::Window,
            Some(v) => match v.as_str() {
                Some("window") => Neighbourhood::Window,
                Some("dilated") => Neighbourhood::Dilated,
                _ => {
                    let why = format!("expected \"window\" or \"dilated\", got {v}");
                    return Err(self.c.err(&at, why));
                }
            },
        };
        Ok(NodeOp::Refine(RefineAttrs {
            iterations,
            sigma: [sig[0], sig[1], sig[2]],
            neighbourhood,
        }))
    }

    /// The op named `op_name` with its attributes and parameters.
    fn op(&self, op_name: &str, at: &str) -> Result<NodeOp, GraphError> {
        Ok(match op_name {
            "conv2d" => self.conv2d()?,
            "batch_norm" => self.batch_norm()?,
            "relu" => NodeOp::Relu,
            "leaky_relu" => NodeOp::LeakyRelu(self.f32_or("alpha", 0.1)?),
            "sigmoid" => NodeOp::Sigmoid,
            "add" => NodeOp::Add,
            "mul" => NodeOp::Mul,
            "concat" => NodeOp::Concat,
            "upsample_bilinear" => NodeOp::UpsampleBilinear {
                out_h: self.usize("out_h")?,
                out_w: self.usize("out_w")?,
            },
            "pixel_shuffle" => NodeOp::PixelShuffle(self.usize("factor")?),
            "global_avg_pool" => NodeOp::GlobalAvgPool,
            "global_max_pool" => NodeOp::GlobalMaxPool,
            "channel_mean" => NodeOp::ChannelMean,
            "channel_max" => NodeOp::ChannelMax,
            "linear" => self.linear()?,
            "minmax_norm" => NodeOp::MinMaxNorm(self.f32_or("eps", 1e-6)?),
            "reciprocal" => NodeOp::Reciprocal(self.f32_or("eps", 1e-3)?),
            "bins_head" => self.bins_head()?,
            "refine" => self.refine()?,
            other => return Err(self.c.err(&join(at, "op"), format!("unknown op {other:?}"))),
        })
    }
}

fn parse_node(
    c: &Ctx,
    o: &Map<String, Value>,
    at: &str,
    tensors: &HashMap<String, Tensor>,
) -> Result<Node, GraphError> {
    let name = c.str(o, at, "name")?.to_string();
    let op_name = c.str(o, at, "op")?;
    let output = c.str(o, at, "output")?.to_string();
    let inputs = c
        .arr(o, at, "inputs")?
        .iter()
        .enumerate()
        .map(|(k, v)| {
            v.as_str()
                .map(str::to_string)
                .ok_or_else(|| c.err(&format!("{at}.inputs[{k}]"), "expected a string"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let empty = Map::new();
    let aat = join(at, "attrs");
    let attrs = match o.get("attrs") {
        Some(v) => c.obj(v, &aat)?,
        None => &empty,
    };
    let pat = join(at, "params");
    let params = match o.get("params") {
        Some(v) => c.obj(v, &pat)?,
        None => &empty,
    };
    let fields = NodeFields {
        c,
        attrs,
        aat,
        params,
        pat,
        tensors,
    };
    let op = fields.op(op_name, at)?;
    let ok = match op.arity() {
        Some(n) => inputs.len() == n,
        None => !inputs.is_empty(),
    };
    if !ok {
        return Err(c.err(
            &join(at, "inputs"),
            format!("{} inputs do not fit op {op_name}", inputs.len()),
        ));
    }
    Ok(Node {
        name,
        inputs,
        output,
        op,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn weights(vals: &[f32]) -> Vec<u8> {
        vals.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    fn doc() -> Value {
        json!({"format": FORMAT, "variant": "t", "height": 2, "width": 2,
            "inputs": [{"name": "rgb", "channels": 3}, {"name": "sparse", "channels": 1}],
            "outputs": ["y"],
            "tensors": {"w": {"shape": [1, 1, 1, 1], "offset": 0}},
            "nodes": [{"op": "conv2d", "name": "c", "inputs": ["sparse"], "output": "y",
                "attrs": {"out_channels": 1, "kernel": [1, 1], "stride": 1, "dilation": 1,
                          "padding": [0, 0], "groups": 1, "activation": "relu"},
                "params": {"weight": "w"}}]})
    }

    fn parse(v: &Value, w: &[u8]) -> Result<Graph, GraphError> {
        Graph::from_parts(Path::new("g.json"), v, Path::new("w.bin"), w)
    }

    #[test]
    fn reads_a_minimal_graph() {
        let g = parse(&doc(), &weights(&[2.5])).unwrap();
        assert_eq!((g.height, g.width, g.nodes.len()), (2, 2, 1));
        match &g.nodes[0].op {
            NodeOp::Conv2d {
                weight,
                activation,
                bias,
                ..
            } => {
                assert_eq!(weight.data, vec![2.5]);
                assert_eq!(*activation, GraphActivation::Relu);
                assert!(bias.is_none());
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn errors_name_file_and_field() {
        let mut d = doc();
        d["nodes"][0]["attrs"]["kernel"] = json!([1]);
        let e = parse(&d, &weights(&[1.0])).unwrap_err().to_string();
        assert_eq!(e, "g.json: nodes[0].attrs.kernel: expected two integers");

        let e = parse(&doc(), &[0u8; 2]).unwrap_err().to_string();
        assert!(e.starts_with("w.bin: tensors.w: 1 f32 at offset 0"), "{e}");

        let mut d = doc();
        d["nodes"][0]["inputs"] = json!(["nothing"]);
        let e = parse(&d, &weights(&[1.0])).unwrap_err().to_string();
        assert!(
            e.contains("nodes[0].inputs[0]: value \"nothing\" is used before"),
            "{e}"
        );

        let mut d = doc();
        d["format"] = json!("other/2");
        assert!(parse(&d, &weights(&[1.0]))
            .unwrap_err()
            .to_string()
            .starts_with("g.json: format:"));

        // refine's neighbourhood: absent = window, a known word, or an error naming the field.
        let refine = |nb: Option<Value>| {
            let mut d = doc();
            let mut attrs = json!({"iterations": 2, "sigma": [1.0, 2.0, 3.0]});
            if let Some(v) = nb {
                attrs["neighbourhood"] = v;
            }
            d["nodes"] = json!([{"op": "refine", "name": "r",
                "inputs": ["sparse", "sparse", "sparse", "sparse", "sparse", "sparse"],
                "output": "y", "attrs": attrs}]);
            parse(&d, &weights(&[1.0])).map(|g| match &g.nodes[0].op {
                NodeOp::Refine(a) => a.neighbourhood,
                other => panic!("{other:?}"),
            })
        };
        use depthor_core::kernels::refine::Neighbourhood as N;
        assert_eq!(refine(None).unwrap(), N::Window);
        assert_eq!(refine(Some(json!("window"))).unwrap(), N::Window);
        assert_eq!(refine(Some(json!("dilated"))).unwrap(), N::Dilated);
        let e = refine(Some(json!("ring"))).unwrap_err().to_string();
        assert!(e.contains("nodes[0].attrs.neighbourhood: expected"), "{e}");

        let mut d = doc();
        d["tensors"]["w"]["offset"] = json!(4);
        let e = parse(&d, &weights(&[1.0, 1.0])).unwrap_err().to_string();
        assert!(
            e.contains("tensors.w.offset: 4 is not 64-byte aligned"),
            "{e}"
        );
    }
}
