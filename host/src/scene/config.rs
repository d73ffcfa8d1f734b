//! Ranges the scene generator draws from. Every field has a default (`#[serde(default)]`), so a
//! JSON file only needs the fields it changes. Ranges are `[lo, hi]`, inclusive for counts.
use serde::{Deserialize, Serialize};

/// Parameters of the random indoor scenes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SceneConfig {
    /// Room width (x), metres.
    pub room_width_m: [f32; 2],
    /// Room depth (z, away from the camera), metres: 2.5–12 m so regions beyond 6 m occur.
    pub room_depth_m: [f32; 2],
    /// Ceiling height, metres.
    pub room_height_m: [f32; 2],
    /// Probability that the space is a corridor instead of a room.
    pub corridor_prob: f32,
    /// Corridor width, metres (its depth is drawn from `room_depth_m`, at least 6 m).
    pub corridor_width_m: [f32; 2],
    /// Number of furniture items (tables, chairs, cabinets, sofas, boxes, round things).
    pub objects: [u32; 2],
    /// Number of thin structures (pipes, floor lamps).
    pub thin_structures: [u32; 2],
    /// Number of boards leaning against walls (slanted planes).
    pub slanted_planes: [u32; 2],
    /// Number of pictures and screens on walls.
    pub wall_items: [u32; 2],
    /// Probability that a scene contains glass (window pane, partition, glass table or door).
    pub glass_prob: f32,
    /// Probability that a scene contains a mirror.
    pub mirror_prob: f32,
    /// Probability that a scene contains dark, absorbing objects.
    pub dark_prob: f32,
    /// Probability that the room has doorways or windows opening to a distant exterior.
    pub opening_prob: f32,
    /// Probability that a surface uses a photo texture rather than a procedural one.
    pub photo_texture_prob: f32,
    /// Number of lamps.
    pub lights: [u32; 2],
    /// Probability of soft shadows (spherical lamps) instead of hard ones.
    pub soft_shadow_prob: f32,
    /// Shadow rays per lamp when shadows are soft.
    pub soft_shadow_samples: u32,
    /// Camera height above the floor, metres.
    pub camera_height_m: [f32; 2],
    /// Camera pitch, degrees (positive looks up).
    pub camera_pitch_deg: [f32; 2],
    /// Camera roll, degrees.
    pub camera_roll_deg: [f32; 2],
    /// Camera yaw relative to the room's long axis, degrees.
    pub camera_yaw_deg: [f32; 2],
    /// Horizontal field of view, degrees, for [`super::camera_for`].
    pub hfov_deg: [f32; 2],
}

impl Default for SceneConfig {
    fn default() -> Self {
        SceneConfig {
            room_width_m: [2.5, 8.0],
            room_depth_m: [2.5, 12.0],
            room_height_m: [2.4, 3.4],
            corridor_prob: 0.2,
            corridor_width_m: [1.4, 2.6],
            objects: [3, 10],
            thin_structures: [0, 3],
            slanted_planes: [0, 1],
            wall_items: [0, 3],
            glass_prob: 0.6,
            mirror_prob: 0.4,
            dark_prob: 0.6,
            opening_prob: 0.5,
            photo_texture_prob: 0.6,
            lights: [1, 3],
            soft_shadow_prob: 0.5,
            soft_shadow_samples: 4,
            camera_height_m: [0.6, 1.8],
            camera_pitch_deg: [-25.0, 10.0],
            camera_roll_deg: [-6.0, 6.0],
            camera_yaw_deg: [-40.0, 40.0],
            hfov_deg: [58.0, 66.0],
        }
    }
}

/// Why a scene configuration file was rejected; displays as one line `field: what is wrong
/// (allowed …)` (the command line puts the file in front).
#[derive(Debug, thiserror::Error)]
pub enum SceneConfigError {
    /// Not JSON, not an object, or a field of the wrong type; `field` is the field's name where
    /// one is to blame, else `JSON syntax` or `JSON`.
    #[error("{field}: {message}")]
    Json {
        /// The field (`objects`, `hfov_deg[1]`), or `JSON syntax` / `JSON`.
        field: String,
        /// serde's message, one line.
        message: String,
    },
    /// A field the generator does not have.
    #[error("{0}: unknown field (allowed: the fields of SceneConfig, e.g. room_depth_m)")]
    UnknownField(String),
    /// A field whose value the generator cannot draw from.
    #[error("{field}: {why}")]
    Invalid {
        /// The field's name.
        field: String,
        /// What is wrong with it, with the allowed range.
        why: String,
    },
}

impl SceneConfigError {
    fn json(field: &str, e: serde_json::Error) -> Self {
        SceneConfigError::Json {
            field: field.into(),
            message: e.to_string(),
        }
    }
}

