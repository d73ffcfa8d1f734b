//! The ray caster: primary rays per pixel (culled per 16×16 tile against each item's projected
//! bounding sphere), Lambert shading from lamps with hard or soft shadow rays plus an ambient
//! term, one-bounce mirrors, glass that blends a Fresnel reflection with the tinted scene behind
//! it, then auto-exposure, a soft tone curve and sRGB encoding.
use super::layout::World;
use super::material::Class;
use super::math::{v3, V3};
use super::shapes::Hit;
use super::texture::luminance;
use super::SceneFrame;
use depthor_core::calibration::CameraIntrinsics;
use rayon::prelude::*;

const TILE: usize = 16;
const EPS: f32 = 1e-3;

thread_local! {
    /// Per-thread list of the items a shadow ray must test (reused, never shared).
    static SCRATCH: std::cell::RefCell<Vec<u16>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Which items a ray is tested against.
#[derive(Clone, Copy)]
enum Cands<'a> {
    All,
    List(&'a [u16]),
}

struct Tracer<'a> {
    w: &'a World,
    /// Per material: is it glass?
    glass: Vec<bool>,
    /// Items that can cast shadows.
    casters: Vec<u16>,
    fx: f32,
}

/// Per-pixel result before tone mapping.
#[derive(Clone, Copy, Default)]
struct Px {
    rgb: V3,
    depth: f32,
    second: f32,
    refl: f32,
    label: u8,
    normal: [f32; 3],
}

#[inline]
fn hash3(a: u32, b: u32, c: u32) -> u32 {
    let mut h =
        a.wrapping_mul(0x9E37_79B1) ^ b.wrapping_mul(0x85EB_CA77) ^ c.wrapping_mul(0xC2B2_AE3D);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^ (h >> 16)
}

#[inline]
fn unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

