//! Accuracy of a blob against its float network: signal-to-quantisation-noise ratio of the final
//! depth per frame, and of every op's output (the engine's int8 tensor dequantised, seen through
//! [`Engine::run_observed`], against the f32 value) accumulated over frames.

use super::blob_writer::quantize_channels;
use super::calibrate::Frame;
use super::golden::GoldenTensor;
use super::net::{Net, OpKind};
use depthor_core::engine::{
    required_arena_bytes_with, Engine, Error as EngineError, Memory, Observed,
};
use depthor_core::kernels::requant::QParams;
use std::collections::HashMap;

/// `10·log10(Σ signal² / Σ (signal − test)²)` in dB (`+∞` when they are equal).
pub fn sqnr_db(reference: &[f32], test: &[f32]) -> f64 {
    let (s, n) = power(reference, test, 0.0);
    ratio_db(s, n)
}

/// SQNR pooled over frames: `10·log10(Σ_frames Σ signal² / Σ_frames Σ (signal − test)²)`,
/// `pairs` being `(reference, test)` depth maps.
pub fn pooled_sqnr_db<'a>(pairs: impl IntoIterator<Item = (&'a [f32], &'a [f32])>) -> f64 {
    let (s, n) = pairs
        .into_iter()
        .map(|(r, t)| power(r, t, 0.0))
        .fold((0.0, 0.0), |(s, n), (a, b)| (s + a, n + b));
    ratio_db(s, n)
}

fn ratio_db(s: f64, n: f64) -> f64 {
    if n == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (s / n).log10()
    }
}

/// (Σ (ref − offset)², Σ (ref − test)²).
fn power(reference: &[f32], test: &[f32], offset: f64) -> (f64, f64) {
    reference
        .iter()
        .zip(test)
        .fold((0.0, 0.0), |(s, n), (&r, &t)| {
            let (r, t) = (r as f64, t as f64);
            (s + (r - offset).powi(2), n + (r - t).powi(2))
        })
}

/// SQNR of one op's output over all compared frames.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerSqnr {
    /// Op index (= blob op index).
    pub op: usize,
    /// Output value name.
    pub name: String,
    /// `10·log10(Σ ref² / Σ err²)` over all frames.
    pub sqnr_db: f64,
    /// Largest |int8 − f32| seen.
    pub max_abs_err: f32,
}

/// What [`compare`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Per frame: SQNR of the final depth.
    pub depth_db: Vec<f64>,
    /// Per frame: SQNR of the depth minus its (float) mean, i.e. of the depth's variation.
    pub depth_centred_db: Vec<f64>,
    /// Per frame: (Σ f32 depth², Σ (int8 − f32)²), for the pooled SQNR.
    pub depth_power: Vec<(f64, f64)>,
    /// Per frame: largest |int8 − f32| depth error, metres.
    pub depth_max_abs_m: Vec<f32>,
    /// Per op, in op order.
    pub layers: Vec<LayerSqnr>,
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

impl Comparison {
    /// Mean and minimum of the per-frame depth SQNR.
    pub fn depth_mean_min(&self) -> (f64, f64) {
        (mean(&self.depth_db), min(&self.depth_db))
    }

    /// Depth SQNR over all frames together (signal and noise energy summed over frames).
    pub fn depth_pooled_db(&self) -> f64 {
        let (s, n) = self
            .depth_power
            .iter()
            .fold((0.0, 0.0), |(s, n), (a, b)| (s + a, n + b));
        ratio_db(s, n)
    }

    /// Mean and minimum of the per-frame centred-depth SQNR.
    pub fn centred_mean_min(&self) -> (f64, f64) {
        (mean(&self.depth_centred_db), min(&self.depth_centred_db))
    }

    /// The `k` layers with the lowest SQNR, worst first.
    pub fn worst_layers(&self, k: usize) -> Vec<&LayerSqnr> {
        let mut v: Vec<&LayerSqnr> = self.layers.iter().collect();
        v.sort_by(|a, b| a.sqnr_db.total_cmp(&b.sqnr_db));
        v.truncate(k);
        v
    }
}

