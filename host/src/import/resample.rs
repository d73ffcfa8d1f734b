//! Resampling between depth and RGB sizes. Pixel centres sit at integer coordinates (the
//! OpenCV convention the intrinsics use), so a pixel `x` of a `w`-wide image covers
//! `[x − 0.5, x + 0.5)` and the image spans `[−0.5, w − 0.5)`.

use std::path::Path;

use depthor_core::calibration::CameraIntrinsics;
use image::RgbImage;

/// Nearest-neighbour resize of a row-major depth map from `sw × sh` to `dw × dh`: output pixel
/// `(x, y)` takes the source pixel under its centre, `floor((x + 0.5)·sw/dw)`. Never mixes depths
/// across an edge and keeps 0 (unknown) as it is.
pub fn depth_nearest(src: &[f32], sw: u32, sh: u32, dw: u32, dh: u32) -> Vec<f32> {
    let map = |d: u32, s: u32, n: u32| -> usize {
        // (d + 0.5) · s / n in integers: (2d + 1) · s / (2n), floored.
        let v = (2 * u64::from(d) + 1) * u64::from(s) / (2 * u64::from(n));
        v.min(u64::from(s).saturating_sub(1)) as usize
    };
    let xs: Vec<usize> = (0..dw).map(|x| map(x, sw, dw)).collect();
    let mut out = Vec::with_capacity(dw as usize * dh as usize);
    for y in 0..dh {
        let row = map(y, sh, dh) * sw as usize;
        out.extend(xs.iter().map(|&x| src.get(row + x).copied().unwrap_or(0.0)));
    }
    out
}

/// `depth_m` (`dw × dh`, read from `depth_path`) at the size of `rgb`: unchanged when the sizes
/// agree, else resampled with [`depth_nearest`] and a note saying so is pushed to `notes`.
pub(crate) fn depth_at_rgb_size(
    kind: &str,
    depth_path: &Path,
    depth_m: Vec<f32>,
    (dw, dh): (u32, u32),
    rgb: &RgbImage,
    notes: &mut Vec<String>,
) -> Vec<f32> {
    let (w, h) = rgb.dimensions();
    if (dw, dh) == (w, h) {
        return depth_m;
    }
    notes.push(format!(
        "{kind}: {}: depth {dw}×{dh} resampled (nearest neighbour) to the RGB's {w}×{h}",
        depth_path
            .file_name()
            .unwrap_or(depth_path.as_os_str())
            .to_string_lossy()
    ));
    depth_nearest(&depth_m, dw, dh, w, h)
}

/// Box-filter downsampling by an integer `factor` (each output pixel is the rounded mean of a
/// `factor × factor` block); trailing rows/columns that do not fill a block are dropped.
pub fn rgb_box_downsample(img: &RgbImage, factor: u32) -> RgbImage {
    let f = factor.max(1);
    let (w, h) = (img.width() / f, img.height() / f);
    let n = f * f;
    RgbImage::from_fn(w, h, |x, y| {
        let mut acc = [0u32; 3];
        for dy in 0..f {
            for dx in 0..f {
                let p = img.get_pixel(x * f + dx, y * f + dy);
                for c in 0..3 {
                    acc[c] += u32::from(p[c]);
                }
            }
        }
        image::Rgb(acc.map(|a| ((a + n / 2) / n) as u8))
    })
}

/// Intrinsics of an image downsampled by an integer `factor` with [`rgb_box_downsample`]:
/// `f' = f/k`, `c' = (c − (k − 1)/2)/k` (block `x'` is centred on old `k·x' + (k − 1)/2`).
pub fn scale_intrinsics(cam: &CameraIntrinsics, factor: u32) -> CameraIntrinsics {
    let k = factor.max(1) as f32;
    let shift = (k - 1.0) / 2.0;
    CameraIntrinsics {
        width: cam.width / factor.max(1),
        height: cam.height / factor.max(1),
        fx: cam.fx / k,
        fy: cam.fy / k,
        cx: (cam.cx - shift) / k,
        cy: (cam.cy - shift) / k,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_upsamples_2x2_to_4x4_and_5x5() {
        let src = [1.0, 2.0, 3.0, 4.0];
        let up = depth_nearest(&src, 2, 2, 4, 4);
        #[rustfmt::skip]
        let want = [1.0, 1.0, 2.0, 2.0,
                    1.0, 1.0, 2.0, 2.0,
                    3.0, 3.0, 4.0, 4.0,
                    3.0, 3.0, 4.0, 4.0];
        assert_eq!(up, want);
        // 2 → 5: centres 0.5, 1.5, 2.5, 3.5, 4.5 map to 0.2, 0.6, 1.0, 1.4, 1.8 → 0, 0, 1, 1, 1.
        let row = depth_nearest(&[7.0, 9.0], 2, 1, 5, 1);
        assert_eq!(row, [7.0, 7.0, 9.0, 9.0, 9.0]);
    }

    #[test]
    fn nearest_downsample_picks_centres() {
        // 4 → 2: centres 1.0 and 3.0 → source pixels 1 and 3.
        assert_eq!(depth_nearest(&[1.0, 2.0, 3.0, 4.0], 4, 1, 2, 1), [2.0, 4.0]);
    }

    #[test]
    fn box_downsample_means_and_intrinsics() {
        let img = RgbImage::from_fn(6, 3, |x, _| image::Rgb([x as u8 * 10, 0, 255]));
        let d = rgb_box_downsample(&img, 3);
        assert_eq!(d.dimensions(), (2, 1));
        assert_eq!(d.get_pixel(0, 0).0, [10, 0, 255]); // mean of 0, 10, 20
        assert_eq!(d.get_pixel(1, 0).0, [40, 0, 255]); // mean of 30, 40, 50
        let cam = CameraIntrinsics {
            width: 1920,
            height: 1440,
            fx: 1500.0,
            fy: 1500.0,
            cx: 959.5,
            cy: 719.5,
        };
        let s = scale_intrinsics(&cam, 3);
        assert_eq!((s.width, s.height), (640, 480));
        assert_eq!((s.fx, s.cx, s.cy), (500.0, 319.5, 239.5));
    }
}
