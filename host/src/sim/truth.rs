//! What the simulator did to each zone, for tests and the sim-to-real gap tool.

use core::fmt;

/// A set of per-zone events (bit flags). Classification flags (`TRANSPARENT`, `SPECULAR`, `DARK`,
/// `BACKGROUND`) say what the zone *is*; the others say what *happened* to its measurement.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct ZoneEvents(u32);

macro_rules! events {
    ($($(#[$doc:meta])* $name:ident = $bit:expr;)*) => {
        impl ZoneEvents {
            $($(#[$doc])* pub const $name: ZoneEvents = ZoneEvents(1 << $bit);)*
            const NAMES: &'static [(ZoneEvents, &'static str)] = &[$((ZoneEvents::$name, stringify!($name))),*];
        }
    };
}

events! {
    /// The zone's nominal centre lies outside the image: it has no depth and reports no target.
    OUT_OF_IMAGE = 0;
    /// No known ground-truth depth under the zone's sampling window: no target.
    NO_DEPTH = 1;
    /// Enough of the window is transparent (label 1) to count as a transparent zone.
    TRANSPARENT = 2;
    /// The transparent zone lost its signal.
    TRANSPARENT_LOSS = 3;
    /// The transparent zone returned the surface behind it.
    TRANSPARENT_BEHIND = 4;
    /// Enough of the window is specular (label 2) to count as a specular zone.
    SPECULAR = 5;
    /// The specular zone lost its signal.
    SPECULAR_LOSS = 6;
    /// The specular zone returned a farther (mirrored-path) distance.
    SPECULAR_FARTHER = 7;
    /// Enough of the window is dark (low HSV V or label 3) to count as a dark zone.
    DARK = 8;
    /// The dark zone lost its signal.
    DARK_LOSS = 9;
    /// The return was lost to range (between the practical range and the limit, or beyond it).
    RANGE_LOSS = 10;
    /// The return was lost at random (low-power sensors, `signal_loss`).
    SIGNAL_LOSS = 11;
    /// The zone's ground-truth peak is deeper than the frame's calibration threshold.
    BACKGROUND = 12;
    /// The background zone took the measurement of the zone at `shift` from it.
    SHIFTED = 13;
    /// The zone became a noise zone (uniform distance in the detection range).
    NOISE = 14;
    /// The zone was blanked at random.
    BLANK = 15;
    /// The return was lost to a `learned` dropout term.
    LEARNED_LOSS = 16;
}

impl ZoneEvents {
    /// No events.
    pub const NONE: ZoneEvents = ZoneEvents(0);

    /// True when every flag of `other` is set in `self`.
    pub fn contains(self, other: ZoneEvents) -> bool {
        self.0 & other.0 == other.0
    }

    /// True when at least one flag of `other` is set in `self`.
    pub fn intersects(self, other: ZoneEvents) -> bool {
        self.0 & other.0 != 0
    }

    /// Sets the flags of `other`.
    pub fn insert(&mut self, other: ZoneEvents) {
        self.0 |= other.0;
    }

    /// The raw bits.
    pub fn bits(self) -> u32 {
        self.0
    }
}

impl core::ops::BitOr for ZoneEvents {
    type Output = ZoneEvents;
    fn bitor(self, rhs: ZoneEvents) -> ZoneEvents {
        ZoneEvents(self.0 | rhs.0)
    }
}

impl fmt::Debug for ZoneEvents {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut set = f.debug_set();
        for (e, name) in ZoneEvents::NAMES {
            if self.contains(*e) {
                set.entry(&format_args!("{name}"));
            }
        }
        set.finish()
    }
}

/// Per-zone record of what the simulator did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ZoneTruth {
    /// Centre `[y, x]` (pixels) of the zone's sampling window after the frame's random
    /// translation and rotation (the nominal centre when `overall_distribution` is off).
    pub center_px: [f32; 2],
    /// Ground-truth value of the zone before any degradation: the depth-histogram peak over the
    /// window (the centre pixel with `overall_distribution` off), metres; 0 = no depth.
    pub peak_m: f32,
    /// What the zone is and what happened to it.
    pub events: ZoneEvents,
    /// `[dr, dc]` zone shift applied by `calibration_shift` (background zones only), else `[0, 0]`.
    pub shift: [i8; 2],
}