/// Why the comparison could not run.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// The engine rejected the blob or failed on a frame.
    #[error("engine: {0}")]
    Engine(#[from] EngineError),
    /// The float network failed.
    #[error("float network: {0}")]
    Float(#[from] super::net::RunError),
    /// The blob's ops do not line up with the network's.
    #[error("the blob has {blob} ops, the network {net}")]
    OpCount {
        /// Ops in the blob.
        blob: usize,
        /// Ops in the network.
        net: usize,
    },
}

/// A zeroed arena large enough for `blob` at `net`'s native size.
/// An arena for the [`Memory::Whole`] plan (every op's output observed).
fn arena_for(blob: &[u8], net: &Net) -> Result<Vec<u8>, CheckError> {
    let need = required_arena_bytes_with(blob, net.height, net.width, Memory::Whole)?;
    Ok(vec![0u8; need + 64])
}

/// An engine at `net`'s size that shows every op to `run_observed` ([`Memory::Whole`]).
fn whole_engine<'a>(
    blob: &'a [u8],
    net: &Net,
    arena: &'a mut [u8],
) -> Result<Engine<'a>, CheckError> {
    Ok(Engine::with_memory(
        blob,
        arena,
        net.height,
        net.width,
        Memory::Whole,
    )?)
}

/// The op count, after checking that the blob's ops line up one to one with `net`'s.
fn ops_line_up(engine: &Engine<'_>, net: &Net) -> Result<usize, CheckError> {
    let n_ops = engine.graph().ops.len();
    if n_ops != net.ops.len() {
        return Err(CheckError::OpCount {
            blob: n_ops,
            net: net.ops.len(),
        });
    }
    Ok(n_ops)
}

/// Runs `blob` in the core engine and `net` in f32 on every frame and compares them.
pub fn compare(blob: &[u8], net: &Net, frames: &[Frame]) -> Result<Comparison, CheckError> {
    let mut arena = arena_for(blob, net)?;
    let mut engine = whole_engine(blob, net, &mut arena)?;
    let n_ops = ops_line_up(&engine, net)?;
    let mut sig = vec![0f64; n_ops];
    let mut noise = vec![0f64; n_ops];
    let mut max_err = vec![0f32; n_ops];
    let mut cmp = Comparison {
        depth_db: Vec::new(),
        depth_centred_db: Vec::new(),
        depth_power: Vec::new(),
        depth_max_abs_m: Vec::new(),
        layers: Vec::new(),
    };
    let mut out = vec![0f32; net.height * net.width];
    for f in frames {
        let reference = net.run_f32(&f.rgb_planar(), &f.sparse_m)?;
        let mut observer = |i: usize, o: Observed<'_>| {
            let Some(r) = net.ops.get(i).and_then(|op| reference.get(op.output)) else {
                return;
            };
            let mut acc = |a: f32, b: f32| {
                let e = (a - b).abs();
                sig[i] += (a as f64).powi(2);
                noise[i] += (e as f64).powi(2);
                max_err[i] = max_err[i].max(e);
            };
            match o {
                Observed::I8(q, p) => r.iter().zip(q).for_each(|(&a, &c)| acc(a, p.dequantize(c))),
                Observed::I16(q, p) => r
                    .iter()
                    .zip(q)
                    .for_each(|(&a, &c)| acc(a, p.dequantize_code(c.into()))),
                Observed::F32(v) => r.iter().zip(v).for_each(|(&a, &b)| acc(a, b)),
            }
        };
        engine.run_observed(&f.rgb, &f.sparse_m, &mut out, &mut observer)?;
        let d = &reference[net.output];
        let m = d.iter().map(|&v| v as f64).sum::<f64>() / d.len().max(1) as f64;
        let (s, n) = power(d, &out, 0.0);
        let (sc, _) = power(d, &out, m);
        cmp.depth_db.push(ratio_db(s, n));
        cmp.depth_power.push((s, n));
        cmp.depth_centred_db.push(ratio_db(sc, n));
        cmp.depth_max_abs_m.push(
            d.iter()
                .zip(&out)
                .fold(0f32, |a, (&x, &y)| a.max((x - y).abs())),
        );
    }
    cmp.layers = (0..n_ops)
        .map(|i| LayerSqnr {
            op: i,
            name: net.values[net.ops[i].output].name.clone(),
            sqnr_db: ratio_db(sig[i], noise[i]),
            max_abs_err: max_err[i],
        })
        .collect();
    Ok(cmp)
}

