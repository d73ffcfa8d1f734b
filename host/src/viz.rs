//! Pixel-level drawing for the CLI's images: the Turbo depth colormap, filled discs, depth and
//! label maps as images. Titles, colour bars and charts are [`crate::plot`]'s.

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

/// Layout of [`draw_points`].
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
    /// range spanning the points' depths (a 1 cm span around a single depth); with 20 points or
    /// more, from their 5th to 95th percentile, so a few noise zones cannot set it.
    pub fn auto(width: u32, height: u32, points: &[ProjectedPoint]) -> Self {
        let mut d: Vec<f32> = points.iter().map(|p| p.depth_m).collect();
        d.sort_by(f32::total_cmp);
        let q = |p: f64| d[((d.len() - 1) as f64 * p).round() as usize];
        let (lo, hi) = match d.len() {
            0 => (f32::INFINITY, 0.0),
            n if n >= 20 => (q(0.05), q(0.95)),
            _ => (d[0], d[d.len() - 1]),
        };
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

/// The RGB image with every point drawn as a Turbo-coloured disc (black rim) over
/// `[overlay.lo_m, overlay.hi_m]` (clamped at the ends); same size as `rgb`. The titled picture
/// with its colour bar is [`crate::plot::figure`]'s.
pub fn draw_points(rgb: &RgbImage, points: &[ProjectedPoint], overlay: &Overlay) -> RgbImage {
    let mut out = rgb.clone();
    for p in points {
        fill_disc(&mut out, p.u, p.v, overlay.radius + 1.0, Rgb([0, 0, 0]));
        let c = depth_colour(p.depth_m, overlay.lo_m, overlay.hi_m);
        fill_disc(&mut out, p.u, p.v, overlay.radius, c);
    }
    out
}

/// The numbers behind a picture of projected zones: one row per point, `zone,u_px,v_px,depth_m`.
pub fn points_csv(points: &[ProjectedPoint]) -> String {
    let mut s = String::from("zone,u_px,v_px,depth_m\n");
    for p in points {
        s += &format!("{},{:.2},{:.2},{:.4}\n", p.zone, p.u, p.v, p.depth_m);
    }
    s
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
    fn points_are_turbo_discs_with_a_black_rim_at_their_centres() {
        use depthor_core::projection::ProjectedPoint;
        let grey = Rgb([128, 128, 128]);
        let rgb = RgbImage::from_pixel(64, 48, grey);
        let pt = |zone, u: f32, v: f32, d| ProjectedPoint {
            zone,
            u,
            v,
            x: u as u32,
            y: v as u32,
            depth_m: d,
        };
        let points = [
            pt(0, 16.0, 8.0, 1.0),
            pt(1, 48.0, 8.0, 2.0),
            pt(2, 16.0, 40.0, 3.0),
        ];
        let overlay = Overlay::auto(64, 48, &points);
        assert_eq!(
            (overlay.lo_m, overlay.hi_m, overlay.radius),
            (1.0, 3.0, 2.0)
        );
        let img = draw_points(&rgb, &points, &overlay);
        assert_eq!(img.dimensions(), (64, 48));
        assert_eq!(*img.get_pixel(16, 8), turbo(0.0));
        assert_eq!(*img.get_pixel(48, 8), turbo(0.5));
        assert_eq!(*img.get_pixel(16, 40), turbo(1.0));
        assert_eq!(*img.get_pixel(18, 8), Rgb([0, 0, 0])); // rim: 2.5 px from the centre
        assert_eq!(*img.get_pixel(32, 24), grey);
    }

    #[test]
    fn a_few_noise_zones_do_not_set_the_colour_range() {
        use depthor_core::projection::ProjectedPoint;
        let mut points: Vec<ProjectedPoint> = (0..64)
            .map(|i| ProjectedPoint {
                zone: i,
                u: 1.0,
                v: 1.0,
                x: 1,
                y: 1,
                depth_m: 1.5 + 0.01 * f32::from(i),
            })
            .collect();
        points[7].depth_m = 12.0; // one noise zone
        let o = Overlay::auto(160, 120, &points);
        assert!(o.hi_m < 2.2 && o.lo_m > 1.5, "{o:?}");
    }
}
