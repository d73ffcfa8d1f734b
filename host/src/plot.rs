//! The pictures the CLI writes, drawn with `plotters` on its bitmap backend: titled panels of
//! images with colour bars (ticks and units), line and bar charts with axis labels and legends,
//! and zone-grid heat maps. Text is DejaVu Sans, embedded in the binary
//! (`host/assets/fonts`, licence beside it), so no system font is needed.
//!
//! Colour conventions: depth on Turbo ([`crate::viz::turbo`], near blue, far red) over a range
//! from robust percentiles of the reference ([`robust_range`]); absolute error on Viridis, a
//! sequential map of its own, from 0 to a robust maximum.

use image::{Rgb, RgbImage};
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use std::path::Path;
use std::sync::Once;

/// The embedded font (DejaVu Sans, Bitstream Vera licence: host/assets/fonts/DejaVu-LICENSE.txt).
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
/// The family name the font is registered under.
const FAMILY: &str = "sans-serif";

/// A picture could not be drawn or written.
#[derive(Debug, thiserror::Error)]
#[error("{what}: {message}")]
pub struct PlotError {
    /// The picture (its path, or what it shows).
    pub what: String,
    /// plotters' or the encoder's message.
    pub message: String,
}

fn err(what: &str, e: impl std::fmt::Display) -> PlotError {
    PlotError {
        what: what.to_string(),
        message: e.to_string(),
    }
}

fn font_once() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The bytes are a valid TTF compiled in; a failure would show as missing text only.
        let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    });
}

fn font(size: u32) -> TextStyle<'static> {
    font_once();
    (FAMILY, size).into_font().color(&BLACK)
}

/// A colour map of the pictures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourMap {
    /// Turbo: depth.
    Turbo,
    /// Viridis: error magnitudes (sequential, 0 dark).
    Viridis,
    /// Blue – white – red: signed quantities, white at the middle of the range.
    Diverging,
}

impl ColourMap {
    /// The colour at `t` in `[0, 1]` (clamped).
    pub fn at(self, t: f32) -> Rgb<u8> {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        match self {
            ColourMap::Turbo => crate::viz::turbo(t),
            ColourMap::Viridis => {
                let c: RGBColor = ViridisRGB.get_color(t);
                Rgb([c.0, c.1, c.2])
            }
            ColourMap::Diverging => diverging(2.0 * t - 1.0),
        }
    }

    /// The colour of `v` on `[lo, hi]`.
    pub fn of(self, v: f32, lo: f32, hi: f32) -> Rgb<u8> {
        let span = hi - lo;
        self.at(if span > 0.0 { (v - lo) / span } else { 0.5 })
    }
}

/// A colour bar beside a panel: the map, its range and what it measures (with the unit).
#[derive(Clone, Debug)]
pub struct ColourBar {
    /// The map.
    pub map: ColourMap,
    /// Value at the bottom.
    pub lo: f32,
    /// Value at the top.
    pub hi: f32,
    /// Label along the bar, e.g. `depth (m)`.
    pub label: String,
}

/// One titled panel: an image, and optionally a colour bar or a legend.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Title above the image.
    pub title: String,
    /// The picture at its own resolution (scaled up for the figure).
    pub image: RgbImage,
    /// Colour bar to the right of the image.
    pub bar: Option<ColourBar>,
    /// Legend entries below the image (colour, label).
    pub legend: Vec<(Rgb<u8>, String)>,
}

impl Panel {
    /// A panel with a title only.
    pub fn new(title: impl Into<String>, image: RgbImage) -> Self {
        Panel {
            title: title.into(),
            image,
            bar: None,
            legend: Vec::new(),
        }
    }

    /// The same panel with a colour bar.
    pub fn with_bar(mut self, map: ColourMap, lo: f32, hi: f32, label: impl Into<String>) -> Self {
        self.bar = Some(ColourBar {
            map,
            lo,
            hi,
            label: label.into(),
        });
        self
    }

    /// The same panel with a legend.
    pub fn with_legend(mut self, legend: Vec<(Rgb<u8>, String)>) -> Self {
        self.legend = legend;
        self
    }
}