/// How closely one int8 op follows its own model: the f32 op run on the engine's dequantised
/// inputs, rounded to the op's output parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct OpFidelity {
    /// Op index (= blob op index).
    pub op: usize,
    /// Output value name.
    pub name: String,
    /// Mean |engine code − model code| over all elements and frames.
    pub mean_abs_codes: f64,
    /// Largest |engine code − model code|.
    pub max_abs_codes: i32,
}

/// For every int8 (and int16) op of `blob`: how far the engine's codes are from the f32 op applied to the
/// codes the engine fed it (the rgb and sparse inputs quantised as the engine quantises them).
/// Weight rounding and accumulation order leave a few hundredths of a code; a kernel that
/// rounds twice or drifts from its float definition shows up as tenths.
pub fn op_fidelity(
    blob: &[u8],
    net: &Net,
    frames: &[Frame],
) -> Result<Vec<OpFidelity>, CheckError> {
    let mut arena = arena_for(blob, net)?;
    let mut engine = whole_engine(blob, net, &mut arena)?;
    let n_ops = ops_line_up(&engine, net)?;
    let tensors = &engine.graph().tensors;
    let sparse_q = tensors[engine.graph().sparse as usize].q;
    let scale_of = |v: usize| tensors.get(v).map_or(1.0, |t| t.q.scale);
    let model_net = with_blob_weights(net, scale_of);
    let net = &model_net;
    let mut sum = vec![0f64; n_ops];
    let mut count = vec![0u64; n_ops];
    let mut max = vec![0i32; n_ops];
    let mut depth = vec![0f32; net.height * net.width];
    for f in frames {
        let sparse: Vec<f32> = f
            .sparse_m
            .iter()
            .map(|&v| sparse_q.dequantize(sparse_q.quantize(v)))
            .collect();
        let mut vals: Vec<Vec<f32>> = vec![f.rgb_planar(), sparse];
        // Codes (as i32), parameters and whether they are int16.
        let mut codes: Vec<Option<(Vec<i32>, QParams, bool)>> = vec![None, None];
        engine.run_observed(&f.rgb, &f.sparse_m, &mut depth, &mut |_, o| match o {
            Observed::I8(q, p) => {
                vals.push(q.iter().map(|&c| p.dequantize(c)).collect());
                codes.push(Some((q.iter().map(|&c| c.into()).collect(), p, false)));
            }
            Observed::I16(q, p) => {
                vals.push(q.iter().map(|&c| p.dequantize_code(c.into())).collect());
                codes.push(Some((q.iter().map(|&c| c.into()).collect(), p, true)));
            }
            Observed::F32(v) => {
                vals.push(v.to_vec());
                codes.push(None);
            }
        })?;
        for (k, op) in net.ops.iter().enumerate() {
            let Some((q, p, wide)) = &codes[op.output] else {
                continue;
            };
            let model = net
                .eval(op, &vals)
                .map_err(|error| super::net::RunError::Kernel {
                    op: k,
                    name: net.values[op.output].name.clone(),
                    error,
                })?;
            for (&m, &c) in model.iter().zip(q) {
                let code = if *wide {
                    p.quantize_i16(m).into()
                } else {
                    i32::from(p.quantize(m))
                };
                let d = (code - c).abs();
                sum[k] += d as f64;
                count[k] += 1;
                max[k] = max[k].max(d);
            }
        }
    }
    Ok((0..n_ops)
        .filter(|&k| count[k] > 0)
        .map(|k| OpFidelity {
            op: k,
            name: net.values[net.ops[k].output].name.clone(),
            mean_abs_codes: sum[k] / count[k] as f64,
            max_abs_codes: max[k],
        })
        .collect())
}

