//! Prepare once, run many: [`Engine::new`] validates the blob, plans the arena
//! ([`plan::plan`]) and caches requantisation constants; [`Engine::run`] only computes.

mod cast;
#[allow(clippy::module_inception)]
mod engine;
pub mod error;
pub mod plan;

pub use engine::{required_arena_bytes, Engine, RunStats};
pub use error::Error;
pub use plan::{plan, BufferReq, Plan, PlanError};
