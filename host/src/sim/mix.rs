//! Measurement mixes: a simulator configuration drawn per frame, so that one recording spans
//! many measurement conditions (issue 39: training that follows the quality of the zones).
//!
//! A mix is JSON over a preset:
//!
//! ```json
//! {
//!   "note": "free text",
//!   "base": {"anomalies": {"enabled": false}},
//!   "conditions": [
//!     {"name": "preset", "weight": 2, "on_base": false, "config": {}},
//!     {"name": "noisy", "weight": 1,
//!      "config": {"range_noise": {"enabled": true, "sigma_per_m": {"uniform": [0.005, 0.035]}}}},
//!     {"name": "estimator", "weight": 1,
//!      "config": {"zone_estimator": {"estimator": {"choice": ["mean", "nearest"]}}}}
//!   ]
//! }
//! ```
//!
//! Frame `i` of a run seeded `seed` picks one condition with probability proportional to its
//! weight, from its own random stream (independent of the scene's and the simulator's streams,
//! so the scenes are those of the same seed without a mix). Its configuration is the preset,
//! then `base` (unless `on_base` is false), then the condition's `config`, partial
//! configurations merged field by field as `depthor sim --config` does. Inside `base` and
//! `config`, a value `{"uniform": [lo, hi]}` is drawn uniformly in `[lo, hi]` and a value
//! `{"choice": [a, b, …]}` is one of its elements, each drawn per frame. A mix may not change
//! the zone grid (`grid`): every frame of a recording shares the header's zone rectangles.

use serde::Deserialize;
use serde_json::Value;

use super::config::SimConfig;
use super::error::SimError;
use crate::rng::Rng;

/// Salt of the mix's random stream per frame (apart from the scene's and the simulator's).
const MIX_STREAM: u64 = 0x4D49_585F_4D45_4153;

/// One measurement condition of a mix, as written in the file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConditionFile {
    name: String,
    #[serde(default = "one")]
    weight: f64,
    #[serde(default = "yes")]
    on_base: bool,
    #[serde(default = "empty_object")]
    config: Value,
}

/// The mix file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MixFile {
    #[serde(default)]
    #[allow(dead_code)]
    note: Option<String>,
    #[serde(default = "empty_object")]
    base: Value,
    conditions: Vec<ConditionFile>,
}

fn one() -> f64 {
    1.0
}

fn yes() -> bool {
    true
}

fn empty_object() -> Value {
    Value::Object(Default::default())
}

/// One condition, ready to draw: its name, weight and the patch over the preset (the mix's
/// `base` merged in unless the condition is off base).
#[derive(Clone, Debug)]
struct Condition {
    name: String,
    weight: f64,
    patch: Value,
}

/// A parsed, validated measurement mix over a preset's configuration.
#[derive(Clone, Debug)]
pub struct MeasurementMix {
    preset: SimConfig,
    conditions: Vec<Condition>,
    total_weight: f64,
}

impl MeasurementMix {
    /// Parses a mix over `preset`. Every condition is drawn once at its ranges' low ends, once
    /// at their high ends and once at random and validated, so a bad value is refused here,
    /// not in the middle of a run. Errors name the condition and the field
    /// (`conditions[2] (noisy).config.range_noise.sigma_per_m: …`).
    pub fn from_json(preset: &SimConfig, text: &str) -> Result<MeasurementMix, SimError> {
        let file: MixFile = serde_json::from_str(text).map_err(|e| SimError::Json {
            field: "mix".into(),
            message: e.to_string(),
        })?;
        if file.conditions.is_empty() {
            return Err(invalid("conditions", "the mix names no condition"));
        }
        if !file.base.is_object() {
            return Err(invalid(
                "base",
                "expected a JSON object (a partial configuration)",
            ));
        }
        let mut conditions = Vec::with_capacity(file.conditions.len());
        for (k, c) in file.conditions.into_iter().enumerate() {
            let at = format!("conditions[{k}] ({})", c.name);
            if !(c.weight.is_finite() && c.weight > 0.0) {
                return Err(invalid(
                    &format!("{at}.weight"),
                    &format!("{} is out of range (allowed a finite number > 0)", c.weight),
                ));
            }
            if !c.config.is_object() {
                return Err(invalid(
                    &format!("{at}.config"),
                    "expected a JSON object (a partial configuration)",
                ));
            }
            let mut patch = if c.on_base {
                file.base.clone()
            } else {
                empty_object()
            };
            crate::json_field::merge(&mut patch, &c.config);
            conditions.push(Condition {
                name: c.name,
                weight: c.weight,
                patch,
            });
        }
        let total_weight = conditions.iter().map(|c| c.weight).sum();
        let mix = MeasurementMix {
            preset: preset.clone(),
            conditions,
            total_weight,
        };
        for (k, c) in mix.conditions.iter().enumerate() {
            let at = format!("conditions[{k}] ({})", c.name);
            for pick in [Pick::Low, Pick::High, Pick::Random] {
                let mut rng = Rng::new(k as u64);
                mix.config_of(c, pick, &mut rng)
                    .map_err(|e| prefix(e, &format!("{at}.config")))?;
            }
        }
        Ok(mix)
    }

