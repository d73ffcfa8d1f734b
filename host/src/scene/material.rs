//! Surface materials: the label class, the visible-light texture and the 940 nm reflectance.
use super::math::{v3, V3};
use super::texture::{luminance, Texture};

/// Material class, written to `labels` (docs/recording.md: 0 diffuse/unknown, 1 transparent,
/// 2 specular/mirror, 3 dark/absorbing).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Class {
    /// Lambertian surface.
    Diffuse = 0,
    /// Glass: the dToF may return the surface behind it.
    Transparent = 1,
    /// Mirror: the dToF may return the reflected path.
    Specular = 2,
    /// Low-reflectance absorber: the dToF may return nothing.
    Dark = 3,
}

/// A surface's appearance in RGB and at 940 nm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Label class.
    pub class: Class,
    /// Visible albedo texture (for glass and mirrors: `c0` is the tint).
    pub tex: Texture,
    /// 940 nm reflectance = `clamp(nir_offset + nir_gain · luminance(albedo), 0, 1)`.
    pub nir_offset: f32,
    /// See `nir_offset`.
    pub nir_gain: f32,
    /// Outdoor surface seen through an opening: lit by daylight, not by the room's lamps.
    pub exterior: bool,
}

impl Material {
    /// 940 nm reflectance of this material where its visible albedo is `albedo`.
    #[inline]
    pub fn nir(&self, albedo: V3) -> f32 {
        (self.nir_offset + self.nir_gain * luminance(albedo)).clamp(0.0, 1.0)
    }

    /// A diffuse material with the given texture.
    pub fn diffuse(tex: Texture, nir_offset: f32, nir_gain: f32) -> Material {
        Material {
            class: Class::Diffuse,
            tex,
            nir_offset,
            nir_gain,
            exterior: false,
        }
    }
}

/// Linear RGB from hue (turns), saturation and value (all in [0, 1]), value given in sRGB
/// terms so that 0.5 looks mid-grey.
pub fn hsv_linear(h: f32, s: f32, v: f32) -> V3 {
    let h6 = (h - h.floor()) * 6.0;
    let c = v * s;
    let x = c * (1.0 - ((h6 % 2.0) - 1.0).abs());
    let m = v - c;
    let (r, g, b) = match h6 as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let lin = |u: f32| {
        let u = (u + m).clamp(0.0, 1.0);
        if u <= 0.04045 {
            u / 12.92
        } else {
            ((u + 0.055) / 1.055).powf(2.4)
        }
    };
    v3(lin(r), lin(g), lin(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_and_nir_by_hand() {
        let red = hsv_linear(0.0, 1.0, 1.0);
        assert_eq!(red, v3(1.0, 0.0, 0.0));
        let grey = hsv_linear(0.3, 0.0, 0.5);
        assert!((grey.x - 0.214).abs() < 1e-3 && grey.x == grey.z);
        let m = Material::diffuse(Texture::plain(V3::ZERO), 0.1, 0.5);
        // luminance of white = 1 → 0.1 + 0.5 = 0.6; clamped at 1 for a big gain.
        assert!((m.nir(V3::splat(1.0)) - 0.6).abs() < 1e-6);
        assert_eq!(
            Material::diffuse(Texture::plain(V3::ZERO), 0.5, 2.0).nir(V3::splat(1.0)),
            1.0
        );
    }
}
