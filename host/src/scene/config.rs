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