/// The `(lo, hi)` percentiles (fractions, e.g. 0.02 and 0.98) of the finite values > 0 of `v`;
/// `None` when there are none. A span under 1 cm is widened to 1 cm around its middle.
pub fn robust_range(v: &[f32], lo: f64, hi: f64) -> Option<(f32, f32)> {
    let mut x: Vec<f32> = v
        .iter()
        .copied()
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if x.is_empty() {
        return None;
    }
    x.sort_by(f32::total_cmp);
    let q = |p: f64| x[((x.len() - 1) as f64 * p).round() as usize];
    let (a, b) = (q(lo), q(hi));
    Some(if b - a < 0.01 {
        let m = 0.5 * (a + b);
        (m - 0.005, m + 0.005)
    } else {
        (a, b)
    })
}

const TITLE_H: u32 = 34;
const PANEL_TITLE_H: u32 = 24;
const BAR_W: u32 = 16;
const BAR_AREA_W: u32 = 92;
const LEGEND_ROW_H: u32 = 20;
const GAP: u32 = 14;
const MARGIN: u32 = 10;

/// Panels side by side under a figure title. Every image is scaled up (nearest neighbour, one
/// integer factor for all) so the widest is at least `min_width` pixels; bars and legends sit
/// beside/below their panel.
pub fn figure(title: &str, panels: &[Panel], min_width: u32) -> Result<RgbImage, PlotError> {
    let widest = panels
        .iter()
        .map(|p| p.image.width())
        .max()
        .unwrap_or(1)
        .max(1);
    let k = min_width.div_ceil(widest).max(1);
    let legend_rows = panels.iter().map(|p| p.legend.len()).max().unwrap_or(0) as u32;
    let img_h = panels
        .iter()
        .map(|p| p.image.height() * k)
        .max()
        .unwrap_or(1);
    let widths: Vec<u32> = panels
        .iter()
        .map(|p| p.image.width() * k + if p.bar.is_some() { BAR_AREA_W } else { 0 })
        .collect();
    let w = 2 * MARGIN + widths.iter().sum::<u32>() + GAP * panels.len().saturating_sub(1) as u32;
    // Wide enough for the title and the panel titles too (≈ 0.6 em per character).
    let text_w = |t: &str, size: u32| (t.chars().count() as u32 * size * 6).div_ceil(10);
    let w = w.max(2 * MARGIN + text_w(title, 18)).max(
        2 * MARGIN
            + panels
                .iter()
                .map(|p| text_w(&p.title, 15))
                .max()
                .unwrap_or(0),
    );
    let h = TITLE_H + PANEL_TITLE_H + img_h + legend_rows * LEGEND_ROW_H + 2 * MARGIN;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let scaled: Vec<RgbImage> = panels
        .iter()
        .map(|p| {
            image::imageops::resize(
                &p.image,
                p.image.width() * k,
                p.image.height() * k,
                image::imageops::FilterType::Nearest,
            )
        })
        .collect();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let e = |x| err(title, x);
        root.draw(&Text::new(title.to_string(), (MARGIN as i32, 8), font(18)))
            .map_err(e)?;
        let mut x = MARGIN;
        for ((p, img), pw) in panels.iter().zip(&scaled).zip(&widths) {
            let y = TITLE_H;
            root.draw(&Text::new(
                p.title.clone(),
                (x as i32, y as i32 + 2),
                font(15),
            ))
            .map_err(e)?;
            let iy = y + PANEL_TITLE_H;
            let elem = BitMapElement::<_, plotters::backend::RGBPixel>::with_ref(
                (x as i32, iy as i32),
                img.dimensions(),
                img.as_raw(),
            )
            .ok_or_else(|| err(title, "panel buffer size"))?;
            root.draw(&elem).map_err(e)?;
            if let Some(b) = &p.bar {
                let bx = x + img.width() + 6;
                colour_bar(&root, b, bx, iy, img.height()).map_err(e)?;
            }
            for (r, (c, label)) in p.legend.iter().enumerate() {
                let ly = (iy + img.height() + 4 + r as u32 * LEGEND_ROW_H) as i32;
                root.draw(&Rectangle::new(
                    [(x as i32, ly + 2), (x as i32 + 14, ly + 16)],
                    RGBColor(c[0], c[1], c[2]).filled(),
                ))
                .map_err(e)?;
                root.draw(&Rectangle::new(
                    [(x as i32, ly + 2), (x as i32 + 14, ly + 16)],
                    BLACK.stroke_width(1),
                ))
                .map_err(e)?;
                root.draw(&Text::new(label.clone(), (x as i32 + 20, ly + 1), font(14)))
                    .map_err(e)?;
            }
            x += pw + GAP;
        }
        root.present().map_err(e)?;
    }
    RgbImage::from_raw(w, h, buf).ok_or_else(|| err(title, "figure buffer size"))
}

