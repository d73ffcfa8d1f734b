//! Furniture and fittings built from primitives: tables, chairs, cabinets and shelves with books,
//! sofas, box stacks, round things and plants, thin poles and lamps, leaning boards (slanted
//! planes), wall items (pictures, screens, mirrors), standing panes and wall openings.
use super::layout::Builder;
use super::material::Material;
use super::math::{v3, M3, V3};
use super::shapes::{Opening, Shape};
use super::texture::{Pattern, Role, Texture, PHOTOS};
use core::f32::consts::{FRAC_PI_2, PI};

impl Builder<'_> {
    pub(super) fn table(&mut self, glass_top: bool, dark: bool) -> bool {
        let (w, d) = (self.rng.range(0.3, 0.9), self.rng.range(0.25, 0.5));
        let Some((x, z)) = self.spot((w * w + d * d).sqrt(), 0.7) else {
            return false;
        };
        let h = self.rng.range(0.4, 0.8);
        let th = self.rng.range(0.02, 0.05);
        let yaw = if self.rng.chance(0.5) {
            0.0
        } else {
            self.rng.range(-PI, PI)
        };
        let top = if glass_top {
            self.glass()
        } else {
            self.object_mat(dark)
        };
        let leg_mat = if dark || self.rng.chance(0.5) {
            self.object_mat(dark)
        } else {
            top_or_new(self, top, glass_top)
        };
        let g = self.begin();
        self.cuboid(v3(x, h - th * 0.5, z), v3(w, th * 0.5, d), yaw, top);
        let lr = self.rng.range(0.012, 0.035);
        let round = self.rng.chance(0.5);
        let rot = M3::rot_y(yaw);
        for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let off = rot.apply(v3(sx * (w - 0.06), 0.0, sz * (d - 0.06)));
            let p = v3(x + off.x, 0.0, z + off.z);
            if round {
                self.push(
                    Shape::Cylinder {
                        base: p,
                        radius: lr,
                        height: h - th,
                    },
                    leg_mat,
                );
            } else {
                self.cuboid(
                    p + v3(0.0, (h - th) * 0.5, 0.0),
                    v3(lr, (h - th) * 0.5, lr),
                    yaw,
                    leg_mat,
                );
            }
        }
        self.end(g);
        // Something on the table now and then.
        if self.rng.chance(0.5) {
            let m = self.object_mat(false);
            let g = self.begin();
            let o = rot.apply(v3(
                self.rng.range(-0.5, 0.5) * w,
                0.0,
                self.rng.range(-0.5, 0.5) * d,
            ));
            let r = self.rng.range(0.04, 0.14);
            match self.rng.below(3) {
                0 => self.push(
                    Shape::Sphere {
                        center: v3(x + o.x, h + r, z + o.z),
                        radius: r,
                    },
                    m,
                ),
                1 => {
                    let height = self.rng.range(0.1, 0.35);
                    self.push(
                        Shape::Cylinder {
                            base: v3(x + o.x, h, z + o.z),
                            radius: r * 0.6,
                            height,
                        },
                        m,
                    )
                }
                _ => self.cuboid(
                    v3(x + o.x, h + r * 0.5, z + o.z),
                    v3(r * 1.5, r * 0.5, r),
                    yaw,
                    m,
                ),
            }
            self.end(g);
        }
        true
    }

    pub(super) fn chair(&mut self, dark: bool) -> bool {
        let s = self.rng.range(0.2, 0.26);
        let Some((x, z)) = self.spot(s * 1.5, 0.6) else {
            return false;
        };
        let yaw = self.rng.range(-PI, PI);
        let rot = M3::rot_y(yaw);
        let h = self.rng.range(0.42, 0.48);
        let m = self.object_mat(dark);
        let lm = if self.rng.chance(0.5) {
            m
        } else {
            self.object_mat(dark)
        };
        let g = self.begin();
        self.cuboid(v3(x, h - 0.02, z), v3(s, 0.02, s), yaw, m);
        for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let off = rot.apply(v3(sx * (s - 0.02), 0.0, sz * (s - 0.02)));
            self.push(
                Shape::Cylinder {
                    base: v3(x + off.x, 0.0, z + off.z),
                    radius: 0.015,
                    height: h - 0.04,
                },
                lm,
            );
        }
        let bh = self.rng.range(0.3, 0.5);
        let off = rot.apply(v3(0.0, 0.0, s - 0.015));
        self.cuboid(
            v3(x + off.x, h + bh * 0.5, z + off.z),
            v3(s, bh * 0.5, 0.015),
            yaw,
            m,
        );
        self.end(g);
        true
    }

    /// A cabinet, shelf or wardrobe, against a wall when possible; a glass door when `glass`.
    pub(super) fn cabinet(&mut self, glass: bool, dark: bool) -> bool {
        let w = self.rng.range(0.25, 1.0);
        let d = self.rng.range(0.15, 0.3);
        let h = self.rng.range(0.4, 2.1).min(self.height - 0.1);
        // Against the far wall or a side wall.
        let side = self.rng.below(3);
        let (x_lo, x_hi) = self.far_span(w);
        let (x_lo, x_hi) = if x_hi > x_lo {
            (x_lo, x_hi)
        } else {
            (-self.hw + w, self.hw - w)
        };
        let s = if side == 1 { -1.0 } else { 1.0 };
        let (z_lo, z_hi) = self.side_span(s, w);
        let (z_lo, z_hi) = if z_hi > z_lo {
            (z_lo, z_hi)
        } else {
            (1.5, self.depth - w)
        };
        let (x, z, yaw) = match side {
            0 => (self.rng.range(x_lo, x_hi), self.depth - d - 0.01, 0.0),
            1 => (
                -self.hw + d + 0.01,
                self.rng.range(z_lo, z_hi).max(1.0),
                FRAC_PI_2,
            ),
            _ => (
                self.hw - d - 0.01,
                self.rng.range(z_lo, z_hi).max(1.0),
                -FRAC_PI_2,
            ),
        };
        let r = (w * w + d * d).sqrt();
        if self
            .taken
            .iter()
            .any(|&(tx, tz, tr)| ((x - tx).powi(2) + (z - tz).powi(2)).sqrt() < r + tr)
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
                            let bm = if self.rng.chance(0.5) {
                                self.diffuse(Role::Object)
                            } else {
                                m
                            };
                            let o = rot.apply(v3(a + bw, 0.0, self.rng.range(0.0, 0.05)));
                            let bd = d * self.rng.range(0.6, 0.9);
                            self.cuboid(
                                v3(x + o.x, y + t + bh * 0.5, z + o.z),
                                v3(bw, bh * 0.5, bd),
                                yaw,
                                bm,
                            );
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
                self.push(
                    Shape::Quad {
                        center: c,
                        u: rot.apply(v3(1.0, 0.0, 0.0)),
                        v: v3(0.0, 1.0, 0.0),
                        hu: w * 0.92,
                        hv: h * 0.45,
                    },
                    gm,
                );
            }
        }
        self.end(g);
        true
    }

    pub(super) fn sofa(&mut self, dark: bool) -> bool {
        let w = self.rng.range(0.6, 1.1);
        let d = self.rng.range(0.35, 0.48);
        let Some((x, z)) = self.spot((w * w + d * d).sqrt(), 0.7) else {
            return false;
        };
        let yaw = if self.rng.chance(0.5) {
            PI
        } else {
            self.rng.range(-PI, PI)
        };
        let rot = M3::rot_y(yaw);
        let m = self.object_mat(dark);
        let g = self.begin();
        let sh = self.rng.range(0.35, 0.48);
        self.cuboid(v3(x, sh * 0.5, z), v3(w, sh * 0.5, d), yaw, m);
        let bh = self.rng.range(0.3, 0.5);
        let o = rot.apply(v3(0.0, 0.0, d - 0.1));
        self.cuboid(
            v3(x + o.x, sh + bh * 0.5, z + o.z),
            v3(w, bh * 0.5, 0.1),
            yaw,
            m,
        );
        for sx in [-1.0, 1.0] {
            let o = rot.apply(v3(sx * (w - 0.08), 0.0, 0.0));
            self.cuboid(v3(x + o.x, sh + 0.1, z + o.z), v3(0.08, 0.1, d), yaw, m);
        }
        self.end(g);
        true
    }

    pub(super) fn boxes(&mut self, dark: bool) -> bool {
        let s = self.rng.range(0.15, 0.45);
        let Some((x, z)) = self.spot(s * 1.5, 0.7) else {
            return false;
        };
        let g = self.begin();
        let mut y = 0.0;
        for _ in 0..1 + self.rng.below(3) {
            let half = v3(
                s * self.rng.range(0.7, 1.0),
                s * self.rng.range(0.4, 1.0),
                s * self.rng.range(0.7, 1.0),
            );
            let yaw = if self.rng.chance(0.4) {
                0.0
            } else {
                self.rng.range(-0.6, 0.6)
            };
            let m = self.object_mat(dark);
            self.cuboid(v3(x, y + half.y, z), half, yaw, m);
            y += 2.0 * half.y;
        }
        self.end(g);
        true
    }

    pub(super) fn round_thing(&mut self, dark: bool) -> bool {
        let r = self.rng.range(0.1, 0.4);
        let Some((x, z)) = self.spot(r, 0.7) else {
            return false;
        };
        let m = self.object_mat(dark);
        let g = self.begin();
        match self.rng.below(4) {
            0 => self.push(
                Shape::Sphere {
                    center: v3(x, r, z),
                    radius: r,
                },
                m,
            ),
            1 => {
                let h = self.rng.range(0.3, 1.0);
                self.push(
                    Shape::Cylinder {
                        base: v3(x, 0.0, z),
                        radius: r * 0.8,
                        height: h,
                    },
                    m,
                );
                if self.rng.chance(0.5) {
                    let m2 = self.object_mat(false);
                    self.push(
                        Shape::Sphere {
                            center: v3(x, h + r * 0.5, z),
                            radius: r * 0.5,
                        },
                        m2,
                    );
                }
            }
            2 => {
                // Round table: top, pole, base.
                let h = self.rng.range(0.45, 0.8);
                self.push(
                    Shape::Cylinder {
                        base: v3(x, h - 0.03, z),
                        radius: r + 0.15,
                        height: 0.03,
                    },
                    m,
                );
                self.push(
                    Shape::Cylinder {
                        base: v3(x, 0.02, z),
                        radius: 0.03,
                        height: h - 0.05,
                    },
                    m,
                );
                self.push(
                    Shape::Cylinder {
                        base: v3(x, 0.0, z),
                        radius: r * 0.6,
                        height: 0.02,
                    },
                    m,
                );
            }
            _ => {
                // Potted plant: pot and a foliage ball.
                let h = self.rng.range(0.25, 0.5);
                self.push(
                    Shape::Cylinder {
                        base: v3(x, 0.0, z),
                        radius: r * 0.6,
                        height: h,
                    },
                    m,
                );
                let leaves = PHOTOS
                    .iter()
                    .position(|p| p.0.contains("leaves"))
                    .unwrap_or(0) as u16;
                let tex = Texture {
                    pattern: Pattern::Photo(leaves),
                    c0: V3::splat(1.0),
                    c1: V3::splat(1.0),
                    scale: 0.4,
                    rot: (1.0, 0.0),
                    offset: (0.0, 0.0),
                    seed: 0,
                };
                // Chlorophyll reflects strongly at 940 nm.
                let lm = self.add_mat(Material::diffuse(tex, 0.45, 0.4));
                self.push(
                    Shape::Sphere {
                        center: v3(x, h + r * 0.9, z),
                        radius: r,
                    },
                    lm,
                );
            }
        }
        self.end(g);
        true
    }

    /// Thin structures: a floor-to-ceiling pipe, a floor lamp, or a coat stand.
    pub(super) fn thin(&mut self) -> bool {
        let Some((x, z)) = self.spot(0.25, 0.7) else {
            return false;
        };
        let dark = self.rng.chance(0.2);
        let m = self.object_mat(dark);
        let g = self.begin();
        if self.rng.chance(0.5) {
            let r = self.rng.range(0.015, 0.06);
            self.push(
                Shape::Cylinder {
                    base: v3(x, 0.0, z),
                    radius: r,
                    height: self.height,
                },
                m,
            );
        } else {
            let h = self.rng.range(1.2, 1.9);
            self.push(
                Shape::Cylinder {
                    base: v3(x, 0.0, z),
                    radius: 0.15,
                    height: 0.02,
                },
                m,
            );
            let radius = self.rng.range(0.01, 0.02);
            self.push(
                Shape::Cylinder {
                    base: v3(x, 0.02, z),
                    radius,
                    height: h,
                },
                m,
            );
            let sm = self.diffuse(Role::Object);
            if self.rng.chance(0.5) {
                let radius = self.rng.range(0.12, 0.22);
                self.push(
                    Shape::Cylinder {
                        base: v3(x, h, z),
                        radius,
                        height: 0.25,
                    },
                    sm,
                );
            } else {
                self.push(
                    Shape::Sphere {
                        center: v3(x, h + 0.12, z),
                        radius: 0.14,
                    },
                    sm,
                );
            }
        }
        self.end(g);
        true
    }

    /// A board leaning against a side or far wall (a slanted plane).
    pub(super) fn slanted(&mut self) {
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
            self.push(
                Shape::Quad {
                    center: c,
                    u: v3(1.0, 0.0, 0.0),
                    v: up,
                    hu: half_w,
                    hv: len * 0.5,
                },
                m,
            );
        } else {
            let s = if self.rng.chance(0.5) { -1.0 } else { 1.0 };
            let z = self.rng.range(1.5, (self.depth - half_w).max(1.6));
            let dx = len * tilt.sin();
            let up = v3(s * tilt.sin(), tilt.cos(), 0.0);
            let c = v3(s * (self.hw - dx * 0.5 - 0.01), len * 0.5 * tilt.cos(), z);
            self.push(
                Shape::Quad {
                    center: c,
                    u: v3(0.0, 0.0, 1.0),
                    v: up,
                    hu: half_w,
                    hv: len * 0.5,
                },
                m,
            );
        }
        self.end(g);
    }

    pub(super) fn wall_item(&mut self, kind: WallItem) {
        let (hu, hv) = match kind {
            WallItem::Mirror => (self.rng.range(0.25, 0.7), self.rng.range(0.35, 0.9)),
            WallItem::Tv => (self.rng.range(0.35, 0.8), 0.0),
            WallItem::Picture => (self.rng.range(0.15, 0.6), self.rng.range(0.15, 0.5)),
        };
        let hv = if kind == WallItem::Tv {
            hu * 0.5625
        } else {
            hv
        };
        let y = self
            .rng
            .range(hv + 0.3, (self.height - hv - 0.15).max(hv + 0.31))
            .min(self.height - hv - 0.05);
        let (c, u, n) = self.wall_spot(hu, y);
        let g = self.begin();
        match kind {
            WallItem::Mirror => {
                let m = self.mirror();
                let fm = self.object_mat(false);
                // Frame behind the glass, mirror surface 1 cm proud of it.
                self.push(
                    Shape::Quad {
                        center: c + n * 0.01,
                        u,
                        v: v3(0.0, 1.0, 0.0),
                        hu: hu + 0.03,
                        hv: hv + 0.03,
                    },
                    fm,
                );
                self.push(
                    Shape::Quad {
                        center: c + n * 0.02,
                        u,
                        v: v3(0.0, 1.0, 0.0),
                        hu,
                        hv,
                    },
                    m,
                );
            }
            WallItem::Tv => {
                let m = self.dark();
                let yaw = if n.z != 0.0 { 0.0 } else { FRAC_PI_2 };
                self.cuboid(c + n * 0.03, v3(hu, hv, 0.03), yaw, m);
            }
            WallItem::Picture => {
                let role = if self.rng.chance(0.5) {
                    Role::Object
                } else {
                    Role::Wall
                };
                let m = self.diffuse(role);
                let dark = self.rng.chance(0.3);
                let fm = self.object_mat(dark);
                let yaw = if n.z != 0.0 { 0.0 } else { FRAC_PI_2 };
                self.cuboid(c + n * 0.015, v3(hu + 0.02, hv + 0.02, 0.015), yaw, fm);
                self.push(
                    Shape::Quad {
                        center: c + n * 0.031,
                        u,
                        v: v3(0.0, 1.0, 0.0),
                        hu,
                        hv,
                    },
                    m,
                );
            }
        }
        self.end_flat(g);
    }

    /// A standing mirror or glass partition in view: a quad on two thin posts.
    pub(super) fn standing_pane(&mut self, mirror: bool) -> bool {
        let hw = self.rng.range(0.3, 0.9);
        let Some((x, z)) = self.spot_within(hw, 1.0, 5.0) else {
            return false;
        };
        let h = self.rng.range(1.0, 2.0).min(self.height - 0.1);
        let yaw = self.yaw + self.rng.range(-0.6, 0.6);
        let tilt = if mirror {
            self.rng.range(-0.15, 0.05)
        } else {
            0.0
        };
        let u = M3::rot_y(yaw).apply(v3(1.0, 0.0, 0.0));
        let fwd = M3::rot_y(yaw).apply(v3(0.0, 0.0, 1.0));
        let up = v3(0.0, tilt.cos(), 0.0) + fwd * tilt.sin();
        let m = if mirror { self.mirror() } else { self.glass() };
        let dark = self.rng.chance(0.3);
        let pm = self.object_mat(dark);
        let g = self.begin();
        let c = v3(x, 0.05 + h * 0.5 * tilt.cos(), z) + fwd * (h * 0.5 * tilt.sin());
        self.push(
            Shape::Quad {
                center: c,
                u,
                v: up.norm(),
                hu: hw,
                hv: h * 0.5,
            },
            m,
        );
        for s in [-1.0, 1.0] {
            let p = v3(x, 0.0, z) + u * (s * (hw + 0.02));
            self.push(
                Shape::Cylinder {
                    base: p,
                    radius: 0.015,
                    height: h + 0.05,
                },
                pm,
            );
        }
        self.end(g);
        true
    }

    /// A hole in a wall to the exterior: a doorway or a window (with a pane when `glass`).
    pub(super) fn opening(&mut self, window: bool, glass: bool, used: &mut Vec<u8>) {
        let face = match self.rng.below(3) {
            0 => 5u8,
            1 => 0,
            _ => 1,
        };
        if used.contains(&face) {
            return;
        }
        let half = if window {
            self.rng.range(0.3, 1.2)
        } else {
            self.rng.range(0.4, 0.8)
        };
        let (y0, y1) = if window {
            (
                self.rng.range(0.6, 1.1),
                (self.height - self.rng.range(0.2, 0.6)).max(1.4),
            )
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
            (
                (self.w.cam_pos.z + 0.8).max(half + 0.1),
                self.depth - half - 0.1,
            )
        };
        if a_hi <= a_lo {
            return;
        }
        let a = self.rng.range(a_lo, a_hi);
        used.push(face);
        self.w.room.openings.push(Opening {
            face,
            rect: [a - half, y0, a + half, y1],
        });
        if glass {
            let gm = self.glass();
            let g = self.begin();
            let yc = 0.5 * (y0 + y1);
            let (c, u) = match face {
                5 => (v3(a, yc, self.depth - 0.05), v3(1.0, 0.0, 0.0)),
                0 => (v3(-self.hw + 0.05, yc, a), v3(0.0, 0.0, 1.0)),
                _ => (v3(self.hw - 0.05, yc, a), v3(0.0, 0.0, 1.0)),
            };
            self.push(
                Shape::Quad {
                    center: c,
                    u,
                    v: v3(0.0, 1.0, 0.0),
                    hu: half + 0.01,
                    hv: 0.5 * (y1 - y0) + 0.01,
                },
                gm,
            );
            // A mullion now and then.
            if self.rng.chance(0.5) {
                let fm = self.object_mat(false);
                let yaw = if face == 5 { 0.0 } else { FRAC_PI_2 };
                self.cuboid(c, v3(0.02, 0.5 * (y1 - y0), 0.04), yaw, fm);
            }
            self.end_flat(g);
        }
    }
}

/// The legs' material: a new one under a glass top, else the top's.
pub(super) fn top_or_new(b: &mut Builder<'_>, top: u16, glass_top: bool) -> u16 {
    if glass_top {
        b.object_mat(false)
    } else {
        top
    }
}

/// Things hung on a wall.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum WallItem {
    /// A framed mirror (label 2).
    Mirror,
    /// A dark screen (label 3).
    Tv,
    /// A framed picture.
    Picture,
}
