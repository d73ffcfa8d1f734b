//! Surface colour: procedural patterns (noise, checker, stripes, wood, marble) and CC0 photo
//! textures embedded from `host/assets/textures` (see `SOURCES.tsv` there), decoded once and
//! mip-mapped so distant surfaces are filtered rather than aliased. All colours here are linear.
use super::math::{v3, V3};
use std::sync::OnceLock;

/// What a photo texture is suited to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Walls and ceilings.
    Wall,
    /// Floors.
    Floor,
    /// Furniture and objects.
    Object,
}

macro_rules! photo {
    ($name:literal, $role:ident) => {
        (
            $name,
            include_bytes!(concat!("../../assets/textures/", $name, ".jpg")).as_slice(),
            Role::$role,
        )
    };
}

/// The embedded photos: file stem, JPEG bytes, role.
pub static PHOTOS: &[(&str, &[u8], Role)] = &[
    photo!("ph_beige_wall_001", Wall),
    photo!("ph_painted_plaster_wall", Wall),
    photo!("ph_plastered_stone_wall", Wall),
    photo!("ph_concrete_wall_001", Wall),
    photo!("ph_brick_wall_001", Wall),
    photo!("ph_patterned_concrete_wall", Wall),
    photo!("ph_long_white_tiles", Wall),
    photo!("ph_factory_wall", Wall),
    photo!("ph_beam_wall_01", Wall),
    photo!("ph_blue_painted_planks", Wall),
    photo!("ph_plank_flooring", Floor),
    photo!("ph_wood_floor_deck", Floor),
    photo!("ph_brown_floor_tiles", Floor),
    photo!("ph_blue_floor_tiles_01", Floor),
    photo!("ph_stone_floor", Floor),
    photo!("ph_brushed_concrete", Floor),
    photo!("ph_brick_floor", Floor),
    photo!("acg_Carpet006", Floor),
    photo!("ph_wood_table_worn", Object),
    photo!("ph_rosewood_veneer1", Object),
    photo!("ph_marble_01", Object),
    photo!("ph_leather_white", Object),
    photo!("acg_Fabric080", Object),
    photo!("ph_green_metal_rust", Object),
    photo!("ph_metal_plate_02", Object),
    photo!("ph_brown_planks_04", Object),
    photo!("ph_black_painted_planks", Object),
    photo!("ph_potted_plant_01_leaves", Object),
];

/// One mip level: `size × size` RGB texels, sRGB bytes.
struct Mip {
    size: usize,
    texels: Vec<u8>,
}

/// A decoded photo with its mip chain (level 0 first).
pub struct Photo {
    mips: Vec<Mip>,
}

/// sRGB byte → linear value table.
pub fn srgb_to_linear_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| {
        let mut t = [0.0f32; 256];
        for (i, v) in t.iter_mut().enumerate() {
            let c = i as f32 / 255.0;
            *v = if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            };
        }
        t
    })
}

/// All embedded photos, decoded on first use. A photo that fails to decode (it cannot: the bytes
/// are fixed at build time and checked by a test) becomes a flat grey texture.
pub fn photos() -> &'static [Photo] {
    static P: OnceLock<Vec<Photo>> = OnceLock::new();
    P.get_or_init(|| {
        PHOTOS
            .iter()
            .map(|(_, bytes, _)| decode_photo(bytes))
            .collect()
    })
}

fn decode_photo(bytes: &[u8]) -> Photo {
    let base = match image::load_from_memory(bytes) {
        Ok(img) => {
            let rgb = img.to_rgb8();
            let side = rgb.width().min(rgb.height()).max(1);
            let sq = image::imageops::crop_imm(&rgb, 0, 0, side, side).to_image();
            // Largest power of two not above the side (and 256), so mips halve exactly.
            let size = 1usize << (usize::BITS - 1 - (side.min(256) as usize).leading_zeros());
            let sq = image::imageops::resize(
                &sq,
                size as u32,
                size as u32,
                image::imageops::FilterType::Triangle,
            );
            Mip {
                size,
                texels: sq.into_raw(),
            }
        }
        Err(_) => Mip {
            size: 1,
            texels: vec![128, 128, 128],
        },
    };
    let mut mips = vec![base];
    while let Some(last) = mips.last() {
        if last.size <= 1 {
            break;
        }
        let s = last.size / 2;
        let mut t = vec![0u8; s * s * 3];
        for y in 0..s {
            for x in 0..s {
                for c in 0..3 {
                    let at =
                        |yy: usize, xx: usize| last.texels[(yy * last.size + xx) * 3 + c] as u32;
                    let sum = at(2 * y, 2 * x)
                        + at(2 * y, 2 * x + 1)
                        + at(2 * y + 1, 2 * x)
                        + at(2 * y + 1, 2 * x + 1);
                    t[(y * s + x) * 3 + c] = ((sum + 2) / 4) as u8;
                }
            }
        }
        mips.push(Mip { size: s, texels: t });
    }
    Photo { mips }
}