/// A vertical colour bar at `(x, y)`, `height` tall: gradient, frame, ticks with values and the
/// label (with its unit) written along it.
fn colour_bar<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    b: &ColourBar,
    x: u32,
    y: u32,
    height: u32,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (x, y, hgt) = (x as i32, y as i32, height.max(2) as i32);
    for r in 0..hgt {
        let t = 1.0 - r as f32 / (hgt - 1) as f32;
        let c = b.map.at(t);
        root.draw(&Rectangle::new(
            [(x, y + r), (x + BAR_W as i32, y + r + 1)],
            RGBColor(c[0], c[1], c[2]).filled(),
        ))?;
    }
    root.draw(&Rectangle::new(
        [(x, y), (x + BAR_W as i32, y + hgt)],
        BLACK.stroke_width(1),
    ))?;
    let ticks = nice_ticks(f64::from(b.lo), f64::from(b.hi), 5);
    let digits = tick_digits(&ticks);
    for t in ticks {
        let f = (t - f64::from(b.lo)) / f64::from(b.hi - b.lo).max(1e-12);
        let ty = y + ((1.0 - f) * (hgt - 1) as f64).round() as i32;
        root.draw(&PathElement::new(
            vec![(x + BAR_W as i32, ty), (x + BAR_W as i32 + 4, ty)],
            BLACK,
        ))?;
        root.draw(&Text::new(
            format!("{t:.digits$}"),
            (x + BAR_W as i32 + 6, ty - 6),
            font(12),
        ))?;
    }
    // The label, rotated, along the right edge.
    let style = font(13).transform(FontTransform::Rotate270);
    root.draw(&Text::new(
        b.label.clone(),
        (
            x + BAR_W as i32 + 58,
            y + hgt / 2 + 4 * b.label.len() as i32,
        ),
        style,
    ))?;
    Ok(())
}

/// Up to about `n` round tick values inside `[lo, hi]`.
pub fn nice_ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return vec![lo];
    }
    let raw = (hi - lo) / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    // The round step whose number of intervals is closest to `n`.
    let span = hi - lo;
    let step = [0.5, 1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .min_by(|a, b| {
            let d = |s: f64| (span / s - n as f64).abs();
            d(*a).total_cmp(&d(*b))
        })
        .unwrap_or(mag);
    let first = (lo / step).ceil() * step;
    (0..)
        .map(|i| first + i as f64 * step)
        .take_while(|t| *t <= hi + step * 1e-9)
        .take(50)
        .collect()
}

/// Decimals that tell the ticks apart.
fn tick_digits(ticks: &[f64]) -> usize {
    let step = match ticks {
        [a, b, ..] => (b - a).abs(),
        _ => 1.0,
    };
    // The fewest decimals that write the step exactly (0.25 → 2, 0.5 → 1, 2 → 0).
    (0..4)
        .find(|d| {
            let k = step * 10f64.powi(*d);
            (k - k.round()).abs() < 1e-6 * k.max(1.0)
        })
        .unwrap_or(4) as usize
}

/// One series of a line chart.
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
    /// Line colour.
    pub colour: Rgb<u8>,
    /// Dashed (e.g. the "after" half of a before/after pair).
    pub dashed: bool,
}

/// Colours of successive series (colour-blind-safe Tableau order).
pub const PALETTE: [Rgb<u8>; 4] = [
    Rgb([214, 39, 40]),
    Rgb([31, 119, 180]),
    Rgb([255, 127, 14]),
    Rgb([44, 160, 44]),
];

/// Dash and gap of dashed lines, pixels (the series and their legend samples alike).
const DASH: (i32, i32) = (6, 4);
/// Length of a line's legend sample, pixels: two dashes and a gap when dashed.
const LEGEND_LINE: i32 = 16;

