//! Minimal 3-vector and ray algebra for the scene tracer (f32, world frame: x right, y up,
//! z forward; camera frame: x right, y down, z forward).
use core::ops::{Add, Mul, Neg, Sub};

/// A 3-vector (point, direction or linear RGB colour).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct V3 {
    /// x component.
    pub x: f32,
    /// y component.
    pub y: f32,
    /// z component.
    pub z: f32,
}

/// Shorthand constructor.
#[inline]
pub const fn v3(x: f32, y: f32, z: f32) -> V3 {
    V3 { x, y, z }
}

impl V3 {
    /// The zero vector.
    pub const ZERO: V3 = v3(0.0, 0.0, 0.0);
    /// All components equal to `s`.
    #[inline]
    pub const fn splat(s: f32) -> V3 {
        v3(s, s, s)
    }
    /// Dot product.
    #[inline]
    pub fn dot(self, o: V3) -> f32 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// Cross product.
    #[inline]
    pub fn cross(self, o: V3) -> V3 {
        v3(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    /// Euclidean length.
    #[inline]
    pub fn len(self) -> f32 {
        self.dot(self).sqrt()
    }
    /// Unit vector in the same direction (zero stays zero).
    #[inline]
    pub fn norm(self) -> V3 {
        let l = self.len();
        if l > 0.0 {
            self * (1.0 / l)
        } else {
            self
        }
    }
    /// Component-wise product.
    #[inline]
    pub fn mul(self, o: V3) -> V3 {
        v3(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    /// Linear interpolation `self·(1−t) + o·t`.
    #[inline]
    pub fn lerp(self, o: V3, t: f32) -> V3 {
        self + (o - self) * t
    }
    /// Reflection of direction `self` about unit normal `n`.
    #[inline]
    pub fn reflect(self, n: V3) -> V3 {
        self - n * (2.0 * self.dot(n))
    }
    /// Component by axis index 0..=2.
    #[inline]
    pub fn axis(self, i: usize) -> f32 {
        match i {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }
    /// Largest component.
    #[inline]
    pub fn max_elem(self) -> f32 {
        self.x.max(self.y).max(self.z)
    }
}

impl Add for V3 {
    type Output = V3;
    #[inline]
    fn add(self, o: V3) -> V3 {
        v3(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl Sub for V3 {
    type Output = V3;
    #[inline]
    fn sub(self, o: V3) -> V3 {
        v3(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl Mul<f32> for V3 {
    type Output = V3;
    #[inline]
    fn mul(self, s: f32) -> V3 {
        v3(self.x * s, self.y * s, self.z * s)
    }
}
impl Neg for V3 {
    type Output = V3;
    #[inline]
    fn neg(self) -> V3 {
        v3(-self.x, -self.y, -self.z)
    }
}

/// A 3×3 rotation stored as its three rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct M3 {
    /// Rows of the matrix.
    pub r: [V3; 3],
}

impl M3 {
    /// The identity rotation.
    pub const IDENTITY: M3 = M3 {
        r: [v3(1.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), v3(0.0, 0.0, 1.0)],
    };
    /// Matrix from its columns.
    pub fn from_cols(a: V3, b: V3, c: V3) -> M3 {
        M3 {
            r: [v3(a.x, b.x, c.x), v3(a.y, b.y, c.y), v3(a.z, b.z, c.z)],
        }
    }
    /// Rotation by `a` radians about the world y (up) axis.
    pub fn rot_y(a: f32) -> M3 {
        let (s, c) = a.sin_cos();
        M3 {
            r: [v3(c, 0.0, s), v3(0.0, 1.0, 0.0), v3(-s, 0.0, c)],
        }
    }
    /// Rotation by `a` radians about the x axis.
    pub fn rot_x(a: f32) -> M3 {
        let (s, c) = a.sin_cos();
        M3 {
            r: [v3(1.0, 0.0, 0.0), v3(0.0, c, -s), v3(0.0, s, c)],
        }
    }
    /// Rotation by `a` radians about the z axis.
    pub fn rot_z(a: f32) -> M3 {
        let (s, c) = a.sin_cos();
        M3 {
            r: [v3(c, -s, 0.0), v3(s, c, 0.0), v3(0.0, 0.0, 1.0)],
        }
    }
    /// `self · v`.
    #[inline]
    pub fn apply(&self, v: V3) -> V3 {
        v3(self.r[0].dot(v), self.r[1].dot(v), self.r[2].dot(v))
    }
    /// `selfᵀ · v` (the inverse for a rotation).
    #[inline]
    pub fn apply_t(&self, v: V3) -> V3 {
        self.r[0] * v.x + self.r[1] * v.y + self.r[2] * v.z
    }
    /// Matrix product `self · o`.
    pub fn mul(&self, o: &M3) -> M3 {
        let c0 = self.apply(v3(o.r[0].x, o.r[1].x, o.r[2].x));
        let c1 = self.apply(v3(o.r[0].y, o.r[1].y, o.r[2].y));
        let c2 = self.apply(v3(o.r[0].z, o.r[1].z, o.r[2].z));
        M3::from_cols(c0, c1, c2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_and_reflection_by_hand() {
        // 90° about y maps +z to +x.
        let r = M3::rot_y(core::f32::consts::FRAC_PI_2);
        let p = r.apply(v3(0.0, 0.0, 1.0));
        assert!((p.x - 1.0).abs() < 1e-6 && p.z.abs() < 1e-6);
        assert!((r.apply_t(p) - v3(0.0, 0.0, 1.0)).len() < 1e-6);
        // Reflecting (1,-1,0) on the floor normal gives (1,1,0).
        assert_eq!(
            v3(1.0, -1.0, 0.0).reflect(v3(0.0, 1.0, 0.0)),
            v3(1.0, 1.0, 0.0)
        );
        let m = M3::rot_x(0.3).mul(&M3::rot_x(-0.3));
        assert!((m.apply(v3(0.2, 0.5, 0.7)) - v3(0.2, 0.5, 0.7)).len() < 1e-6);
    }
}
