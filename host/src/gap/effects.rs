//! The effect library the gap tool chooses from (docs/design.md "Sim-to-real gap tool"). Each
//! effect is one module under [`crate::sim::effects`] holding its parameters, forward model and
//! fit description ([`EffectFit`]: bounds, stratum, separating-data hint, start unit); the tool
//! iterates over [`ALL`] and looks names up with [`by_name`], which fails on a name the library
//! does not have. What is the tool's own, not one effect's, lives here: the pairs it also fits
//! jointly and the hint that contrasts two look-alikes.

pub use crate::sim::effects::{
    by_name, names, Covariate, EffectFit, ParamSpec, UnknownEffect, ALL,
};

/// Pairs of effects that a calibration can hide from one-at-a-time search: the data show only
/// their joint pattern, which neither explains alone, so selection also fits each pair jointly
/// (first, second, why).
pub const JOINT_PAIRS: [(&str, &str, &str); 1] = [(
    "radial_distance",
    "range_bias",
    "a range-scale calibration absorbs the mean radial lengthening, leaving only its zero-mean pattern across the grid",
)];

/// The library effect `name`, for names the tool took from [`ALL`] itself (selection state,
/// [`JOINT_PAIRS`], the benchmark's case lists): a name outside the library there is a bug, and
/// this panics naming it.
pub fn library(name: &str) -> &'static EffectFit {
    by_name(name).unwrap_or_else(|e| panic!("{e}"))
}

/// What data would tell effects `a` and `b` apart when both explain the same residual.
pub fn separating_data(a: &EffectFit, b: &EffectFit) -> String {
    format!(
        "{} (for {}) vs {} (for {})",
        a.separating_data, a.name, b.separating_data, b.name
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joint_pairs_name_library_effects() {
        for (a, b, _) in JOINT_PAIRS {
            by_name(a).unwrap();
            by_name(b).unwrap();
        }
    }

    #[test]
    fn separating_data_names_both() {
        let s = separating_data(library("range_dropout"), library("dark_dropout"));
        assert_eq!(
            s,
            "bright surfaces far away (range without darkness) (for range_dropout) vs \
             dark surfaces close by (darkness without range) (for dark_dropout)"
        );
    }

    #[test]
    #[should_panic(expected = "unknown effect \"timing_offset\"")]
    fn library_panics_naming_an_unknown_effect() {
        library("timing_offset");
    }
}