impl SceneConfig {
    /// `base` with the fields of the JSON object `text` replaced (a file only names what it
    /// changes), then validated: every range `lo ≤ hi` within the bounds the generator is
    /// built for, counts at most 64 with at least one lamp, probabilities in [0, 1].
    pub fn with_overrides(&self, text: &str) -> Result<SceneConfig, SceneConfigError> {
        let doc: serde_json::Value =
            serde_json::from_str(text).map_err(|e| SceneConfigError::json("JSON syntax", e))?;
        let serde_json::Value::Object(patch) = &doc else {
            return Err(SceneConfigError::Json {
                field: "(root)".into(),
                message: "expected a JSON object of fields to replace".into(),
            });
        };
        let base = serde_json::to_value(self).map_err(|e| SceneConfigError::json("JSON", e))?;
        let mut merged = match &base {
            serde_json::Value::Object(m) => m.clone(),
            _ => unreachable!("SceneConfig serialises to an object"),
        };
        for (k, v) in patch {
            if !merged.contains_key(k) {
                return Err(SceneConfigError::UnknownField(k.clone()));
            }
            merged.insert(k.clone(), v.clone());
        }
        let cfg: SceneConfig =
            serde_json::from_value(serde_json::Value::Object(merged)).map_err(|e| {
                let field = crate::json_field::locate::<SceneConfig>(&base, &doc, &e.to_string())
                    .unwrap_or_else(|| "JSON".into());
                SceneConfigError::json(&field, e)
            })?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks that every range can be drawn from (see [`SceneConfig::with_overrides`]).
    pub fn validate(&self) -> Result<(), SceneConfigError> {
        let invalid = |field: &str, why: String| SceneConfigError::Invalid {
            field: field.into(),
            why,
        };
        // (field, range, smallest and largest value the generator is built for, unit); NaN fails
        let ranges = [
            ("room_width_m", self.room_width_m, 1.0, 100.0, " m"),
            ("room_depth_m", self.room_depth_m, 1.0, 100.0, " m"),
            ("room_height_m", self.room_height_m, 1.5, 30.0, " m"),
            ("corridor_width_m", self.corridor_width_m, 0.8, 100.0, " m"),
            ("camera_height_m", self.camera_height_m, 0.1, 30.0, " m"),
            ("hfov_deg", self.hfov_deg, 10.0, 150.0, "°"),
            ("camera_pitch_deg", self.camera_pitch_deg, -89.0, 89.0, "°"),
            ("camera_roll_deg", self.camera_roll_deg, -89.0, 89.0, "°"),
            ("camera_yaw_deg", self.camera_yaw_deg, -89.0, 89.0, "°"),
        ];
        for (field, [lo, hi], min, max, unit) in ranges {
            if !(lo >= min && lo <= hi && hi <= max) {
                return Err(invalid(
                    field,
                    format!(
                        "[{lo}, {hi}] is not an ordered range (allowed {min} ≤ lo ≤ hi ≤ {max}{unit})"
                    ),
                ));
            }
        }
        let counts = [
            ("objects", self.objects),
            ("thin_structures", self.thin_structures),
            ("slanted_planes", self.slanted_planes),
            ("wall_items", self.wall_items),
            ("lights", self.lights),
        ];
        for (field, [lo, hi]) in counts {
            if lo > hi || hi > 64 {
                return Err(invalid(
                    field,
                    format!("[{lo}, {hi}] is not an ordered range (allowed 0 ≤ lo ≤ hi ≤ 64)"),
                ));
            }
        }
        if self.lights[0] == 0 {
            return Err(invalid(
                "lights[0]",
                "0 is out of range (allowed 1 to 64 lamps)".into(),
            ));
        }
        if self.soft_shadow_samples == 0 || self.soft_shadow_samples > 64 {
            return Err(invalid(
                "soft_shadow_samples",
                format!(
                    "{} is out of range (allowed 1 to 64)",
                    self.soft_shadow_samples
                ),
            ));
        }
        let probabilities = [
            ("corridor_prob", self.corridor_prob),
            ("glass_prob", self.glass_prob),
            ("mirror_prob", self.mirror_prob),
            ("dark_prob", self.dark_prob),
            ("opening_prob", self.opening_prob),
            ("photo_texture_prob", self.photo_texture_prob),
            ("soft_shadow_prob", self.soft_shadow_prob),
        ];
        for (field, p) in probabilities {
            if !(0.0..=1.0).contains(&p) {
                return Err(invalid(
                    field,
                    format!("{p} is out of range (allowed 0 to 1)"),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_replace_named_fields_and_keep_the_rest() {
        let base = SceneConfig {
            hfov_deg: [48.0, 54.0],
            ..SceneConfig::default()
        };
        let cfg = base
            .with_overrides(r#"{"room_depth_m": [1.5, 4.0], "objects": [6, 12]}"#)
            .unwrap();
        assert_eq!(cfg.room_depth_m, [1.5, 4.0]);
        assert_eq!(cfg.objects, [6, 12]);
        assert_eq!(cfg.hfov_deg, [48.0, 54.0]);
        assert_eq!(cfg.glass_prob, base.glass_prob);
        SceneConfig::default().validate().unwrap();
    }

    #[test]
    fn bad_files_name_the_field() {
        let base = SceneConfig::default();
        let err = |t: &str| base.with_overrides(t).unwrap_err().to_string();
        assert!(err(r#"{"room_depht_m": [1, 2]}"#).contains("room_depht_m"));
        assert!(err(r#"{"room_depth_m": [4, 2]}"#).contains("room_depth_m"));
        assert!(err(r#"{"glass_prob": 1.5}"#).contains("glass_prob"));
        assert!(err(r#"{"objects": [3, 1]}"#).contains("objects"));
        assert!(err(r#"{"lights": [0, 0]}"#).contains("lights"));
        assert!(err(r#"{"camera_pitch_deg": [-95, 0]}"#).contains("camera_pitch_deg"));
        assert!(err(r#"{"objects": "many"}"#).starts_with("objects: "));
        assert!(err(r#"{"hfov_deg": [50, "wide"]}"#).starts_with("hfov_deg[1]: "));
        assert!(err(r#"{"soft_shadow_samples": -1}"#).starts_with("soft_shadow_samples: "));
        assert!(err(r#"{"glass_prob": 1.5}"#).contains("(allowed 0 to 1)"));
        assert!(err("[1, 2]").starts_with("(root): "));
        assert!(err("{").starts_with("JSON syntax: "));
    }
}