impl Tracer<'_> {
    fn nearest(&self, o: V3, d: V3, tmin: f32, cands: Cands<'_>, skip_glass: bool) -> Option<Hit> {
        let w = self.w;
        let mut room = w.room.intersect(o, d, tmin);
        if room.is_none() {
            room = w.outer.as_ref().and_then(|r| r.intersect(o, d, tmin));
        }
        let mut tmax = room.map_or(f32::INFINITY, |h| h.t);
        let mut best: Option<(usize, f32, u8)> = None;
        let mut test = |gi: usize| {
            let g = &w.groups[gi];
            let oc = o - g.bc;
            let a = d.dot(d);
            let b = oc.dot(d);
            let c = oc.dot(oc) - g.br * g.br;
            let disc = b * b - a * c;
            if disc < 0.0 {
                return;
            }
            let s = disc.sqrt();
            if (-b + s) / a <= tmin || (-b - s) / a >= tmax {
                return;
            }
            for i in g.start as usize..g.end as usize {
                let p = &w.prims[i];
                if skip_glass && self.glass[p.mat as usize] {
                    continue;
                }
                if let Some((t, part)) = p.hit(o, d, tmin, tmax) {
                    tmax = t;
                    best = Some((i, t, part));
                }
            }
        };
        match cands {
            Cands::All => (0..w.groups.len()).for_each(&mut test),
            Cands::List(l) => l.iter().for_each(|&g| test(g as usize)),
        }
        match best {
            Some((i, t, part)) => Some(w.prims[i].surface(o, d, t, part)),
            None => room,
        }
    }

    /// Whether the segment `p → p + d` meets group `g`'s bounding sphere grown by `grow`.
    #[inline]
    fn segment_meets(&self, g: usize, p: V3, d: V3, grow: f32) -> bool {
        let g = &self.w.groups[g];
        let oc = p - g.bc;
        let r = g.br + grow;
        let a = d.dot(d);
        let b = oc.dot(d);
        let c = oc.dot(oc) - r * r;
        let disc = b * b - a * c;
        if disc < 0.0 {
            return false;
        }
        let s = disc.sqrt();
        (-b + s) / a > EPS && (-b - s) / a < 1.0
    }

    /// Whether anything opaque in groups `cands` lies on the segment `p → p + d`.
    fn occluded(&self, p: V3, d: V3, cands: &[u16]) -> bool {
        let w = self.w;
        for &gi in cands {
            if !self.segment_meets(gi as usize, p, d, 0.0) {
                continue;
            }
            let g = &w.groups[gi as usize];
            for pr in &w.prims[g.start as usize..g.end as usize] {
                if !self.glass[pr.mat as usize] && pr.hit(p, d, EPS, 1.0 - EPS).is_some() {
                    return true;
                }
            }
        }
        false
    }

    /// Irradiance at `p` with normal `n` (indoor lamps, shadows, ambient).
    fn irradiance(&self, p: V3, n: V3, samples: u32, jitter: u32) -> V3 {
        let w = self.w;
        let e = w.ambient * (0.8 + 0.2 * n.y);
        let p0 = p + n * EPS;
        SCRATCH.with(|c| self.irradiance_into(&mut c.borrow_mut(), p0, n, samples, jitter, e))
    }

    fn irradiance_into(
        &self,
        cands: &mut Vec<u16>,
        p0: V3,
        n: V3,
        samples: u32,
        jitter: u32,
        mut e: V3,
    ) -> V3 {
        let w = self.w;
        for (k, l) in w.lights.iter().enumerate() {
            let to = l.pos - p0;
            let d2 = to.dot(to);
            let cos = n.dot(to) / d2.sqrt();
            if cos <= 0.0 {
                continue;
            }
            // Items that can shadow any point of the lamp: the segment to its centre passes
            // within their sphere grown by the lamp's radius. None → fully lit, no shadow rays.
            let soft = samples > 1 && l.radius > 0.0;
            let grow = if soft { l.radius } else { 0.0 };
            cands.clear();
            cands.extend(
                self.casters
                    .iter()
                    .copied()
                    .filter(|&g| self.segment_meets(g as usize, p0, to, grow)),
            );
            let vis = if cands.is_empty() {
                1.0
            } else if !soft {
                if self.occluded(p0, to, cands) {
                    0.0
                } else {
                    1.0
                }
            } else {
                let ax = to * (1.0 / d2.sqrt());
                let t1 = if ax.x.abs() < 0.9 {
                    v3(1.0, 0.0, 0.0)
                } else {
                    v3(0.0, 1.0, 0.0)
                };
                let t1 = (t1 - ax * t1.dot(ax)).norm();
                let t2 = ax.cross(t1);
                let rot = unit(hash3(jitter, k as u32, 0x51AD));
                let sample_free = |s: u32| {
                    let ang = core::f32::consts::TAU * (s as f32 + rot) / samples as f32;
                    let r = l.radius * ((s as f32 + 0.5) / samples as f32).sqrt();
                    let q = l.pos + t1 * (r * ang.cos()) + t2 * (r * ang.sin());
                    !self.occluded(p0, q - p0, cands)
                };
                // Two opposite samples first; when they agree the point is taken as fully lit
                // or fully shadowed, otherwise (a penumbra) all samples are traced.
                let (a, b) = (sample_free(0), sample_free(samples / 2));
                let free = if a == b {
                    if a {
                        samples
                    } else {
                        0
                    }
                } else {
                    (0..samples).filter(|&s| sample_free(s)).count() as u32
                };
                free as f32 / samples as f32
            };
            if vis > 0.0 {
                e = e + l.power * (vis * cos / (d2 + 0.3));
            }
        }
        e
    }

    /// Colour leaving a surface hit by ray `(o, d)`; `path` is the length of the path so far
    /// (for texture filtering); `budget` bounds further mirror/glass bounces.
    fn radiance(&self, o: V3, d: V3, h: &Hit, path: f32, budget: u32, jitter: u32) -> V3 {
        let w = self.w;
        let m = &w.mats[h.mat as usize];
        let p = o + d * h.t;
        let dl = d.len();
        let cos = (d.dot(h.n) / dl).abs().max(0.2);
        let reach = path + h.t * dl;
        match m.class {
            Class::Diffuse | Class::Dark => {
                let a = m.tex.sample(h.uv, reach / self.fx / cos);
                self.lambert(p, h, a, m.exterior, budget, jitter)
            }
            Class::Specular => {
                let tint = m.tex.c0;
                if budget == 0 {
                    return tint.mul(w.ambient) * 2.0;
                }
                let dr = d.reflect(h.n);
                match self.nearest(p, dr, EPS, Cands::All, false) {
                    Some(rh) => tint.mul(self.radiance(p, dr, &rh, reach, budget - 1, jitter)),
                    None => tint.mul(w.ambient),
                }
            }
            Class::Transparent => {
                let tint = m.tex.c0;
                let behind = self.nearest(p, d, EPS, Cands::All, true);
                let trans = match (&behind, budget) {
                    (Some(bh), b) if b > 0 => self.radiance(p, d, bh, reach, b - 1, jitter),
                    _ => w.ambient,
                };
                self.glass_mix(p, d, h, tint, trans, reach, budget, jitter)
            }
        }
    }

    /// Lambertian colour of albedo `a` at `p`: daylight outdoors, lamps and ambient indoors.
    fn lambert(&self, p: V3, h: &Hit, a: V3, exterior: bool, budget: u32, jitter: u32) -> V3 {
        let w = self.w;
        if exterior {
            a.mul(w.daylight) * (0.75 + 0.25 * h.n.y.abs())
        } else {
            let samples = if budget >= 2 { w.shadow_samples } else { 1 };
            a.mul(self.irradiance(p, h.n, samples, jitter))
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn glass_mix(
        &self,
        p: V3,
        d: V3,
        h: &Hit,
        tint: V3,
        trans: V3,
        reach: f32,
        budget: u32,
        jitter: u32,
    ) -> V3 {
        let c = (d.dot(h.n) / d.len()).abs();
        let f = 0.04 + 0.96 * (1.0 - c).powi(5);
        let refl = if budget >= 2 {
            let dr = d.reflect(h.n);
            match self.nearest(p, dr, EPS, Cands::All, false) {
                Some(rh) => self.radiance(p, dr, &rh, reach, 0, jitter),
                None => V3::ZERO,
            }
        } else {
            self.w.ambient
        };
        // A little extra reflection makes panes visible, as real glass with dust and coatings.
        let f = (f + 0.04).min(1.0);
        refl * f + trans.mul(tint) * (1.0 - f)
    }

    fn pixel(&self, x: usize, y: usize, cam: &CameraIntrinsics, cands: Cands<'_>, seed: u32) -> Px {
        let w = self.w;
        let dc = v3(
            (x as f32 - cam.cx) / cam.fx,
            (y as f32 - cam.cy) / cam.fy,
            1.0,
        );
        let d = w.cam_rot.apply(dc);
        let o = w.cam_pos;
        let jitter = hash3(x as u32, y as u32, seed);
        let Some(h) = self.nearest(o, d, 1e-4, cands, false) else {
            // Cannot happen inside a closed room; keep buffers valid regardless.
            return Px {
                depth: 100.0,
                refl: 0.0,
                normal: [0.0, 0.0, -1.0],
                ..Px::default()
            };
        };
        let m = &w.mats[h.mat as usize];
        let p = o + d * h.t;
        let nc = w.cam_rot.apply_t(h.n).norm();
        let mut px = Px {
            depth: h.t,
            label: m.class as u8,
            normal: [nc.x, nc.y, nc.z],
            ..Px::default()
        };
        match m.class {
            Class::Diffuse | Class::Dark => {
                let cos = (d.dot(h.n) / d.len()).abs().max(0.2);
                let a = m.tex.sample(h.uv, h.t * d.len() / self.fx / cos);
                px.refl = m.nir(a);
                px.rgb = self.lambert(p, &h, a, m.exterior, 2, jitter);
            }
            Class::Transparent => {
                px.refl = m.nir_offset;
                let behind = self.nearest(p, d, EPS, cands, true);
                px.second = behind.map_or(h.t * 2.0, |b| h.t + b.t);
                let trans = match &behind {
                    Some(bh) => self.radiance(p, d, bh, h.t * d.len(), 1, jitter),
                    None => w.ambient,
                };
                px.rgb = self.glass_mix(p, d, &h, m.tex.c0, trans, h.t * d.len(), 2, jitter);
            }
            Class::Specular => {
                px.refl = m.nir_offset;
                let dr = d.reflect(h.n);
                match self.nearest(p, dr, EPS, Cands::All, false) {
                    Some(rh) => {
                        // |dr| = |d|, so the reflected leg adds rh.t in units of planar depth.
                        px.second = h.t + rh.t;
                        px.rgb = m
                            .tex
                            .c0
                            .mul(self.radiance(p, dr, &rh, h.t * d.len(), 1, jitter));
                    }
                    None => {
                        px.second = h.t * 2.0;
                        px.rgb = m.tex.c0.mul(w.ambient);
                    }
                }
            }
        }
        px
    }
}

/// Lists, per tile, the items whose bounding sphere may cover it.
fn tile_lists(w: &World, cam: &CameraIntrinsics, tx: usize, ty: usize) -> Vec<Vec<u16>> {
    let mut lists = vec![Vec::new(); tx * ty];
    let (wd, ht) = (cam.width as f32, cam.height as f32);
    for (gi, g) in w.groups.iter().enumerate() {
        let c = w.cam_rot.apply_t(g.bc - w.cam_pos);
        let r = g.br;
        let (x0, x1, y0, y1) = if c.z - r <= 0.02 {
            (0.0, wd, 0.0, ht)
        } else {
            // x/z over the sphere's bounding box is extremal at its corners.
            let xs = [
                (c.x - r) / (c.z - r),
                (c.x - r) / (c.z + r),
                (c.x + r) / (c.z - r),
                (c.x + r) / (c.z + r),
            ];
            let ys = [
                (c.y - r) / (c.z - r),
                (c.y - r) / (c.z + r),
                (c.y + r) / (c.z - r),
                (c.y + r) / (c.z + r),
            ];
            let mn = |a: [f32; 4]| a.iter().copied().fold(f32::INFINITY, f32::min);
            let mx = |a: [f32; 4]| a.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            (
                mn(xs) * cam.fx + cam.cx - 1.0,
                mx(xs) * cam.fx + cam.cx + 1.0,
                mn(ys) * cam.fy + cam.cy - 1.0,
                mx(ys) * cam.fy + cam.cy + 1.0,
            )
        };
        if x1 < 0.0 || y1 < 0.0 || x0 > wd || y0 > ht {
            continue;
        }
        let tx0 = (x0.max(0.0) as usize / TILE).min(tx - 1);
        let tx1 = (x1.min(wd - 1.0).max(0.0) as usize / TILE).min(tx - 1);
        let ty0 = (y0.max(0.0) as usize / TILE).min(ty - 1);
        let ty1 = (y1.min(ht - 1.0).max(0.0) as usize / TILE).min(ty - 1);
        for ty_ in ty0..=ty1 {
            for tx_ in tx0..=tx1 {
                lists[ty_ * tx + tx_].push(gi as u16);
            }
        }
    }
    lists
}

/// Renders `w` through `cam` into a frame.
pub fn render(w: &World, cam: &CameraIntrinsics, seed: u64) -> SceneFrame {
    let (wd, ht) = (cam.width as usize, cam.height as usize);
    let tracer = Tracer {
        w,
        glass: w
            .mats
            .iter()
            .map(|m| m.class == Class::Transparent)
            .collect(),
        casters: (0..w.groups.len() as u16)
            .filter(|&g| w.groups[g as usize].casts_shadow)
            .collect(),
        fx: cam.fx.max(1.0),
    };
    let (tx, ty) = (wd.div_ceil(TILE).max(1), ht.div_ceil(TILE).max(1));
    let lists = tile_lists(w, cam, tx, ty);
    let s = seed as u32 ^ (seed >> 32) as u32;
    let rows: Vec<Vec<Px>> = (0..ht)
        .into_par_iter()
        .map(|y| {
            (0..wd)
                .map(|x| {
                    tracer.pixel(
                        x,
                        y,
                        cam,
                        Cands::List(&lists[(y / TILE) * tx + x / TILE]),
                        s,
                    )
                })
                .collect()
        })
        .collect();
    let n = wd * ht;
    // Auto-exposure: map the log-average luminance to the scene's key (summed in a fixed order).
    let mut log_sum = 0.0f64;
    for row in &rows {
        for p in row {
            log_sum += f64::from((luminance(p.rgb) + 1e-4).ln());
        }
    }
    let l_avg = if n > 0 {
        (log_sum / n as f64).exp() as f32
    } else {
        1.0
    };
    let scale = w.exposure_key / l_avg.max(1e-6);
    let mut frame = SceneFrame {
        width: cam.width,
        height: cam.height,
        camera: *cam,
        rgb: Vec::with_capacity(n * 3),
        depth_m: Vec::with_capacity(n),
        second_depth_m: Vec::with_capacity(n),
        reflectance: Vec::with_capacity(n),
        labels: Vec::with_capacity(n),
        normals: Vec::with_capacity(n),
    };
    let lut = encode_lut();
    let (hx, hy) = (wd as f32 * 0.5, ht as f32 * 0.5);
    let rr = 1.0 / (hx * hx + hy * hy);
    for (y, row) in rows.iter().enumerate() {
        for (x, p) in row.iter().enumerate() {
            let r2 = ((x as f32 - hx).powi(2) + (y as f32 - hy).powi(2)) * rr;
            let vig = 1.0 - 0.2 * r2;
            let c = p.rgb * (scale * vig);
            let h = hash3(x as u32, y as u32, s ^ 0xD17E);
            for (k, v) in [c.x, c.y, c.z].into_iter().enumerate() {
                let t = tone(v);
                // Triangular dither of about one level: sensor-like grain, no banding.
                let noise =
                    unit(h.rotate_left(8 * k as u32)) + unit(h.rotate_left(8 * k as u32 + 5)) - 1.0;
                let code = lut[((t * 4095.0) as usize).min(4095)] + noise * 1.5;
                frame.rgb.push(code.round().clamp(0.0, 255.0) as u8);
            }
            frame.depth_m.push(p.depth);
            frame.second_depth_m.push(p.second);
            frame.reflectance.push(p.refl.clamp(0.0, 1.0));
            frame.labels.push(p.label);
            frame.normals.push(p.normal);
        }
    }
    frame
}

/// Soft shoulder: extended Reinhard with white point 3.
#[inline]
fn tone(v: f32) -> f32 {
    let v = v.max(0.0);
    (v * (1.0 + v / 9.0) / (1.0 + v)).min(1.0)
}

/// Linear [0, 1] (4096 steps) → sRGB code value (0–255, unrounded).
fn encode_lut() -> &'static [f32; 4096] {
    static LUT: std::sync::OnceLock<[f32; 4096]> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        let mut t = [0.0f32; 4096];
        for (i, v) in t.iter_mut().enumerate() {
            let c = i as f32 / 4095.0;
            let s = if c <= 0.003_130_8 {
                12.92 * c
            } else {
                1.055 * c.powf(1.0 / 2.4) - 0.055
            };
            *v = s * 255.0;
        }
        t
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_curve_and_encoding_by_hand() {
        assert_eq!(tone(0.0), 0.0);
        // 1·(1 + 1/9)/2 = 0.5556; white point 3 maps to 1.
        assert!((tone(1.0) - 0.555_56).abs() < 1e-4);
        assert!((tone(3.0) - 1.0).abs() < 1e-6);
        let lut = encode_lut();
        assert!((lut[4095] - 255.0).abs() < 1e-3);
        // Linear 0.2140 (index 876) is sRGB ≈ 0.5 → 127.5.
        assert!((lut[876] - 127.5).abs() < 0.3, "{}", lut[876]);
    }
}
