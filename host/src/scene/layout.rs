//! Random scene layout: a room or corridor with openings to an exterior, furniture built from
//! primitives, thin structures, glass, mirrors, dark absorbers, lamps and a camera pose, all drawn
//! from one [`Rng`] stream so a seed fixes the scene.
use super::config::SceneConfig;
use super::material::{hsv_linear, Class, Material};
use super::math::{v3, M3, V3};
use super::shapes::{Opening, Prim, RoomBox, Shape};
use super::texture::{Pattern, Role, Texture, PHOTOS};
use crate::rng::Rng;
use core::f32::consts::{FRAC_PI_2, PI};

/// A point light (a small sphere when `radius > 0`, giving soft shadows).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Position, world frame.
    pub pos: V3,
    /// Radiant intensity per colour channel (irradiance at 1 m, before the cosine).
    pub power: V3,
    /// Radius of the emitter, metres (0: hard shadows).
    pub radius: f32,
}

/// A furniture item: a contiguous range of primitives with a bounding sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Group {
    /// First primitive index.
    pub start: u32,
    /// One past the last primitive index.
    pub end: u32,
    /// Bounding-sphere centre.
    pub bc: V3,
    /// Bounding-sphere radius.
    pub br: f32,
}

/// Everything the tracer needs.
#[derive(Clone, Debug)]
pub struct World {
    /// The room (or corridor), seen from inside.
    pub room: RoomBox,
    /// The exterior box seen through openings, if any.
    pub outer: Option<RoomBox>,
    /// Primitives of all items, grouped by `groups`.
    pub prims: Vec<Prim>,
    /// Items.
    pub groups: Vec<Group>,
    /// Material table.
    pub mats: Vec<Material>,
    /// Lamps.
    pub lights: Vec<Light>,
    /// Ambient irradiance indoors.
    pub ambient: V3,
    /// Irradiance of exterior surfaces.
    pub daylight: V3,
    /// Shadow rays per light (1: hard shadows).
    pub shadow_samples: u32,
    /// Camera centre, world frame.
    pub cam_pos: V3,
    /// Camera → world rotation (columns: image right, image down, optical axis).
    pub cam_rot: M3,
    /// Exposure key (linear mid-tone the log-average luminance maps to).
    pub exposure_key: f32,
}

struct Builder<'a> {
    rng: Rng,
    cfg: &'a SceneConfig,
    w: World,
    /// Floor footprints `(x, z, radius)` already taken.
    taken: Vec<(f32, f32, f32)>,
    hw: f32,
    depth: f32,
    height: f32,
    yaw: f32,
    hfov: f32,
}

fn range(r: &mut Rng, lr: [f32; 2]) -> f32 {
    if lr[1] > lr[0] {
        r.range(lr[0], lr[1])
    } else {
        lr[0]
    }
}

fn count(r: &mut Rng, lr: [u32; 2]) -> u32 {
    lr[0] + r.below(u64::from(lr[1].saturating_sub(lr[0])) + 1) as u32
}

