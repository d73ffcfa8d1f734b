//! Analytic ray–primitive intersection: the room (an inward-facing box with openings), oriented
//! boxes, vertical cylinders, spheres and two-sided rectangles (quads). Rays are `o + t·d` with `d`
//! not necessarily unit; `t` is returned in units of `d`.
use super::math::{v3, M3, V3};

/// A rectangular hole in one face of a [`RoomBox`] (a doorway or a window).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Opening {
    /// Face index: `2·axis + side` (axis 0 = x, 1 = y, 2 = z; side 0 = min, 1 = max).
    pub face: u8,
    /// `[a0, b0, a1, b1]` in the face's (a, b) coordinates, see [`RoomBox::face_coords`].
    pub rect: [f32; 4],
}

/// An axis-aligned box seen from the inside: a room, a corridor, or the exterior around them.
#[derive(Clone, Debug, PartialEq)]
pub struct RoomBox {
    /// Minimum corner.
    pub min: V3,
    /// Maximum corner.
    pub max: V3,
    /// Holes in the walls, through which rays leave the box.
    pub openings: Vec<Opening>,
    /// Material index of each face (`2·axis + side`).
    pub face_mat: [u16; 6],
}

/// Where a ray met a surface.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Unit world normal, facing the incoming ray.
    pub n: V3,
    /// Surface coordinates in metres, for texturing.
    pub uv: (f32, f32),
    /// Material index.
    pub mat: u16,
}

impl RoomBox {
    /// In-face coordinates `(a, b)` of point `p` on a face with the given axis: floor/ceiling
    /// (x, z); x-walls (z, y); z-walls (x, y).
    #[inline]
    pub fn face_coords(axis: usize, p: V3) -> (f32, f32) {
        match axis {
            0 => (p.z, p.y),
            1 => (p.x, p.z),
            _ => (p.x, p.y),
        }
    }

    /// The face the ray leaves through (the ray's origin must be inside); `None` when the exit
    /// point lies in an opening or is not beyond `tmin`.
    pub fn intersect(&self, o: V3, d: V3, tmin: f32) -> Option<Hit> {
        let mut best_t = f32::INFINITY;
        let mut best_axis = 0usize;
        for axis in 0..3 {
            let di = d.axis(axis);
            if di == 0.0 {
                continue;
            }
            let bound = if di > 0.0 {
                self.max.axis(axis)
            } else {
                self.min.axis(axis)
            };
            let t = (bound - o.axis(axis)) / di;
            if t < best_t {
                best_t = t;
                best_axis = axis;
            }
        }
        if !(best_t > tmin && best_t.is_finite()) {
            return None;
        }
        let p = o + d * best_t;
        let side = u8::from(d.axis(best_axis) > 0.0);
        let face = 2 * best_axis as u8 + side;
        let (a, b) = Self::face_coords(best_axis, p);
        for op in &self.openings {
            if op.face == face
                && a > op.rect[0]
                && a < op.rect[2]
                && b > op.rect[1]
                && b < op.rect[3]
            {
                return None;
            }
        }
        let mut n = V3::ZERO;
        let s = if side == 1 { -1.0 } else { 1.0 };
        match best_axis {
            0 => n.x = s,
            1 => n.y = s,
            _ => n.z = s,
        }
        Some(Hit {
            t: best_t,
            n,
            uv: (a, b),
            mat: self.face_mat[face as usize],
        })
    }
}

/// A closed or flat primitive placed in the room.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Box with half extents `half` rotated by `rot` (local → world) about `center`.
    Cuboid {
        /// Centre.
        center: V3,
        /// Half extents along the local axes.
        half: V3,
        /// Local → world rotation.
        rot: M3,
    },
    /// Vertical capped cylinder standing on `base` (centre of its bottom disc).
    Cylinder {
        /// Centre of the bottom cap.
        base: V3,
        /// Radius.
        radius: f32,
        /// Height.
        height: f32,
    },
    /// Sphere.
    Sphere {
        /// Centre.
        center: V3,
        /// Radius.
        radius: f32,
    },
    /// Two-sided rectangle `center + a·u + b·v`, `|a| ≤ hu`, `|b| ≤ hv`; `u ⟂ v` unit.
    Quad {
        /// Centre.
        center: V3,
        /// First in-plane unit axis.
        u: V3,
        /// Second in-plane unit axis.
        v: V3,
        /// Half size along `u`.
        hu: f32,
        /// Half size along `v`.
        hv: f32,
    },
}

