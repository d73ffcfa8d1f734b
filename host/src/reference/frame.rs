//! Camera frame → model inputs at the model's size: bilinear RGB resize, the matching intrinsics
//! (and zone rectangles), and the zone projection of `depthor_core::projection`.
//!
//! Pixel centres sit at integer coordinates (as in `depthor_core::projection`), so resizing a
//! `W`-wide image to `W'` maps a coordinate `x` to `x' = (x + ½)·s − ½` with `s = W'/W`. The
//! resize samples each output pixel centre at its source position by bilinear interpolation of
//! the four nearest source pixels (half-pixel centres, no antialiasing: OpenCV `INTER_LINEAR`,
//! PyTorch `align_corners=False`), clamping at the borders, and rounds to the nearest byte.
//! The intrinsics follow the same map: `fx' = fx·sx`, `cx' = (cx + ½)·sx − ½` (and `y`), and so
//! do the four coordinates of `zone_rects_px`.

use depthor_core::calibration::{Calibration, CameraIntrinsics};
use depthor_core::hal::ZoneView;
use depthor_core::projection::{project_to_sparse, ProjectionStats};
use image::RgbImage;

use super::ReferenceError;

/// A frame ready for the model: RGB and sparse depth at the model size.
#[derive(Clone, Debug)]
pub struct PreparedFrame {
    /// RGB at the model size (the input image itself when it already had that size).
    pub rgb: RgbImage,
    /// Sparse depth `S`, row-major, metres, 0 = no point.
    pub sparse_m: Vec<f32>,
    /// The intrinsics the zones were projected with (scaled to the model size).
    pub camera: CameraIntrinsics,
    /// What the projection did with the zones.
    pub stats: ProjectionStats,
}

/// Maps a coordinate (pixel centres at integers) through a resize by `scale`.
fn map_coord(v: f32, scale: f64) -> f32 {
    ((f64::from(v) + 0.5) * scale - 0.5) as f32
}

/// The intrinsics of `cam` after resizing its images to `width × height`.
pub fn scale_intrinsics(cam: &CameraIntrinsics, width: u32, height: u32) -> CameraIntrinsics {
    let sx = f64::from(width) / f64::from(cam.width);
    let sy = f64::from(height) / f64::from(cam.height);
    CameraIntrinsics {
        width,
        height,
        fx: (f64::from(cam.fx) * sx) as f32,
        fy: (f64::from(cam.fy) * sy) as f32,
        cx: map_coord(cam.cx, sx),
        cy: map_coord(cam.cy, sy),
    }
}

/// Zone rectangles `[y0, x0, y1, x1]` of a `cam`-sized image, mapped to `width × height`.
pub fn scale_rects(
    rects: &[[f32; 4]],
    cam: &CameraIntrinsics,
    width: u32,
    height: u32,
) -> Vec<[f32; 4]> {
    let sx = f64::from(width) / f64::from(cam.width);
    let sy = f64::from(height) / f64::from(cam.height);
    rects
        .iter()
        .map(|&[y0, x0, y1, x1]| {
            [
                map_coord(y0, sy),
                map_coord(x0, sx),
                map_coord(y1, sy),
                map_coord(x1, sx),
            ]
        })
        .collect()
}

/// Source sample position and weight for output coordinate `o` of a resize from `src` to `dst`
/// samples: `(i0, i1, t)` with value `(1 − t)·a[i0] + t·a[i1]`.
fn taps(o: u32, src: u32, dst: u32) -> (u32, u32, f32) {
    let pos = (f64::from(o) + 0.5) * f64::from(src) / f64::from(dst) - 0.5;
    let last = f64::from(src - 1);
    let pos = pos.clamp(0.0, last);
    let i0 = pos.floor();
    let t = (pos - i0) as f32;
    let i0 = i0 as u32;
    (i0, (i0 + 1).min(src - 1), t)
}

/// Bilinear resize of `src` to `width × height` (see the module doc). An empty source or target
/// gives an empty (or black, when only the source is empty) image.
pub fn resize_bilinear(src: &RgbImage, width: u32, height: u32) -> RgbImage {
    let (sw, sh) = src.dimensions();
    if (sw, sh) == (width, height) {
        return src.clone();
    }
    let mut out = RgbImage::new(width, height);
    if sw == 0 || sh == 0 {
        return out;
    }
    let xs: Vec<(u32, u32, f32)> = (0..width).map(|x| taps(x, sw, width)).collect();
    for y in 0..height {
        let (y0, y1, ty) = taps(y, sh, height);
        for (x, &(x0, x1, tx)) in xs.iter().enumerate() {
            let p = |xx: u32, yy: u32| src.get_pixel(xx, yy).0;
            let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
            let mut px = [0u8; 3];
            for ch in 0..3 {
                let top = f32::from(a[ch]) * (1.0 - tx) + f32::from(b[ch]) * tx;
                let bottom = f32::from(c[ch]) * (1.0 - tx) + f32::from(d[ch]) * tx;
                let v = top * (1.0 - ty) + bottom * ty;
                px[ch] = (v + 0.5).clamp(0.0, 255.0) as u8;
            }
            out.put_pixel(x as u32, y, image::Rgb(px));
        }
    }
    out
}

