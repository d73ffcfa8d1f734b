//! Prepare once, run many: [`Engine::new`] validates the blob, plans the arena
//! ([`plan::plan`]) and caches requantisation constants; [`Engine::run`] only computes.
//!
//! ## Memory
//! - The caller's arena: [`Plan::arena_bytes`] / [`required_arena_bytes`]. For the 47-op test
//!   network of `core/tests/common` (every op, 8–12 channel features, full-resolution
//!   refinement heads) at 120×160 it is 1 965 151 bytes, of which the three int8 affinity maps
//!   take 80 × 19 200 = 1 536 000 bytes while they are alive together, since `refine` consumes
//!   all of them (`cargo test -p depthor-core --test engine arena_at_mcu -- --nocapture`).
//!   Refine's own scratch is `8·H·W` bytes (two f32 depth maps). Getting under the 384 KiB
//!   goal needs the affinity heads fused into `refine` per row band (not done yet).
//! - `size_of::<Engine>()` is 48 736 bytes on x86-64 (fixed-capacity op, tensor and buffer
//!   tables, no heap; less on 32-bit targets): keep it in a `static` on a microcontroller.
//!   `Engine::new` also uses ≈ 25 KiB of stack once, for the planner's temporary tables.

mod cast;
#[allow(clippy::module_inception)]
mod engine;
pub mod error;
pub mod plan;

pub use engine::{required_arena_bytes, DepthIn, DepthOut, Engine, Observed, Observer, RunStats};
pub use error::Error;
pub use plan::{plan, BufferReq, Plan, PlanError};