impl Photo {
    /// Bilinear sample at `(u, v)` in texture units (1.0 = one tile), wrapping, from the mip level
    /// whose texels are about `texels_per_px` level-0 texels wide.
    pub fn sample(&self, u: f32, v: f32, texels_per_px: f32) -> V3 {
        let lut = srgb_to_linear_lut();
        let level = if texels_per_px > 1.0 {
            texels_per_px.log2() as usize
        } else {
            0
        };
        let m = &self.mips[level.min(self.mips.len() - 1)];
        let s = m.size;
        let x = u.rem_euclid(1.0) * s as f32 - 0.5;
        let y = v.rem_euclid(1.0) * s as f32 - 0.5;
        let (xf, yf) = (x.floor(), y.floor());
        let (fx, fy) = (x - xf, y - yf);
        let x0 = (xf as isize).rem_euclid(s as isize) as usize;
        let y0 = (yf as isize).rem_euclid(s as isize) as usize;
        let (x1, y1) = ((x0 + 1) % s, (y0 + 1) % s);
        let px = |yy: usize, xx: usize| {
            let i = (yy * s + xx) * 3;
            v3(
                lut[m.texels[i] as usize],
                lut[m.texels[i + 1] as usize],
                lut[m.texels[i + 2] as usize],
            )
        };
        let top = px(y0, x0).lerp(px(y0, x1), fx);
        let bot = px(y1, x0).lerp(px(y1, x1), fx);
        top.lerp(bot, fy)
    }

    /// Level-0 size in texels.
    pub fn size(&self) -> usize {
        self.mips[0].size
    }
}

/// A procedural or photo pattern.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pattern {
    /// Flat colour with faint low-frequency variation.
    Plain,
    /// Fractal value noise between the two colours.
    Noise,
    /// Checkerboard of period `scale`.
    Checker,
    /// Stripes along u, duty cycle `0.5`.
    Stripes,
    /// Wood grain: noisy rings elongated along v.
    Wood,
    /// Marble: sine veins perturbed by turbulence.
    Marble,
    /// Photo number `0` of [`PHOTOS`], one tile per `scale` metres, tinted by `c0`.
    Photo(u16),
}

/// A pattern mapped onto surface coordinates (metres) with scale, rotation and offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Texture {
    /// Pattern.
    pub pattern: Pattern,
    /// First colour (tint for photos), linear.
    pub c0: V3,
    /// Second colour, linear.
    pub c1: V3,
    /// Metres per pattern period / photo tile.
    pub scale: f32,
    /// Rotation of the pattern (cos, sin).
    pub rot: (f32, f32),
    /// Offset in metres.
    pub offset: (f32, f32),
    /// Seed of the noise lattice.
    pub seed: u32,
}

