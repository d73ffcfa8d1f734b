//! Prepare once, run many: [`Engine::new`] validates the blob, plans the arena
//! ([`plan::plan`]) and caches requantisation constants; [`Engine::run`] only computes.
//!
//! ## Memory
//! - The caller's arena: [`Plan::arena_bytes`] / [`required_arena_bytes`], for the default
//!   [`Memory::Streamed`] plan (the least memory): a refinement's affinity heads run row by row
//!   inside it into a ring of `(T − 1)·r + 1` rows ([`crate::kernels::refine::ConvRows`]), its
//!   kmix/tmix heads into rings of `T·3 + 1` rows ([`crate::kernels::refine::MixConvRows`],
//!   recomputed per branch), `D_0`'s upsample row by row
//!   ([`crate::kernels::refine::UpsampledDepth`]); the refinement is a row wavefront (windows
//!   of 8 rows per iteration) that accumulates straight into the caller's f32 output; a concat
//!   read only by one conv is read in place by it; a conv packs at most 16 K weight elements
//!   at a time; convs compute their per-channel constants per run in their scratch. The
//!   planner places buffers greedily and searches the order ([`plan::place`]) and picks, among
//!   the [`Fusion`] levels, the smallest plan ([`Memory::Streamed`]) or the least fused that
//!   fits a budget ([`Memory::Budget`]). The bits are those of [`Memory::Whole`], which keeps
//!   every op's output for `Engine::run_observed`. Shipped blobs at their native sizes
//!   (`cargo test -p depthor-core --test arena_budget -- --nocapture`):
//!
//!   | variant | H×W | `Memory::Streamed` | `Memory::Budget(1.5 ×)` | `Memory::Whole` |
//!   |---|---|---|---|---|
//!   | `mcu` | 120×160 | 384 191 B (goal 384 KiB) | 518 591 B (affinities only) | 1 922 703 B |
//!   | `phone` | 320×240 | 1 672 271 B (goal 2 MiB) | 1 672 271 B | 7 431 615 B |
//!
//!   The `mcu` peaks are the last decoder stage (skips and a conv's scratch, 382 128 B) and the
//!   refinement (guidance 153 600 B, the ring, windows and heads' scratch 206 448 B, the bins
//!   map 19 200 B). Fusing kmix/tmix costs instructions (≈ 33 M per frame on a Cortex-M4):
//!   `Memory::Budget` trades them back where the arena allows.
//! - `size_of::<Engine>()` is 48 736 bytes on x86-64 (fixed-capacity op, tensor and buffer
//!   tables, no heap; less on 32-bit targets): keep it in a `static` on a microcontroller.
//!   `Engine::new` also uses ≈ 25 KiB of stack once, for the planner's temporary tables.

pub(crate) mod cast;
#[allow(clippy::module_inception)]
mod engine;
pub mod error;
pub mod plan;

pub use engine::{
    required_arena_bytes, required_arena_bytes_io, required_arena_bytes_with, Engine, Observed,
    Observer, RunStats, Staging,
};
pub use error::Error;
pub use plan::{
    plan, plan_with, plan_with_into, BufferReq, FusedRefine, Fusion, Io, Memory, Plan, PlanError,
    RefineScratch,
};
