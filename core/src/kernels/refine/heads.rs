//! [`ConvRows`]: the refinement's affinities computed row by row by their own int8 convolution
//! heads into a ring of [`super::ring_rows`] rows, so that no affinity map is stored whole;
//! [`MixConvRows`]: the same for the kmix and tmix heads, in rings of [`mix_ring_rows`] rows
//! (module doc of [`super`], "Streaming").

use super::{mix_ring_rows, ring_bytes, ring_rows, AffinityRows, I8Map, MixRows, RefineAttrs};
use crate::kernels::conv::{conv2d_rows_packed, Conv2d, OutRows};
use crate::kernels::isa::Isa;
use crate::kernels::requant::QParams;
use crate::kernels::{KernelError, Shape};

/// One branch's affinity head: the convolution, its input and its output quantisation.
#[derive(Clone, Copy, Debug)]
pub struct Head<'a> {
    /// The head (stride 1, output one channel per neighbour at the refinement's size).
    pub conv: Conv2d<'a>,
    /// Its int8 input.
    pub input: &'a [i8],
    /// Shape of `input`.
    pub in_shape: Shape,
    /// Quantisation of its output codes.
    pub out_q: QParams,
}

impl Head<'_> {
    /// Output row `y` into `ring` at its slot (channels `stride` apart), with the weights
    /// `scratch` already holds packed where `packed`.
    fn row(
        &self,
        isa: Isa,
        y: usize,
        stride: usize,
        ring: &mut [i8],
        scratch: &mut [i32],
        packed: bool,
    ) -> Result<(), KernelError> {
        let dst = OutRows {
            rows: y..y + 1,
            stride,
        };
        let (input, shape) = (self.input, self.in_shape);
        conv2d_rows_packed(isa, &self.conv, input, shape, &dst, ring, scratch, packed)?;
        Ok(())
    }

    /// `Err(Shape)` unless the head's output is `out`; `Err(Scratch)` unless `scratch` i32 hold
    /// its conv scratch.
    fn check(&self, out: Shape, scratch: usize) -> Result<(), KernelError> {
        if self.conv.check(self.in_shape)? != out {
            return Err(KernelError::Shape);
        }
        if scratch < Conv2d::scratch_len(&self.conv.geometry, self.in_shape, out) {
            return Err(KernelError::Scratch);
        }
        Ok(())
    }
}

/// [`AffinityRows`] that runs each branch's [`Head`] one output row at a time into `ring`.
#[derive(Debug)]
pub struct ConvRows<'a, 'r> {
    isa: Isa,
    heads: [Head<'a>; 3],
    ring: &'r mut [i8],
    scratch: &'r mut [i32],
    h: usize,
    w: usize,
    attrs: RefineAttrs,
    /// The branch whose head's weights `scratch` holds packed.
    packed: Option<usize>,
}

impl<'a, 'r> ConvRows<'a, 'r> {
    /// Heads of kernels 3, 5, 7 for a `h × w` refinement with `attrs`; `ring` holds ≥
    /// [`ring_bytes`] bytes and `scratch` ≥ every head's [`Conv2d::scratch_len`] i32.
    /// `Err(Shape)` where a head's output is not `[neighbours, h, w]` or a buffer is short.
    pub fn new(
        isa: Isa,
        heads: [Head<'a>; 3],
        (h, w): (usize, usize),
        attrs: &RefineAttrs,
        ring: &'r mut [i8],
        scratch: &'r mut [i32],
    ) -> Result<Self, KernelError> {
        if ring.len() < ring_bytes(h, w, attrs) {
            return Err(KernelError::Shape);
        }
        for (k, head) in heads.iter().enumerate() {
            head.check(Shape::new(attrs.neighbours(k), h, w), scratch.len())?;
        }
        Ok(ConvRows {
            isa,
            heads,
            ring,
            scratch,
            h,
            w,
            attrs: *attrs,
            packed: None,
        })
    }

    /// Rows in branch `k`'s ring.
    fn rows(&self, k: usize) -> usize {
        ring_rows(k, self.h, self.attrs.iterations).max(1)
    }
}

impl AffinityRows for ConvRows<'_, '_> {
    type View<'v>
        = I8Map<'v>
    where
        Self: 'v;

