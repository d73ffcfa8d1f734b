//! Random scene layout: a room or corridor with openings to an exterior, furniture built from
//! primitives, thin structures, glass, mirrors, dark absorbers, lamps and a camera pose, all drawn
//! from one [`Rng`] stream so a seed fixes the scene.
use super::config::SceneConfig;
use super::furniture::WallItem;
use super::material::{hsv_linear, Material};
use super::math::{v3, M3, V3};
use super::shapes::{Prim, RoomBox, Shape};
use super::texture::{Role, Texture};
use crate::rng::Rng;
use core::f32::consts::FRAC_PI_2;

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
    /// Whether it can shadow anything (false for flat things hung on walls).
    pub casts_shadow: bool,
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

/// Scene under construction, with the random stream that draws it.
pub(super) struct Builder<'a> {
    /// The scene's random stream.
    pub(super) rng: Rng,
    /// Ranges to draw from.
    pub(super) cfg: &'a SceneConfig,
    /// The world built so far.
    pub(super) w: World,
    /// Floor footprints `(x, z, radius)` already taken.
    pub(super) taken: Vec<(f32, f32, f32)>,
    /// Half the room width, metres.
    pub(super) hw: f32,
    /// Room depth, metres.
    pub(super) depth: f32,
    /// Ceiling height, metres.
    pub(super) height: f32,
    /// Camera yaw, radians.
    pub(super) yaw: f32,
    /// Camera horizontal field of view, radians.
    pub(super) hfov: f32,
}

pub(super) fn range(r: &mut Rng, lr: [f32; 2]) -> f32 {
    if lr[1] > lr[0] {
        r.range(lr[0], lr[1])
    } else {
        lr[0]
    }
}

pub(super) fn count(r: &mut Rng, lr: [u32; 2]) -> u32 {
    lr[0] + r.below(u64::from(lr[1].saturating_sub(lr[0])) + 1) as u32
}