/// The legend sample of a line at backend pixel `(x, y)`: a short segment in `style`, dashed like
/// the line (solid: one dash as long as the sample).
fn legend_line(
    (x, y): (i32, i32),
    style: ShapeStyle,
    dashed: bool,
) -> DashedPathElement<std::vec::IntoIter<(i32, i32)>, i32> {
    let (on, off) = if dashed { DASH } else { (LEGEND_LINE, 0) };
    DashedPathElement::new(vec![(x, y), (x + LEGEND_LINE, y)], on, off, style)
}

fn span(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-9 {
        (lo - 0.5, hi + 0.5)
    } else {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    }
}

/// A line chart with title, axis labels (with units) and a legend; also writes the numbers
/// beside it as `<path>.csv` (`series,x,y`).
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), PlotError> {
    let what = path.display().to_string();
    let e = |x| err(&what, x);
    let (x0, x1) = span(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let (y0, y1) = span(
        series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .chain([0.0]),
    );
    let (w, h) = (640u32, 420u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let mut chart = ChartBuilder::on(&root)
            .caption(title, font(17))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(font(12))
            .axis_desc_style(font(14))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(e)?;
        chart
            .draw_series(LineSeries::new(
                [(x0, 0.0), (x1, 0.0)],
                RGBColor(160, 160, 160),
            ))
            .map_err(e)?;
        for s in series {
            let c = RGBColor(s.colour[0], s.colour[1], s.colour[2]);
            let (style, dashed) = (c.stroke_width(2), s.dashed);
            let drawn = if dashed {
                chart.draw_series(DashedLineSeries::new(
                    s.points.iter().copied(),
                    DASH.0,
                    DASH.1,
                    style,
                ))
            } else {
                chart.draw_series(LineSeries::new(s.points.iter().copied(), style))
            };
            drawn
                .map_err(e)?
                .label(s.label.clone())
                .legend(move |p| legend_line(p, style, dashed));
            chart
                .draw_series(s.points.iter().map(|p| Circle::new(*p, 3, c.filled())))
                .map_err(e)?;
        }
        chart
            .configure_series_labels()
            .label_font(font(12))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
    }
    let mut csv = String::from("series,x,y\n");
    for s in series {
        for (x, y) in &s.points {
            csv += &format!("{},{x},{y}\n", s.label.replace(',', ";"));
        }
    }
    save_with_csv(path, w, h, buf, &csv)
}

/// A bar chart of `values` over equal bins of `[x0, x1]` with a dashed reference level, title,
/// axis labels and legend; numbers beside it as `<path>.csv` (`bin_lo,bin_hi,value`).
#[allow(clippy::too_many_arguments)]
pub fn bar_chart(
    path: &Path,
    title: &str,
    (x0, x1): (f64, f64),
    x_label: &str,
    y_label: &str,
    values: &[f64],
    reference: (f64, &str),
) -> Result<(), PlotError> {
    let what = path.display().to_string();
    let e = |x| err(&what, x);
    let n = values.len().max(1);
    let bw = (x1 - x0) / n as f64;
    let top = values
        .iter()
        .copied()
        .chain([reference.0])
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        * 1.15;
    let (w, h) = (640u32, 420u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let mut chart = ChartBuilder::on(&root)
            .caption(title, font(17))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(x0..x1, 0.0..top.max(1e-9))
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(font(12))
            .axis_desc_style(font(14))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(e)?;
        let blue = RGBColor(31, 119, 180);
        chart
            .draw_series(values.iter().enumerate().map(|(i, v)| {
                let a = x0 + i as f64 * bw;
                Rectangle::new([(a + 0.05 * bw, 0.0), (a + 0.95 * bw, *v)], blue.filled())
            }))
            .map_err(e)?
            .label("observed")
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], blue.filled()));
        let red = RGBColor(214, 39, 40).stroke_width(2);
        chart
            .draw_series(DashedLineSeries::new(
                [(x0, reference.0), (x1, reference.0)],
                DASH.0,
                DASH.1,
                red,
            ))
            .map_err(e)?
            .label(reference.1.to_string())
            .legend(move |p| legend_line(p, red, true));
        chart
            .configure_series_labels()
            .label_font(font(12))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
    }
    let mut csv = String::from("bin_lo,bin_hi,value\n");
    for (i, v) in values.iter().enumerate() {
        let a = x0 + i as f64 * bw;
        csv += &format!("{a},{},{v}\n", a + bw);
    }
    save_with_csv(path, w, h, buf, &csv)
}

