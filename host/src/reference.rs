//! The host's float reference: an exported DEPTHOR NNEF model run through tract (docs/design.md,
//! layout: "float reference through tract-nnef").
//!
//! [`FloatReference::load`] reads a `.nnef.tgz`, `.tar` or NNEF directory, fixes its inputs to
//! one `H × W` (binding any symbolic dimension), optimises it once and keeps the runnable plan;
//! [`FloatReference::run`] then runs one frame. The tensor convention is docs/graph.md's:
//!
//! | tensor | shape | content |
//! |---|---|---|
//! | input `rgb` | `[1, 3, H, W]` f32 | RGB byte / 255, no mean/std normalisation |
//! | input `sparse` | `[1, 1, H, W]` f32 | projected dToF depth in metres, 0 = no point |
//! | output `depth` | `[1, 1, H, W]` f32 | depth in metres |
//!
//! Inputs are matched by name (`rgb`, `sparse`), else by position; the output is the one named
//! `depth`, else the only one. tract's `tract_core` NNEF extensions, which torch-to-nnef output
//! uses, are enabled by `tract_nnef::nnef()` by default in tract 0.23.
//!
//! [`frame`] turns a camera frame (RGB of any size, zones, calibration) into model inputs;
//! [`FloatReference::run_frame`] chains the two.

pub mod frame;
pub mod prior;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use depthor_core::calibration::Calibration;
use depthor_core::hal::ZoneView;
use depthor_core::projection::ProjectionError;
use tract_core::internal::{
    format_err, tvec, DatumType, Framework, IntoTValue, Symbol, TDim, Tensor, TypedModel,
    TypedSimplePlan, TypedSimpleState,
};
use tract_core::tract_linalg::multithread::{multithread_tract_scope, Executor};