#[inline]
fn hash2(i: i32, j: i32, seed: u32) -> f32 {
    let mut h = (i as u32).wrapping_mul(0x8DA6_B343)
        ^ (j as u32).wrapping_mul(0xD816_3841)
        ^ seed.wrapping_mul(0xCB1A_B31F);
    h ^= h >> 13;
    h = h.wrapping_mul(0x5BD1_E995);
    h ^= h >> 15;
    (h >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Smooth value noise in [0, 1).
#[inline]
pub fn value_noise(x: f32, y: f32, seed: u32) -> f32 {
    let (xf, yf) = (x.floor(), y.floor());
    let (i, j) = (xf as i32, yf as i32);
    let (fx, fy) = (x - xf, y - yf);
    let sx = fx * fx * (3.0 - 2.0 * fx);
    let sy = fy * fy * (3.0 - 2.0 * fy);
    let a = hash2(i, j, seed);
    let b = hash2(i + 1, j, seed);
    let c = hash2(i, j + 1, seed);
    let d = hash2(i + 1, j + 1, seed);
    let top = a + (b - a) * sx;
    let bot = c + (d - c) * sx;
    top + (bot - top) * sy
}

/// Fractal noise of up to `octaves` octaves, dropping those finer than `min_period` (same units
/// as x, y), in [0, 1).
pub fn fbm(x: f32, y: f32, seed: u32, octaves: u32, min_period: f32) -> f32 {
    let mut sum = 0.0;
    let mut amp = 0.5;
    let mut freq = 1.0;
    let mut norm = 0.0;
    for o in 0..octaves {
        if 1.0 / freq < min_period {
            // Replace the filtered-out detail by its mean.
            sum += amp * 0.5;
        } else {
            sum += amp * value_noise(x * freq, y * freq, seed.wrapping_add(o * 7919));
        }
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / norm
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Texture {
    /// A flat colour.
    pub fn plain(c: V3) -> Texture {
        Texture {
            pattern: Pattern::Plain,
            c0: c,
            c1: c,
            scale: 1.0,
            rot: (1.0, 0.0),
            offset: (0.0, 0.0),
            seed: 0,
        }
    }

    /// Linear albedo at surface coordinates `uv` (metres) seen with a pixel footprint of
    /// `footprint_m` metres.
    pub fn sample(&self, uv: (f32, f32), footprint_m: f32) -> V3 {
        let (c, s) = self.rot;
        let u0 = uv.0 + self.offset.0;
        let v0 = uv.1 + self.offset.1;
        let u = (c * u0 - s * v0) / self.scale;
        let v = (s * u0 + c * v0) / self.scale;
        let fp = footprint_m / self.scale; // footprint in pattern periods
        match self.pattern {
            Pattern::Plain => {
                // One octave of very low-frequency shading variation (period ≥ 2 tiles).
                let n = value_noise(u * 0.5, v * 0.5, self.seed);
                self.c0 * (0.93 + 0.14 * n)
            }
            Pattern::Noise => {
                let n = fbm(u * 2.0, v * 2.0, self.seed, 5, fp * 2.0);
                self.c0.lerp(self.c1, smoothstep(0.25, 0.75, n))
            }
            Pattern::Checker => {
                let k = ((u.floor() as i64 + v.floor() as i64) & 1) as f32;
                // Fade to the mean when the squares get smaller than ~2 pixels.
                let w = smoothstep(0.25, 0.5, fp);
                let m = k * (1.0 - w) + 0.5 * w;
                self.c0.lerp(self.c1, m) * (0.95 + 0.1 * value_noise(u * 3.0, v * 3.0, self.seed))
            }
            Pattern::Stripes => {
                let f = u - u.floor();
                let k = smoothstep(0.45, 0.55, f) - smoothstep(0.95, 1.0, f);
                let w = smoothstep(0.25, 0.5, fp);
                self.c0.lerp(self.c1, k * (1.0 - w) + 0.5 * w)
            }
            Pattern::Wood => {
                let n = fbm(u * 1.5, v * 0.15, self.seed, 4, fp);
                let r = (u * 6.0 + n * 6.0).abs();
                let ring = r - r.floor();
                let w = smoothstep(0.08, 0.2, fp);
                let k = smoothstep(0.0, 0.6, ring) * (1.0 - w) + 0.45 * w;
                let grain = fbm(u * 20.0, v * 1.0, self.seed ^ 77, 2, fp) * 0.2 + 0.9;
                self.c0.lerp(self.c1, k) * grain
            }
            Pattern::Marble => {
                let n = fbm(u * 2.0, v * 2.0, self.seed, 5, fp);
                let vein = 0.5 + 0.5 * ((u + v * 0.3) * 3.0 + n * 8.0).sin();
                let w = smoothstep(0.1, 0.3, fp);
                let k = vein.powf(6.0) * (1.0 - w) + 0.15 * w;
                self.c0.lerp(self.c1, k)
            }
            Pattern::Photo(i) => {
                let photos = photos();
                let p = &photos[i as usize % photos.len()];
                p.sample(u, v, fp * p.size() as f32).mul(self.c0)
            }
        }
    }
}

/// Luminance of a linear RGB colour (Rec. 709 weights).
#[inline]
pub fn luminance(c: V3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_photo_decodes_to_a_mip_chain() {
        let ps = photos();
        assert_eq!(ps.len(), PHOTOS.len());
        for (p, (name, _, _)) in ps.iter().zip(PHOTOS) {
            assert!(p.size() >= 128, "{name} decoded to {}", p.size());
            assert_eq!(p.mips.last().map(|m| m.size), Some(1));
        }
    }

    #[test]
    fn lut_and_filtering_by_hand() {
        let lut = srgb_to_linear_lut();
        assert_eq!(lut[0], 0.0);
        assert!((lut[255] - 1.0).abs() < 1e-6);
        assert!((lut[128] - 0.2158).abs() < 1e-3); // ((128/255+0.055)/1.055)^2.4
                                                   // A checker seen from far away becomes the mean of its colours.
        let t = Texture {
            pattern: Pattern::Checker,
            c0: V3::ZERO,
            c1: V3::splat(1.0),
            ..Texture::plain(V3::ZERO)
        };
        let far = t.sample((0.3, 0.7), 10.0);
        assert!(
            (far.x / (0.95 + 0.1 * value_noise(0.9, 2.1, 0)) - 0.5).abs() < 1e-4,
            "{far:?}"
        );
        let near = t.sample((1.5, 0.5), 0.001);
        assert!(near.x > 0.9, "{near:?}");
    }
}
