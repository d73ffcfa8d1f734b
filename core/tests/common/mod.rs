//! Test helpers: a tiny float network in the blob's op vocabulary, and a calibration-based
//! quantizer turning it into a blob (a miniature of the host quantizer: min/max ranges, plain
//! per-channel rounding) written through the one blob writer, `host/src/quantize/blob_format.rs`,
//! included here by path. The core's tests cannot depend on `depthor-host` (it depends on
//! `depthor-core`), and the core itself never allocates, so the writer lives with the host.
#![allow(dead_code)]

#[path = "../../../host/src/quantize/blob_format.rs"]
mod blob_format;

pub use blob_format::BlobWriter;
use blob_format::{bins_head_attrs, conv_attrs, pixel_shuffle_attrs, refine_attrs, upsample_attrs};
use depthor_core::blob::checksum::crc32;
use depthor_core::blob::format::{dtype, opcode, upsample_mode, HEADER_LEN, NONE};
use depthor_core::kernels::bins::BinsAttrs;
use depthor_core::kernels::conv::{Activation, ConvGeometry};
use depthor_core::kernels::elementwise::build_lut;
use depthor_core::kernels::float::{self, Broadcast};
use depthor_core::kernels::refine::{Neighbourhood, RefineAttrs};
use depthor_core::kernels::requant::QParams;
use depthor_core::kernels::resize::upsample_bilinear_f32;
use depthor_core::kernels::Shape;

/// Re-computes the header CRC after a test mutated the payload.
pub fn fix_crc(blob: &mut [u8]) {
    if blob.len() < HEADER_LEN {
        return;
    }
    let len = u32::from_le_bytes([blob[8], blob[9], blob[10], blob[11]]) as usize;
    let end = (HEADER_LEN + len).min(blob.len());
    let c = crc32(&blob[HEADER_LEN..end]);
    blob[12..16].copy_from_slice(&c.to_le_bytes());
}

/// One op of the float test network (blob vocabulary, f32 weights).
#[derive(Clone, Debug)]
pub enum Op {
    Conv {
        x: usize,
        out_c: usize,
        g: ConvGeometry,
        act: Activation,
        w: Vec<f32>,
        b: Vec<f32>,
        linear: bool,
    },
    Sigmoid(usize),
    Reciprocal(usize, f32),
    Add(usize, usize),
    Mul(usize, usize),
    Concat(Vec<usize>),
    UpsampleLike(usize, usize),
    UpsampleScale(usize, usize),
    PixelShuffle(usize, usize),
    Gap(usize),
    Gmp(usize),
    ChanMean(usize),
    ChanMax(usize),
    MinMax(usize, f32),
    Bins {
        f: usize,
        logits: usize,
        attrs: BinsAttrs,
        w: Vec<f32>,
        b: Vec<f32>,
    },
    Refine {
        ins: [usize; 6],
        attrs: RefineAttrs,
    },
}

/// A float network: value 0 = rgb `[3,H,W]`, 1 = sparse `[1,H,W]`, op k produces value k + 2.
pub struct Net {
    pub h: usize,
    pub w: usize,
    pub ops: Vec<Op>,
}

pub struct Lcg(pub u64);
impl Lcg {
    pub fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

impl Net {
    fn push(&mut self, op: Op) -> usize {
        self.ops.push(op);
        self.ops.len() + 1
    }
    pub fn conv(
        &mut self,
        rng: &mut Lcg,
        x: usize,
        in_c: usize,
        out_c: usize,
        g: ConvGeometry,
        act: Activation,
    ) -> usize {
        let n = g.weight_len(in_c, out_c).unwrap();
        let fan = n / out_c;
        let k = 1.7 / (fan as f32).sqrt();
        let w = (0..n).map(|_| rng.next() * k).collect();
        let b = (0..out_c).map(|_| rng.next() * 0.1).collect();
        self.push(Op::Conv {
            x,
            out_c,
            g,
            act,
            w,
            b,
            linear: false,
        })
    }
    pub fn add_op(&mut self, op: Op) -> usize {
        self.push(op)
    }