/// A boxed error from tract (its context chain is kept as the source).
pub type TractError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// What can go wrong loading or running the float reference.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReferenceError {
    /// The file is missing or tract could not read, type or optimise the model in it.
    #[error("cannot load NNEF model {}: {stage}", path.display())]
    Load {
        /// The model path given to [`FloatReference::load`].
        path: PathBuf,
        /// What was being done (`reading`, `binding the input size`, `optimising`…).
        stage: &'static str,
        /// tract's error.
        #[source]
        source: TractError,
    },
    /// The model loaded but does not follow the docs/graph.md contract (inputs, outputs, shapes).
    #[error("NNEF model {}: {what}", path.display())]
    Contract {
        /// The model path.
        path: PathBuf,
        /// What does not match.
        what: String,
    },
    /// A caller's buffer or image has the wrong size.
    #[error("{name}: expected {expected} values, got {got}")]
    InputSize {
        /// Which input (`rgb`, `sparse`, `camera image`…).
        name: &'static str,
        /// Values the model (or calibration) needs.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// Zones could not be projected (bad calibration or zone shape).
    #[error("projecting the zones: {0}")]
    Projection(ProjectionError),
    /// A calibration value cannot be rescaled to the model size.
    #[error("calibration: {0}")]
    Calibration(&'static str),
    /// tract failed while running the plan.
    #[error("running NNEF model {}", path.display())]
    Run {
        /// The model path.
        path: PathBuf,
        /// tract's error.
        #[source]
        source: TractError,
    },
}

/// An NNEF DEPTHOR model, optimised for one input size and ready to run.
#[derive(Debug)]
pub struct FloatReference {
    path: PathBuf,
    height: u32,
    width: u32,
    plan: std::sync::Arc<TypedSimplePlan>,
    /// Position of `rgb` among the model's inputs (`sparse` is the other one).
    rgb_input: usize,
}

/// Positions of the `wanted` inputs among the model's: by name when every one is found, else in
/// the given order. `None` when the model has another number of inputs.
fn input_positions(model: &TypedModel, wanted: &[(&str, usize)]) -> Option<Vec<usize>> {
    let outlets = model.input_outlets().ok()?;
    if outlets.len() != wanted.len() {
        return None;
    }
    let names: Vec<&str> = outlets
        .iter()
        .map(|o| model.node(o.node).name.as_str())
        .collect();
    let by_name: Option<Vec<usize>> = wanted
        .iter()
        .map(|(w, _)| names.iter().position(|n| n == w))
        .collect();
    Some(by_name.unwrap_or_else(|| (0..wanted.len()).collect()))
}

/// Checks `dims` of the model at `path` against `expected`, collecting bindings for plain
/// symbolic dimensions; a mismatch is a [`ReferenceError::Contract`].
fn bind_dims(
    path: &Path,
    name: &str,
    dims: &[TDim],
    expected: [usize; 4],
    subs: &mut HashMap<Symbol, TDim>,
) -> Result<(), ReferenceError> {
    let contract = |what: String| ReferenceError::Contract {
        path: path.to_path_buf(),
        what,
    };
    let shape_text = || {
        let d: Vec<String> = dims.iter().map(|d| d.to_string()).collect();
        format!("[{}]", d.join(", "))
    };
    if dims.len() != 4 {
        return Err(contract(format!(
            "input {name} has shape {}, expected {expected:?}",
            shape_text()
        )));
    }
    for (dim, &want) in dims.iter().zip(expected.iter()) {
        match dim {
            TDim::Val(v) if *v == want as i64 => {}
            TDim::Sym(s) => match subs.get(s) {
                Some(TDim::Val(bound)) if *bound != want as i64 => {
                    return Err(contract(format!(
                        "input {name} has shape {}: symbol {s} cannot be both {bound} and {want}",
                        shape_text()
                    )))
                }
                _ => {
                    subs.insert(s.clone(), TDim::Val(want as i64));
                }
            },
            _ => {
                return Err(contract(format!(
                    "input {name} has shape {}, expected {expected:?}",
                    shape_text()
                )))
            }
        }
    }
    Ok(())
}

impl FloatReference {
    /// Loads the NNEF model at `path` (`.nnef.tgz`, `.tar` or a directory holding `graph.nnef`),
    /// fixes its inputs to `height × width`, checks it against docs/graph.md (inputs `rgb`
    /// `[1,3,H,W]` and `sparse` `[1,1,H,W]`, f32; output `[1,1,H,W]` f32) and optimises it.
    ///
    /// Every error names the file.
    pub fn load(path: &Path, height: u32, width: u32) -> Result<Self, ReferenceError> {
        let (plan, positions) =
            prepare(path, height, width, &[("rgb", 3), ("sparse", 1)], "depth")?;
        Ok(FloatReference {
            path: path.to_path_buf(),
            height,
            width,
            plan,
            rgb_input: positions[0],
        })
    }

    /// The model's input size `(height, width)`.
    pub fn input_shape(&self) -> (u32, u32) {
        (self.height, self.width)
    }

    /// The file the model was loaded from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn pixels(&self) -> usize {
        self.height as usize * self.width as usize
    }

    /// Runs one frame: `rgb` is `H × W × 3` RGB888 (row-major, interleaved), `sparse_m` is
    /// `H × W` metres (0 = no point). Returns `H × W` depth in metres, row-major.
    pub fn run(&self, rgb: &[u8], sparse_m: &[f32]) -> Result<Vec<f32>, ReferenceError> {
        let planar = rgb_to_planar(rgb, self.pixels())?;
        self.run_planar(&planar, sparse_m)
    }

    /// Runs one frame from the model's own tensors: `rgb_chw` is `[3, H, W]` planar f32 in
    /// [0, 1] (as the golden files store it), `sparse_m` is `H × W` metres.
    pub fn run_planar(
        &self,
        rgb_chw: &[f32],
        sparse_m: &[f32],
    ) -> Result<Vec<f32>, ReferenceError> {
        let mut state = self.spawn()?;
        self.run_state(&mut state, rgb_chw, sparse_m)
    }

    fn spawn(&self) -> Result<TypedSimpleState, ReferenceError> {
        self.plan.spawn().map_err(|e| self.run_err(e))
    }

    fn run_err(&self, e: tract_core::internal::TractError) -> ReferenceError {
        ReferenceError::Run {
            path: self.path.clone(),
            source: e.into(),
        }
    }

    fn run_state(
        &self,
        state: &mut TypedSimpleState,
        rgb_chw: &[f32],
        sparse_m: &[f32],
    ) -> Result<Vec<f32>, ReferenceError> {
        let n = self.pixels();
        check_len("rgb", 3 * n, rgb_chw.len())?;
        check_len("sparse", n, sparse_m.len())?;
        let (h, w) = (self.height as usize, self.width as usize);
        let rgb = Tensor::from_shape(&[1, 3, h, w], rgb_chw).map_err(|e| self.run_err(e))?;
        let sparse = Tensor::from_shape(&[1, 1, h, w], sparse_m).map_err(|e| self.run_err(e))?;
        let inputs = if self.rgb_input == 0 {
            tvec!(rgb.into_tvalue(), sparse.into_tvalue())
        } else {
            tvec!(sparse.into_tvalue(), rgb.into_tvalue())
        };
        let outputs = state.run(inputs).map_err(|e| self.run_err(e))?;
        let depth = outputs
            .first()
            .ok_or_else(|| self.run_err(format_err!("no output")))?;
        let view = depth
            .to_plain_array_view::<f32>()
            .map_err(|e| self.run_err(e))?;
        let out: Vec<f32> = view.iter().copied().collect();
        check_len("depth output", n, out.len())?;
        Ok(out)
    }

    /// Runs a camera frame: resizes `rgb` to the model size if needed (bilinear, see
    /// [`frame::prepare`]) with the intrinsics scaled to match, projects `zones` with
    /// [`depthor_core::projection::project_to_sparse`], and runs. `rgb` must have the
    /// calibration's camera size.
    pub fn run_frame(
        &self,
        calib: &Calibration,
        rgb: &image::RgbImage,
        zones: &ZoneView,
    ) -> Result<Vec<f32>, ReferenceError> {
        let prepared = frame::prepare(calib, rgb, zones, self.height, self.width)?;
        self.run(prepared.rgb.as_raw(), &prepared.sparse_m)
    }

    /// Median wall time of one frame over `runs` runs (after one warm-up run) on one thread,
    /// on a fixed synthetic frame (smooth RGB, 64 sparse points). `runs == 0` is taken as 1.
    /// This is what `depthor bench engine` reports for tract.
    pub fn time_per_frame(&self, runs: usize) -> Result<Duration, ReferenceError> {
        let (rgb, sparse) = synthetic_frame(self.height as usize, self.width as usize);
        let mut state = self.spawn()?;
        multithread_tract_scope(Executor::SingleThread, || {
            self.run_state(&mut state, &rgb, &sparse)?;
            let mut times = Vec::with_capacity(runs.max(1));
            for _ in 0..runs.max(1) {
                let start = Instant::now();
                self.run_state(&mut state, &rgb, &sparse)?;
                times.push(start.elapsed());
            }
            times.sort_unstable();
            Ok(times[times.len() / 2])
        })
    }
}

