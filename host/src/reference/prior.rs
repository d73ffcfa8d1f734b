//! The monocular prior alone (`prior.nnef.tgz`: `rgb` → `d_inv`, relative inverse depth) run by
//! tract, and the paper's "DAv2-RS" baseline built on it: the prior's inverse depth fitted to the
//! dToF points by least-squares scale and shift, then inverted to metres.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use depthor_core::projection::ProjectedPoint;
use tract_core::internal::{format_err, tvec, IntoTValue, Tensor, TypedSimplePlan};

use super::{check_len, prepare, rgb_to_planar, ReferenceError};

/// The prior network, optimised for one input size.
#[derive(Debug)]
pub struct PriorReference {
    path: PathBuf,
    height: usize,
    width: usize,
    plan: Arc<TypedSimplePlan>,
}

impl PriorReference {
    /// Loads `prior.nnef.tgz` (input `rgb` `[1,3,H,W]`, output `d_inv` `[1,1,H,W]`) at
    /// `height × width`; errors name the file.
    pub fn load(path: &Path, height: u32, width: u32) -> Result<Self, ReferenceError> {
        let (plan, _) = prepare(path, height, width, &[("rgb", 3)], "d_inv")?;
        Ok(PriorReference {
            path: path.to_path_buf(),
            height: height as usize,
            width: width as usize,
            plan,
        })
    }

    /// Relative inverse depth `H × W` of an RGB888 image (`H × W × 3`).
    pub fn run(&self, rgb: &[u8]) -> Result<Vec<f32>, ReferenceError> {
        let n = self.height * self.width;
        let run_err = |e: tract_core::internal::TractError| ReferenceError::Run {
            path: self.path.clone(),
            source: e.into(),
        };
        let planar = rgb_to_planar(rgb, n)?;
        let input =
            Tensor::from_shape(&[1, 3, self.height, self.width], &planar).map_err(run_err)?;
        let out = self.plan.run(tvec!(input.into_tvalue())).map_err(run_err)?;
        let d = out
            .first()
            .ok_or_else(|| run_err(format_err!("no output")))?
            .to_plain_array_view::<f32>()
            .map_err(run_err)?
            .iter()
            .copied()
            .collect::<Vec<f32>>();
        check_len("d_inv output", n, d.len())?;
        Ok(d)
    }
}

/// Fits `a·d_inv + b ≈ 1/z` by least squares over the dToF points (each point's pixel, `z` its
/// depth), then returns `1/(a·d_inv + b)` clamped to `[lo_m, hi_m]` for every pixel. With fewer
/// than two usable points or a degenerate fit, every pixel gets the points' median depth (or
/// `hi_m` without points), so the baseline always answers.
pub fn fit_scale_shift(
    d_inv: &[f32],
    width: usize,
    points: &[ProjectedPoint],
    lo_m: f32,
    hi_m: f32,
) -> Vec<f32> {
    let samples: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.depth_m > 0.0)
        .filter_map(|p| {
            let i = p.y as usize * width + p.x as usize;
            d_inv.get(i).map(|&x| (x as f64, 1.0 / p.depth_m as f64))
        })
        .collect();
    let n = samples.len() as f64;
    let (sx, sy) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n.max(1.0), sy / n.max(1.0));
    let (sxx, sxy) = samples.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (x - mx), b + (x - mx) * (y - my))
    });
    let clamp = |z: f64| (z as f32).clamp(lo_m, hi_m);
    if samples.len() < 2 || sxx <= 1e-12 {
        let mut z: Vec<f32> = points
            .iter()
            .map(|p| p.depth_m)
            .filter(|d| *d > 0.0)
            .collect();
        z.sort_by(f32::total_cmp);
        let fill = z
            .get(z.len() / 2)
            .copied()
            .unwrap_or(hi_m)
            .clamp(lo_m, hi_m);
        return vec![fill; d_inv.len()];
    }
    let a = sxy / sxx;
    let b = my - a * mx;
    d_inv
        .iter()
        .map(|&x| {
            let inv = a * x as f64 + b;
            if inv > 0.0 {
                clamp(1.0 / inv)
            } else {
                hi_m
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(x: u32, depth_m: f32) -> ProjectedPoint {
        ProjectedPoint {
            u: x as f32,
            v: 0.0,
            x,
            y: 0,
            depth_m,
            zone: x as u16,
        }
    }

    #[test]
    fn recovers_an_affine_inverse_depth() {
        // d_inv = 2·(1/z) − 0.1 exactly: the fit inverts it.
        let z = [1.0f32, 2.0, 4.0, 5.0];
        let d_inv: Vec<f32> = z.iter().map(|z| 2.0 / z - 0.1).collect();
        let pts: Vec<ProjectedPoint> = (0..3).map(|i| point(i, z[i as usize])).collect();
        let out = fit_scale_shift(&d_inv, 4, &pts, 0.1, 10.0);
        for (o, z) in out.iter().zip(z) {
            assert!((o - z).abs() < 1e-4, "{o} vs {z}");
        }
    }

    #[test]
    fn degenerate_inputs_still_answer() {
        let out = fit_scale_shift(&[0.5; 4], 4, &[point(0, 3.0), point(1, 2.0)], 0.1, 10.0);
        assert!(out.iter().all(|&d| d == 3.0));
        let out = fit_scale_shift(&[0.5; 4], 4, &[], 0.1, 10.0);
        assert!(out.iter().all(|&d| d == 10.0));
    }
}
