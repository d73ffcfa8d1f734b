//! The sim-to-real effects of the gap tool's library (docs/design.md "Sim-to-real gap tool"), one
//! module each. A module holds the effect's parameters (its [`SimConfig`] field), its forward
//! model (a `ZoneEffect`, run by [`crate::sim::simulate`]) and its fit description, the
//! `FIT` constant ([`EffectFit`]): the parameters the gap tool fits with their bounds, the
//! covariate stratum where its signature shows, the data that separate it from look-alikes and
//! the starting size of the detection-limit calibration.
//!
//! [`ALL`] lists them in a fixed order (the gap tool's candidate order); [`by_name`] looks one up
//! and fails, naming it, on a name the library does not have. `SimConfig`'s by-name access
//! ([`SimConfig::set_effect`], [`SimConfig::effect_params`], [`SimConfig::effect_enabled`]) goes
//! through it.
//!
//! Adding an effect: a module here with its parameter struct (implementing `ZoneEffect` and
//! `EffectParams`) and its `FIT`, a field and a pipeline slot in [`SimConfig`], and an entry
//! in [`ALL`].

/// Implements `EffectParams` for an effect whose fitted parameters are `f32` fields of its
/// parameter struct (`$field`s in `FIT.params` order) beside its `enabled` switch.
macro_rules! f32_params {
    ($t:ty: $($field:ident),+) => {
        impl super::EffectParams for $t {
            fn switch(&mut self) -> &mut bool {
                &mut self.enabled
            }
            fn values(&self) -> Vec<f32> {
                vec![$(self.$field),+]
            }
            fn set_values(&mut self, v: &[f64]) {
                let mut i = 0..;
                $(self.$field = super::value(v, i.next().unwrap_or_default());)+
            }
        }
    };
}

pub mod bin_wiggle;
pub mod border_dropout;
pub mod calibration_shift;
pub mod dark_dropout;
pub mod edge_mixing;
pub mod multipath;
pub mod radial_distance;
pub mod range_bias;
pub mod range_dropout;
pub mod range_noise;
pub mod zone_crosstalk;

pub use bin_wiggle::BinWiggle;
pub use border_dropout::BorderDropout;
pub use calibration_shift::CalibrationShift;
pub use dark_dropout::DarkDropout;
pub use edge_mixing::EdgeMixing;
pub use multipath::Multipath;
pub use radial_distance::RadialDistance;
pub use range_bias::RangeBias;
pub use range_dropout::RangeDropout;
pub use range_noise::RangeNoise;
pub use zone_crosstalk::ZoneCrosstalk;

use std::fmt;

pub use super::covariates::Covariate;
use super::frame::ZoneEffect;
use super::SimConfig;

/// One fitted parameter: a numeric field of the effect's configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// Field name in the effect's JSON object.
    pub field: &'static str,
    /// Lower bound of the search.
    pub lo: f64,
    /// Upper bound of the search.
    pub hi: f64,
    /// Only integers are tried (zone shifts).
    pub integer: bool,
}

/// A continuous parameter searched in `[lo, hi]`.
const fn param(field: &'static str, lo: f64, hi: f64) -> ParamSpec {
    ParamSpec {
        field,
        lo,
        hi,
        integer: false,
    }
}

/// An effect's parameters as the fit sees them: its switch and a vector of numbers in
/// [`EffectFit::params`] order.
pub(crate) trait EffectParams: ZoneEffect {
    /// The switch.
    fn switch(&mut self) -> &mut bool;
    /// The fitted parameters, in [`EffectFit::params`] order.
    fn values(&self) -> Vec<f32>;
    /// Writes the fitted parameters (missing entries read as 0, see [`value`]).
    fn set_values(&mut self, v: &[f64]);
}

/// Entry `i` of `v` as the f32 of a configuration field, 0 when `v` is shorter.
fn value(v: &[f64], i: usize) -> f32 {
    v.get(i).copied().unwrap_or(0.0) as f32
}

/// What fitting one effect needs, next to its forward model (each module's `FIT`).
#[derive(Clone, Copy)]
pub struct EffectFit {
    /// docs/design.md name (also the [`SimConfig`] field and the random stream's name).
    pub name: &'static str,
    /// The physics in words.
    pub physics: &'static str,
    /// Fitted parameters.
    pub params: &'static [ParamSpec],
    /// Where its signature shows.
    pub stratum: Covariate,
    /// What data would tell it apart from an effect that explains the same residual.
    pub separating_data: &'static str,
    /// Hand estimate of the minimum detectable size with ~20 held-out 8×8 frames (in
    /// [`EffectFit::params`] order): where the detection-limit calibration starts.
    pub start_unit: &'static [f64],
    /// Its parameters in a configuration.
    pub(crate) config: fn(&SimConfig) -> &dyn EffectParams,
    /// Its parameters in a configuration, to write.
    pub(crate) config_mut: fn(&mut SimConfig) -> &mut dyn EffectParams,
}

impl fmt::Debug for EffectFit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("EffectFit")
            .field("name", &self.name)
            .field("params", &self.params)
            .field("stratum", &self.stratum)
            .field("start_unit", &self.start_unit)
            .finish_non_exhaustive()
    }
}

impl EffectFit {
    /// Whether the effect is switched on in `cfg`.
    pub fn enabled(&self, cfg: &SimConfig) -> bool {
        (self.config)(cfg).enabled()
    }