/// Reads, checks and optimises an NNEF model whose `inputs` (name, channels) are `[1, C, H, W]`
/// f32 and whose output `output` (by name, else the only one) is `[1, 1, H, W]` f32; returns the
/// plan and the position of each wanted input among the model's.
fn prepare(
    path: &Path,
    height: u32,
    width: u32,
    inputs: &[(&'static str, usize)],
    output_name: &str,
) -> Result<(std::sync::Arc<TypedSimplePlan>, Vec<usize>), ReferenceError> {
    let load_err = |stage: &'static str| {
        move |e: tract_core::internal::TractError| ReferenceError::Load {
            path: path.to_path_buf(),
            stage,
            source: e.into(),
        }
    };
    let contract = |what: String| ReferenceError::Contract {
        path: path.to_path_buf(),
        what,
    };
    if height == 0 || width == 0 {
        return Err(contract(format!(
            "requested size {height}×{width} is empty"
        )));
    }
    if !path.exists() {
        return Err(ReferenceError::Load {
            path: path.to_path_buf(),
            stage: "opening",
            source: "no such file or directory".into(),
        });
    }
    let mut model = tract_nnef::nnef()
        .model_for_path(path)
        .map_err(load_err("reading"))?;

    let positions = input_positions(&model, inputs).ok_or_else(|| {
        let names: Vec<&str> = inputs.iter().map(|i| i.0).collect();
        contract(format!(
            "expected {} input(s) ({}), found {}",
            inputs.len(),
            names.join(", "),
            model.inputs.len()
        ))
    })?;
    let (h, w) = (height as usize, width as usize);
    let mut subs = HashMap::new();
    for (&(name, channels), &input) in inputs.iter().zip(&positions) {
        let fact = model
            .input_fact(input)
            .map_err(load_err("reading inputs"))?;
        if fact.datum_type != DatumType::F32 {
            return Err(contract(format!(
                "input {name} is {:?}, expected f32",
                fact.datum_type
            )));
        }
        bind_dims(
            path,
            name,
            fact.shape.dims(),
            [1, channels, h, w],
            &mut subs,
        )?;
    }

    let outputs = model
        .output_outlets()
        .map_err(load_err("reading outputs"))?;
    let output = match outputs.len() {
        1 => 0,
        _ => outputs
            .iter()
            .position(|o| {
                model.outlet_label(*o) == Some(output_name)
                    || model.node(o.node).name == output_name
            })
            .ok_or_else(|| {
                contract(format!(
                    "expected one output ({output_name}), found {} and none named {output_name}",
                    outputs.len()
                ))
            })?,
    };
    if model.outputs.len() > 1 {
        let keep = model.outputs[output];
        model.outputs = vec![keep];
    }

    if !subs.is_empty() {
        model = model
            .set_symbols(&subs)
            .map_err(load_err("binding the input size"))?;
    }
    let model = model.into_optimized().map_err(load_err("optimising"))?;

    let out_fact = model.output_fact(0).map_err(load_err("reading outputs"))?;
    let out_shape = out_fact.shape.as_concrete();
    if out_fact.datum_type != DatumType::F32 || out_shape != Some(&[1, 1, h, w][..]) {
        return Err(contract(format!(
            "output is {:?} {:?}, expected f32 [1, 1, {h}, {w}]",
            out_fact.datum_type, out_fact.shape
        )));
    }
    let plan = TypedSimplePlan::new(model).map_err(load_err("planning"))?;
    Ok((plan, positions))
}

fn check_len(name: &'static str, expected: usize, got: usize) -> Result<(), ReferenceError> {
    if expected == got {
        Ok(())
    } else {
        Err(ReferenceError::InputSize {
            name,
            expected,
            got,
        })
    }
}

/// Interleaved RGB888 (`pixels × 3`) → planar `[3, pixels]` f32, byte / 255.
pub fn rgb_to_planar(rgb: &[u8], pixels: usize) -> Result<Vec<f32>, ReferenceError> {
    check_len("rgb", 3 * pixels, rgb.len())?;
    let mut planar = vec![0.0f32; 3 * pixels];
    for (i, px) in rgb.chunks_exact(3).enumerate() {
        for (c, &byte) in px.iter().enumerate() {
            planar[c * pixels + i] = f32::from(byte) / 255.0;
        }
    }
    Ok(planar)
}

/// A deterministic frame for timing: smooth colour ramps and 64 points between 0.5 and 4.5 m.
fn synthetic_frame(h: usize, w: usize) -> (Vec<f32>, Vec<f32>) {
    let n = h * w;
    let mut rgb = vec![0.0f32; 3 * n];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            rgb[i] = x as f32 / w as f32;
            rgb[n + i] = y as f32 / h as f32;
            rgb[2 * n + i] = ((x + y) % 32) as f32 / 31.0;
        }
    }
    let mut sparse = vec![0.0f32; n];
    for k in 0..64 {
        let (y, x) = ((k / 8) * h / 8 + h / 16, (k % 8) * w / 8 + w / 16);
        if let Some(s) = sparse.get_mut(y * w + x) {
            *s = 0.5 + 4.0 * k as f32 / 63.0;
        }
    }
    (rgb, sparse)
}