    fn compute(&mut self, k: usize, y: usize) -> Result<(), KernelError> {
        let rows = self.rows(k);
        let head = self.heads.get(k).ok_or(KernelError::Shape)?;
        let slot = y % rows;
        let ring = self
            .ring
            .get_mut(slot * self.w..)
            .ok_or(KernelError::Shape)?;
        let packed = self.packed == Some(k);
        head.row(self.isa, y, rows * self.w, ring, self.scratch, packed)?;
        self.packed = Some(k);
        Ok(())
    }

    fn view(&self, k: usize, y: usize) -> Result<(I8Map<'_>, usize), KernelError> {
        let rows = self.rows(k);
        let head = self.heads.get(k).ok_or(KernelError::Shape)?;
        let n = self.attrs.neighbours(k);
        let map = I8Map::new(self.ring, head.out_q, n, rows * self.w)?;
        Ok((map, (y % rows) * self.w))
    }
}

/// [`MixRows`] that runs the kmix and tmix [`Head`]s (3 channels each) one output row at a
/// time into rings of [`mix_ring_rows`] rows, each head with its own conv scratch (its weights
/// stay packed).
#[derive(Debug)]
pub struct MixConvRows<'a, 'r> {
    isa: Isa,
    heads: [Head<'a>; 2],
    rings: [&'r mut [i8]; 2],
    scratch: [&'r mut [i32]; 2],
    w: usize,
    rows: usize,
    packed: [bool; 2],
}

impl<'a, 'r> MixConvRows<'a, 'r> {
    /// Bytes of one head's ring for an `h × w` image and `iterations` steps.
    pub fn ring_bytes(h: usize, w: usize, iterations: usize) -> usize {
        mix_ring_rows(h, iterations)
            .saturating_mul(3)
            .saturating_mul(w)
    }

    /// The kmix and tmix heads of a `h × w` refinement of `iterations` steps; each ring holds
    /// ≥ [`MixConvRows::ring_bytes`] bytes and each scratch ≥ its head's
    /// [`Conv2d::scratch_len`] i32. `Err(Shape)` where a head's output is not `[3, h, w]` or a
    /// buffer is short.
    pub fn new(
        isa: Isa,
        heads: [Head<'a>; 2],
        h: usize,
        w: usize,
        iterations: usize,
        rings: [&'r mut [i8]; 2],
        scratch: [&'r mut [i32]; 2],
    ) -> Result<Self, KernelError> {
        for ((head, ring), scratch) in heads.iter().zip(&rings).zip(&scratch) {
            if ring.len() < Self::ring_bytes(h, w, iterations) {
                return Err(KernelError::Shape);
            }
            head.check(Shape::new(3, h, w), scratch.len())?;
        }
        Ok(MixConvRows {
            isa,
            heads,
            rings,
            scratch,
            w,
            rows: mix_ring_rows(h, iterations),
            packed: [false; 2],
        })
    }
}

impl MixRows for MixConvRows<'_, '_> {
    type View<'v>
        = I8Map<'v>
    where
        Self: 'v;

    fn compute(&mut self, y: usize) -> Result<(), KernelError> {
        let (rows, w) = (self.rows, self.w);
        for m in 0..2 {
            let ring = self.rings[m]
                .get_mut((y % rows) * w..)
                .ok_or(KernelError::Shape)?;
            let scratch = &mut *self.scratch[m];
            self.heads[m].row(self.isa, y, rows * w, ring, scratch, self.packed[m])?;
            self.packed[m] = true;
        }
        Ok(())
    }

    fn view(&self, y: usize) -> Result<(I8Map<'_>, I8Map<'_>, usize), KernelError> {
        let plane = self.rows * self.w;
        let map = |m: usize| I8Map::new(self.rings[m], self.heads[m].out_q, 3, plane);
        Ok((map(0)?, map(1)?, (y % self.rows) * self.w))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::conv::{conv2d_with, Activation, ChannelQuant, ConvGeometry, ConvQuant};
    use crate::kernels::refine::{
        refine_with, scratch_len, Neighbourhood, RefineAttrs, Sources, UpsampledDepth, WholeDepth,
        WholeMaps, WholeMix,
    };
    use crate::kernels::resize::upsample_bilinear_f32;
    use std::vec::Vec;

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 33) as u32
        }
        fn codes(&mut self, n: usize) -> Vec<i8> {
            (0..n).map(|_| self.next() as i8).collect()
        }
    }

    /// Streamed heads (affinities, kmix, tmix) and a row-by-row upsampled `D_0` give the bits
    /// of heads run whole, an upsample run whole, then refined from whole maps, for every
    /// kernel set, 1×1 and 3×3 heads, images taller than a window and T up to 8.
    #[test]
    fn streamed_heads_equal_whole_maps() {
        let mut rng = Rng(99);
        for (h, w, t, k, nb) in [
            (17usize, 21usize, 6usize, 3usize, Neighbourhood::Window),
            (9, 8, 2, 1, Neighbourhood::Window),
            (40, 13, 8, 3, Neighbourhood::Window),
            (5, 30, 4, 1, Neighbourhood::Window),
            (24, 32, 6, 3, Neighbourhood::Window),
            (23, 19, 6, 1, Neighbourhood::Dilated),
            (6, 11, 4, 3, Neighbourhood::Dilated),
        ] {
            let cin = 6;
            let in_shape = Shape::new(cin, h, w);
            let input = rng.codes(cin * h * w);
            let in_q = QParams {
                scale: 0.04,
                zero_point: 3,
            };
            let geometry = ConvGeometry {
                kernel: [k, k],
                stride: [1, 1],
                dilation: [1, 1],
                padding: [k / 2, k / 2],
                groups: 1,
            };
            // Heads 0..3: affinities of kernels 3, 5, 7; 3: kmix; 4: tmix.
            let outs = [nb.neighbours(3), nb.neighbours(5), nb.neighbours(7), 3, 3];
            let mut weights = Vec::new();
            let mut chans = Vec::new();
            let mut qs = Vec::new();
            for (b, &n) in outs.iter().enumerate() {
                weights.push(rng.codes(n * cin * k * k));
                chans.push(
                    (0..n)
                        .map(|o| {
                            ChannelQuant::new(
                                o as i32 * 37 - 300,
                                in_q.scale,
                                0.003,
                                0.05,
                                Activation::None,
                            )
                        })
                        .collect::<Vec<_>>(),
                );
                qs.push(QParams {
                    scale: 0.05 + 0.01 * b as f32,
                    zero_point: -10 + 5 * b as i32,
                });
            }
            let convs: Vec<Conv2d> = (0..5)
                .map(|b| Conv2d {
                    geometry,
                    quant: ConvQuant::new(in_q.zero_point, qs[b].zero_point, Activation::None),
                    weights: &weights[b],
                    channels: &chans[b],
                })
                .collect();
            let half = Shape::new(1, h.div_ceil(2), w.div_ceil(2));
            let small: Vec<f32> = (0..half.plane().unwrap())
                .map(|_| 0.5 + (rng.next() % 1000) as f32 * 0.006)
                .collect();
            let attrs = RefineAttrs {
                iterations: t,
                sigma: [1.0, 1.4, 2.1],
                neighbourhood: nb,
            };
            let conv_scratch_len = (0..5)
                .map(|b| {
                    let out = convs[b].check(in_shape).unwrap();
                    Conv2d::scratch_len(&geometry, in_shape, out)
                })
                .max()
                .unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut scratch = std::vec![0i32; conv_scratch_len];
                let maps: Vec<Vec<i8>> = (0..5)
                    .map(|b| {
                        let out = convs[b].check(in_shape).unwrap();
                        let mut y = std::vec![0i8; out.len().unwrap()];
                        conv2d_with(isa, &convs[b], &input, in_shape, &mut y, &mut scratch)
                            .unwrap();
                        y
                    })
                    .collect();
                let views: Vec<I8Map> = (0..5)
                    .map(|b| I8Map::new(&maps[b], qs[b], outs[b], h * w).unwrap())
                    .collect();
                let mut d0 = std::vec![0f32; h * w];
                upsample_bilinear_f32(&small, half, &mut d0, Shape::new(1, h, w)).unwrap();
                let mut whole = std::vec![0f32; h * w];
                let mut rs = std::vec![0f32; scratch_len(w, t)];
                let sources = Sources {
                    depth: &mut WholeDepth::new(&d0, w),
                    aff: &mut WholeMaps::new([&views[0], &views[1], &views[2]], w),
                    mix: &mut WholeMix::new(&views[3], &views[4], w),
                };
                refine_with(isa, sources, h, w, &attrs, &mut whole, &mut rs).unwrap();

                let head = |b: usize| Head {
                    conv: convs[b],
                    input: &input,
                    in_shape,
                    out_q: qs[b],
                };
                let mut ring = std::vec![0i8; ring_bytes(h, w, &attrs)];
                let mut mix_rings =
                    [0, 1].map(|_| std::vec![0i8; MixConvRows::ring_bytes(h, w, t)]);
                let mut mix_scratch = [0, 1].map(|_| std::vec![0i32; conv_scratch_len]);
                let [r0, r1] = &mut mix_rings;
                let [s0, s1] = &mut mix_scratch;
                let mut streamed = std::vec![0f32; h * w];
                let heads = [head(0), head(1), head(2)];
                let mut rows =
                    ConvRows::new(isa, heads, (h, w), &attrs, &mut ring, &mut scratch).unwrap();
                let mut mix =
                    MixConvRows::new(isa, [head(3), head(4)], h, w, t, [r0, r1], [s0, s1]).unwrap();
                let sources = Sources {
                    depth: &mut UpsampledDepth::new(&small, half, h, w),
                    aff: &mut rows,
                    mix: &mut mix,
                };
                refine_with(isa, sources, h, w, &attrs, &mut streamed, &mut rs).unwrap();
                let same = whole
                    .iter()
                    .zip(&streamed)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(
                    same,
                    "{} {h}x{w} T{t} k{k} {nb:?}: streamed heads differ",
                    isa.name()
                );
            }
        }
    }

    #[test]
    fn short_buffers_are_errors() {
        let w = [0i8; 8 * 2];
        let ch = [ChannelQuant::new(0, 0.1, 0.1, 0.1, Activation::None); 8];
        let geometry = ConvGeometry {
            kernel: [1, 1],
            stride: [1, 1],
            dilation: [1, 1],
            padding: [0, 0],
            groups: 1,
        };
        let conv = Conv2d {
            geometry,
            quant: ConvQuant::new(0, 0, Activation::None),
            weights: &w,
            channels: &ch,
        };
        let input = [0i8; 2 * 4 * 4];
        let head = Head {
            conv,
            input: &input,
            in_shape: Shape::new(2, 4, 4),
            out_q: QParams {
                scale: 0.1,
                zero_point: 0,
            },
        };
        let window = RefineAttrs {
            iterations: 2,
            sigma: [1.0; 3],
            neighbourhood: Neighbourhood::Window,
        };
        let dilated = RefineAttrs {
            neighbourhood: Neighbourhood::Dilated,
            ..window
        };
        let mut ring = std::vec![0i8; ring_bytes(4, 4, &window)];
        let mut scratch = std::vec![0i32; 4096];
        // The 8-channel head cannot stand for the 24- and 48-channel branches.
        let r = ConvRows::new(
            Isa::Portable,
            [head; 3],
            (4, 4),
            &window,
            &mut ring,
            &mut scratch,
        );
        assert_eq!(r.err(), Some(KernelError::Shape));
        // With 8 dilated neighbours per branch it can; the ring then needs fewer bytes.
        let need = ring_bytes(4, 4, &dilated);
        assert!(need < ring.len());
        let r = ConvRows::new(
            Isa::Portable,
            [head; 3],
            (4, 4),
            &dilated,
            &mut ring[..need],
            &mut scratch,
        );
        assert!(r.is_ok());
        let r = ConvRows::new(
            Isa::Portable,
            [head; 3],
            (4, 4),
            &dilated,
            &mut ring[..need - 1],
            &mut scratch,
        );
        assert_eq!(r.err(), Some(KernelError::Shape));
    }
}