impl Builder<'_> {
    pub(super) fn add_mat(&mut self, m: Material) -> u16 {
        self.w.mats.push(m);
        (self.w.mats.len() - 1) as u16
    }

    pub(super) fn begin(&self) -> u32 {
        self.w.prims.len() as u32
    }

    /// Closes the item begun at `start` (see [`Self::begin`]).
    pub(super) fn end(&mut self, start: u32) {
        self.end_item(start, true);
    }

    /// Closes an item flat against a wall, which casts no shadow worth a ray.
    pub(super) fn end_flat(&mut self, start: u32) {
        self.end_item(start, false);
    }

    fn end_item(&mut self, start: u32, casts_shadow: bool) {
        let end = self.w.prims.len() as u32;
        if end == start {
            return;
        }
        let ps = &self.w.prims[start as usize..end as usize];
        let mut lo = V3::splat(f32::INFINITY);
        let mut hi = V3::splat(f32::NEG_INFINITY);
        for p in ps {
            lo = v3(
                lo.x.min(p.bc.x - p.br),
                lo.y.min(p.bc.y - p.br),
                lo.z.min(p.bc.z - p.br),
            );
            hi = v3(
                hi.x.max(p.bc.x + p.br),
                hi.y.max(p.bc.y + p.br),
                hi.z.max(p.bc.z + p.br),
            );
        }
        let bc = (lo + hi) * 0.5;
        let br = ps
            .iter()
            .map(|p| (p.bc - bc).len() + p.br)
            .fold(0.0f32, f32::max);
        self.w.groups.push(Group {
            start,
            end,
            bc,
            br,
            casts_shadow,
        });
    }

    pub(super) fn push(&mut self, s: Shape, mat: u16) {
        self.w.prims.push(Prim::new(s, mat));
    }

    pub(super) fn cuboid(&mut self, center: V3, half: V3, yaw: f32, mat: u16) {
        let rot = if yaw == 0.0 {
            M3::IDENTITY
        } else {
            M3::rot_y(yaw)
        };
        self.push(Shape::Cuboid { center, half, rot }, mat);
    }

    pub(super) fn colour(&mut self, sat: [f32; 2], val: [f32; 2]) -> V3 {
        let h = self.rng.f32();
        let s = range(&mut self.rng, sat);
        let v = range(&mut self.rng, val);
        hsv_linear(h, s, v)
    }

    /// A free floor spot for a footprint of radius `r`: in view with probability `p_view`.
    pub(super) fn spot(&mut self, r: f32, p_view: f32) -> Option<(f32, f32)> {
        self.spot_within(r, p_view, f32::INFINITY)
    }

    /// Like [`Self::spot`], at most `max_d` metres from the camera when in view.
    pub(super) fn spot_within(&mut self, r: f32, p_view: f32, max_d: f32) -> Option<(f32, f32)> {
        let cam = self.w.cam_pos;
        for _ in 0..16 {
            let (x, z) = if self.rng.chance(p_view) {
                let a = self.yaw + self.rng.range(-0.45, 0.45) * self.hfov;
                let d = self
                    .rng
                    .range(1.0, (self.depth - cam.z).min(max_d).max(1.2));
                (cam.x + d * a.sin(), cam.z + d * a.cos())
            } else {
                (
                    self.rng.range(-self.hw, self.hw),
                    self.rng.range(0.0, self.depth),
                )
            };
            let m = r + 0.05;
            if x - m < -self.hw || x + m > self.hw || z - m < 0.0 || z + m > self.depth {
                continue;
            }
            let dc = ((x - cam.x).powi(2) + (z - cam.z).powi(2)).sqrt();
            if dc < r + 0.6 {
                continue;
            }
            if self
                .taken
                .iter()
                .any(|&(tx, tz, tr)| ((x - tx).powi(2) + (z - tz).powi(2)).sqrt() < r + tr)
            {
                continue;
            }
            self.taken.push((x, z, r));
            return Some((x, z));
        }
        None
    }

    /// The x-interval of the far wall inside the view cone, for an item of half width `half`.
    pub(super) fn far_span(&self, half: f32) -> (f32, f32) {
        let (cam, half_fov) = (self.w.cam_pos, 0.42 * self.hfov);
        let dz = self.depth - cam.z;
        let lo = (cam.x + dz * (self.yaw - half_fov).tan()).max(-self.hw + half + 0.02);
        let hi = (cam.x + dz * (self.yaw + half_fov).tan()).min(self.hw - half - 0.02);
        (lo, hi)
    }

    /// The z-interval of side wall `side` (−1 left, +1 right) inside the view cone.
    pub(super) fn side_span(&self, side: f32, half: f32) -> (f32, f32) {
        let (cam, half_fov) = (self.w.cam_pos, 0.42 * self.hfov);
        let dx = (side * self.hw - cam.x).abs();
        let ang = (FRAC_PI_2 - half_fov - side * self.yaw).max(0.05);
        let lo = (cam.z + dx * ang.tan()).max(cam.z + 0.8).max(half + 0.05);
        (lo, self.depth - half - 0.05)
    }

    /// A rectangle on a wall facing into the room, placed where the camera sees it when it can
    /// be: `(center, u, normal)`; `half_u` is its half size along the wall.
    pub(super) fn wall_spot(&mut self, half_u: f32, y: f32) -> (V3, V3, V3) {
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
            (
                v3(side * self.hw, y, z),
                v3(0.0, 0.0, 1.0),
                v3(-side, 0.0, 0.0),
            )
        } else {
            let x = self
                .rng
                .range(-self.hw + half_u, self.hw - half_u)
                .clamp(-self.hw, self.hw);
            (v3(x, y, self.depth), v3(1.0, 0.0, 0.0), v3(0.0, 0.0, -1.0))
        }
    }
}

