//! Whether the held-out frames can show anything: the sign-flip test over `n` scored frames
//! (2-fold cross-fitting scores every frame, each under the fit of the other half) cannot return
//! a p-value below `2^−n` (all gains positive: only the identity pattern reaches the observed
//! sum), nor below `1/(permutations + 1)`. When that floor is above the level the
//! selection tests at, "no significant missing physics" would say nothing about the data, so the
//! report says "inconclusive" with the frames a conclusive run needs.

use serde::Serialize;

/// The power of one run's held-out test, as `report.json` carries it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Power {
    /// Whether the run could have found an effect: it found one, or the smallest achievable p
    /// is at or below the level.
    pub conclusive: bool,
    /// Frames scored by a fit that did not see them (every frame: each half is held out from
    /// the other half's fit).
    pub heldout_frames: usize,
    /// Smallest p-value the sign-flip test can return with these frames.
    pub min_achievable_p: f64,
    /// Level the first test of a selection round must reach (α/2).
    pub level: f64,
    /// Frames in the recording for the smallest achievable p to reach the level.
    pub frames_needed: usize,
}

impl Power {
    /// Power of a run with `heldout` scored frames, `permutations` sign patterns and test
    /// level `level`; `found`: whether the run accepted any effect.
    pub fn of(heldout: usize, permutations: usize, level: f64, found: bool) -> Power {
        let floor_mc = 1.0 / (permutations as f64 + 1.0);
        let min_p = 0.5f64.powi(heldout.min(1000) as i32).max(floor_mc);
        // Smallest n with 2^−n ≤ level; every frame is scored.
        let mut n = 0usize;
        while 0.5f64.powi(n as i32) > level && n < 1000 {
            n += 1;
        }
        Power {
            conclusive: found || min_p <= level,
            heldout_frames: heldout,
            min_achievable_p: min_p,
            level,
            frames_needed: n,
        }
    }

    /// The first line of `report.md` when the run is inconclusive.
    pub fn headline(&self) -> Option<String> {
        (!self.conclusive).then(|| {
            format!(
                "**Inconclusive**: with {} held-out frames the sign-flip test cannot reach p ≤ {} \
                 (smallest achievable p = {:.4}); nothing can be called significant. Record at \
                 least {} frames.",
                self.heldout_frames, self.level, self.min_achievable_p, self.frames_needed
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_heldout_frames_cannot_reach_the_level() {
        let p = Power::of(4, 1999, 0.025, false);
        assert!(!p.conclusive);
        assert_eq!(p.min_achievable_p, 1.0 / 16.0);
        // 2^−6 = 0.0156 ≤ 0.025 < 2^−5: six frames.
        assert_eq!(p.frames_needed, 6);
        assert!(p.headline().unwrap().contains("6 frames"));
    }

    #[test]
    fn enough_frames_or_a_finding_is_conclusive() {
        assert!(Power::of(6, 1999, 0.025, false).conclusive);
        assert!(Power::of(24, 1999, 0.025, false).conclusive);
        assert!(Power::of(3, 1999, 0.025, true).conclusive);
        assert!(Power::of(24, 1999, 0.025, true).headline().is_none());
        // Too few sign patterns also bound p from below.
        let few = Power::of(24, 20, 0.025, false);
        assert!(!few.conclusive && few.min_achievable_p > 0.04);
    }
}