    /// Runs in f32; returns every value with its shape.
    pub fn run_float(&self, rgb: &[f32], sparse: &[f32]) -> Vec<(Shape, Vec<f32>)> {
        let (h, w) = (self.h, self.w);
        let mut v: Vec<(Shape, Vec<f32>)> = vec![
            (Shape::new(3, h, w), rgb.to_vec()),
            (Shape::new(1, h, w), sparse.to_vec()),
        ];
        for op in &self.ops {
            let r = match op {
                Op::Conv {
                    x,
                    out_c,
                    g,
                    act,
                    w: wt,
                    b,
                    ..
                } => {
                    let (s, d) = &v[*x];
                    let os = g.output_shape(*s, *out_c).unwrap();
                    let mut o = vec![0.0; os.len().unwrap()];
                    float::conv2d(g, d, *s, wt, Some(b), *act, &mut o, os).unwrap();
                    (os, o)
                }
                Op::Sigmoid(x) => (
                    v[*x].0,
                    v[*x].1.iter().map(|&a| float::sigmoid(a)).collect(),
                ),
                Op::Reciprocal(x, eps) => (
                    v[*x].0,
                    v[*x]
                        .1
                        .iter()
                        .map(|&a| float::reciprocal(a, *eps))
                        .collect(),
                ),
                Op::Add(a, b) => {
                    let mut o = vec![0.0; v[*a].1.len()];
                    float::add(&v[*a].1, &v[*b].1, &mut o).unwrap();
                    (v[*a].0, o)
                }
                Op::Mul(a, b) => {
                    let (sa, sb) = (v[*a].0, v[*b].0);
                    let bc = if sb == sa {
                        Broadcast::None
                    } else if sb.c == 1 {
                        Broadcast::OverChannels
                    } else {
                        Broadcast::OverSpace
                    };
                    let mut o = vec![0.0; v[*a].1.len()];
                    float::mul(&v[*a].1, sa, &v[*b].1, bc, &mut o).unwrap();
                    (sa, o)
                }
                Op::Concat(xs) => {
                    let s0 = v[xs[0]].0;
                    let c = xs.iter().map(|&i| v[i].0.c).sum();
                    (
                        Shape::new(c, s0.h, s0.w),
                        xs.iter().flat_map(|&i| v[i].1.clone()).collect(),
                    )
                }
                Op::UpsampleLike(x, like) | Op::UpsampleScale(x, like) => {
                    let s = v[*x].0;
                    let os = match op {
                        Op::UpsampleLike(..) => Shape::new(s.c, v[*like].0.h, v[*like].0.w),
                        _ => Shape::new(s.c, s.h * like, s.w * like),
                    };
                    let mut o = vec![0.0; os.len().unwrap()];
                    upsample_bilinear_f32(&v[*x].1, s, &mut o, os).unwrap();
                    (os, o)
                }
                Op::PixelShuffle(x, r) => {
                    let s = v[*x].0;
                    let mut o = vec![0.0; s.len().unwrap()];
                    let os = float::pixel_shuffle(&v[*x].1, s, *r, &mut o).unwrap();
                    (os, o)
                }
                Op::Gap(x) | Op::Gmp(x) => {
                    let s = v[*x].0;
                    let mut o = vec![0.0; s.c];
                    if matches!(op, Op::Gap(_)) {
                        float::global_avg_pool(&v[*x].1, s, &mut o).unwrap();
                    } else {
                        float::global_max_pool(&v[*x].1, s, &mut o).unwrap();
                    }
                    (Shape::new(s.c, 1, 1), o)
                }
                Op::ChanMean(x) | Op::ChanMax(x) => {
                    let s = v[*x].0;
                    let mut o = vec![0.0; s.h * s.w];
                    if matches!(op, Op::ChanMean(_)) {
                        float::channel_mean(&v[*x].1, s, &mut o).unwrap();
                    } else {
                        float::channel_max(&v[*x].1, s, &mut o).unwrap();
                    }
                    (Shape::new(1, s.h, s.w), o)
                }
                Op::MinMax(x, eps) => {
                    let mut o = vec![0.0; v[*x].1.len()];
                    float::minmax_norm(&v[*x].1, *eps, &mut o).unwrap();
                    (v[*x].0, o)
                }
                Op::Bins {
                    f,
                    logits,
                    attrs,
                    w: wt,
                    b,
                } => {
                    let s = v[*f].0;
                    let mut o = vec![0.0; s.h * s.w];
                    float::bins_head(&v[*f].1, s, &v[*logits].1, wt, b, attrs, &mut o).unwrap();
                    (Shape::new(1, s.h, s.w), o)
                }
                Op::Refine { ins, attrs } => {
                    let s = v[ins[0]].0;
                    let p = s.h * s.w;
                    let mut o = vec![0.0; p];
                    let mut scratch =
                        vec![
                            0.0;
                            depthor_core::kernels::refine::scratch_len(s.w, attrs.iterations)
                        ];
                    float::refine(
                        &v[ins[0]].1,
                        s.h,
                        s.w,
                        [&v[ins[1]].1, &v[ins[2]].1, &v[ins[3]].1],
                        &v[ins[4]].1,
                        &v[ins[5]].1,
                        attrs,
                        &mut o,
                        &mut scratch,
                    )
                    .unwrap();
                    (Shape::new(1, s.h, s.w), o)
                }
            };
            v.push(r);
        }
        v
    }