/// Brings one camera frame to the model size `width × height`: resizes `rgb` (which must be the
/// calibration's camera size) when the sizes differ, scales the intrinsics and zone rectangles to
/// match, and projects `zones` into the sparse map.
pub fn prepare(
    calib: &Calibration,
    rgb: &RgbImage,
    zones: &ZoneView,
    height: u32,
    width: u32,
) -> Result<PreparedFrame, ReferenceError> {
    let cam = &calib.camera;
    if cam.width == 0 || cam.height == 0 {
        return Err(ReferenceError::Calibration(
            "camera width or height is zero",
        ));
    }
    if rgb.dimensions() != (cam.width, cam.height) {
        return Err(ReferenceError::InputSize {
            name: "camera image pixels (calibration width × height)",
            expected: cam.width as usize * cam.height as usize,
            got: rgb.width() as usize * rgb.height() as usize,
        });
    }
    let camera = scale_intrinsics(cam, width, height);
    let rects = calib
        .zone_rects_px
        .map(|r| scale_rects(r, cam, width, height));
    let scaled = Calibration {
        camera,
        dtof: calib.dtof,
        dtof_to_camera: calib.dtof_to_camera,
        zone_rects_px: rects.as_deref(),
    };
    let mut sparse_m = vec![0.0f32; width as usize * height as usize];
    let stats =
        project_to_sparse(&scaled, zones, &mut sparse_m).map_err(ReferenceError::Projection)?;
    Ok(PreparedFrame {
        rgb: resize_bilinear(rgb, width, height),
        sparse_m,
        camera,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halving_averages_two_by_two_blocks() {
        // 4×2 → 2×1: each output centre sits at source (2x + 0.5, 0.5), the middle of a 2×2 block.
        let src = RgbImage::from_raw(
            4,
            2,
            vec![
                0, 0, 0, 10, 20, 30, 100, 100, 100, 200, 200, 200, //
                20, 40, 60, 30, 60, 90, 100, 100, 100, 201, 200, 200,
            ],
        )
        .unwrap();
        let out = resize_bilinear(&src, 2, 1);
        // (0+10+20+30)/4 = 15, (0+20+40+60)/4 = 30, (0+30+60+90)/4 = 45;
        // red (100+200+100+201)/4 = 150.25 → 150.
        assert_eq!(out.get_pixel(0, 0).0, [15, 30, 45]);
        assert_eq!(out.get_pixel(1, 0).0, [150, 150, 150]);
    }

    #[test]
    fn doubling_interpolates_and_clamps() {
        // 2×1 → 4×1: output x samples source (x + 0.5)/2 − 0.5 = −0.25, 0.25, 0.75, 1.25,
        // clamped to 0, 0.25, 0.75, 1: values 0, 25, 75, 100 for a 0 → 100 ramp.
        let src = RgbImage::from_raw(2, 1, vec![0, 0, 0, 100, 200, 40]).unwrap();
        let out = resize_bilinear(&src, 4, 1);
        let red: Vec<u8> = (0..4).map(|x| out.get_pixel(x, 0).0[0]).collect();
        assert_eq!(red, [0, 25, 75, 100]);
        // green 0 → 200: 0, 50, 150, 200; blue 0 → 40: 0, 10, 30, 40.
        assert_eq!(out.get_pixel(1, 0).0, [25, 50, 10]);
        assert_eq!(out.get_pixel(2, 0).0, [75, 150, 30]);
    }

    #[test]
    fn same_size_is_a_copy() {
        let src = RgbImage::from_fn(5, 3, |x, y| image::Rgb([x as u8, y as u8, 7]));
        assert_eq!(resize_bilinear(&src, 5, 3), src);
    }

    #[test]
    fn intrinsics_follow_pixel_centres() {
        let cam = CameraIntrinsics {
            width: 640,
            height: 480,
            fx: 600.0,
            fy: 580.0,
            cx: 319.5,
            cy: 239.5,
        };
        let s = scale_intrinsics(&cam, 160, 120);
        // s = 1/4: fx 150, fy 145; the image centre 319.5 maps to (320)/4 − 0.5 = 79.5.
        assert_eq!((s.width, s.height), (160, 120));
        assert_eq!((s.fx, s.fy, s.cx, s.cy), (150.0, 145.0, 79.5, 59.5));
        // Source pixel 0's centre (x = 0) lands at 0.5/4 − 0.5 = −0.375.
        let r = scale_rects(&[[0.0, 0.0, 479.0, 639.0]], &cam, 160, 120);
        assert_eq!(r, vec![[-0.375, -0.375, 119.375, 159.375]]);
    }
}
