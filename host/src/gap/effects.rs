//! The effect library the gap tool chooses from (docs/design.md "Sim-to-real gap tool"). Each effect is
//! a simulator aspect (its module in `crate::sim` holds the parameters and the forward model);
//! here it gets what fitting needs: the parameters to fit with their bounds, how to write them into
//! a [`SimConfig`], the covariate stratum where its signature shows, and what separates it from
//! look-alikes.

use crate::sim::SimConfig;

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

const fn p(field: &'static str, lo: f64, hi: f64) -> ParamSpec {
    ParamSpec {
        field,
        lo,
        hi,
        integer: false,
    }
}

/// Covariates along which the tool localises residuals (and the stratum of each effect).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Covariate {
    /// Simulated/reference range of the zone, metres.
    Range,
    /// In-zone depth spread (p90 − p10), metres: edges.
    Spread,
    /// Mean brightness (V / 255): reflectance proxy.
    Brightness,
    /// Fraction of transparent/specular pixels.
    Material,
    /// Normalised distance from the grid centre.
    Radius,
    /// Zone row.
    Row,
    /// Zone column.
    Col,
    /// Frame time.
    Time,
}

impl Covariate {
    /// Every covariate, in report order.
    pub const ALL: [Covariate; 8] = [
        Covariate::Range,
        Covariate::Spread,
        Covariate::Brightness,
        Covariate::Material,
        Covariate::Radius,
        Covariate::Row,
        Covariate::Col,
        Covariate::Time,
    ];

    /// Short name (file names, report).
    pub fn name(self) -> &'static str {
        match self {
            Covariate::Range => "range_m",
            Covariate::Spread => "depth_spread_m",
            Covariate::Brightness => "brightness",
            Covariate::Material => "transparent_specular_fraction",
            Covariate::Radius => "grid_radius",
            Covariate::Row => "zone_row",
            Covariate::Col => "zone_col",
            Covariate::Time => "time_s",
        }
    }
}

/// One effect of the library.
#[derive(Clone, Copy, Debug)]
pub struct Candidate {
    /// docs/design.md name (also the [`SimConfig`] field).
    pub name: &'static str,
    /// The physics in words.
    pub physics: &'static str,
    /// Fitted parameters.
    pub params: &'static [ParamSpec],
    /// Where its signature shows.
    pub stratum: Covariate,
}

/// The library, in docs/design.md order (11 of the 13 effects; `cover_glass` and `timing_offset` are
/// not implemented).
pub const LIBRARY: [Candidate; 11] = [
    Candidate {
        name: "range_dropout",
        physics: "detection probability falls with range (signal ∝ ρ/r²): p_loss = 1 − exp(−k·d²)",
        params: &[p("loss_per_m2", 0.0, 0.5)],
        stratum: Covariate::Range,
    },
    Candidate {
        name: "dark_dropout",
        physics: "low-reflectance surfaces return too few photons: p_loss = p_black·(1 − b/knee)₊",
        params: &[p("p_black", 0.0, 1.0)],
        stratum: Covariate::Brightness,
    },
    Candidate {
        name: "border_dropout",
        physics: "vignetting / illumination roll-off toward the grid's corners: p_loss = p_corner·r⁴",
        params: &[p("p_corner", 0.0, 1.0)],
        stratum: Covariate::Radius,
    },
    Candidate {
        name: "calibration_shift",
        physics: "zone grid misregistered against the camera: background zones report a neighbour's depth",
        params: &[
            ParamSpec {
                field: "max_shift_zones",
                lo: 1.0,
                hi: 2.0,
                integer: true,
            },
            p("frame_probability", 0.0, 1.0),
        ],
        stratum: Covariate::Spread,
    },
    Candidate {
        name: "radial_distance",
        physics: "the sensor reports range along the ray where the simulator assumes z: d·(1 + f·(√(1+tx²+ty²) − 1))",
        params: &[p("fraction", -1.0, 2.0)],
        stratum: Covariate::Radius,
    },
    Candidate {
        name: "range_bias",
        physics: "offset and scale error of the reported distance: d' = offset + (1 + scale)·d",
        params: &[p("offset_m", -0.3, 0.3), p("scale", -0.2, 0.2)],
        stratum: Covariate::Range,
    },
    Candidate {
        name: "range_noise",
        physics: "noise growing with range: Gaussian with σ = sigma_per_m·d",
        params: &[p("sigma_per_m", 0.0, 0.2)],
        stratum: Covariate::Range,
    },
    Candidate {
        name: "multipath",
        physics: "transparent/specular surfaces return farther depth: d·(1 + extra·min(1, 4·f_material))",
        params: &[p("extra", 0.0, 1.0)],
        stratum: Covariate::Material,
    },
    Candidate {
        name: "edge_mixing",
        physics: "zones straddling depth edges report a mix of the returns: d + w·(mean − d)",
        params: &[p("weight", 0.0, 1.0)],
        stratum: Covariate::Spread,
    },
    Candidate {
        name: "zone_crosstalk",
        physics: "returns blur into neighbouring zones: (1 − c)·d + c·mean(neighbours)",
        params: &[p("coupling", 0.0, 1.0)],
        stratum: Covariate::Spread,
    },
    Candidate {
        name: "bin_wiggle",
        physics: "periodic range error from histogram binning: d + A·sin(2πd/0.3 m)",
        params: &[p("amplitude_m", 0.0, 0.1)],
        stratum: Covariate::Range,
    },
];

