//! Per-frame summaries printed by `depthor info`.

use super::reader::Frame;

/// Statistics of a reference depth map over its known pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthSummary {
    /// Fraction of pixels with known (> 0, finite) depth.
    pub valid_fraction: f64,
    /// Smallest known depth, metres (0 when none is known).
    pub min_m: f32,
    /// Median of the known depths, metres (lower median for an even count; 0 when none).
    pub median_m: f32,
    /// Largest known depth, metres (0 when none is known).
    pub max_m: f32,
}

impl DepthSummary {
    /// Summarises `depth_m` (0 or non-finite = unknown).
    pub fn of(depth_m: &[f32]) -> Self {
        let mut valid: Vec<f32> = depth_m
            .iter()
            .copied()
            .filter(|d| d.is_finite() && *d > 0.0)
            .collect();
        let valid_fraction = if depth_m.is_empty() {
            0.0
        } else {
            valid.len() as f64 / depth_m.len() as f64
        };
        if valid.is_empty() {
            return DepthSummary {
                valid_fraction,
                min_m: 0.0,
                median_m: 0.0,
                max_m: 0.0,
            };
        }
        let mid = (valid.len() - 1) / 2;
        let (_, &mut median_m, _) = valid.select_nth_unstable_by(mid, f32::total_cmp);
        DepthSummary {
            valid_fraction,
            min_m: valid.iter().copied().fold(f32::INFINITY, f32::min),
            median_m,
            max_m: valid.iter().copied().fold(0.0, f32::max),
        }
    }
}

/// What `depthor info` reports for one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSummary {
    /// Frame id.
    pub id: String,
    /// Image width and height.
    pub size: (u32, u32),
    /// Reference depth statistics, when the frame has depth.
    pub depth: Option<DepthSummary>,
    /// `(valid zones, zones)` when the frame has zones.
    pub dtof_valid: Option<(usize, usize)>,
    /// Whether the frame has material labels.
    pub has_labels: bool,
}

impl FrameSummary {
    /// Summarises a frame.
    pub fn of(frame: &Frame) -> Self {
        FrameSummary {
            id: frame.id.clone(),
            size: frame.rgb.dimensions(),
            depth: frame.depth_m.as_deref().map(DepthSummary::of),
            dtof_valid: frame
                .dtof
                .as_ref()
                .map(|z| (z.valid_zones(), z.status.len())),
            has_labels: frame.labels.is_some(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::DepthSummary;

    #[test]
    fn summary_ignores_unknown_and_takes_lower_median() {
        let s = DepthSummary::of(&[0.0, 2.0, 1.0, f32::NAN, 4.0, 3.0, 0.0, 0.0]);
        assert_eq!(s.valid_fraction, 0.5);
        assert_eq!((s.min_m, s.median_m, s.max_m), (1.0, 2.0, 4.0));
        let empty = DepthSummary::of(&[0.0, 0.0]);
        assert_eq!((empty.valid_fraction, empty.max_m), (0.0, 0.0));
    }
}