impl Builder<'_> {
    fn add_mat(&mut self, m: Material) -> u16 {
        self.w.mats.push(m);
        (self.w.mats.len() - 1) as u16
    }

    fn begin(&self) -> u32 {
        self.w.prims.len() as u32
    }

    fn end(&mut self, start: u32) {
        let end = self.w.prims.len() as u32;
        if end == start {
            return;
        }
        let ps = &self.w.prims[start as usize..end as usize];
        let mut lo = V3::splat(f32::INFINITY);
        let mut hi = V3::splat(f32::NEG_INFINITY);
        for p in ps {
            lo = v3(lo.x.min(p.bc.x - p.br), lo.y.min(p.bc.y - p.br), lo.z.min(p.bc.z - p.br));
            hi = v3(hi.x.max(p.bc.x + p.br), hi.y.max(p.bc.y + p.br), hi.z.max(p.bc.z + p.br));
        }
        let bc = (lo + hi) * 0.5;
        let br = ps.iter().map(|p| (p.bc - bc).len() + p.br).fold(0.0f32, f32::max);
        self.w.groups.push(Group { start, end, bc, br });
    }

    fn push(&mut self, s: Shape, mat: u16) {
        self.w.prims.push(Prim::new(s, mat));
    }

    fn cuboid(&mut self, center: V3, half: V3, yaw: f32, mat: u16) {
        let rot = if yaw == 0.0 { M3::IDENTITY } else { M3::rot_y(yaw) };
        self.push(Shape::Cuboid { center, half, rot }, mat);
    }

    fn colour(&mut self, sat: [f32; 2], val: [f32; 2]) -> V3 {
        let h = self.rng.f32();
        let s = range(&mut self.rng, sat);
        let v = range(&mut self.rng, val);
        hsv_linear(h, s, v)
    }

    fn texture(&mut self, role: Role) -> Texture {
        let cfg = self.cfg;
        let seed = self.rng.next_u64() as u32;
        let ang = self.rng.range(0.0, 2.0 * PI);
        let rot = if self.rng.chance(0.7) { (1.0, 0.0) } else { (ang.cos(), ang.sin()) };
        let offset = (self.rng.range(0.0, 10.0), self.rng.range(0.0, 10.0));
        if self.rng.chance(cfg.photo_texture_prob) {
            let idx: Vec<usize> = (0..PHOTOS.len()).filter(|&i| PHOTOS[i].2 == role).collect();
            let i = idx[self.rng.below(idx.len() as u64) as usize];
            let scale = match role {
                Role::Wall => self.rng.range(1.0, 3.0),
                Role::Floor => self.rng.range(0.8, 2.5),
                Role::Object => self.rng.range(0.4, 1.5),
            };
            // Mild tint around white keeps the photo's look while varying colours.
            let t = self.colour([0.0, 0.35], [0.75, 1.0]);
            let tint = t * (1.0 / t.max_elem().max(1e-3)) * self.rng.range(0.7, 1.0);
            return Texture { pattern: Pattern::Photo(i as u16), c0: tint, c1: tint, scale, rot: (1.0, 0.0), offset, seed };
        }
        let (sat, val) = match role {
            Role::Wall => ([0.0, 0.3], [0.55, 0.95]),
            Role::Floor => ([0.05, 0.5], [0.25, 0.8]),
            Role::Object => ([0.0, 0.8], [0.2, 0.9]),
        };
        let c0 = self.colour(sat, val);
        let k = self.rng.f32();
        let (pattern, c1, scale) = match role {
            Role::Wall if k < 0.55 => (Pattern::Plain, c0, 1.0),
            Role::Wall if k < 0.7 => (Pattern::Stripes, c0 * self.rng.range(0.6, 0.9), self.rng.range(0.05, 0.4)),
            Role::Wall if k < 0.85 => (Pattern::Checker, c0 * self.rng.range(0.7, 0.95), self.rng.range(0.1, 0.4)),
            Role::Wall => (Pattern::Noise, c0 * self.rng.range(0.6, 0.9), self.rng.range(0.3, 2.0)),
            Role::Floor if k < 0.35 => {
                let wood = hsv_linear(self.rng.range(0.05, 0.11), self.rng.range(0.4, 0.8), self.rng.range(0.35, 0.75));
                (Pattern::Wood, wood * 0.55, self.rng.range(0.3, 1.0))
            }
            Role::Floor if k < 0.6 => (Pattern::Checker, self.colour([0.0, 0.4], [0.2, 0.9]), self.rng.range(0.2, 0.6)),
            Role::Floor if k < 0.8 => (Pattern::Marble, c0 * 0.5, self.rng.range(0.5, 2.0)),
            Role::Floor => (Pattern::Noise, c0 * 0.7, self.rng.range(0.2, 1.5)),
            Role::Object if k < 0.3 => (Pattern::Plain, c0, 1.0),
            Role::Object if k < 0.5 => {
                let wood = hsv_linear(self.rng.range(0.05, 0.11), self.rng.range(0.4, 0.8), self.rng.range(0.3, 0.75));
                (Pattern::Wood, wood * 0.6, self.rng.range(0.2, 0.8))
            }
            Role::Object if k < 0.65 => (Pattern::Noise, self.colour([0.0, 0.8], [0.2, 0.9]), self.rng.range(0.1, 0.8)),
            Role::Object if k < 0.75 => (Pattern::Checker, self.colour([0.0, 0.8], [0.2, 0.9]), self.rng.range(0.05, 0.3)),
            Role::Object if k < 0.88 => (Pattern::Stripes, self.colour([0.0, 0.8], [0.2, 0.9]), self.rng.range(0.03, 0.3)),
            Role::Object => (Pattern::Marble, c0 * 0.4, self.rng.range(0.3, 1.0)),
        };
        let (c0, c1) = if matches!(pattern, Pattern::Wood) { (c1 * (1.0 / 0.55), c1) } else { (c0, c1) };
        Texture { pattern, c0, c1, scale, rot, offset, seed }
    }

    fn diffuse(&mut self, role: Role) -> u16 {
        let tex = self.texture(role);
        let off = self.rng.range(0.05, 0.3);
        let gain = self.rng.range(0.5, 1.1);
        self.add_mat(Material::diffuse(tex, off, gain))
    }

    fn dark(&mut self) -> u16 {
        let c = self.colour([0.0, 0.5], [0.04, 0.16]);
        let pattern = if self.rng.chance(0.5) { Pattern::Plain } else { Pattern::Noise };
        let tex = Texture { pattern, c0: c, c1: c * 0.6, scale: self.rng.range(0.1, 0.5), ..Texture::plain(c) };
        let off = self.rng.range(0.018, 0.045);
        self.add_mat(Material { class: Class::Dark, tex, nir_offset: off, nir_gain: 0.3, exterior: false })
    }

    fn glass(&mut self) -> u16 {
        let tint = v3(self.rng.range(0.8, 0.95), self.rng.range(0.88, 1.0), self.rng.range(0.85, 1.0));
        let refl = self.rng.range(0.04, 0.08);
        self.add_mat(Material { class: Class::Transparent, tex: Texture::plain(tint), nir_offset: refl, nir_gain: 0.0, exterior: false })
    }

    fn mirror(&mut self) -> u16 {
        let r = self.rng.range(0.82, 0.95);
        let tint = v3(r, r * self.rng.range(0.97, 1.0), r * self.rng.range(0.95, 1.0));
        self.add_mat(Material { class: Class::Specular, tex: Texture::plain(tint), nir_offset: r, nir_gain: 0.0, exterior: false })
    }

    fn object_mat(&mut self, dark: bool) -> u16 {
        if dark {
            self.dark()
        } else {
            self.diffuse(Role::Object)
        }
    }

    /// A free floor spot for a footprint of radius `r`: in view with probability `p_view`.
    fn spot(&mut self, r: f32, p_view: f32) -> Option<(f32, f32)> {
        self.spot_within(r, p_view, f32::INFINITY)
    }

    /// Like [`Self::spot`], at most `max_d` metres from the camera when in view.
    fn spot_within(&mut self, r: f32, p_view: f32, max_d: f32) -> Option<(f32, f32)> {
        let cam = self.w.cam_pos;
        for _ in 0..16 {
            let (x, z) = if self.rng.chance(p_view) {
                let a = self.yaw + self.rng.range(-0.45, 0.45) * self.hfov;
                let d = self.rng.range(1.0, (self.depth - cam.z).min(max_d).max(1.2));
                (cam.x + d * a.sin(), cam.z + d * a.cos())
            } else {
                (self.rng.range(-self.hw, self.hw), self.rng.range(0.0, self.depth))
            };
            let m = r + 0.05;
            if x - m < -self.hw || x + m > self.hw || z - m < 0.0 || z + m > self.depth {
                continue;
            }
            let dc = ((x - cam.x).powi(2) + (z - cam.z).powi(2)).sqrt();
            if dc < r + 0.6 {
                continue;
            }
            if self.taken.iter().any(|&(tx, tz, tr)| ((x - tx).powi(2) + (z - tz).powi(2)).sqrt() < r + tr) {
                continue;
            }
            self.taken.push((x, z, r));
            return Some((x, z));
        }
        None
    }

    fn table(&mut self, glass_top: bool, dark: bool) -> bool {
        let (w, d) = (self.rng.range(0.3, 0.9), self.rng.range(0.25, 0.5));
        let Some((x, z)) = self.spot((w * w + d * d).sqrt(), 0.7) else { return false };
        let h = self.rng.range(0.4, 0.8);
        let th = self.rng.range(0.02, 0.05);
        let yaw = if self.rng.chance(0.5) { 0.0 } else { self.rng.range(-PI, PI) };
        let top = if glass_top { self.glass() } else { self.object_mat(dark) };
        let leg_mat = if dark || self.rng.chance(0.5) { self.object_mat(dark) } else { top_or_new(self, top, glass_top) };
        let g = self.begin();
        self.cuboid(v3(x, h - th * 0.5, z), v3(w, th * 0.5, d), yaw, top);
        let lr = self.rng.range(0.012, 0.035);
        let round = self.rng.chance(0.5);
        let rot = M3::rot_y(yaw);
        for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let off = rot.apply(v3(sx * (w - 0.06), 0.0, sz * (d - 0.06)));
            let p = v3(x + off.x, 0.0, z + off.z);
            if round {
                self.push(Shape::Cylinder { base: p, radius: lr, height: h - th }, leg_mat);
            } else {
                self.cuboid(p + v3(0.0, (h - th) * 0.5, 0.0), v3(lr, (h - th) * 0.5, lr), yaw, leg_mat);
            }
        }
        self.end(g);
        // Something on the table now and then.
        if self.rng.chance(0.5) {
            let m = self.object_mat(false);
            let g = self.begin();
            let o = rot.apply(v3(self.rng.range(-0.5, 0.5) * w, 0.0, self.rng.range(-0.5, 0.5) * d));
            let r = self.rng.range(0.04, 0.14);
            match self.rng.below(3) {
                0 => self.push(Shape::Sphere { center: v3(x + o.x, h + r, z + o.z), radius: r }, m),
                1 => {
                    let height = self.rng.range(0.1, 0.35);
                    self.push(Shape::Cylinder { base: v3(x + o.x, h, z + o.z), radius: r * 0.6, height }, m)
                }
                _ => self.cuboid(v3(x + o.x, h + r * 0.5, z + o.z), v3(r * 1.5, r * 0.5, r), yaw, m),
            }
            self.end(g);
        }
        true
    }

    fn chair(&mut self, dark: bool) -> bool {
        let s = self.rng.range(0.2, 0.26);
        let Some((x, z)) = self.spot(s * 1.5, 0.6) else { return false };
        let yaw = self.rng.range(-PI, PI);
        let rot = M3::rot_y(yaw);
        let h = self.rng.range(0.42, 0.48);
        let m = self.object_mat(dark);
        let lm = if self.rng.chance(0.5) { m } else { self.object_mat(dark) };
        let g = self.begin();
        self.cuboid(v3(x, h - 0.02, z), v3(s, 0.02, s), yaw, m);
        for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let off = rot.apply(v3(sx * (s - 0.02), 0.0, sz * (s - 0.02)));
            self.push(Shape::Cylinder { base: v3(x + off.x, 0.0, z + off.z), radius: 0.015, height: h - 0.04 }, lm);
        }
        let bh = self.rng.range(0.3, 0.5);
        let off = rot.apply(v3(0.0, 0.0, s - 0.015));
        self.cuboid(v3(x + off.x, h + bh * 0.5, z + off.z), v3(s, bh * 0.5, 0.015), yaw, m);
        self.end(g);
        true
    }

    /// A cabinet, shelf or wardrobe, against a wall when possible; a glass door when `glass`.
    fn cabinet(&mut self, glass: bool, dark: bool) -> bool {
        let w = self.rng.range(0.25, 1.0);
        let d = self.rng.range(0.15, 0.3);
        let h = self.rng.range(0.4, 2.1).min(self.height - 0.1);
        // Against the far wall or a side wall.
        let side = self.rng.below(3);
        let (x_lo, x_hi) = self.far_span(w);
        let (x_lo, x_hi) = if x_hi > x_lo { (x_lo, x_hi) } else { (-self.hw + w, self.hw - w) };
        let s = if side == 1 { -1.0 } else { 1.0 };
        let (z_lo, z_hi) = self.side_span(s, w);
        let (z_lo, z_hi) = if z_hi > z_lo { (z_lo, z_hi) } else { (1.5, self.depth - w) };
        let (x, z, yaw) = match side {
            0 => (self.rng.range(x_lo, x_hi), self.depth - d - 0.01, 0.0),
            1 => (-self.hw + d + 0.01, self.rng.range(z_lo, z_hi).max(1.0), FRAC_PI_2),
            _ => (self.hw - d - 0.01, self.rng.range(z_lo, z_hi).max(1.0), -FRAC_PI_2),
        };
        let r = (w * w + d * d).sqrt();
        if self.taken.iter().any(|&(tx, tz, tr)| ((x - tx).powi(2) + (z - tz).powi(2)).sqrt() < r + tr)
            || ((x - self.w.cam_pos.x).powi(2) + (z - self.w.cam_pos.z).powi(2)).sqrt() < r + 0.6
        {
            return false;
        }
        self.taken.push((x, z, r));
        let m = self.object_mat(dark);
        let rot = M3::rot_y(yaw);
        let g = self.begin();
        let open_shelf = !glass && self.rng.chance(0.5);
        if open_shelf {
            // Two sides, a back, shelves, and books: thin structures and occlusion edges.
            let t = 0.015;
            for sx in [-1.0, 1.0] {
                let o = rot.apply(v3(sx * (w - t), 0.0, 0.0));
                self.cuboid(v3(x + o.x, h * 0.5, z + o.z), v3(t, h * 0.5, d), yaw, m);
            }
            let o = rot.apply(v3(0.0, 0.0, d - t));
            self.cuboid(v3(x + o.x, h * 0.5, z + o.z), v3(w, h * 0.5, t), yaw, m);
            let n = ((h / 0.35) as u32).clamp(1, 6);
            for k in 0..=n {
                let y = (k as f32 / n as f32) * (h - 2.0 * t) + t;
                self.cuboid(v3(x, y, z), v3(w, t, d), yaw, m);
                if k < n && self.rng.chance(0.7) {
                    let mut a = -w + 2.0 * t;
                    while a < w - 0.06 {
                        let bw = self.rng.range(0.012, 0.035);
                        let bh = self.rng.range(0.12, (h / n as f32 - 0.05).clamp(0.13, 0.3));
                        if a + 2.0 * bw > w - t {
                            break;
                        }
                        if self.rng.chance(0.85) {
                            let bm = if self.rng.chance(0.5) { self.diffuse(Role::Object) } else { m };
                            let o = rot.apply(v3(a + bw, 0.0, self.rng.range(0.0, 0.05)));
                            let bd = d * self.rng.range(0.6, 0.9);
                            self.cuboid(v3(x + o.x, y + t + bh * 0.5, z + o.z), v3(bw, bh * 0.5, bd), yaw, bm);
                        }
                        a += 2.0 * bw + 0.002;
                    }
                }
            }
        } else {
            self.cuboid(v3(x, h * 0.5, z), v3(w, h * 0.5, d), yaw, m);
            if glass {
                let gm = self.glass();
                let n = rot.apply(v3(0.0, 0.0, -1.0));
                let c = v3(x, h * 0.5, z) + n * (d + 0.03);
                self.push(Shape::Quad { center: c, u: rot.apply(v3(1.0, 0.0, 0.0)), v: v3(0.0, 1.0, 0.0), hu: w * 0.92, hv: h * 0.45 }, gm);
            }
        }
        self.end(g);
        true
    }

    fn sofa(&mut self, dark: bool) -> bool {
        let w = self.rng.range(0.6, 1.1);
        let d = self.rng.range(0.35, 0.48);
        let Some((x, z)) = self.spot((w * w + d * d).sqrt(), 0.7) else { return false };
        let yaw = if self.rng.chance(0.5) { PI } else { self.rng.range(-PI, PI) };
        let rot = M3::rot_y(yaw);
        let m = self.object_mat(dark);
        let g = self.begin();
        let sh = self.rng.range(0.35, 0.48);
        self.cuboid(v3(x, sh * 0.5, z), v3(w, sh * 0.5, d), yaw, m);
        let bh = self.rng.range(0.3, 0.5);
        let o = rot.apply(v3(0.0, 0.0, d - 0.1));
        self.cuboid(v3(x + o.x, sh + bh * 0.5, z + o.z), v3(w, bh * 0.5, 0.1), yaw, m);
        for sx in [-1.0, 1.0] {
            let o = rot.apply(v3(sx * (w - 0.08), 0.0, 0.0));
            self.cuboid(v3(x + o.x, sh + 0.1, z + o.z), v3(0.08, 0.1, d), yaw, m);
        }
        self.end(g);
        true
    }

    fn boxes(&mut self, dark: bool) -> bool {
        let s = self.rng.range(0.15, 0.45);
        let Some((x, z)) = self.spot(s * 1.5, 0.7) else { return false };
        let g = self.begin();
        let mut y = 0.0;
        for _ in 0..1 + self.rng.below(3) {
            let half = v3(s * self.rng.range(0.7, 1.0), s * self.rng.range(0.4, 1.0), s * self.rng.range(0.7, 1.0));
            let yaw = if self.rng.chance(0.4) { 0.0 } else { self.rng.range(-0.6, 0.6) };
            let m = self.object_mat(dark);
            self.cuboid(v3(x, y + half.y, z), half, yaw, m);
            y += 2.0 * half.y;
        }
        self.end(g);
        true
    }

    fn round_thing(&mut self, dark: bool) -> bool {
        let r = self.rng.range(0.1, 0.4);
        let Some((x, z)) = self.spot(r, 0.7) else { return false };
        let m = self.object_mat(dark);
        let g = self.begin();
        match self.rng.below(4) {
            0 => self.push(Shape::Sphere { center: v3(x, r, z), radius: r }, m),
            1 => {
                let h = self.rng.range(0.3, 1.0);
                self.push(Shape::Cylinder { base: v3(x, 0.0, z), radius: r * 0.8, height: h }, m);
                if self.rng.chance(0.5) {
                    let m2 = self.object_mat(false);
                    self.push(Shape::Sphere { center: v3(x, h + r * 0.5, z), radius: r * 0.5 }, m2);
                }
            }
            2 => {
                // Round table: top, pole, base.
                let h = self.rng.range(0.45, 0.8);
                self.push(Shape::Cylinder { base: v3(x, h - 0.03, z), radius: r + 0.15, height: 0.03 }, m);
                self.push(Shape::Cylinder { base: v3(x, 0.02, z), radius: 0.03, height: h - 0.05 }, m);
                self.push(Shape::Cylinder { base: v3(x, 0.0, z), radius: r * 0.6, height: 0.02 }, m);
            }
            _ => {
                // Potted plant: pot and a foliage ball.
                let h = self.rng.range(0.25, 0.5);
                self.push(Shape::Cylinder { base: v3(x, 0.0, z), radius: r * 0.6, height: h }, m);
                let leaves = PHOTOS.iter().position(|p| p.0.contains("leaves")).unwrap_or(0) as u16;
                let tex = Texture { pattern: Pattern::Photo(leaves), c0: V3::splat(1.0), c1: V3::splat(1.0), scale: 0.4, rot: (1.0, 0.0), offset: (0.0, 0.0), seed: 0 };
                // Chlorophyll reflects strongly at 940 nm.
                let lm = self.add_mat(Material::diffuse(tex, 0.45, 0.4));
                self.push(Shape::Sphere { center: v3(x, h + r * 0.9, z), radius: r }, lm);
            }
        }
        self.end(g);
        true
    }

    /// Thin structures: a floor-to-ceiling pipe, a floor lamp, or a coat stand.
    fn thin(&mut self) -> bool {
        let Some((x, z)) = self.spot(0.25, 0.7) else { return false };
        let dark = self.rng.chance(0.2);
        let m = self.object_mat(dark);
        let g = self.begin();
        if self.rng.chance(0.5) {
            let r = self.rng.range(0.015, 0.06);
            self.push(Shape::Cylinder { base: v3(x, 0.0, z), radius: r, height: self.height }, m);
        } else {
            let h = self.rng.range(1.2, 1.9);
            self.push(Shape::Cylinder { base: v3(x, 0.0, z), radius: 0.15, height: 0.02 }, m);
            let radius = self.rng.range(0.01, 0.02);
            self.push(Shape::Cylinder { base: v3(x, 0.02, z), radius, height: h }, m);
            let sm = self.diffuse(Role::Object);
            if self.rng.chance(0.5) {
                let radius = self.rng.range(0.12, 0.22);
                self.push(Shape::Cylinder { base: v3(x, h, z), radius, height: 0.25 }, sm);
            } else {
                self.push(Shape::Sphere { center: v3(x, h + 0.12, z), radius: 0.14 }, sm);
            }
        }
        self.end(g);
        true
    }

    /// A board leaning against a side or far wall (a slanted plane).
    fn slanted(&mut self) {
        let m = self.diffuse(Role::Object);
        let len = self.rng.range(0.8, 2.0).min(self.height - 0.2);
        let half_w = self.rng.range(0.2, 0.6);
        let tilt = self.rng.range(0.15, 0.45);
        let g = self.begin();
        if self.rng.chance(0.5) {
            // Against the far wall: foot on the floor, top on the wall.
            let x = self.rng.range(-self.hw + half_w, self.hw - half_w);
            let dz = len * tilt.sin();
            let up = v3(0.0, tilt.cos(), tilt.sin());
            let c = v3(x, len * 0.5 * tilt.cos(), self.depth - dz * 0.5 - 0.01);
            self.push(Shape::Quad { center: c, u: v3(1.0, 0.0, 0.0), v: up, hu: half_w, hv: len * 0.5 }, m);
        } else {
            let s = if self.rng.chance(0.5) { -1.0 } else { 1.0 };
            let z = self.rng.range(1.5, (self.depth - half_w).max(1.6));
            let dx = len * tilt.sin();
            let up = v3(s * tilt.sin(), tilt.cos(), 0.0);
            let c = v3(s * (self.hw - dx * 0.5 - 0.01), len * 0.5 * tilt.cos(), z);
            self.push(Shape::Quad { center: c, u: v3(0.0, 0.0, 1.0), v: up, hu: half_w, hv: len * 0.5 }, m);
        }
        self.end(g);
    }

    /// The x-interval of the far wall inside the view cone, for an item of half width `half`.
    fn far_span(&self, half: f32) -> (f32, f32) {
        let (cam, half_fov) = (self.w.cam_pos, 0.42 * self.hfov);
        let dz = self.depth - cam.z;
        let lo = (cam.x + dz * (self.yaw - half_fov).tan()).max(-self.hw + half + 0.02);
        let hi = (cam.x + dz * (self.yaw + half_fov).tan()).min(self.hw - half - 0.02);
        (lo, hi)
    }

    /// The z-interval of side wall `side` (−1 left, +1 right) inside the view cone.
    fn side_span(&self, side: f32, half: f32) -> (f32, f32) {
        let (cam, half_fov) = (self.w.cam_pos, 0.42 * self.hfov);
        let dx = (side * self.hw - cam.x).abs();
        let ang = (FRAC_PI_2 - half_fov - side * self.yaw).max(0.05);
        let lo = (cam.z + dx * ang.tan()).max(cam.z + 0.8).max(half + 0.05);
        (lo, self.depth - half - 0.05)
    }

    /// A rectangle on a wall facing into the room, placed where the camera sees it when it can
    /// be: `(center, u, normal)`; `half_u` is its half size along the wall.
    fn wall_spot(&mut self, half_u: f32, y: f32) -> (V3, V3, V3) {
        let (x_lo, x_hi) = self.far_span(half_u);
        let side = if self.rng.chance(0.5) { -1.0f32 } else { 1.0 };
        let (z_lo, z_hi) = self.side_span(side, half_u);
        let far_ok = x_hi > x_lo;
        let side_ok = z_hi > z_lo;
        if far_ok && (!side_ok || self.rng.chance(0.5)) {
            let x = self.rng.range(x_lo, x_hi);
            (v3(x, y, self.depth), v3(1.0, 0.0, 0.0), v3(0.0, 0.0, -1.0))
        } else if side_ok {
            let z = self.rng.range(z_lo, z_hi);
            (v3(side * self.hw, y, z), v3(0.0, 0.0, 1.0), v3(-side, 0.0, 0.0))
        } else {
            let x = self.rng.range(-self.hw + half_u, self.hw - half_u).clamp(-self.hw, self.hw);
            (v3(x, y, self.depth), v3(1.0, 0.0, 0.0), v3(0.0, 0.0, -1.0))
        }
    }

    fn wall_item(&mut self, kind: WallItem) {
        let (hu, hv) = match kind {
            WallItem::Mirror => (self.rng.range(0.25, 0.7), self.rng.range(0.35, 0.9)),
            WallItem::Tv => (self.rng.range(0.35, 0.8), 0.0),
            WallItem::Picture => (self.rng.range(0.15, 0.6), self.rng.range(0.15, 0.5)),
        };
        let hv = if kind == WallItem::Tv { hu * 0.5625 } else { hv };
        let y = self.rng.range(hv + 0.3, (self.height - hv - 0.15).max(hv + 0.31)).min(self.height - hv - 0.05);
        let (c, u, n) = self.wall_spot(hu, y);
        let g = self.begin();
        match kind {
            WallItem::Mirror => {
                let m = self.mirror();
                let fm = self.object_mat(false);
                // Frame behind the glass, mirror surface 1 cm proud of it.
                self.push(Shape::Quad { center: c + n * 0.01, u, v: v3(0.0, 1.0, 0.0), hu: hu + 0.03, hv: hv + 0.03 }, fm);
                self.push(Shape::Quad { center: c + n * 0.02, u, v: v3(0.0, 1.0, 0.0), hu, hv }, m);
            }
            WallItem::Tv => {
                let m = self.dark();
                let yaw = if n.z != 0.0 { 0.0 } else { FRAC_PI_2 };
                self.cuboid(c + n * 0.03, v3(hu, hv, 0.03), yaw, m);
            }
            WallItem::Picture => {
                let role = if self.rng.chance(0.5) { Role::Object } else { Role::Wall };
                let m = self.diffuse(role);
                let dark = self.rng.chance(0.3);
                let fm = self.object_mat(dark);
                let yaw = if n.z != 0.0 { 0.0 } else { FRAC_PI_2 };
                self.cuboid(c + n * 0.015, v3(hu + 0.02, hv + 0.02, 0.015), yaw, fm);
                self.push(Shape::Quad { center: c + n * 0.031, u, v: v3(0.0, 1.0, 0.0), hu, hv }, m);
            }
        }
        self.end(g);
    }

    /// A standing mirror or glass partition in view: a quad on two thin posts.
    fn standing_pane(&mut self, mirror: bool) -> bool {
        let hw = self.rng.range(0.3, 0.9);
        let Some((x, z)) = self.spot_within(hw, 1.0, 5.0) else { return false };
        let h = self.rng.range(1.0, 2.0).min(self.height - 0.1);
        let yaw = self.yaw + self.rng.range(-0.6, 0.6);
        let tilt = if mirror { self.rng.range(-0.15, 0.05) } else { 0.0 };
        let u = M3::rot_y(yaw).apply(v3(1.0, 0.0, 0.0));
        let fwd = M3::rot_y(yaw).apply(v3(0.0, 0.0, 1.0));
        let up = v3(0.0, tilt.cos(), 0.0) + fwd * tilt.sin();
        let m = if mirror { self.mirror() } else { self.glass() };
        let dark = self.rng.chance(0.3);
        let pm = self.object_mat(dark);
        let g = self.begin();
        let c = v3(x, 0.05 + h * 0.5 * tilt.cos(), z) + fwd * (h * 0.5 * tilt.sin());
        self.push(Shape::Quad { center: c, u, v: up.norm(), hu: hw, hv: h * 0.5 }, m);
        for s in [-1.0, 1.0] {
            let p = v3(x, 0.0, z) + u * (s * (hw + 0.02));
            self.push(Shape::Cylinder { base: p, radius: 0.015, height: h + 0.05 }, pm);
        }
        self.end(g);
        true
    }

    /// A hole in a wall to the exterior: a doorway or a window (with a pane when `glass`).
    fn opening(&mut self, window: bool, glass: bool, used: &mut Vec<u8>) {
        let face = match self.rng.below(3) {
            0 => 5u8,
            1 => 0,
            _ => 1,
        };
        if used.contains(&face) {
            return;
        }
        let half = if window { self.rng.range(0.3, 1.2) } else { self.rng.range(0.4, 0.8) };
        let (y0, y1) = if window {
            (self.rng.range(0.6, 1.1), (self.height - self.rng.range(0.2, 0.6)).max(1.4))
        } else {
            (0.0, (self.height - 0.2).min(self.rng.range(2.0, 2.3)))
        };
        // Prefer the part of the wall the camera sees.
        let (a_lo, a_hi) = match face {
            5 => self.far_span(half + 0.08),
            0 => self.side_span(-1.0, half + 0.08),
            _ => self.side_span(1.0, half + 0.08),
        };
        let (a_lo, a_hi) = if a_hi > a_lo {
            (a_lo, a_hi)
        } else if face == 5 {
            (-self.hw + half + 0.1, self.hw - half - 0.1)
        } else {
            ((self.w.cam_pos.z + 0.8).max(half + 0.1), self.depth - half - 0.1)
        };
        if a_hi <= a_lo {
            return;
        }
        let a = self.rng.range(a_lo, a_hi);
        used.push(face);
        self.w.room.openings.push(Opening { face, rect: [a - half, y0, a + half, y1] });
        if glass {
            let gm = self.glass();
            let g = self.begin();
            let yc = 0.5 * (y0 + y1);
            let (c, u) = match face {
                5 => (v3(a, yc, self.depth - 0.05), v3(1.0, 0.0, 0.0)),
                0 => (v3(-self.hw + 0.05, yc, a), v3(0.0, 0.0, 1.0)),
                _ => (v3(self.hw - 0.05, yc, a), v3(0.0, 0.0, 1.0)),
            };
            self.push(Shape::Quad { center: c, u, v: v3(0.0, 1.0, 0.0), hu: half + 0.01, hv: 0.5 * (y1 - y0) + 0.01 }, gm);
            // A mullion now and then.
            if self.rng.chance(0.5) {
                let fm = self.object_mat(false);
                let yaw = if face == 5 { 0.0 } else { FRAC_PI_2 };
                self.cuboid(c, v3(0.02, 0.5 * (y1 - y0), 0.04), yaw, fm);
            }
            self.end(g);
        }
    }
}

