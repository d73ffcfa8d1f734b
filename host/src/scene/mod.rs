//! Synthetic indoor scenes, the training data of the network (the paper trains on Hypersim, §4.1;
//! we render our own). A seed fixes a room or corridor 2.5–12 m deep with furniture, thin
//! structures, slanted planes, glass, mirrors, dark absorbers, openings to a distant exterior,
//! procedural and CC0 photo textures, and 1–3 lamps; an analytic ray caster renders RGB, planar
//! depth, the depth behind glass or along a mirror's reflected path, 940 nm reflectance, material
//! labels and normals. The dToF simulator and the `depthor sim` command build on [`render_scene`].
//!
//! Everything is a pure function of `(config, seed, camera)`: rows are rendered in parallel but
//! each pixel depends only on its own coordinates, so the thread count never changes a bit.
//!
//! ```no_run
//! use depthor_host::scene::{camera_near, render_scene, SceneConfig};
//! let cam = camera_near(7, 160, 120, 63.0);
//! let frame = render_scene(&SceneConfig::default(), 7, cam);
//! assert_eq!(frame.depth_m.len(), 160 * 120);
//! ```
mod config;
mod furniture;
mod layout;
mod material;
mod math;
mod palette;
mod render;
mod shapes;
mod texture;

pub use config::{SceneConfig, SceneConfigError};
pub use material::Class;
pub use texture::PHOTOS;

use crate::rng::Rng;
use depthor_core::calibration::CameraIntrinsics;

/// One rendered frame: all buffers are row-major, `width × height` pixels (RGB: three bytes per
/// pixel), pixel `(x, y)` looks along `((x − cx)/fx, (y − cy)/fy, 1)` in the camera frame
/// (x right, y down, z forward; OpenCV convention, pixel centres at integer coordinates).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneFrame {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Intrinsics the frame was rendered with.
    pub camera: CameraIntrinsics,
    /// RGB interleaved, 8-bit sRGB.
    pub rgb: Vec<u8>,
    /// Planar z in metres of the first surface hit (glass and mirrors included).
    pub depth_m: Vec<f32>,
    /// Transparent: planar z of the first opaque surface behind the glass. Mirror: planar-z
    /// equivalent of the reflected path (camera → mirror → surface, divided by the ray's length
    /// per unit z). 0 elsewhere.
    pub second_depth_m: Vec<f32>,
    /// 940 nm albedo in [0, 1] of the first surface (glass ≈ 0.04–0.08, mirror its specular
    /// reflectance ≈ 0.82–0.95, dark ≈ 0.02–0.06).
    pub reflectance: Vec<f32>,
    /// Material class ([`Class`] as `u8`): 0 diffuse/unknown, 1 transparent, 2 specular/mirror,
    /// 3 dark/absorbing.
    pub labels: Vec<u8>,
    /// Camera-frame unit normals of the first surface, facing the camera.
    pub normals: Vec<[f32; 3]>,
}

impl SceneFrame {
    /// The simulator input of this frame: every ground-truth map the scene renders (depth, RGB,
    /// labels, reflectance, the surface behind glass or along a mirror).
    pub fn sim_input(&self) -> crate::sim::SimInput<'_> {
        crate::sim::SimInput {
            width: self.width,
            height: self.height,
            depth_m: &self.depth_m,
            rgb: &self.rgb,
            labels: Some(&self.labels),
            reflectance: Some(&self.reflectance),
            second_depth_m: Some(&self.second_depth_m),
        }
    }
}

/// Renders scene `seed` drawn from `cfg` through `camera`.
pub fn render_scene(cfg: &SceneConfig, seed: u64, camera: CameraIntrinsics) -> SceneFrame {
    let hfov = 2.0 * (camera.width as f32 / (2.0 * camera.fx.max(1e-3))).atan();
    let world = layout::build(cfg, seed, hfov);
    render::render(&world, &camera, seed)
}

/// Random intrinsics near a nominal horizontal field of view: hfov ± 1.5°, fy within ±1 % of fx,
/// principal point within ±2 % of the image size from the centre.
pub fn camera_near(seed: u64, width: u32, height: u32, hfov_deg: f32) -> CameraIntrinsics {
    let mut r = Rng::derive(seed, 0xCA3E_0001);
    let hfov = (hfov_deg + r.range(-1.5, 1.5))
        .clamp(1.0, 170.0)
        .to_radians();
    let fx = width as f32 * 0.5 / (hfov * 0.5).tan();
    let fy = fx * (1.0 + r.range(-0.01, 0.01));
    let cx = (width as f32 - 1.0) * 0.5 + r.range(-0.02, 0.02) * width as f32;
    let cy = (height as f32 - 1.0) * 0.5 + r.range(-0.02, 0.02) * height as f32;
    CameraIntrinsics {
        width,
        height,
        fx,
        fy,
        cx,
        cy,
    }
}

/// Intrinsics for scene `seed` with a nominal field of view drawn from `cfg.hfov_deg`.
pub fn camera_for(cfg: &SceneConfig, seed: u64, width: u32, height: u32) -> CameraIntrinsics {
    let mut r = Rng::derive(seed, 0xCA3E_0002);
    let hfov = if cfg.hfov_deg[1] > cfg.hfov_deg[0] {
        r.range(cfg.hfov_deg[0], cfg.hfov_deg[1])
    } else {
        cfg.hfov_deg[0]
    };
    camera_near(seed, width, height, hfov)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_near_stays_near_the_nominal_fov() {
        for seed in 0..20 {
            let c = camera_near(seed, 640, 480, 62.0);
            let hfov = 2.0 * (320.0 / c.fx).atan().to_degrees();
            assert!((hfov - 62.0).abs() <= 1.5 + 1e-3, "{hfov}");
            assert!((c.fy / c.fx - 1.0).abs() <= 0.01 + 1e-6);
            assert!((c.cx - 319.5).abs() <= 12.8 + 1e-3 && (c.cy - 239.5).abs() <= 9.6 + 1e-3);
        }
    }
}