/// Pairs of effects that a calibration can hide from one-at-a-time search: the data show only
/// their joint pattern, which neither explains alone, so selection also fits each pair jointly
/// (first, second, why).
pub const JOINT_PAIRS: [(&str, &str, &str); 1] = [(
    "radial_distance",
    "range_bias",
    "a range-scale calibration absorbs the mean radial lengthening, leaving only its zero-mean pattern across the grid",
)];

/// The library entry named `name`.
pub fn candidate(name: &str) -> Option<&'static Candidate> {
    LIBRARY.iter().find(|c| c.name == name)
}

/// Whether effect `name` is switched on in `cfg`.
pub fn enabled(cfg: &SimConfig, name: &str) -> bool {
    match name {
        "range_dropout" => cfg.range_dropout.enabled,
        "dark_dropout" => cfg.dark_dropout.enabled,
        "border_dropout" => cfg.border_dropout.enabled,
        "calibration_shift" => cfg.calibration_shift.enabled,
        "radial_distance" => cfg.radial_distance.enabled,
        "range_bias" => cfg.range_bias.enabled,
        "range_noise" => cfg.range_noise.enabled,
        "multipath" => cfg.multipath.enabled,
        "edge_mixing" => cfg.edge_mixing.enabled,
        "zone_crosstalk" => cfg.zone_crosstalk.enabled,
        "bin_wiggle" => cfg.bin_wiggle.enabled,
        _ => false,
    }
}

/// Switches effect `name` on in `cfg` with parameter values `v` (in [`Candidate::params`] order),
/// or off when `v` is `None`.
pub fn set(cfg: &mut SimConfig, name: &str, v: Option<&[f64]>) {
    let on = v.is_some();
    let v = v.unwrap_or(&[]);
    let x = |i: usize| v.get(i).copied().unwrap_or(0.0) as f32;
    match name {
        "range_dropout" => {
            cfg.range_dropout.enabled = on;
            cfg.range_dropout.loss_per_m2 = x(0);
        }
        "dark_dropout" => {
            cfg.dark_dropout.enabled = on;
            cfg.dark_dropout.p_black = x(0);
        }
        "border_dropout" => {
            cfg.border_dropout.enabled = on;
            cfg.border_dropout.p_corner = x(0);
        }
        "calibration_shift" => {
            cfg.calibration_shift.enabled = on;
            let m = x(0).round().clamp(0.0, 64.0) as u8;
            cfg.calibration_shift.max_shift_zones = [m, m];
            cfg.calibration_shift.frame_probability = x(1);
        }
        "radial_distance" => {
            cfg.radial_distance.enabled = on;
            cfg.radial_distance.fraction = x(0);
        }
        "range_bias" => {
            cfg.range_bias.enabled = on;
            cfg.range_bias.offset_m = x(0);
            cfg.range_bias.scale = x(1);
        }
        "range_noise" => {
            cfg.range_noise.enabled = on;
            cfg.range_noise.sigma_per_m = x(0);
        }
        "multipath" => {
            cfg.multipath.enabled = on;
            cfg.multipath.extra = x(0);
        }
        "edge_mixing" => {
            cfg.edge_mixing.enabled = on;
            cfg.edge_mixing.weight = x(0);
        }
        "zone_crosstalk" => {
            cfg.zone_crosstalk.enabled = on;
            cfg.zone_crosstalk.coupling = x(0);
        }
        "bin_wiggle" => {
            cfg.bin_wiggle.enabled = on;
            cfg.bin_wiggle.amplitude_m = x(0);
        }
        _ => {}
    }
}