fn top_or_new(b: &mut Builder<'_>, top: u16, glass_top: bool) -> u16 {
    if glass_top {
        b.object_mat(false)
    } else {
        top
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum WallItem {
    Mirror,
    Tv,
    Picture,
}

/// Builds the world of scene `seed` for a camera with horizontal field of view `hfov` (radians).
pub fn build(cfg: &SceneConfig, seed: u64, hfov: f32) -> World {
    let mut rng = Rng::derive(seed, 0x5CE7E);
    let corridor = rng.chance(cfg.corridor_prob);
    let (width, depth) = if corridor {
        let d_lo = cfg.room_depth_m[0].max(6.0).min(cfg.room_depth_m[1]);
        (range(&mut rng, cfg.corridor_width_m), range(&mut rng, [d_lo, cfg.room_depth_m[1]]))
    } else {
        (range(&mut rng, cfg.room_width_m), range(&mut rng, cfg.room_depth_m))
    };
    let height = range(&mut rng, cfg.room_height_m);
    let hw = width * 0.5;
    let cam_z = rng.range(0.25, (0.3 * depth).min(1.5));
    let cam_x = rng.range(-0.6, 0.6) * (hw - 0.3).max(0.0);
    let cam_y = range(&mut rng, cfg.camera_height_m).min(height - 0.3);
    let yaw_range = if corridor { [cfg.camera_yaw_deg[0] * 0.4, cfg.camera_yaw_deg[1] * 0.4] } else { cfg.camera_yaw_deg };
    let yaw = range(&mut rng, yaw_range).to_radians();
    let pitch = range(&mut rng, cfg.camera_pitch_deg).to_radians();
    let roll = range(&mut rng, cfg.camera_roll_deg).to_radians();
    let flip = M3 { r: [v3(1.0, 0.0, 0.0), v3(0.0, -1.0, 0.0), v3(0.0, 0.0, 1.0)] };
    let cam_rot = M3::rot_y(yaw).mul(&M3::rot_x(-pitch)).mul(&M3::rot_z(roll)).mul(&flip);

    let room = RoomBox { min: v3(-hw, 0.0, 0.0), max: v3(hw, height, depth), openings: vec![], face_mat: [0; 6] };
    let world = World {
        room,
        outer: None,
        prims: vec![],
        groups: vec![],
        mats: vec![],
        lights: vec![],
        ambient: V3::ZERO,
        daylight: V3::ZERO,
        shadow_samples: 1,
        cam_pos: v3(cam_x, cam_y, cam_z),
        cam_rot,
        exposure_key: 0.3,
    };
    let mut b = Builder { rng, cfg, w: world, taken: vec![], hw, depth, height, yaw, hfov };

    // Surfaces of the room: one wall material, sometimes an accent wall.
    let wall = b.diffuse(Role::Wall);
    let floor = b.diffuse(Role::Floor);
    let ceil_c = b.colour([0.0, 0.1], [0.75, 0.95]);
    let ceiling = b.add_mat(Material::diffuse(Texture::plain(ceil_c), 0.2, 0.7));
    let mut fm = [wall, wall, floor, ceiling, wall, wall];
    if b.rng.chance(0.35) {
        let accent = b.diffuse(Role::Wall);
        fm[[0usize, 1, 5][b.rng.below(3) as usize]] = accent;
    }
    b.w.room.face_mat = fm;

    // What this scene has.
    let has_glass = b.rng.chance(cfg.glass_prob);
    let has_mirror = b.rng.chance(cfg.mirror_prob);
    let has_dark = b.rng.chance(cfg.dark_prob);
    let has_opening = b.rng.chance(cfg.opening_prob);

    let mut used = vec![];
    if has_opening {
        for _ in 0..1 + b.rng.below(2) {
            let window = b.rng.chance(0.6);
            let glass = window && has_glass && b.rng.chance(0.85);
            b.opening(window, glass, &mut used);
        }
    }
    if !b.w.room.openings.is_empty() {
        let ex = b.rng.range(2.0, 8.0);
        let ez = b.rng.range(3.0, 12.0);
        let ground = b.diffuse(Role::Floor);
        let facade = b.diffuse(Role::Wall);
        let sky_c = hsv_linear(b.rng.range(0.55, 0.62), b.rng.range(0.05, 0.4), b.rng.range(0.8, 1.0));
        let sky = b.add_mat(Material::diffuse(Texture::plain(sky_c), 0.05, 0.2));
        for &m in &[ground, facade, sky] {
            b.w.mats[m as usize].exterior = true;
        }
        b.w.outer = Some(RoomBox {
            min: v3(-hw - ex, -0.1, -1.0),
            max: v3(hw + ex, height + b.rng.range(3.0, 10.0), depth + ez),
            openings: vec![],
            face_mat: [facade, facade, ground, sky, facade, facade],
        });
    }

    // Special materials first so they are not crowded out.
    if has_glass {
        // Besides any window pane, one piece of glass furniture placed in view.
        let ok = match b.rng.below(5) {
            0 | 1 => b.standing_pane(false),
            2 => b.table(true, false),
            _ => b.cabinet(true, false),
        };
        if !ok {
            b.standing_pane(false);
        }
    }
    if has_mirror {
        if b.rng.chance(0.7) {
            b.wall_item(WallItem::Mirror);
        } else if !b.standing_pane(true) {
            b.wall_item(WallItem::Mirror);
        }
    }
    let mut n_dark = if has_dark { 1 + b.rng.below(2) as u32 } else { 0 };
    let n_obj = count(&mut b.rng, cfg.objects);
    for i in 0..n_obj {
        let dark = n_dark > 0 && (i >= n_obj.saturating_sub(n_dark) || b.rng.chance(0.3));
        let ok = match b.rng.below(8) {
            0 | 1 => b.table(false, dark),
            2 => b.chair(dark),
            3 => b.cabinet(false, dark),
            4 => b.sofa(dark),
            5 => b.boxes(dark),
            _ => b.round_thing(dark),
        };
        if ok && dark {
            n_dark -= 1;
        }
    }
    if n_dark > 0 {
        b.wall_item(WallItem::Tv);
    }
    for _ in 0..count(&mut b.rng, cfg.thin_structures) {
        b.thin();
    }
    for _ in 0..count(&mut b.rng, cfg.slanted_planes) {
        b.slanted();
    }
    for _ in 0..count(&mut b.rng, cfg.wall_items) {
        let k = if b.rng.chance(0.75) { WallItem::Picture } else { WallItem::Tv };
        b.wall_item(k);
    }

    // Lamps near the ceiling, warm to cool.
    let n_lights = count(&mut b.rng, cfg.lights).max(1);
    let soft = b.rng.chance(cfg.soft_shadow_prob);
    b.w.shadow_samples = if soft { cfg.soft_shadow_samples.max(1) } else { 1 };
    for _ in 0..n_lights {
        let warm = b.rng.f32();
        let col = v3(1.0, 0.92 + 0.08 * (1.0 - warm), 0.75 + 0.3 * (1.0 - warm));
        let pos = v3(
            b.rng.range(-0.8, 0.8) * hw,
            height - b.rng.range(0.15, 0.5),
            b.rng.range(0.1, 0.9) * depth,
        );
        let power = col * (b.rng.range(2.0, 6.0) / n_lights as f32 * (1.0 + depth / 8.0));
        let radius = if soft { b.rng.range(0.1, 0.35) } else { 0.0 };
        b.w.lights.push(Light { pos, power, radius });
    }
    b.w.ambient = v3(0.9, 0.95, 1.0) * b.rng.range(0.04, 0.15);
    b.w.daylight = v3(0.95, 0.97, 1.0) * b.rng.range(0.8, 2.0);
    b.w.exposure_key = b.rng.range(0.22, 0.4);
    b.w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_lamps_and_items_sit_inside_the_room() {
        for seed in 0..40 {
            let w = build(&SceneConfig::default(), seed, 1.1);
            let (lo, hi) = (w.room.min, w.room.max);
            let inside = |p: V3| p.x > lo.x && p.x < hi.x && p.y > lo.y && p.y < hi.y && p.z > lo.z && p.z < hi.z;
            assert!(inside(w.cam_pos), "seed {seed}: camera {:?}", w.cam_pos);
            assert!(!w.lights.is_empty() && w.lights.len() <= 3);
            assert!(w.lights.iter().all(|l| inside(l.pos)));
            let depth = hi.z - lo.z;
            assert!((2.5..=12.0).contains(&depth), "seed {seed}: depth {depth}");
            // Each group's sphere encloses its primitives' spheres, and groups tile the list.
            let mut next = 0;
            for g in &w.groups {
                assert_eq!(g.start, next);
                next = g.end;
                for p in &w.prims[g.start as usize..g.end as usize] {
                    assert!((p.bc - g.bc).len() + p.br <= g.br * 1.0001 + 1e-5);
                }
            }
            assert_eq!(next as usize, w.prims.len());
            // The camera is outside every item.
            for p in &w.prims {
                if let Shape::Cuboid { .. } | Shape::Sphere { .. } | Shape::Cylinder { .. } = p.shape {
                    assert!((w.cam_pos - p.bc).len() > 0.3 || p.br > 1.5, "seed {seed}: camera in {:?}", p.shape);
                }
            }
        }
    }
}
