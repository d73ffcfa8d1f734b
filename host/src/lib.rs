//! # depthor-host
//!
//! The std side of depthor: recordings (`depthor-recording/1`), file-backed sensors, importers of
//! the real RGB-D sets, the scene generator and dToF simulator, the float reference, evaluation,
//! the quantizer that makes the core's blob, the sim-to-real gap tool, and the `depthor` command
//! line (`src/cli`, the only place that reports errors with `anyhow`; every library module
//! returns its own typed error). Contracts: docs/recording.md, docs/graph.md, docs/blob.md,
//! docs/eval.md, docs/sim.md, docs/gap.md.
//!
//! ## Modules, from data to figures
//!
//! | module | what |
//! |---|---|
//! | [`recording`] | the `depthor-recording/1` format: reader, writer, shards and their merge |
//! | [`import`] | importers of the real RGB-D sets and sensor logs into recordings |
//! | [`sensors`] | a recording replayed through the core's HAL traits |
//! | [`scene`] | synthetic indoor scenes (RGB, depth, labels, reflectance, normals) |
//! | [`sim`] | the dToF simulator: ground-truth maps → the zones a sensor would report |
//! | [`dataset`] | scene generator + simulator → recording frames; resampling to a model's size |
//! | [`models`] | the shipped model folders and how `--model` finds them |
//! | [`inference`] | the core's int8 engine over an owned blob and arena |
//! | [`reference`](mod@reference) | the float network and the monocular prior through tract |
//! | [`baselines`] | nearest zone, bilinear zones, joint bilateral upsampling |
//! | [`evaluation`] | frames, methods and predictions of `depthor eval` and `demo`; the eval output format |
//! | [`quantize`] | graph.json + weights.bin → the int8 blob (fold, calibrate, write, check) |
//! | [`gap`] | the sim-to-real gap tool and its bench |
//! | [`plot`], [`viz`] | the pictures: panels, charts, colour maps, zone points |
//! | [`atomic`] | outputs written into a temporary sibling and renamed when complete |
//! | [`rng`] | the deterministic random stream of the scene generator and simulator |
pub mod atomic;
pub mod baselines;
pub mod dataset;
pub mod evaluation;
pub mod gap;
pub mod import;
pub mod inference;
mod json_field;
pub mod models;
pub mod plot;
pub mod quantize;
pub mod recording;
pub mod reference;
pub mod rng;
pub mod scene;
pub mod sensors;
pub mod sim;
pub mod viz;