/// `net` with every conv's weights and bias replaced by the values the blob stores (weights
/// rounded per output channel, bias in units of input × weight scale; `input_scale(value)` gives
/// a value's activation scale).
fn with_blob_weights(net: &Net, input_scale: impl Fn(usize) -> f32) -> Net {
    let mut out = net.clone();
    for op in out.ops.iter_mut() {
        let s_in = input_scale(op.inputs[0]);
        if let OpKind::Conv { weight, bias, .. } = &mut op.kind {
            let (wq, bq, sc) = quantize_channels(weight, bias, bias.len(), s_in);
            let per = weight.len() / bias.len().max(1);
            for (i, w) in weight.iter_mut().enumerate() {
                *w = wq[i] as f32 * sc[i / per.max(1)];
            }
            for (o, b) in bias.iter_mut().enumerate() {
                *b = (bq[o] as f64 * s_in as f64 * sc[o] as f64) as f32;
            }
        }
    }
    out
}

/// Max |f32 run − golden| for every golden tensor the folded network still has (inputs taken
/// from the golden set; intermediates fused away by folding are skipped). `(name, max abs)`,
/// output first.
pub fn golden_diff(
    net: &Net,
    golden: &HashMap<String, GoldenTensor>,
) -> Result<Vec<(String, f32)>, GoldenCheckError> {
    let get = |n: &str| {
        golden
            .get(n)
            .ok_or(GoldenCheckError::Missing(n.to_string()))
    };
    let vals = net.run_f32(&get("rgb")?.data, &get("sparse")?.data)?;
    let mut out = Vec::new();
    let mut names: Vec<&String> = golden.keys().collect();
    names.sort_by_key(|n| (golden[*n].role != "output", n.as_str()));
    for name in names {
        let g = &golden[name];
        if g.role == "input" {
            continue;
        }
        if let Some(v) = net.value(name) {
            if vals[v].len() != g.data.len() {
                return Err(GoldenCheckError::Shape(name.clone()));
            }
            let d = vals[v]
                .iter()
                .zip(&g.data)
                .fold(0f32, |a, (&x, &y)| a.max((x - y).abs()));
            out.push((name.clone(), d));
        }
    }
    Ok(out)
}

/// Why [`golden_diff`] failed.
#[derive(Debug, thiserror::Error)]
pub enum GoldenCheckError {
    /// The golden set lacks an input.
    #[error("golden set has no {0:?}")]
    Missing(String),
    /// A golden tensor's size differs from the network's value.
    #[error("golden {0:?} has another size than the network's value")]
    Shape(String),
    /// The float run failed.
    #[error("float network: {0}")]
    Float(#[from] super::net::RunError),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sqnr_by_hand() {
        // Signal power 3² + 4² = 25, noise 0.5² = 0.25 → ratio 100 → 20 dB.
        assert!((sqnr_db(&[3.0, 4.0], &[3.5, 4.0]) - 20.0).abs() < 1e-9);
        assert_eq!(sqnr_db(&[1.0], &[1.0]), f64::INFINITY);
        // Centred: mean 3.5, Σ(r − 3.5)² = 0.5, noise 0.25 → 10·log10(2).
        let (s, n) = power(&[3.0, 4.0], &[3.5, 4.0], 3.5);
        assert!((ratio_db(s, n) - 10.0 * 2f64.log10()).abs() < 1e-9);
    }
}