/// A `rows × cols` zone grid coloured on a diverging blue–white–red scale symmetric about 0,
/// with title, row/column labels and a colour bar; numbers as `<path>.csv` (`row,col,value`).
pub fn zone_heat_map(
    path: &Path,
    title: &str,
    bar_label: &str,
    values: &[f64],
    rows: usize,
    cols: usize,
) -> Result<(), PlotError> {
    let m = values
        .iter()
        .filter(|v| v.is_finite())
        .fold(0.0f64, |a, v| a.max(v.abs()))
        .max(1e-6);
    let cell = (320 / cols.max(1)).clamp(8, 48) as u32;
    let mut img = RgbImage::new(cols as u32 * cell, rows as u32 * cell);
    for (i, v) in values.iter().enumerate().take(rows * cols) {
        let t = (v / m).clamp(-1.0, 1.0);
        let c = diverging(t as f32);
        let (r, c0) = ((i / cols) as u32, (i % cols) as u32);
        for y in 0..cell {
            for x in 0..cell {
                let edge = x == 0 || y == 0;
                img.put_pixel(
                    c0 * cell + x,
                    r * cell + y,
                    if edge { Rgb([200, 200, 200]) } else { c },
                );
            }
        }
    }
    let panel = Panel {
        title: format!("{rows}×{cols} zones (row 0 at the top, column 0 at the left)"),
        image: img,
        bar: Some(ColourBar {
            map: ColourMap::Diverging,
            lo: -m as f32,
            hi: m as f32,
            label: bar_label.to_string(),
        }),
        legend: Vec::new(),
    };
    let fig = figure(title, &[panel], 320)?;
    let mut csv = String::from("row,col,value\n");
    for (i, v) in values.iter().enumerate() {
        csv += &format!("{},{},{v}\n", i / cols.max(1), i % cols.max(1));
    }
    let (w, h) = fig.dimensions();
    save_with_csv(path, w, h, fig.into_raw(), &csv)
}

