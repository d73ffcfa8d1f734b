//! Instructions per frame over a set of frames: minimum, maximum, mean and spread, for the
//! firmware's frame-time check on adversarial frames (`firmware-sim` feature `adversarial`,
//! firmware-sim README "Frame time on adversarial frames").
//!
//! Integer arithmetic only, so the firmware and a test reading its per-frame lines get the same
//! figures: `mean = ⌊sum / frames⌋`, `spread = ⌊(max − min) · 100 000 / mean⌋` thousandths of a
//! percent, i.e. the whole range of the frame times as a share of their mean.
//!
//! Frames the core refuses (no valid zone: the model does not run, see
//! [`crate::pipeline::LoopError::Frame`]) are counted apart: they take a small fraction of a
//! model frame, so they would only widen the range downwards, never lengthen the worst case.

/// Running figures over the frames seen so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameTimes {
    /// Frames that produced depth (the model ran).
    pub frames: u64,
    /// Sum of their instruction counts.
    pub sum: u64,
    /// Smallest instruction count of a frame with depth (`u64::MAX` before the first).
    pub min: u64,
    /// Largest instruction count of a frame with depth.
    pub max: u64,
    /// Frames the core refused (no valid zone).
    pub refused: u64,
    /// Largest instruction count of a refused frame.
    pub refused_max: u64,
}

impl FrameTimes {
    /// No frames yet.
    pub const fn new() -> Self {
        FrameTimes {
            frames: 0,
            sum: 0,
            min: u64::MAX,
            max: 0,
            refused: 0,
            refused_max: 0,
        }
    }

    /// Adds a frame that produced depth and took `instructions`.
    pub fn add(&mut self, instructions: u64) {
        self.frames += 1;
        self.sum = self.sum.saturating_add(instructions);
        self.min = self.min.min(instructions);
        self.max = self.max.max(instructions);
    }

    /// Adds a frame the core refused after `instructions`.
    pub fn add_refused(&mut self, instructions: u64) {
        self.refused += 1;
        self.refused_max = self.refused_max.max(instructions);
    }

    /// `⌊sum / frames⌋` (0 without frames).
    pub fn mean(&self) -> u64 {
        self.sum.checked_div(self.frames).unwrap_or(0)
    }

    /// `⌊(max − min) · 100 000 / mean⌋`: the spread in thousandths of a percent (0 without
    /// frames).
    pub fn spread_milli_percent(&self) -> u64 {
        if self.frames == 0 {
            return 0;
        }
        let range = u128::from(self.max - self.min) * 100_000;
        (range / u128::from(self.mean().max(1))) as u64
    }
}

impl core::fmt::Display for FrameTimes {
    /// `adversarial: frames 16 with depth, min … max … mean … spread 0.123% ((max - min) / mean);
    /// refused 2 (no valid zone, model not run), at most … instructions`: the summary line the
    /// firmware prints.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let spread = self.spread_milli_percent();
        write!(
            f,
            "adversarial: frames {} with depth, min {} max {} mean {} spread {}.{:03}% \
             ((max - min) / mean); refused {} (no valid zone, model not run), at most {} \
             instructions",
            self.frames,
            if self.frames == 0 { 0 } else { self.min },
            self.max,
            self.mean(),
            spread / 1000,
            spread % 1000,
            self.refused,
            self.refused_max
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_of_known_counts() {
        let mut t = FrameTimes::new();
        for n in [1_000_000, 1_010_000, 990_000] {
            t.add(n);
        }
        t.add_refused(5_000);
        t.add_refused(7_000);
        assert_eq!(
            (t.frames, t.min, t.max, t.mean()),
            (3, 990_000, 1_010_000, 1_000_000)
        );
        // 20 000 / 1 000 000 = 2 %.
        assert_eq!(t.spread_milli_percent(), 2_000);
        assert_eq!((t.refused, t.refused_max), (2, 7_000));
        let line = t.to_string();
        assert!(
            line.starts_with(
                "adversarial: frames 3 with depth, min 990000 max 1010000 mean 1000000 \
                 spread 2.000% "
            ),
            "{line}"
        );
        assert!(line.contains("refused 2 (no valid zone, model not run), at most 7000"));
    }

    #[test]
    fn spread_rounds_down_and_empty_is_zero() {
        let mut t = FrameTimes::new();
        assert_eq!((t.mean(), t.spread_milli_percent()), (0, 0));
        assert!(t.to_string().contains("min 0 max 0 mean 0 spread 0.000%"));
        t.add(3);
        t.add(4);
        // mean ⌊7 / 2⌋ = 3; 1 · 100 000 / 3 = 33 333.3 → 33.333 %.
        assert_eq!(t.spread_milli_percent(), 33_333);
        assert!(t.to_string().contains("spread 33.333%"), "{t}");
    }
}