/// A shape with its material and bounding sphere.
#[derive(Clone, Debug, PartialEq)]
pub struct Prim {
    /// Geometry.
    pub shape: Shape,
    /// Material index.
    pub mat: u16,
    /// Bounding-sphere centre.
    pub bc: V3,
    /// Bounding-sphere radius.
    pub br: f32,
}

impl Prim {
    /// Wraps a shape, computing its bounding sphere.
    pub fn new(shape: Shape, mat: u16) -> Prim {
        let (bc, br) = match &shape {
            Shape::Cuboid { center, half, .. } => (*center, half.len()),
            Shape::Cylinder {
                base,
                radius,
                height,
            } => {
                let h = height * 0.5;
                (*base + v3(0.0, h, 0.0), (radius * radius + h * h).sqrt())
            }
            Shape::Sphere { center, radius } => (*center, *radius),
            Shape::Quad { center, hu, hv, .. } => (*center, (hu * hu + hv * hv).sqrt()),
        };
        Prim {
            shape,
            mat,
            bc,
            br: br * 1.0001 + 1e-4,
        }
    }

    /// Whether the ray can meet the bounding sphere within `(tmin, tmax)`.
    #[inline]
    pub fn may_hit(&self, o: V3, d: V3, tmin: f32, tmax: f32) -> bool {
        let oc = o - self.bc;
        let a = d.dot(d);
        let b = oc.dot(d);
        let c = oc.dot(oc) - self.br * self.br;
        let disc = b * b - a * c;
        if disc < 0.0 {
            return false;
        }
        let s = disc.sqrt();
        let t1 = (-b + s) / a;
        let t0 = (-b - s) / a;
        t1 > tmin && t0 < tmax
    }

    /// Nearest intersection in `(tmin, tmax)`: its ray parameter and which part of the shape
    /// (box axis, cylinder side/cap) was hit, for [`Prim::surface`]. Cheap: no normal, no uv.
    #[inline]
    pub fn hit(&self, o: V3, d: V3, tmin: f32, tmax: f32) -> Option<(f32, u8)> {
        if !self.may_hit(o, d, tmin, tmax) {
            return None;
        }
        match &self.shape {
            Shape::Cuboid { center, half, rot } => cuboid(*center, *half, rot, o, d, tmin, tmax),
            Shape::Cylinder {
                base,
                radius,
                height,
            } => cylinder(*base, *radius, *height, o, d, tmin, tmax),
            Shape::Sphere { center, radius } => sphere(*center, *radius, o, d, tmin, tmax),
            Shape::Quad {
                center,
                u,
                v,
                hu,
                hv,
            } => quad(*center, *u, *v, *hu, *hv, o, d, tmin, tmax),
        }
    }

    /// Normal (facing the ray) and texture coordinates where [`Prim::hit`] found `(t, part)`.
    pub fn surface(&self, o: V3, d: V3, t: f32, part: u8) -> Hit {
        let p = o + d * t;
        let (n, uv) = match &self.shape {
            Shape::Cuboid { center, half, rot } => {
                let lp = rot.apply_t(p - *center);
                let axis = part as usize;
                let mut ln = V3::ZERO;
                let s = lp.axis(axis).signum();
                match axis {
                    0 => ln.x = s,
                    1 => ln.y = s,
                    _ => ln.z = s,
                }
                // The face's two local coordinates, offset so faces differ.
                let uv = match axis {
                    0 => (lp.z + half.z, lp.y + half.y),
                    1 => (lp.x + half.x, lp.z + half.z),
                    _ => (lp.x + half.x, lp.y + half.y),
                };
                (rot.apply(ln), uv)
            }
            Shape::Cylinder { base, radius, .. } => {
                let (px, py, pz) = (p.x - base.x, p.y - base.y, p.z - base.z);
                match part {
                    0 => (v3(px, 0.0, pz).norm(), (pz.atan2(px) * radius, py)),
                    1 => (v3(0.0, -1.0, 0.0), (px, pz)),
                    _ => (v3(0.0, 1.0, 0.0), (px, pz)),
                }
            }
            Shape::Sphere { center, radius } => {
                let n = (p - *center).norm();
                (
                    n,
                    (
                        n.z.atan2(n.x) * radius,
                        n.y.clamp(-1.0, 1.0).asin() * radius,
                    ),
                )
            }
            Shape::Quad {
                center,
                u,
                v,
                hu,
                hv,
            } => {
                let q = p - *center;
                (u.cross(*v), (q.dot(*u) + hu, q.dot(*v) + hv))
            }
        };
        let n = if n.dot(d) > 0.0 { -n } else { n };
        Hit {
            t,
            n,
            uv,
            mat: self.mat,
        }
    }

