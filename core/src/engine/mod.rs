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
//!   | `mcu` | 120×160 | 384 127 B (goal 384 KiB) | 518 591 B (affinities only) | 1 922 703 B |
//!   | `mcu_lite` | 120×160 | 289 199 B | 289 199 B | 504 767 B |
//!   | `phone` | 320×240 | 1 672 239 B (goal 2 MiB) | 1 672 239 B | 7 431 615 B |
//!
//!   The `mcu` peaks are the last decoder stage (skips and a conv's scratch, 382 128 B) and the
//!   refinement (guidance 153 600 B, the ring, windows and heads' scratch 206 448 B, the bins
//!   map 19 200 B). Fusing kmix/tmix costs instructions (≈ 33 M per frame on a Cortex-M4):
//!   `Memory::Budget` trades them back where the arena allows.
//! - `size_of::<Engine>()` is 49 376 bytes on x86-64 and 33 056 on 32-bit Arm (fixed-capacity
//!   op, tensor and buffer tables, no heap; 19 152 with the `small-tables` feature): keep it in
//!   a `static` on a microcontroller, built there by [`Engine::init_in`], which fills the tables
//!   in place ([`crate::blob::parse::parse_into`], [`plan_with_into`]): the firmware's whole
//!   stack high-water is then ≈ 9.4 KiB. `Engine::new` returns the engine by value and uses
//!   ≈ 25 KiB more stack once, for the planner's tables.
//! - [`Io::Arena`]: the RGB frame and the sparse depth are written into staging areas of the
//!   arena ([`Engine::staging`]) placed beside the inputs at step 0, and the dense depth is read
//!   from it ([`Engine::output_m`], or in millimetres in place [`Engine::output_mm`]): the caller
//!   holds no frame buffer, and the shipped networks' arenas do not grow (an f32 output area
//!   after the activations where the refinement writes the output, `mcu` and `phone`).
//! - Run order: an op whose output is larger than its inputs and first read much later runs just
//!   before that reader where that lowers the arena ([`Plan::order`]; `mcu_lite`: an upsample
//!   of a decoder skip, − 57 600 B). A conv reads a concat in place also where some parts are
//!   int16 (requantised into its scratch first; `mcu_lite` − 14 416 B with the placement's second
//!   starting order), and a `mul` whose first operand nobody reads later writes over it
//!   ([`Plan::in_place_of`]; `mcu_lite` − 2 384 B).

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