    /// The condition names, in file order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.conditions.iter().map(|c| c.name.as_str())
    }

    /// The configuration of frame `index` of a run seeded `seed`, with the index of the
    /// condition it was drawn from. Same `(seed, index)` ⇒ same configuration.
    pub fn draw(&self, seed: u64, index: u64) -> Result<(usize, SimConfig), SimError> {
        let mut rng = Rng::derive(seed ^ MIX_STREAM, index);
        let mut u = rng.f64() * self.total_weight;
        let mut k = self.conditions.len() - 1;
        for (j, c) in self.conditions.iter().enumerate() {
            if u < c.weight {
                k = j;
                break;
            }
            u -= c.weight;
        }
        let cfg = self.config_of(&self.conditions[k], Pick::Random, &mut rng)?;
        Ok((k, cfg))
    }

    /// The preset with `c`'s patch, its ranges resolved by `pick`.
    fn config_of(&self, c: &Condition, pick: Pick, rng: &mut Rng) -> Result<SimConfig, SimError> {
        let patch = resolve(&c.patch, pick, rng, &mut Vec::new())?;
        let cfg = self.preset.with_overrides_value(&patch)?;
        if cfg.grid != self.preset.grid {
            return Err(invalid(
                "grid",
                "a mix may not change the zone grid (every frame shares the header's zones)",
            ));
        }
        Ok(cfg)
    }
}

/// Which value a range gives: its low end, its high end, or a random draw.
#[derive(Clone, Copy)]
enum Pick {
    Low,
    High,
    Random,
}

/// `v` with every `{"uniform": [lo, hi]}` and `{"choice": […]}` replaced by a value.
fn resolve(
    v: &Value,
    pick: Pick,
    rng: &mut Rng,
    path: &mut Vec<String>,
) -> Result<Value, SimError> {
    match v {
        Value::Object(m) if m.len() == 1 && m.contains_key("uniform") => {
            let here = path.join(".").replace(".[", "[");
            let bounds = m["uniform"]
                .as_array()
                .filter(|a| a.len() == 2)
                .and_then(|a| Some([a[0].as_f64()?, a[1].as_f64()?]))
                .ok_or_else(|| invalid(&here, "`uniform` takes [lo, hi], two numbers"))?;
            let [lo, hi] = bounds;
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(invalid(
                    &here,
                    &format!("uniform [{lo}, {hi}] is not a range (allowed finite lo ≤ hi)"),
                ));
            }
            let x = match pick {
                Pick::Low => lo,
                Pick::High => hi,
                Pick::Random => lo + (hi - lo) * rng.f64(),
            };
            Ok(serde_json::json!(x))
        }
        Value::Object(m) if m.len() == 1 && m.contains_key("choice") => {
            let here = path.join(".").replace(".[", "[");
            let options = m["choice"]
                .as_array()
                .filter(|a| !a.is_empty())
                .ok_or_else(|| invalid(&here, "`choice` takes a non-empty list of values"))?;
            let k = match pick {
                Pick::Low => 0,
                Pick::High => options.len() - 1,
                Pick::Random => rng.below(options.len() as u64) as usize,
            };
            resolve(&options[k], pick, rng, path)
        }
        Value::Object(m) => {
            let mut out = serde_json::Map::new();
            for (key, value) in m {
                path.push(key.clone());
                out.insert(key.clone(), resolve(value, pick, rng, path)?);
                path.pop();
            }
            Ok(Value::Object(out))
        }
        Value::Array(a) => {
            let mut out = Vec::with_capacity(a.len());
            for (i, value) in a.iter().enumerate() {
                path.push(format!("[{i}]"));
                out.push(resolve(value, pick, rng, path)?);
                path.pop();
            }
            Ok(Value::Array(out))
        }
        other => Ok(other.clone()),
    }
}

fn invalid(field: &str, reason: &str) -> SimError {
    SimError::InvalidConfig {
        field: field.into(),
        reason: reason.into(),
    }
}

/// `e` with its field path put under `at`.
fn prefix(e: SimError, at: &str) -> SimError {
    match e {
        SimError::InvalidConfig { field, reason } => SimError::InvalidConfig {
            field: join(at, &field),
            reason,
        },
        SimError::Json { field, message } => SimError::Json {
            field: join(at, &field),
            message,
        },
        other => other,
    }
}

fn join(at: &str, field: &str) -> String {
    if field.is_empty() || field == "(root)" {
        at.to_string()
    } else {
        format!("{at}.{}", field.replace(".[", "["))
    }
}