    /// Nearest intersection in `(tmin, tmax)` with its surface.
    #[cfg(test)]
    pub fn intersect(&self, o: V3, d: V3, tmin: f32, tmax: f32) -> Option<Hit> {
        let (t, part) = self.hit(o, d, tmin, tmax)?;
        Some(self.surface(o, d, t, part))
    }
}

type Raw = (f32, u8);

fn cuboid(c: V3, h: V3, rot: &M3, o: V3, d: V3, tmin: f32, tmax: f32) -> Option<Raw> {
    let lo = rot.apply_t(o - c);
    let ld = rot.apply_t(d);
    let mut t0 = f32::NEG_INFINITY;
    let mut t1 = f32::INFINITY;
    let (mut ax0, mut ax1) = (0u8, 0u8);
    for i in 0..3 {
        let oi = lo.axis(i);
        let di = ld.axis(i);
        let hi = h.axis(i);
        if di.abs() < 1e-12 {
            if oi.abs() > hi {
                return None;
            }
            continue;
        }
        let inv = 1.0 / di;
        let (mut a, mut b) = ((-hi - oi) * inv, (hi - oi) * inv);
        if a > b {
            core::mem::swap(&mut a, &mut b);
        }
        if a > t0 {
            t0 = a;
            ax0 = i as u8;
        }
        if b < t1 {
            t1 = b;
            ax1 = i as u8;
        }
    }
    if t0 > t1 {
        return None;
    }
    let hit = if t0 > tmin {
        (t0, ax0)
    } else if t1 > tmin {
        (t1, ax1)
    } else {
        return None;
    };
    (hit.0 < tmax).then_some(hit)
}

fn cylinder(base: V3, r: f32, hgt: f32, o: V3, d: V3, tmin: f32, tmax: f32) -> Option<Raw> {
    let mut best: Option<Raw> = None;
    let mut best_t = tmax;
    let ox = o.x - base.x;
    let oz = o.z - base.z;
    let a = d.x * d.x + d.z * d.z;
    if a > 1e-12 {
        let b = ox * d.x + oz * d.z;
        let c = ox * ox + oz * oz - r * r;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let s = disc.sqrt();
            for t in [(-b - s) / a, (-b + s) / a] {
                if t > tmin && t < best_t {
                    let y = o.y + d.y * t - base.y;
                    if (0.0..=hgt).contains(&y) {
                        best_t = t;
                        best = Some((t, 0));
                        break;
                    }
                }
            }
        }
    }
    if d.y.abs() > 1e-12 {
        for (yc, part) in [(base.y, 1u8), (base.y + hgt, 2)] {
            let t = (yc - o.y) / d.y;
            if t > tmin && t < best_t {
                let px = ox + d.x * t;
                let pz = oz + d.z * t;
                if px * px + pz * pz <= r * r {
                    best_t = t;
                    best = Some((t, part));
                }
            }
        }
    }
    best
}

fn sphere(c: V3, r: f32, o: V3, d: V3, tmin: f32, tmax: f32) -> Option<Raw> {
    let oc = o - c;
    let a = d.dot(d);
    let b = oc.dot(d);
    let cc = oc.dot(oc) - r * r;
    let disc = b * b - a * cc;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let t = [(-b - s) / a, (-b + s) / a]
        .into_iter()
        .find(|&t| t > tmin && t < tmax)?;
    Some((t, 0))
}

#[allow(clippy::too_many_arguments)]
fn quad(c: V3, u: V3, v: V3, hu: f32, hv: f32, o: V3, d: V3, tmin: f32, tmax: f32) -> Option<Raw> {
    let n = u.cross(v);
    let dn = d.dot(n);
    if dn.abs() < 1e-12 {
        return None;
    }
    let t = (c - o).dot(n) / dn;
    if !(t > tmin && t < tmax) {
        return None;
    }
    let p = o + d * t - c;
    if p.dot(u).abs() > hu || p.dot(v).abs() > hv {
        return None;
    }
    Some((t, 0))
}

