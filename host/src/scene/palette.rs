//! The materials a scene draws: textured diffuse surfaces (procedural or photo), dark absorbers,
//! glass and mirrors, each with its 940 nm reflectance.
use super::layout::Builder;
use super::material::{hsv_linear, Class, Material};
use super::math::v3;
use super::texture::{Pattern, Role, Texture, PHOTOS};
use core::f32::consts::PI;

impl Builder<'_> {
    pub(super) fn texture(&mut self, role: Role) -> Texture {
        let cfg = self.cfg;
        let seed = self.rng.next_u64() as u32;
        let ang = self.rng.range(0.0, 2.0 * PI);
        let rot = if self.rng.chance(0.7) {
            (1.0, 0.0)
        } else {
            (ang.cos(), ang.sin())
        };
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
            return Texture {
                pattern: Pattern::Photo(i as u16),
                c0: tint,
                c1: tint,
                scale,
                rot: (1.0, 0.0),
                offset,
                seed,
            };
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
            Role::Wall if k < 0.7 => (
                Pattern::Stripes,
                c0 * self.rng.range(0.6, 0.9),
                self.rng.range(0.05, 0.4),
            ),
            Role::Wall if k < 0.85 => (
                Pattern::Checker,
                c0 * self.rng.range(0.7, 0.95),
                self.rng.range(0.1, 0.4),
            ),
            Role::Wall => (
                Pattern::Noise,
                c0 * self.rng.range(0.6, 0.9),
                self.rng.range(0.3, 2.0),
            ),
            Role::Floor if k < 0.35 => {
                let wood = hsv_linear(
                    self.rng.range(0.05, 0.11),
                    self.rng.range(0.4, 0.8),
                    self.rng.range(0.35, 0.75),
                );
                (Pattern::Wood, wood * 0.55, self.rng.range(0.3, 1.0))
            }
            Role::Floor if k < 0.6 => (
                Pattern::Checker,
                self.colour([0.0, 0.4], [0.2, 0.9]),
                self.rng.range(0.2, 0.6),
            ),
            Role::Floor if k < 0.8 => (Pattern::Marble, c0 * 0.5, self.rng.range(0.5, 2.0)),
            Role::Floor => (Pattern::Noise, c0 * 0.7, self.rng.range(0.2, 1.5)),
            Role::Object if k < 0.3 => (Pattern::Plain, c0, 1.0),
            Role::Object if k < 0.5 => {
                let wood = hsv_linear(
                    self.rng.range(0.05, 0.11),
                    self.rng.range(0.4, 0.8),
                    self.rng.range(0.3, 0.75),
                );
                (Pattern::Wood, wood * 0.6, self.rng.range(0.2, 0.8))
            }
            Role::Object if k < 0.65 => (
                Pattern::Noise,
                self.colour([0.0, 0.8], [0.2, 0.9]),
                self.rng.range(0.1, 0.8),
            ),
            Role::Object if k < 0.75 => (
                Pattern::Checker,
                self.colour([0.0, 0.8], [0.2, 0.9]),
                self.rng.range(0.05, 0.3),
            ),
            Role::Object if k < 0.88 => (
                Pattern::Stripes,
                self.colour([0.0, 0.8], [0.2, 0.9]),
                self.rng.range(0.03, 0.3),
            ),
            Role::Object => (Pattern::Marble, c0 * 0.4, self.rng.range(0.3, 1.0)),
        };
        let (c0, c1) = if matches!(pattern, Pattern::Wood) {
            (c1 * (1.0 / 0.55), c1)
        } else {
            (c0, c1)
        };
        Texture {
            pattern,
            c0,
            c1,
            scale,
            rot,
            offset,
            seed,
        }
    }

    pub(super) fn diffuse(&mut self, role: Role) -> u16 {
        let tex = self.texture(role);
        let off = self.rng.range(0.05, 0.3);
        let gain = self.rng.range(0.5, 1.1);
        self.add_mat(Material::diffuse(tex, off, gain))
    }

    pub(super) fn dark(&mut self) -> u16 {
        let c = self.colour([0.0, 0.5], [0.04, 0.16]);
        let pattern = if self.rng.chance(0.5) {
            Pattern::Plain
        } else {
            Pattern::Noise
        };
        let tex = Texture {
            pattern,
            c0: c,
            c1: c * 0.6,
            scale: self.rng.range(0.1, 0.5),
            ..Texture::plain(c)
        };
        let off = self.rng.range(0.018, 0.045);
        self.add_mat(Material {
            class: Class::Dark,
            tex,
            nir_offset: off,
            nir_gain: 0.3,
            exterior: false,
        })
    }

    pub(super) fn glass(&mut self) -> u16 {
        let tint = v3(
            self.rng.range(0.8, 0.95),
            self.rng.range(0.88, 1.0),
            self.rng.range(0.85, 1.0),
        );
        let refl = self.rng.range(0.04, 0.08);
        self.add_mat(Material {
            class: Class::Transparent,
            tex: Texture::plain(tint),
            nir_offset: refl,
            nir_gain: 0.0,
            exterior: false,
        })
    }

    pub(super) fn mirror(&mut self) -> u16 {
        let r = self.rng.range(0.82, 0.95);
        let tint = v3(
            r,
            r * self.rng.range(0.97, 1.0),
            r * self.rng.range(0.95, 1.0),
        );
        self.add_mat(Material {
            class: Class::Specular,
            tex: Texture::plain(tint),
            nir_offset: r,
            nir_gain: 0.0,
            exterior: false,
        })
    }

    pub(super) fn object_mat(&mut self, dark: bool) -> u16 {
        if dark {
            self.dark()
        } else {
            self.diffuse(Role::Object)
        }
    }
}