/// The parameter values of effect `name` in `cfg` (in [`Candidate::params`] order).
pub fn get(cfg: &SimConfig, name: &str) -> Vec<f64> {
    let v: Vec<f32> = match name {
        "range_dropout" => vec![cfg.range_dropout.loss_per_m2],
        "dark_dropout" => vec![cfg.dark_dropout.p_black],
        "border_dropout" => vec![cfg.border_dropout.p_corner],
        "calibration_shift" => vec![
            f32::from(cfg.calibration_shift.max_shift_zones[0]),
            cfg.calibration_shift.frame_probability,
        ],
        "radial_distance" => vec![cfg.radial_distance.fraction],
        "range_bias" => vec![cfg.range_bias.offset_m, cfg.range_bias.scale],
        "range_noise" => vec![cfg.range_noise.sigma_per_m],
        "multipath" => vec![cfg.multipath.extra],
        "edge_mixing" => vec![cfg.edge_mixing.weight],
        "zone_crosstalk" => vec![cfg.zone_crosstalk.coupling],
        "bin_wiggle" => vec![cfg.bin_wiggle.amplitude_m],
        _ => vec![],
    };
    v.into_iter().map(f64::from).collect()
}

/// What data would tell effects `a` and `b` apart when both explain the same residual.
pub fn separating_data(a: &str, b: &str) -> String {
    let hint = |n: &str| {
        match n {
        "range_dropout" => "bright surfaces far away (range without darkness)",
        "dark_dropout" => "dark surfaces close by (darkness without range)",
        "border_dropout" => "near, bright targets filling the corner zones",
        "calibration_shift" => "frames with a near object in front of a far background at several positions",
        "radial_distance" => "a flat wall facing the sensor at several distances (radial error ∝ d, grows toward corners)",
        "range_bias" => "a flat wall at several distances (offset vs scale) seen centred",
        "range_noise" => "repeated frames of a static scene at several ranges",
        "multipath" => "glass/mirrors in front of known-depth backgrounds",
        "edge_mixing" => "depth edges with large and small depth steps at zone-centred positions",
        "zone_crosstalk" => "an isolated near object on a far background (crosstalk reaches neighbours, mixing stays in the zone)",
        "bin_wiggle" => "a wall swept finely in range (periodic pattern)",
        _ => "more varied scenes",
    }
    };
    format!("{} (for {a}) vs {} (for {b})", hint(a), hint(b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::preset;

    #[test]
    fn set_and_get_round_trip_for_every_effect() {
        let mut cfg = preset("l5").unwrap();
        for c in LIBRARY {
            let v: Vec<f64> = c
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
            set(&mut cfg, c.name, Some(&v));
            assert!(enabled(&cfg, c.name), "{}", c.name);
            let back = get(&cfg, c.name);
            for (a, b) in v.iter().zip(&back) {
                assert!((a - b).abs() < 1e-6, "{}: {v:?} vs {back:?}", c.name);
            }
            cfg.validate().unwrap();
            set(&mut cfg, c.name, None);
            assert!(!enabled(&cfg, c.name));
        }
    }
}