    /// Switches the effect on in `cfg` with parameter values `v` (in [`EffectFit::params`]
    /// order; missing entries read as 0), or off, its fitted parameters zeroed, when `v` is
    /// `None`.
    pub fn set(&self, cfg: &mut SimConfig, v: Option<&[f64]>) {
        let p = (self.config_mut)(cfg);
        *p.switch() = v.is_some();
        p.set_values(v.unwrap_or(&[]));
    }

    /// The effect's parameter values in `cfg` (in [`EffectFit::params`] order).
    pub fn get(&self, cfg: &SimConfig) -> Vec<f64> {
        (self.config)(cfg)
            .values()
            .into_iter()
            .map(f64::from)
            .collect()
    }
}

/// The library in docs/design.md order (11 of the 13 effects; `cover_glass` and `timing_offset`
/// are not implemented). The order is the gap tool's candidate order.
pub const ALL: &[EffectFit] = &[
    range_dropout::FIT,
    dark_dropout::FIT,
    border_dropout::FIT,
    calibration_shift::FIT,
    radial_distance::FIT,
    range_bias::FIT,
    range_noise::FIT,
    multipath::FIT,
    edge_mixing::FIT,
    zone_crosstalk::FIT,
    bin_wiggle::FIT,
];

/// A name that is not an effect of [`ALL`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown effect \"{name}\" (the library has {})", names().join(", "))]
pub struct UnknownEffect {
    /// The name asked for.
    pub name: String,
}

/// The names of [`ALL`], in order.
pub fn names() -> Vec<&'static str> {
    ALL.iter().map(|e| e.name).collect()
}

/// The effect named `name`.
pub fn by_name(name: &str) -> Result<&'static EffectFit, UnknownEffect> {
    ALL.iter()
        .find(|e| e.name == name)
        .ok_or_else(|| UnknownEffect { name: name.into() })
}

impl SimConfig {
    /// Whether library effect `name` is switched on.
    pub fn effect_enabled(&self, name: &str) -> Result<bool, UnknownEffect> {
        Ok(by_name(name)?.enabled(self))
    }

    /// Switches library effect `name` on with parameter values `v` (its
    /// [`EffectFit::params`] order) or off when `v` is `None` ([`EffectFit::set`]).
    pub fn set_effect(&mut self, name: &str, v: Option<&[f64]>) -> Result<(), UnknownEffect> {
        by_name(name)?.set(self, v);
        Ok(())
    }

    /// The parameter values of library effect `name` (its [`EffectFit::params`] order).
    pub fn effect_params(&self, name: &str) -> Result<Vec<f64>, UnknownEffect> {
        Ok(by_name(name)?.get(self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::preset;

    #[test]
    fn unknown_effect_is_an_error_naming_it() {
        let e = by_name("cover_glass").unwrap_err();
        assert_eq!(e.name, "cover_glass");
        let msg = e.to_string();
        assert!(msg.contains("\"cover_glass\""), "{msg}");
        for n in names() {
            assert!(msg.contains(n), "{msg} lacks {n}");
        }
        let mut cfg = preset("l5").unwrap();
        let before = cfg.clone();
        assert_eq!(
            cfg.set_effect("rangebias", Some(&[0.1])).unwrap_err().name,
            "rangebias"
        );
        assert_eq!(cfg, before);
        assert!(cfg.effect_params("").is_err());
        assert!(cfg.effect_enabled("Range_Bias").is_err());
    }

    #[test]
    fn every_effect_round_trips_through_by_name_and_the_config() {
        assert_eq!(ALL.len(), 11);
        let mut cfg = preset("l5").unwrap();
        for (k, e) in ALL.iter().enumerate() {
            // `ALL` is a constant: compare what `by_name` returns by content, not by address
            // (each use of a constant may be its own copy in an unoptimised build).
            let found = by_name(e.name).unwrap();
            assert_eq!(found.name, ALL[k].name);
            assert_eq!(found.params, ALL[k].params, "{}", e.name);
            assert_eq!(ALL.iter().filter(|o| o.name == e.name).count(), 1);
            // The name is the effect's SimConfig field, its stream name and its JSON key.
            assert_eq!((e.config)(&cfg).name(), e.name);
            assert!(cfg.to_json().contains(&format!("\"{}\"", e.name)));
            assert_eq!(e.start_unit.len(), e.params.len(), "{}", e.name);
            assert!(!e.separating_data.is_empty() && !e.physics.is_empty());
            for s in e.params {
                assert!(s.lo < s.hi, "{}.{}", e.name, s.field);
            }
            let v: Vec<f64> = e
                .params
                .iter()
                .map(|s| {
                    if s.integer {
                        s.hi
                    } else {
                        (s.lo + s.hi) / 2.0 + 0.01
                    }
                })
                .collect();
            cfg.set_effect(e.name, Some(&v)).unwrap();
            assert!(cfg.effect_enabled(e.name).unwrap(), "{}", e.name);
            let back = cfg.effect_params(e.name).unwrap();
            assert_eq!(back.len(), v.len(), "{}", e.name);
            for (a, b) in v.iter().zip(&back) {
                assert!((a - b).abs() < 1e-6, "{}: {v:?} vs {back:?}", e.name);
            }
            cfg.validate().unwrap();
            // The JSON a fitted configuration is written as reads back with the same values.
            let again = SimConfig::from_json(&cfg.to_json()).unwrap();
            assert_eq!(again.effect_params(e.name).unwrap(), back);
            cfg.set_effect(e.name, None).unwrap();
            assert!(!cfg.effect_enabled(e.name).unwrap());
            assert!(!e.enabled(&cfg));
        }
    }
}
