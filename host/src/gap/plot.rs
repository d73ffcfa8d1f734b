//! A small plotting helper for the report's PNGs: line plots, bar plots and zone-grid heat maps,
//! drawn with the `image` crate and the numeric font of [`crate::viz`].

use std::path::Path;

use image::{Rgb, RgbImage};

use crate::viz::{draw_text, fill_rect};

/// Colours of successive series.
pub const PALETTE: [Rgb<u8>; 4] = [
    Rgb([214, 39, 40]),
    Rgb([31, 119, 180]),
    Rgb([255, 127, 14]),
    Rgb([44, 160, 44]),
];

const W: u32 = 480;
const H: u32 = 300;
const M: u32 = 40;

fn line(img: &mut RgbImage, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: Rgb<u8>) {
    let n = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as usize).max(1);
    for i in 0..=n {
        let t = i as f64 / n as f64;
        let (x, y) = (x0 + t * (x1 - x0), y0 + t * (y1 - y0));
        if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
            img.put_pixel(x as u32, y as u32, c);
            if (y as u32) + 1 < img.height() {
                img.put_pixel(x as u32, y as u32 + 1, c);
            }
        }
    }
}

fn label(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// Axes of a plot over `[x0, x1] × [y0, y1]`: the frame, a zero line, numbers at the ends.
struct Axes {
    x: [f64; 2],
    y: [f64; 2],
}

impl Axes {
    fn px(&self, x: f64, y: f64) -> (f64, f64) {
        let sx = if self.x[1] > self.x[0] {
            (x - self.x[0]) / (self.x[1] - self.x[0])
        } else {
            0.5
        };
        let sy = if self.y[1] > self.y[0] {
            (y - self.y[0]) / (self.y[1] - self.y[0])
        } else {
            0.5
        };
        (
            f64::from(M) + sx * f64::from(W - 2 * M),
            f64::from(H - M) - sy * f64::from(H - 2 * M),
        )
    }

    fn draw(&self, img: &mut RgbImage) {
        let grey = Rgb([90, 90, 90]);
        let (l, r, t, b) = (
            f64::from(M),
            f64::from(W - M),
            f64::from(M),
            f64::from(H - M),
        );
        line(img, (l, t), (l, b), grey);
        line(img, (l, b), (r, b), grey);
        if self.y[0] < 0.0 && self.y[1] > 0.0 {
            let (_, zy) = self.px(0.0, 0.0);
            line(img, (l, zy), (r, zy), Rgb([190, 190, 190]));
        }
        draw_text(img, M, H - M + 6, &label(self.x[0]), 2, grey);
        let xl = label(self.x[1]);
        draw_text(
            img,
            W - M - crate::viz::text_width(&xl, 2),
            H - M + 6,
            &xl,
            2,
            grey,
        );
        draw_text(img, 2, M - 14, &label(self.y[1]), 2, grey);
        draw_text(img, 2, H - M - 14, &label(self.y[0]), 2, grey);
    }
}

fn range(vals: impl Iterator<Item = f64>) -> [f64; 2] {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return [0.0, 1.0];
    }
    if hi - lo < 1e-9 {
        return [lo - 0.5, hi + 0.5];
    }
    [lo, hi]
}

/// A line plot of `series` (points `(x, y)`, one colour of [`PALETTE`] each, in order), y-range
/// including 0.
pub fn line_plot(path: &Path, series: &[Vec<(f64, f64)>]) -> image::ImageResult<()> {
    let mut img = RgbImage::from_pixel(W, H, Rgb([255, 255, 255]));
    let pts = || series.iter().flatten();
    let mut y = range(pts().map(|p| p.1).chain([0.0]));
    let pad = (y[1] - y[0]) * 0.05;
    y = [y[0] - pad, y[1] + pad];
    let ax = Axes {
        x: range(pts().map(|p| p.0)),
        y,
    };
    ax.draw(&mut img);
    for (k, s) in series.iter().enumerate() {
        let c = PALETTE[k % PALETTE.len()];
        for w in s.windows(2) {
            if w[0].1.is_finite() && w[1].1.is_finite() {
                line(&mut img, ax.px(w[0].0, w[0].1), ax.px(w[1].0, w[1].1), c);
            }
        }
        for p in s.iter().filter(|p| p.1.is_finite()) {
            let (x, y) = ax.px(p.0, p.1);
            crate::viz::fill_disc(&mut img, x as f32, y as f32, 3.0, c);
        }
    }
    img.save(path)
}

/// A bar plot of `values` with a reference level `reference` drawn as a grey line.
pub fn bar_plot(path: &Path, values: &[f64], reference: f64) -> image::ImageResult<()> {
    let mut img = RgbImage::from_pixel(W, H, Rgb([255, 255, 255]));
    let y = range(values.iter().copied().chain([0.0, reference * 1.2]));
    let ax = Axes {
        x: [0.0, values.len() as f64],
        y,
    };
    ax.draw(&mut img);
    for (i, &v) in values.iter().enumerate() {
        let (x0, yv) = ax.px(i as f64 + 0.1, v);
        let (x1, y0) = ax.px(i as f64 + 0.9, 0.0);
        let (top, h) = if yv < y0 {
            (yv, y0 - yv)
        } else {
            (y0, yv - y0)
        };
        fill_rect(
            &mut img,
            x0 as u32,
            top as u32,
            (x1 - x0) as u32,
            h.max(1.0) as u32,
            PALETTE[1],
        );
    }
    let (l, ry) = ax.px(0.0, reference);
    let (r, _) = ax.px(values.len() as f64, reference);
    line(&mut img, (l, ry), (r, ry), Rgb([120, 120, 120]));
    img.save(path)
}

/// A heat map of `values` (`rows × cols`, row-major) on a diverging scale symmetric about 0
/// (blue negative, white 0, red positive), 40 px per zone.
pub fn heat_map(path: &Path, values: &[f64], rows: usize, cols: usize) -> image::ImageResult<()> {
    const C: u32 = 40;
    let mut img = RgbImage::from_pixel(cols as u32 * C, rows as u32 * C + 16, Rgb([255, 255, 255]));
    let m = values.iter().fold(
        1e-9f64,
        |a, v| if v.is_finite() { a.max(v.abs()) } else { a },
    );
    for r in 0..rows {
        for c in 0..cols {
            let v = values.get(r * cols + c).copied().unwrap_or(0.0);
            let t = if v.is_finite() {
                (v / m).clamp(-1.0, 1.0)
            } else {
                0.0
            };
            let fade = |x: f64| (255.0 * (1.0 - x.abs())) as u8;
            let col = if t >= 0.0 {
                Rgb([255, fade(t), fade(t)])
            } else {
                Rgb([fade(t), fade(t), 255])
            };
            fill_rect(&mut img, c as u32 * C, r as u32 * C, C - 1, C - 1, col);
        }
    }
    draw_text(
        &mut img,
        2,
        rows as u32 * C + 3,
        &label(m),
        2,
        Rgb([60, 60, 60]),
    );
    img.save(path)
}