/// A table of ratios as a heat map: one row per `row_labels`, one column per `col_labels`, each
/// cell coloured on the blue–white–red scale centred on 1 (blue below: better than the
/// reference; red above) and labelled with its value (`—` where not finite); a colour bar with
/// `bar_label`, a title. With `means`, the last row and column are set apart by a gap (they hold
/// means over the others). The numbers are written as `<path>.csv` (`row,col,value`).
pub fn ratio_heat_map(
    path: &Path,
    title: &str,
    bar_label: &str,
    row_labels: &[String],
    col_labels: &[String],
    values: &[Vec<f64>],
    means: bool,
) -> Result<(), PlotError> {
    let what = path.display().to_string();
    let e = |x| err(&what, x);
    let (nr, nc) = (row_labels.len(), col_labels.len());
    // The scale: symmetric about 1, wide enough for the values, at least ±0.25, at most ±1.
    let m = values
        .iter()
        .flatten()
        .filter(|v| v.is_finite())
        .fold(0.25f64, |a, v| a.max((v - 1.0).abs()))
        .min(1.0);
    let (lo, hi) = (1.0 - m, 1.0 + m);
    let text_w = |t: &str, size: u32| (t.chars().count() as u32 * size * 6).div_ceil(10);
    let label_w = row_labels.iter().map(|l| text_w(l, 14)).max().unwrap_or(0) + 12;
    let cell_w = col_labels
        .iter()
        .map(|l| text_w(l, 14) + 12)
        .max()
        .unwrap_or(0)
        .max(78);
    let cell_h = 26u32;
    let sep = 8u32;
    let head_h = 26u32;
    let gap = |i: usize, n: usize| if means && i + 1 == n && n > 1 { sep } else { 0 };
    let grid_w = nc as u32 * cell_w + gap(nc - 1, nc);
    let grid_h = nr as u32 * cell_h + gap(nr - 1, nr);
    let x0 = MARGIN + label_w;
    let y0 = TITLE_H + head_h;
    // Tall enough for the bar's label, written along it.
    let bar_h = grid_h.max(text_w(bar_label, 13) + 24);
    let w = (x0 + grid_w + 12 + BAR_AREA_W + MARGIN).max(2 * MARGIN + text_w(title, 18));
    let h = y0 + bar_h + 2 * MARGIN;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.draw(&Text::new(title.to_string(), (MARGIN as i32, 8), font(18)))
            .map_err(e)?;
        let cx = |c: usize| (x0 + c as u32 * cell_w + gap(c, nc)) as i32;
        let ry = |r: usize| (y0 + r as u32 * cell_h + gap(r, nr)) as i32;
        for (c, l) in col_labels.iter().enumerate() {
            let x = cx(c) + (cell_w as i32 - text_w(l, 14) as i32) / 2;
            root.draw(&Text::new(l.clone(), (x, (TITLE_H + 4) as i32), font(14)))
                .map_err(e)?;
        }
        for (r, l) in row_labels.iter().enumerate() {
            let y = ry(r);
            root.draw(&Text::new(l.clone(), (MARGIN as i32, y + 5), font(14)))
                .map_err(e)?;
            for c in 0..nc {
                let v = values.get(r).and_then(|row| row.get(c)).copied();
                let v = v.unwrap_or(f64::NAN);
                let (fill, dark) = if v.is_finite() {
                    let t = ((v - lo) / (hi - lo)) as f32;
                    (ColourMap::Diverging.at(t), (2.0 * t - 1.0).abs() > 0.6)
                } else {
                    (Rgb([230, 230, 230]), false)
                };
                let x = cx(c);
                let rect = [(x, y), (x + cell_w as i32, y + cell_h as i32)];
                root.draw(&Rectangle::new(
                    rect,
                    RGBColor(fill[0], fill[1], fill[2]).filled(),
                ))
                .map_err(e)?;
                root.draw(&Rectangle::new(
                    rect,
                    RGBColor(160, 160, 160).stroke_width(1),
                ))
                .map_err(e)?;
                let label = if v.is_finite() {
                    format!("{v:.2}")
                } else {
                    "—".into()
                };
                let colour = if dark { WHITE } else { BLACK };
                let tx = x + (cell_w as i32 - text_w(&label, 14) as i32) / 2;
                root.draw(&Text::new(
                    label,
                    (tx, y + 5),
                    (FAMILY, 14).into_font().color(&colour),
                ))
                .map_err(e)?;
            }
        }
        let bar = ColourBar {
            map: ColourMap::Diverging,
            lo: lo as f32,
            hi: hi as f32,
            label: bar_label.to_string(),
        };
        let bx = x0 + grid_w + 12;
        colour_bar(&root, &bar, bx, y0, bar_h).map_err(e)?;
        root.present().map_err(e)?;
    }
    let mut csv = String::from("row,col,value\n");
    for (r, rl) in row_labels.iter().enumerate() {
        for (c, cl) in col_labels.iter().enumerate() {
            let v = values.get(r).and_then(|row| row.get(c)).copied();
            csv += &format!("{rl},{cl},{}\n", v.unwrap_or(f64::NAN));
        }
    }
    save_with_csv(path, w, h, buf, &csv)
}

/// Blue (−1) – white (0) – red (+1).
fn diverging(t: f32) -> Rgb<u8> {
    let t = if t.is_nan() { 0.0 } else { t.clamp(-1.0, 1.0) };
    let mix = |a: f32, b: f32, f: f32| (a + (b - a) * f).round() as u8;
    if t < 0.0 {
        let f = -t;
        Rgb([
            mix(255.0, 33.0, f),
            mix(255.0, 102.0, f),
            mix(255.0, 172.0, f),
        ])
    } else {
        Rgb([
            mix(255.0, 178.0, t),
            mix(255.0, 24.0, t),
            mix(255.0, 43.0, t),
        ])
    }
}