#[cfg(test)]
mod tests {
    use super::*;

    const Z: V3 = v3(0.0, 0.0, 1.0);

    #[test]
    fn primitives_hit_where_computed_by_hand() {
        let o = V3::ZERO;
        // Unit cube centred at z = 3: front face at z = 2.5.
        let b = Prim::new(
            Shape::Cuboid {
                center: v3(0.0, 0.0, 3.0),
                half: V3::splat(0.5),
                rot: M3::IDENTITY,
            },
            0,
        );
        let h = b.intersect(o, Z, 1e-4, 100.0).unwrap();
        assert!((h.t - 2.5).abs() < 1e-5 && (h.n - v3(0.0, 0.0, -1.0)).len() < 1e-6);
        // Rotated by 45°: the nearest edge is at 3 - 0.5·√2.
        let b = Prim::new(
            Shape::Cuboid {
                center: v3(0.0, 0.0, 3.0),
                half: V3::splat(0.5),
                rot: M3::rot_y(core::f32::consts::FRAC_PI_4),
            },
            0,
        );
        let h = b.intersect(o, Z, 1e-4, 100.0).unwrap();
        assert!((h.t - (3.0 - 0.5 * 2f32.sqrt())).abs() < 1e-4, "{}", h.t);
        // Sphere radius 1 at z = 5, ray with d = (0,0,2): t = 2 (point z = 4).
        let s = Prim::new(
            Shape::Sphere {
                center: v3(0.0, 0.0, 5.0),
                radius: 1.0,
            },
            0,
        );
        assert!((s.intersect(o, v3(0.0, 0.0, 2.0), 1e-4, 100.0).unwrap().t - 2.0).abs() < 1e-5);
        // Cylinder radius 0.5 standing at z = 4 from y = -1 to 1: side at z = 3.5.
        let c = Prim::new(
            Shape::Cylinder {
                base: v3(0.0, -1.0, 4.0),
                radius: 0.5,
                height: 2.0,
            },
            0,
        );
        assert!((c.intersect(o, Z, 1e-4, 100.0).unwrap().t - 3.5).abs() < 1e-5);
        // Looking down on its top cap from above: y = 1 reached at t = 2.
        let h = c
            .intersect(v3(0.0, 3.0, 4.0), v3(0.0, -1.0, 0.0), 1e-4, 100.0)
            .unwrap();
        assert!((h.t - 2.0).abs() < 1e-5 && h.n.y > 0.99);
        // Quad at z = 2 of half size 1; a ray through x = 1.5 misses it.
        let q = Prim::new(
            Shape::Quad {
                center: v3(0.0, 0.0, 2.0),
                u: v3(1.0, 0.0, 0.0),
                v: v3(0.0, 1.0, 0.0),
                hu: 1.0,
                hv: 1.0,
            },
            0,
        );
        assert!((q.intersect(o, Z, 1e-4, 100.0).unwrap().t - 2.0).abs() < 1e-6);
        assert!(q.intersect(v3(1.5, 0.0, 0.0), Z, 1e-4, 100.0).is_none());
        // tmax excludes hits beyond it.
        assert!(q.intersect(o, Z, 1e-4, 1.9).is_none());
    }

    #[test]
    fn room_exit_face_and_opening() {
        let mut room = RoomBox {
            min: v3(-2.0, 0.0, 0.0),
            max: v3(2.0, 3.0, 6.0),
            openings: vec![],
            face_mat: [0, 1, 2, 3, 4, 5],
        };
        let o = v3(0.0, 1.5, 1.0);
        let h = room.intersect(o, Z, 1e-4).unwrap();
        assert!((h.t - 5.0).abs() < 1e-6 && h.mat == 5 && h.n.z < -0.99);
        // Towards the floor, 45° down: exits y = 0 at t = 1.5.
        let h = room.intersect(o, v3(0.0, -1.0, 1.0), 1e-4).unwrap();
        assert!((h.t - 1.5).abs() < 1e-6 && h.mat == 2);
        room.openings.push(Opening {
            face: 5,
            rect: [-0.5, 1.0, 0.5, 2.0],
        });
        assert!(room.intersect(o, Z, 1e-4).is_none());
    }
}
