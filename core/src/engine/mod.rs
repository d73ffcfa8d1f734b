//! Prepare once, run many: [`Engine::new`] validates the blob, plans the arena
//! ([`plan::plan`]) and caches requantisation constants; [`Engine::run`] only computes.
//!
//! ## Memory
//! - The caller's arena: [`Plan::arena_bytes`] / [`required_arena_bytes`], for the default
//!   [`Memory::Streamed`] plan: a refinement's three affinity heads run row by row inside it
//!   into a ring of `(T − 1)·r + 1` rows ([`crate::kernels::refine::ConvRows`]), the
//!   refinement itself is a row wavefront (windows of 14 rows per iteration, not two whole
//!   maps), a concat read only by one conv is read in place by that conv, and convs compute
//!   their per-channel constants per run in their scratch (the persistent region keeps only
//!   the element-wise ops' few constants). No affinity map
//!   and no such concat is ever stored whole; the bits are those of [`Memory::Whole`], which
//!   keeps every op's output for `Engine::run_observed`. Shipped blobs at their native sizes
//!   (`cargo test -p depthor-core --test arena_budget -- --nocapture`):
//!
//!   | variant | H×W | `Memory::Streamed` | `Memory::Whole` |
//!   |---|---|---|---|
//!   | `mcu` | 120×160 | 654 863 B | 1 922 687 B |
//!   | `phone` | 320×240 | 1 826 479 B | 7 431 599 B |
//!
//!   The `mcu` peak is now the refinement step (the 8-channel full-resolution guidance the
//!   heads read, d0 and the output in f32, the mixing maps and the 7×7 ring); the 384 KiB
//!   goal needs the half-resolution refinement of `mcu_lite`.
//! - `size_of::<Engine>()` is 48 736 bytes on x86-64 (fixed-capacity op, tensor and buffer
//!   tables, no heap; less on 32-bit targets): keep it in a `static` on a microcontroller.
//!   `Engine::new` also uses ≈ 25 KiB of stack once, for the planner's temporary tables.

mod cast;
#[allow(clippy::module_inception)]
mod engine;
pub mod error;
pub mod plan;

pub use engine::{
    required_arena_bytes, required_arena_bytes_with, Engine, Observed, Observer, RunStats,
};
pub use error::Error;
pub use plan::{
    plan, plan_with, BufferReq, FusedRefine, Fusion, Memory, Plan, PlanError, RefineScratch,
};
