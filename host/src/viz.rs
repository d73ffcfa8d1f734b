//! Drawing helpers for the CLI's images: the Turbo depth colormap, filled discs, a tiny bitmap
//! font for numbers, and a colour bar with its range written beside it.

use depthor_core::projection::ProjectedPoint;
use image::{Rgb, RgbImage};

/// Turbo colormap at `t` in `[0, 1]` (clamped; NaN maps to 0): blue for low values, red for high.
///
/// Uses the published degree-5 polynomial approximation of Turbo (A. Mikhailov, "Turbo, an
/// improved rainbow colormap", Google AI blog, 2019).
pub fn turbo(t: f32) -> Rgb<u8> {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) } as f64;
    let poly = |c: [f64; 6]| {
        let v = c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))));
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    };
    Rgb([
        poly([
            0.135_721_38,
            4.615_392_6,
            -42.660_322_58,
            132.131_082_34,
            -152.942_393_96,
            59.286_379_43,
        ]),
        poly([
            0.091_402_61,
            2.194_188_39,
            4.842_966_58,
            -14.185_033_33,
            4.277_298_57,
            2.829_566_04,
        ]),
        poly([
            0.106_673_3,
            12.641_946_08,
            -60.582_048_36,
            110.362_767_71,
            -89.903_109_12,
            27.348_249_73,
        ]),
    ])
}

/// Maps `value` in `[lo, hi]` to the Turbo colour (`lo` blue, `hi` red).
pub fn depth_colour(value: f32, lo: f32, hi: f32) -> Rgb<u8> {
    let span = hi - lo;
    turbo(if span > 0.0 { (value - lo) / span } else { 0.5 })
}

/// Fills the pixels whose centres lie within `radius` of `(cx, cy)` (pixel `x` spans
/// `[x, x + 1)`); parts outside the image are clipped.
pub fn fill_disc(img: &mut RgbImage, cx: f32, cy: f32, radius: f32, colour: Rgb<u8>) {
    if !(cx.is_finite() && cy.is_finite() && radius.is_finite()) || radius < 0.0 {
        return;
    }
    let (w, h) = img.dimensions();
    let x0 = (cx - radius).floor().max(0.0) as u32;
    let y0 = (cy - radius).floor().max(0.0) as u32;
    let x1 = ((cx + radius).ceil().max(0.0) as u32).min(w);
    let y1 = ((cy + radius).ceil().max(0.0) as u32).min(h);
    for y in y0..y1 {
        for x in x0..x1 {
            let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
            if dx * dx + dy * dy <= radius * radius {
                img.put_pixel(x, y, colour);
            }
        }
    }
}

/// Fills the rectangle `[x0, x0 + w) × [y0, y0 + h)`, clipped to the image.
pub fn fill_rect(img: &mut RgbImage, x0: u32, y0: u32, w: u32, h: u32, colour: Rgb<u8>) {
    let (iw, ih) = img.dimensions();
    for y in y0..y0.saturating_add(h).min(ih) {
        for x in x0..x0.saturating_add(w).min(iw) {
            img.put_pixel(x, y, colour);
        }
    }
}

/// 3×5 glyphs, one row per entry, bit 2 = left column.
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        'm' => [0b000, 0b000, 0b111, 0b111, 0b101],
        ' ' => [0; 5],
        _ => return None,
    })
}

/// Width in pixels of `text` drawn by [`draw_text`] at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    (text.chars().count() as u32 * 4).saturating_sub(1) * scale
}

/// Draws `text` (digits, `.`, `-`, `m`, space; other characters are skipped as spaces) with its
/// top-left corner at `(x, y)`, each font pixel a `scale × scale` square.
pub fn draw_text(img: &mut RgbImage, x: u32, y: u32, text: &str, scale: u32, colour: Rgb<u8>) {
    for (k, c) in text.chars().enumerate() {
        let Some(rows) = glyph(c) else { continue };
        let gx = x + k as u32 * 4 * scale;
        for (r, bits) in rows.iter().enumerate() {
            for col in 0..3 {
                if bits & (0b100 >> col) != 0 {
                    fill_rect(
                        img,
                        gx + col * scale,
                        y + r as u32 * scale,
                        scale,
                        scale,
                        colour,
                    );
                }
            }
        }
    }
}

/// Layout of [`render_projection`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Overlay {
    /// Disc radius in pixels.
    pub radius: f32,
    /// Depth mapped to the blue end of the colormap, metres.
    pub lo_m: f32,
    /// Depth mapped to the red end, metres.
    pub hi_m: f32,
}

impl Overlay {
    /// Radius scaled to the image (≈1/100 of the larger side, at least 2 px) and the colour
    /// range spanning the points' depths (a 1 cm span around a single depth).
    pub fn auto(width: u32, height: u32, points: &[ProjectedPoint]) -> Self {
        let (lo, hi) = points.iter().fold((f32::INFINITY, 0.0f32), |(lo, hi), p| {
            (lo.min(p.depth_m), hi.max(p.depth_m))
        });
        let (lo_m, hi_m) = if points.is_empty() {
            (0.0, 1.0)
        } else if hi - lo < 0.01 {
            (lo - 0.005, hi + 0.005)
        } else {
            (lo, hi)
        };
        Overlay {
            radius: (width.max(height) as f32 / 100.0).max(2.0),
            lo_m,
            hi_m,
        }
    }
}