/// Builds the world of scene `seed` for a camera with horizontal field of view `hfov` (radians).
pub fn build(cfg: &SceneConfig, seed: u64, hfov: f32) -> World {
    let mut rng = Rng::derive(seed, 0x5CE7E);
    let corridor = rng.chance(cfg.corridor_prob);
    let (width, depth) = if corridor {
        let d_lo = cfg.room_depth_m[0].max(6.0).min(cfg.room_depth_m[1]);
        (
            range(&mut rng, cfg.corridor_width_m),
            range(&mut rng, [d_lo, cfg.room_depth_m[1]]),
        )
    } else {
        (
            range(&mut rng, cfg.room_width_m),
            range(&mut rng, cfg.room_depth_m),
        )
    };
    let height = range(&mut rng, cfg.room_height_m);
    let hw = width * 0.5;
    let cam_z = rng.range(0.25, (0.3 * depth).min(1.5));
    let cam_x = rng.range(-0.6, 0.6) * (hw - 0.3).max(0.0);
    let cam_y = range(&mut rng, cfg.camera_height_m).min(height - 0.3);
    let yaw_range = if corridor {
        [cfg.camera_yaw_deg[0] * 0.4, cfg.camera_yaw_deg[1] * 0.4]
    } else {
        cfg.camera_yaw_deg
    };
    let yaw = range(&mut rng, yaw_range).to_radians();
    let pitch = range(&mut rng, cfg.camera_pitch_deg).to_radians();
    let roll = range(&mut rng, cfg.camera_roll_deg).to_radians();
    let flip = M3 {
        r: [v3(1.0, 0.0, 0.0), v3(0.0, -1.0, 0.0), v3(0.0, 0.0, 1.0)],
    };
    let cam_rot = M3::rot_y(yaw)
        .mul(&M3::rot_x(-pitch))
        .mul(&M3::rot_z(roll))
        .mul(&flip);

    let room = RoomBox {
        min: v3(-hw, 0.0, 0.0),
        max: v3(hw, height, depth),
        openings: vec![],
        face_mat: [0; 6],
    };
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
    let mut b = Builder {
        rng,
        cfg,
        w: world,
        taken: vec![],
        hw,
        depth,
        height,
        yaw,
        hfov,
    };

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
        let sky_c = hsv_linear(
            b.rng.range(0.55, 0.62),
            b.rng.range(0.05, 0.4),
            b.rng.range(0.8, 1.0),
        );
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
    // A wall mirror, or a standing one (falling back to the wall when there is no room).
    if has_mirror && (b.rng.chance(0.7) || !b.standing_pane(true)) {
        b.wall_item(WallItem::Mirror);
    }
    let mut n_dark = if has_dark {
        1 + b.rng.below(2) as u32
    } else {
        0
    };
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
        let k = if b.rng.chance(0.75) {
            WallItem::Picture
        } else {
            WallItem::Tv
        };
        b.wall_item(k);
    }

    // Lamps near the ceiling, warm to cool.
    let n_lights = count(&mut b.rng, cfg.lights).max(1);
    let soft = b.rng.chance(cfg.soft_shadow_prob);
    b.w.shadow_samples = if soft {
        cfg.soft_shadow_samples.max(1)
    } else {
        1
    };
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
    pub(super) fn camera_lamps_and_items_sit_inside_the_room() {
        for seed in 0..40 {
            let w = build(&SceneConfig::default(), seed, 1.1);
            let (lo, hi) = (w.room.min, w.room.max);
            let inside = |p: V3| {
                p.x > lo.x && p.x < hi.x && p.y > lo.y && p.y < hi.y && p.z > lo.z && p.z < hi.z
            };
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
                if let Shape::Cuboid { .. } | Shape::Sphere { .. } | Shape::Cylinder { .. } =
                    p.shape
                {
                    assert!(
                        (w.cam_pos - p.bc).len() > 0.3 || p.br > 1.5,
                        "seed {seed}: camera in {:?}",
                        p.shape
                    );
                }
            }
        }
    }
}