    /// Which values are f32 in the blob (depth maps).
    fn is_f32(&self, id: usize) -> bool {
        if id < 2 {
            return false;
        }
        match &self.ops[id - 2] {
            Op::Bins { .. } | Op::Refine { .. } => true,
            Op::UpsampleLike(x, _) | Op::UpsampleScale(x, _) | Op::PixelShuffle(x, _) => {
                self.is_f32(*x)
            }
            _ => false,
        }
    }

    /// Quantises with activation ranges calibrated on `calib` (the float run's values) and
    /// writes the blob. Ops whose int8 output must share the input's parameters get them.
    pub fn to_blob(&self, calib: &[(Shape, Vec<f32>)]) -> Vec<u8> {
        let mut bw = BlobWriter::new(self.h as u16, self.w as u16);
        let mut qs: Vec<QParams> = Vec::new();
        for (id, (s, d)) in calib.iter().enumerate() {
            let shared = if id >= 2 {
                match &self.ops[id - 2] {
                    Op::UpsampleLike(x, _) | Op::UpsampleScale(x, _) | Op::PixelShuffle(x, _) => {
                        Some(qs[*x])
                    }
                    _ => None,
                }
            } else {
                None
            };
            let q = match (id, shared) {
                (0, _) => QParams {
                    scale: 1.0 / 255.0,
                    zero_point: -128,
                },
                (1, _) => QParams {
                    scale: 10.0 / 255.0,
                    zero_point: -128,
                },
                (_, Some(q)) => q,
                _ => {
                    let lo = d.iter().fold(0f32, |m, &x| m.min(x));
                    let hi = d.iter().fold(0f32, |m, &x| m.max(x));
                    let scale = ((hi - lo) / 255.0).max(1e-6);
                    let zero_point = (-128.0 - lo / scale).round().clamp(-128.0, 127.0) as i32;
                    QParams { scale, zero_point }
                }
            };
            qs.push(q);
            let dt = if self.is_f32(id) {
                dtype::F32
            } else {
                dtype::I8
            };
            bw.tensor(dt, s.c as u16, q);
        }
        let n = calib.len();
        bw.io(0, 1, (n - 1) as u16);
        for (k, op) in self.ops.iter().enumerate() {
            let out = (k + 2) as u16;
            match op {
                Op::Conv {
                    x,
                    out_c,
                    g,
                    act,
                    w,
                    b,
                    linear,
                } => {
                    let (wq, bias, scales) =
                        quantize_rows(w, b, *out_c, w.len() / out_c, qs[*x].scale);
                    let a = conv_attrs(g, *act, bw.weights(&wq, &bias, &scales));
                    bw.op(
                        if *linear {
                            opcode::LINEAR
                        } else {
                            opcode::CONV2D
                        },
                        &[*x as u16],
                        out,
                        &a,
                    );
                }
                Op::Sigmoid(x) => {
                    let t = build_lut(qs[*x], qs[k + 2], float::sigmoid);
                    bw.op(opcode::SIGMOID, &[*x as u16], out, &t.map(|v| v as u8));
                }
                Op::Reciprocal(x, eps) => {
                    let e = *eps;
                    let t = build_lut(qs[*x], qs[k + 2], move |v| float::reciprocal(v, e));
                    bw.op(opcode::RECIPROCAL, &[*x as u16], out, &t.map(|v| v as u8));
                }
                Op::Add(a, b) => bw.op(opcode::ADD, &[*a as u16, *b as u16], out, &[]),
                Op::Mul(a, b) => bw.op(opcode::MUL, &[*a as u16, *b as u16], out, &[]),
                Op::Concat(xs) => bw.op(
                    opcode::CONCAT,
                    &xs.iter().map(|&v| v as u16).collect::<Vec<_>>(),
                    out,
                    &[],
                ),
                Op::UpsampleLike(x, like) => {
                    let a = upsample_attrs(upsample_mode::LIKE, *like as u16, 0);
                    bw.op(opcode::UPSAMPLE_BILINEAR, &[*x as u16], out, &a);
                }
                Op::UpsampleScale(x, f) => {
                    let a = upsample_attrs(upsample_mode::SCALE, *f as u16, *f as u16);
                    bw.op(opcode::UPSAMPLE_BILINEAR, &[*x as u16], out, &a);
                }
                Op::PixelShuffle(x, r) => bw.op(
                    opcode::PIXEL_SHUFFLE,
                    &[*x as u16],
                    out,
                    &pixel_shuffle_attrs(*r as u16),
                ),
                Op::Gap(x) => bw.op(opcode::GLOBAL_AVG_POOL, &[*x as u16], out, &[]),
                Op::Gmp(x) => bw.op(opcode::GLOBAL_MAX_POOL, &[*x as u16], out, &[]),
                Op::ChanMean(x) => bw.op(opcode::CHANNEL_MEAN, &[*x as u16], out, &[]),
                Op::ChanMax(x) => bw.op(opcode::CHANNEL_MAX, &[*x as u16], out, &[]),
                Op::MinMax(x, eps) => {
                    bw.op(opcode::MINMAX_NORM, &[*x as u16], out, &eps.to_le_bytes())
                }
                Op::Bins {
                    f,
                    logits,
                    attrs,
                    w,
                    b,
                } => {
                    let (wq, bias, scales) =
                        quantize_rows(w, b, attrs.n_bins, calib[*f].0.c, qs[*f].scale);
                    let refs = bw.weights(&wq, &bias, &scales);
                    let a = bins_head_attrs(
                        attrs.n_bins as u16,
                        attrs.min_depth,
                        attrs.max_depth,
                        refs,
                    );
                    bw.op(opcode::BINS_HEAD, &[*f as u16, *logits as u16], out, &a);
                }
                Op::Refine { ins, attrs } => {
                    let nb = attrs.neighbourhood.code();
                    let a = refine_attrs(attrs.iterations as u16, nb, attrs.sigma);
                    bw.op(opcode::REFINE, &ins.map(|v| v as u16), out, &a);
                }
            }
        }
        let _ = NONE;
        bw.finish()
    }
}

/// Symmetric per-row int8 weights of `rows` rows of `per` values of `w` (scale `max|w|/127`, at
/// least 1e-8/127) and the int32 bias in units of `s_in · scale`: `(weights, bias, scales)`.
fn quantize_rows(
    w: &[f32],
    b: &[f32],
    rows: usize,
    per: usize,
    s_in: f32,
) -> (Vec<i8>, Vec<i32>, Vec<f32>) {
    let mut wq = Vec::new();
    let mut scales = Vec::new();
    let mut bias = Vec::new();
    for o in 0..rows {
        let row = &w[o * per..(o + 1) * per];
        let s = row.iter().fold(0f32, |a, &v| a.max(v.abs())).max(1e-8) / 127.0;
        scales.push(s);
        wq.extend(row.iter().map(|&v| (v / s).round() as i8));
        bias.push((b[o] / (s_in * s)).round() as i32);
    }
    (wq, bias, scales)
}

/// The test network at `h × w` (both divisible by 2): every op of the blob vocabulary appears.
pub fn tiny_net(h: usize, w: usize) -> Net {
    tiny_net_with(h, w, Neighbourhood::Window)
}

/// [`tiny_net`] with the refinement's neighbourhood `hood`.
pub fn tiny_net_with(h: usize, w: usize, hood: Neighbourhood) -> Net {
    net_of(h, w, hood, Widths::TEST)
}

/// Channel counts of the test network's layers.
#[derive(Clone, Copy)]
pub struct Widths {
    /// Feature channels of the encoder and of the attention output.
    pub feat: usize,
    /// Hidden channels of the channel attention's two MLPs.
    pub mid: usize,
    /// Hidden channels of the bin logits' first linear layer.
    pub hidden: usize,
    /// Depth bins.
    pub bins: usize,
    /// Guidance channels after the pixel shuffle (the 1×1 conv makes 4× as many).
    pub guide: usize,
}

impl Widths {
    /// The test network's (`tiny_net`).
    pub const TEST: Widths = Widths {
        feat: 8,
        mid: 4,
        hidden: 16,
        bins: 16,
        guide: 4,
    };
    /// Few channels, every op kept, one full group of four and odd counts: the fuzz targets'
    /// cheap network (`core/fuzz/seeds/micro_net.dblob`).
    pub const MICRO: Widths = Widths {
        feat: 4,
        mid: 2,
        hidden: 4,
        bins: 4,
        guide: 1,
    };
}

/// The test network's graph at `h × w` with the channel counts `c`.
pub fn net_of(h: usize, w: usize, hood: Neighbourhood, c: Widths) -> Net {
    let mut rng = Lcg(7);
    let mut n = Net {
        h,
        w,
        ops: Vec::new(),
    };
    let p3 = |c| {
        ConvGeometry {
            kernel: [3, 3],
            padding: [1, 1],
            ..ConvGeometry::POINTWISE
        }
        .with_groups(c)
    };
    let f = c.feat;
    let t2 = n.conv(&mut rng, 0, 3, f, p3(1), Activation::LeakyRelu(0.1));
    let u1 = n.add_op(Op::ChanMean(t2));
    let u2 = n.add_op(Op::MinMax(u1, 1e-6));
    let u3 = n.add_op(Op::Reciprocal(u2, 0.5));
    let t3 = n.add_op(Op::Concat(vec![t2, u3, 1]));
    let s2 = ConvGeometry {
        kernel: [3, 3],
        stride: [2, 2],
        padding: [1, 1],
        ..ConvGeometry::POINTWISE
    };
    let t4 = n.conv(&mut rng, t3, f + 2, f, s2, Activation::Relu);
    let dw = n.conv(&mut rng, t4, f, f, p3(f), Activation::None); // depthwise
    let t4 = n.add_op(Op::Add(t4, dw));
    // CBAM: channel attention …
    let gap = n.add_op(Op::Gap(t4));
    let gmp = n.add_op(Op::Gmp(t4));
    let pw = ConvGeometry::POINTWISE;
    let ma = n.conv(&mut rng, gap, f, c.mid, pw, Activation::Relu);
    let ma = n.conv(&mut rng, ma, c.mid, f, pw, Activation::None);
    let mb = n.conv(&mut rng, gmp, f, c.mid, pw, Activation::Relu);
    let mb = n.conv(&mut rng, mb, c.mid, f, pw, Activation::None);
    let att = n.add_op(Op::Add(ma, mb));
    let att = n.add_op(Op::Sigmoid(att));
    let t11 = n.add_op(Op::Mul(t4, att));
    // … spatial attention.
    let cm = n.add_op(Op::ChanMean(t11));
    let cx = n.add_op(Op::ChanMax(t11));
    let cc = n.add_op(Op::Concat(vec![cm, cx]));
    let g7 = ConvGeometry {
        kernel: [7, 7],
        padding: [3, 3],
        ..ConvGeometry::POINTWISE
    };
    let sa = n.conv(&mut rng, cc, 2, 1, g7, Activation::None);
    let sa = n.add_op(Op::Sigmoid(sa));
    let t17 = n.add_op(Op::Mul(t11, sa));
    // Bin logits: pooled → linear → linear.
    let pooled = n.add_op(Op::Gap(t17));
    let nb = c.bins;
    let l1 = n.conv(&mut rng, pooled, f, c.hidden, pw, Activation::Relu);
    if let Some(Op::Conv { linear, .. }) = n.ops.last_mut() {
        *linear = true;
    }
    let logits = n.conv(&mut rng, l1, c.hidden, nb, pw, Activation::None);
    if let Some(Op::Conv { linear, .. }) = n.ops.last_mut() {
        *linear = true;
    }
    let attrs = BinsAttrs {
        n_bins: nb,
        min_depth: 0.1,
        max_depth: 10.0,
    };
    let bw: Vec<f32> = (0..nb * f).map(|_| rng.next() * 6.0).collect();
    let bb: Vec<f32> = (0..nb).map(|_| rng.next() * 0.2).collect();
    let d_half = n.add_op(Op::Bins {
        f: t17,
        logits,
        attrs,
        w: bw,
        b: bb,
    });
    let d0 = n.add_op(Op::UpsampleLike(d_half, 0));
    // Guidance: 1×1 conv → pixel_shuffle(2), concat with upsampled features.
    let gf = n.conv(
        &mut rng,
        t17,
        f,
        4 * c.guide,
        pw,
        Activation::LeakyRelu(0.1),
    );
    let gf = n.add_op(Op::PixelShuffle(gf, 2));
    let up = n.add_op(Op::UpsampleScale(t11, 2));
    let gcat = n.add_op(Op::Concat(vec![gf, up]));
    let gc = c.guide + f;
    let g3 = ConvGeometry {
        kernel: [3, 3],
        padding: [1, 1],
        ..ConvGeometry::POINTWISE
    };
    let a3 = n.conv(&mut rng, gcat, gc, hood.neighbours(3), g3, Activation::None);
    let a5 = n.conv(&mut rng, gcat, gc, hood.neighbours(5), g3, Activation::None);
    let a7 = n.conv(&mut rng, gcat, gc, hood.neighbours(7), g3, Activation::None);
    let km = n.conv(&mut rng, gcat, gc, 3, g3, Activation::None);
    let tm = n.conv(&mut rng, gcat, gc, 3, g3, Activation::None);
    n.add_op(Op::Refine {
        ins: [d0, a3, a5, a7, km, tm],
        attrs: RefineAttrs {
            iterations: 4,
            sigma: [1.0, 1.5, 2.0],
            neighbourhood: hood,
        },
    });
    n
}

trait WithGroups {
    fn with_groups(self, g: usize) -> Self;
}
impl WithGroups for ConvGeometry {
    fn with_groups(mut self, g: usize) -> Self {
        self.groups = g;
        self
    }
}

/// A deterministic test frame: RGB888 interleaved and sparse metres.
pub fn frame(h: usize, w: usize) -> (Vec<u8>, Vec<f32>) {
    let mut rgb = Vec::with_capacity(h * w * 3);
    let mut sparse = vec![0f32; h * w];
    for y in 0..h {
        for x in 0..w {
            rgb.push((x * 255 / w.max(1)) as u8);
            rgb.push((y * 255 / h.max(1)) as u8);
            rgb.push((((x + y) * 37) % 256) as u8);
            if y % 4 == 1 && x % 4 == 2 {
                sparse[y * w + x] = 1.0 + 4.0 * (x as f32 / w as f32) + (y as f32 / h as f32);
            }
        }
    }
    (rgb, sparse)
}

/// rgb bytes as the float network's `[3,H,W]` input in [0, 1].
pub fn rgb_planar(rgb: &[u8], h: usize, w: usize) -> Vec<f32> {
    let mut v = vec![0f32; 3 * h * w];
    for i in 0..h * w {
        for c in 0..3 {
            v[c * h * w + i] = rgb[3 * i + c] as f32 / 255.0;
        }
    }
    v
}

/// Signal-to-quantisation-noise ratio in dB.
pub fn sqnr_db(reference: &[f32], test: &[f32]) -> f64 {
    let s: f64 = reference.iter().map(|&v| (v as f64).powi(2)).sum();
    let n: f64 = reference
        .iter()
        .zip(test)
        .map(|(&a, &b)| (a as f64 - b as f64).powi(2))
        .sum();
    10.0 * (s / n.max(1e-30)).log10()
}