/// The RGB image with every point drawn as a Turbo-coloured disc (black rim) and, to its right,
/// a colour bar labelled with the range in metres (top = far). Points keep the image's pixel
/// coordinates; the output is wider than `rgb` by the bar panel.
pub fn render_projection(rgb: &RgbImage, points: &[ProjectedPoint], overlay: &Overlay) -> RgbImage {
    let (w, h) = rgb.dimensions();
    let scale = (h / 120).max(1);
    let labels = [
        format!("{:.2}m", overlay.hi_m),
        format!("{:.2}m", overlay.lo_m),
    ];
    let label_w = labels
        .iter()
        .map(|l| text_width(l, scale))
        .max()
        .unwrap_or(0);
    let bar_w = 6 * scale;
    let pad = 3 * scale;
    let panel = pad + bar_w + pad + label_w + pad;
    let mut out = RgbImage::from_pixel(w + panel, h, Rgb([255, 255, 255]));
    image::imageops::replace(&mut out, rgb, 0, 0);
    for p in points {
        fill_disc(&mut out, p.u, p.v, overlay.radius + 1.0, Rgb([0, 0, 0]));
        let c = depth_colour(p.depth_m, overlay.lo_m, overlay.hi_m);
        fill_disc(&mut out, p.u, p.v, overlay.radius, c);
    }
    // Colour bar: top row = hi (far), bottom row = lo (near).
    let top = pad;
    let bar_h = h.saturating_sub(2 * pad).max(1);
    let bx = w + pad;
    for r in 0..bar_h {
        let t = 1.0 - r as f32 / (bar_h.max(2) - 1) as f32;
        fill_rect(&mut out, bx, top + r, bar_w, 1, turbo(t));
    }
    let black = Rgb([0, 0, 0]);
    let lx = bx + bar_w + pad;
    draw_text(&mut out, lx, top, &labels[0], scale, black);
    let bottom = (top + bar_h).saturating_sub(5 * scale);
    draw_text(&mut out, lx, bottom, &labels[1], scale, black);
    out
}

/// A depth map (metres, row-major `width × height`) as a Turbo image over `[lo, hi]`; unknown
/// depth (0 or non-finite) is black.
pub fn depth_image(depth_m: &[f32], width: u32, height: u32, lo: f32, hi: f32) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        let d = depth_m
            .get(y as usize * width as usize + x as usize)
            .copied()
            .unwrap_or(0.0);
        if d.is_finite() && d > 0.0 {
            depth_colour(d, lo, hi)
        } else {
            Rgb([0, 0, 0])
        }
    })
}

/// Colours of the material classes of `labels.png` (docs/recording.md): diffuse grey, transparent cyan,
/// specular magenta, dark yellow.
pub const LABEL_COLOURS: [[u8; 3]; 4] = [[70, 70, 70], [0, 230, 230], [230, 0, 230], [240, 220, 0]];

/// A label map as an image in [`LABEL_COLOURS`] (unknown classes white).
pub fn labels_image(labels: &[u8], width: u32, height: u32) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        let l = labels
            .get(y as usize * width as usize + x as usize)
            .copied()
            .unwrap_or(0) as usize;
        Rgb(LABEL_COLOURS.get(l).copied().unwrap_or([255, 255, 255]))
    })
}

/// Images side by side (top-aligned, white background, `gap` pixels between them).
pub fn mosaic(images: &[RgbImage], gap: u32) -> RgbImage {
    let w =
        images.iter().map(|i| i.width()).sum::<u32>() + gap * images.len().saturating_sub(1) as u32;
    let h = images.iter().map(|i| i.height()).max().unwrap_or(0);
    let mut out = RgbImage::from_pixel(w.max(1), h.max(1), Rgb([255, 255, 255]));
    let mut x = 0i64;
    for img in images {
        image::imageops::replace(&mut out, img, x, 0);
        x += i64::from(img.width() + gap);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turbo_ends_are_dark_blue_and_dark_red_and_middle_is_green() {
        // Polynomial at t = 0: (0.1357, 0.0914, 0.1067) · 255.
        assert_eq!(turbo(0.0), Rgb([35, 23, 27]));
        // At t = 1 the coefficients sum to (0.5659, 0.0505, -0.0255 → 0).
        assert_eq!(turbo(1.0), Rgb([144, 13, 0]));
        let mid = turbo(0.5);
        assert!(mid[1] > 240 && mid[0] < 160 && mid[2] < 100, "{mid:?}");
        assert_eq!(turbo(f32::NAN), turbo(-3.0));
    }

    #[test]
    fn disc_covers_pixel_centres_within_radius() {
        let mut img = RgbImage::new(8, 8);
        fill_disc(&mut img, 4.0, 4.0, 1.0, Rgb([9, 9, 9]));
        // Centres (3.5, 3.5), (4.5, 3.5), (3.5, 4.5), (4.5, 4.5) are 0.707 px away: inside.
        // (2.5, 3.5) is 1.58 px away: outside.
        let lit: Vec<(u32, u32)> = img
            .enumerate_pixels()
            .filter(|p| p.2[0] == 9)
            .map(|p| (p.0, p.1))
            .collect();
        assert_eq!(lit, vec![(3, 3), (4, 3), (3, 4), (4, 4)]);
        fill_disc(&mut img, -10.0, 50.0, 3.0, Rgb([1, 1, 1])); // clipped away, no panic
    }

    #[test]
    fn text_draws_glyph_bits() {
        let mut img = RgbImage::new(8, 6);
        draw_text(&mut img, 0, 0, "1", 1, Rgb([255, 0, 0]));
        // '1' row 0 = 0b010: only the middle column.
        assert_eq!(img.get_pixel(0, 0)[0], 0);
        assert_eq!(img.get_pixel(1, 0)[0], 255);
        assert_eq!(text_width("1.5m", 2), (16 - 1) * 2);
    }
}