/// Writes the RGB buffer as PNG at `path` and `csv` at `path` with the extension `.csv`.
fn save_with_csv(path: &Path, w: u32, h: u32, buf: Vec<u8>, csv: &str) -> Result<(), PlotError> {
    let what = path.display().to_string();
    let img = RgbImage::from_raw(w, h, buf).ok_or_else(|| err(&what, "buffer size"))?;
    img.save(path).map_err(|x| err(&what, x))?;
    let csv_path = path.with_extension("csv");
    std::fs::write(&csv_path, csv).map_err(|x| err(&csv_path.display().to_string(), x))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robust_range_ignores_a_few_outliers_and_unknown_pixels() {
        let mut v: Vec<f32> = (0..100).map(|i| 1.5 + i as f32 * 0.01).collect();
        v.push(40.0); // one noise zone
        v.push(0.0); // unknown
        v.push(f32::NAN);
        let (lo, hi) = robust_range(&v, 0.02, 0.98).unwrap();
        assert!(
            (1.5..1.6).contains(&lo) && (2.4..2.5).contains(&hi),
            "{lo} {hi}"
        );
        assert_eq!(robust_range(&[0.0, f32::NAN], 0.02, 0.98), None);
    }

    #[test]
    fn ticks_are_round_and_inside_the_range() {
        let close = |a: Vec<f64>, b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
        };
        assert!(close(
            nice_ticks(1.53, 2.91, 5),
            &[1.75, 2.0, 2.25, 2.5, 2.75]
        ));
        assert!(close(
            nice_ticks(0.0, 1.0, 5),
            &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
        ));
        assert_eq!(tick_digits(&[1.75, 2.0]), 2);
    }

    /// Runs of pixels of colour `c` along the row of the upper right quarter (where the legend
    /// is) that holds the most of them.
    fn legend_runs(img: &RgbImage, c: Rgb<u8>) -> usize {
        let (w, h) = img.dimensions();
        let row = (0..h / 2)
            .max_by_key(|&y| (w / 2..w).filter(|&x| *img.get_pixel(x, y) == c).count())
            .unwrap();
        let on: Vec<bool> = (w / 2..w).map(|x| *img.get_pixel(x, row) == c).collect();
        on.windows(2).filter(|p| p[1] && !p[0]).count() + usize::from(on[0])
    }

    #[test]
    fn dashed_series_have_dashed_legend_samples() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lines.png");
        // Both lines low in the chart, away from the legend in the upper right corner.
        let series = [
            Series {
                label: "before".into(),
                points: vec![(0.0, -1.0), (1.0, -0.9)],
                colour: PALETTE[1],
                dashed: false,
            },
            Series {
                label: "after".into(),
                points: vec![(0.0, -0.8), (1.0, -1.0)],
                colour: PALETTE[0],
                dashed: true,
            },
        ];
        line_chart(&path, "t", "x", "y", &series).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(legend_runs(&img, PALETTE[1]), 1, "solid sample");
        assert_eq!(
            legend_runs(&img, PALETTE[0]),
            2,
            "dashed sample: two dashes"
        );

        let path = dir.path().join("bars.png");
        // The dashed reference level low in the chart, below the legend.
        bar_chart(
            &path,
            "t",
            (0.0, 1.0),
            "x",
            "y",
            &[0.05; 4],
            (0.01, "level"),
        )
        .unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(legend_runs(&img, PALETTE[0]), 2, "dashed reference sample");
    }

    #[test]
    fn figure_has_the_title_row_and_scaled_panels() {
        let p = Panel::new("a", RgbImage::from_pixel(16, 12, Rgb([0, 0, 255]))).with_bar(
            ColourMap::Turbo,
            1.0,
            3.0,
            "depth (m)",
        );
        let f = figure("t", &[p], 160).unwrap();
        // 16 px scaled ×10 plus the bar area and margins.
        assert_eq!(f.width(), 2 * MARGIN + 160 + BAR_AREA_W);
        let iy = TITLE_H + PANEL_TITLE_H;
        assert_eq!(*f.get_pixel(MARGIN + 5, iy + 5), Rgb([0, 0, 255]));
        // Text was drawn in the title row (some dark pixel there).
        let dark = (0..f.width()).any(|x| (0..TITLE_H).any(|y| f.get_pixel(x, y)[0] < 100));
        assert!(dark, "no title text");
        // The bar's top is the far (red) end of Turbo.
        let top = *f.get_pixel(MARGIN + 160 + 6 + BAR_W / 2, iy + 2);
        assert!(top[0] > 100 && top[2] < 60, "{top:?}");
    }
}
