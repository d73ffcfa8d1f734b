//! The float reference on hand-written NNEF models (a 1×1 convolution plus the sparse input,
//! results worked out by hand) and, when it has been exported, on the `mcu` model against its
//! golden tensors.

use std::io::Write;
use std::path::{Path, PathBuf};

use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};
use depthor_core::hal::ZoneView;
use depthor_host::reference::{FloatReference, ReferenceError};

/// An NNEF `.dat` tensor of f32: the 128-byte header (magic 4E EF, version 1.0, data bytes,
/// rank, 8 dims, bits per item, item type 0 = IEEE float) then the little-endian data.
fn dat(shape: &[u32], data: &[f32]) -> Vec<u8> {
    let mut h = vec![0x4e, 0xef, 1, 0];
    h.extend_from_slice(&((data.len() * 4) as u32).to_le_bytes());
    h.extend_from_slice(&(shape.len() as u32).to_le_bytes());
    for i in 0..8 {
        h.extend_from_slice(&shape.get(i).copied().unwrap_or(0).to_le_bytes());
    }
    h.extend_from_slice(&32u32.to_le_bytes());
    h.extend_from_slice(&0u32.to_le_bytes()); // item type 0, vendor 0
    h.resize(128, 0);
    for v in data {
        h.extend_from_slice(&v.to_le_bytes());
    }
    h
}

/// Weights of the test model: depth = 0.5·r + 1·g + 2·b + 0.25 + sparse.
const WEIGHT: [f32; 3] = [0.5, 1.0, 2.0];
const BIAS: f32 = 0.25;

/// The test graph; `inputs` is the graph's parameter list, `h`/`w` the dims written in it.
fn graph(inputs: &str, extensions: &str, h: &str, w: &str) -> String {
    format!(
        "version 1.0;\n{extensions}\n\
         graph net({inputs}) -> (depth)\n{{\n\
         rgb = external<scalar>(shape = [1, 3, {h}, {w}]);\n\
         sparse = external<scalar>(shape = [1, 1, {h}, {w}]);\n\
         weight = variable<scalar>(shape = [1, 3, 1, 1], label = 'weight');\n\
         bias = variable<scalar>(shape = [1, 1], label = 'bias');\n\
         mix = conv(rgb, weight, bias);\n\
         depth = add(mix, sparse);\n}}\n"
    )
}

fn files(graph_text: String) -> Vec<(&'static str, Vec<u8>)> {
    vec![
        ("graph.nnef", graph_text.into_bytes()),
        ("weight.dat", dat(&[1, 3, 1, 1], &WEIGHT)),
        ("bias.dat", dat(&[1, 1], &[BIAS])),
    ]
}

fn write_dir(dir: &Path, files: &[(&str, Vec<u8>)]) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for (name, bytes) in files {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    dir.to_path_buf()
}

fn tar_bytes(files: &[(&str, Vec<u8>)]) -> Vec<u8> {
    let mut builder = tar::Builder::new(Vec::new());
    for (name, bytes) in files {
        let mut header = tar::Header::new_gnu();
        header.set_size(bytes.len() as u64);
        header.set_mode(0o644);
        header.set_cksum();
        builder.append_data(&mut header, name, &bytes[..]).unwrap();
    }
    builder.into_inner().unwrap()
}

fn fixed_model_files() -> Vec<(&'static str, Vec<u8>)> {
    files(graph("rgb, sparse", "", "2", "3"))
}

/// A 2×3 frame: RGB bytes and sparse metres, with the depth worked out by hand.
fn frame_2x3() -> (Vec<u8>, Vec<f32>, Vec<f32>) {
    #[rustfmt::skip]
    let rgb = vec![
        255, 0, 51,   0, 255, 0,   0, 0, 255,
        0, 0, 0,      51, 102, 153, 255, 255, 255,
    ];
    let sparse = vec![0.0, 1.5, 0.0, 0.0, 0.0, 2.0];
    // 0.5·r + g + 2·b + 0.25 (+ sparse), channels = byte / 255:
    // (1, 0, 0.2): 0.5 + 0.4 + 0.25 = 1.15      (0, 1, 0): 1 + 0.25 + 1.5 = 2.75
    // (0, 0, 1): 2 + 0.25 = 2.25                (0, 0, 0): 0.25
    // (0.2, 0.4, 0.6): 0.1 + 0.4 + 1.2 + 0.25 = 1.95   (1, 1, 1): 3.5 + 0.25 + 2 = 5.75
    let expected = vec![1.15, 2.75, 2.25, 0.25, 1.95, 5.75];
    (rgb, sparse, expected)
}

fn assert_close(got: &[f32], want: &[f32]) {
    assert_eq!(got.len(), want.len());
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() < 1e-5, "pixel {i}: got {g}, want {w}");
    }
}

#[test]
fn directory_model_matches_hand_computation() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = write_dir(&tmp.path().join("m"), &fixed_model_files());
    let model = FloatReference::load(&dir, 2, 3).unwrap();
    assert_eq!(model.input_shape(), (2, 3));
    let (rgb, sparse, expected) = frame_2x3();
    assert_close(&model.run(&rgb, &sparse).unwrap(), &expected);
}

#[test]
fn tar_and_tgz_models_load_too() {
    let tmp = tempfile::tempdir().unwrap();
    let tar = tar_bytes(&fixed_model_files());
    let tar_path = tmp.path().join("m.tar");
    std::fs::write(&tar_path, &tar).unwrap();
    let tgz_path = tmp.path().join("m.nnef.tgz");
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&tar).unwrap();
    std::fs::write(&tgz_path, gz.finish().unwrap()).unwrap();
    let (rgb, sparse, expected) = frame_2x3();
    for path in [tar_path, tgz_path] {
        let model = FloatReference::load(&path, 2, 3).unwrap();
        assert_close(&model.run(&rgb, &sparse).unwrap(), &expected);
    }
}

#[test]
fn inputs_are_matched_by_name_not_position() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = write_dir(
        &tmp.path().join("m"),
        &files(graph("sparse, rgb", "", "2", "3")),
    );
    let model = FloatReference::load(&dir, 2, 3).unwrap();
    let (rgb, sparse, expected) = frame_2x3();
    assert_close(&model.run(&rgb, &sparse).unwrap(), &expected);
}

#[test]
fn symbolic_size_is_bound_at_load() {
    let tmp = tempfile::tempdir().unwrap();
    let ext = "extension tract_symbol H;\nextension tract_symbol W;";
    let dir = write_dir(
        &tmp.path().join("m"),
        &files(graph("rgb, sparse", ext, "H", "W")),
    );
    let (rgb, sparse, expected) = frame_2x3();
    let small = FloatReference::load(&dir, 2, 3).unwrap();
    assert_close(&small.run(&rgb, &sparse).unwrap(), &expected);

    // 4×5, all pixels (0, 1, 0) (1.25 m) with one 3 m point at (3, 4).
    let big = FloatReference::load(&dir, 4, 5).unwrap();
    assert_eq!(big.input_shape(), (4, 5));
    let rgb: Vec<u8> = [0u8, 255, 0].repeat(20);
    let mut sparse = vec![0.0; 20];
    sparse[19] = 3.0;
    let mut expected = vec![1.25; 20];
    expected[19] = 4.25;
    assert_close(&big.run(&rgb, &sparse).unwrap(), &expected);
}

#[test]
fn errors_name_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("absent.nnef.tgz");
    let err = FloatReference::load(&missing, 2, 3).unwrap_err();
    assert!(err.to_string().contains("absent.nnef.tgz"), "{err}");

    let garbage = tmp.path().join("garbage.nnef.tgz");
    std::fs::write(&garbage, b"not a model at all").unwrap();
    let err = FloatReference::load(&garbage, 2, 3).unwrap_err();
    assert!(matches!(err, ReferenceError::Load { .. }), "{err:?}");
    assert!(err.to_string().contains("garbage.nnef.tgz"), "{err}");

    // A fixed 2×3 model cannot be run at 4×5.
    let dir = write_dir(&tmp.path().join("fixed"), &fixed_model_files());
    let err = FloatReference::load(&dir, 4, 5).unwrap_err();
    assert!(matches!(err, ReferenceError::Contract { .. }), "{err:?}");
    let text = err.to_string();
    assert!(text.contains("fixed") && text.contains("rgb"), "{text}");
}

#[test]
fn wrong_buffer_sizes_are_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = write_dir(&tmp.path().join("m"), &fixed_model_files());
    let model = FloatReference::load(&dir, 2, 3).unwrap();
    let (rgb, sparse, _) = frame_2x3();
    let err = model.run(&rgb[..17], &sparse).unwrap_err();
    assert!(
        matches!(
            err,
            ReferenceError::InputSize {
                expected: 18,
                got: 17,
                ..
            }
        ),
        "{err:?}"
    );
    let err = model.run(&rgb, &sparse[..5]).unwrap_err();
    assert!(
        matches!(
            err,
            ReferenceError::InputSize {
                expected: 6,
                got: 5,
                ..
            }
        ),
        "{err:?}"
    );
}

/// A 6×4 (W×H) camera with two registered zone rectangles, run by a 3×2 model.
#[test]
fn run_frame_resizes_scales_and_projects() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = write_dir(&tmp.path().join("m"), &fixed_model_files());
    let model = FloatReference::load(&dir, 2, 3).unwrap();
    // Zone centres (u, v) = (1, 1) and (4, 2) in camera pixels; halving maps a coordinate to
    // (c + ½)/2 − ½: (0.25, 0.25) → pixel (0, 0) and (1.75, 0.75) → pixel row 1, column 2.
    let rects = [[1.0, 1.0, 1.0, 1.0], [2.0, 4.0, 2.0, 4.0]];
    let calib = Calibration {
        camera: CameraIntrinsics {
            width: 6,
            height: 4,
            fx: 5.0,
            fy: 5.0,
            cx: 2.5,
            cy: 1.5,
        },
        dtof: DtofGeometry {
            rows: 1,
            cols: 2,
            fov_deg: [45.0, 45.0],
            distance: DistanceKind::Z,
            max_range_m: 4.0,
        },
        dtof_to_camera: Extrinsics::IDENTITY,
        zone_rects_px: Some(&rects),
    };
    let zones = ZoneView {
        rows: 1,
        cols: 2,
        distance_mm: &[1500.0, 2000.0],
        status: &[5, 5],
    };
    // Uniform (51, 102, 255) = (0.2, 0.4, 1): 0.1 + 0.4 + 2 + 0.25 = 2.75 m without a point.
    let rgb = image::RgbImage::from_pixel(6, 4, image::Rgb([51, 102, 255]));
    let depth = model.run_frame(&calib, &rgb, &zones).unwrap();
    assert_close(&depth, &[4.25, 2.75, 2.75, 2.75, 2.75, 4.75]);

    // The image must have the calibration's size.
    let wrong = image::RgbImage::new(6, 3);
    let err = model.run_frame(&calib, &wrong, &zones).unwrap_err();
    assert!(matches!(err, ReferenceError::InputSize { .. }), "{err:?}");
}

#[test]
fn timing_helper_measures_something() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = write_dir(&tmp.path().join("m"), &fixed_model_files());
    let model = FloatReference::load(&dir, 2, 3).unwrap();
    let t = model.time_per_frame(5).unwrap();
    assert!(
        t > std::time::Duration::ZERO && t < std::time::Duration::from_secs(1),
        "{t:?}"
    );
}

// ---- the exported mcu model against its golden tensors ----

fn read_f32(path: &Path) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(bytes.len() % 4, 0, "{}", path.display());
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

/// The golden tensor `name` of `index.json`: its data and shape.
fn golden_tensor(golden: &Path, index: &serde_json::Value, name: &str) -> (Vec<f32>, Vec<usize>) {
    let entry = index["tensors"]
        .as_array()
        .and_then(|t| t.iter().find(|e| e["name"] == name))
        .unwrap_or_else(|| panic!("golden index has no tensor {name}"));
    let shape: Vec<usize> = entry["shape"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.as_u64().unwrap() as usize)
        .collect();
    let data = read_f32(&golden.join(entry["file"].as_str().unwrap()));
    assert_eq!(data.len(), shape.iter().product::<usize>(), "{name}");
    (data, shape)
}

#[test]
fn mcu_model_matches_golden_output() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/mcu");
    let model_path = dir.join("depthor.nnef.tgz");
    let golden = dir.join("golden");
    if !model_path.exists() || !golden.join("index.json").exists() {
        eprintln!(
            "SKIPPED: {} or its golden/index.json is absent (export it with \
             `python -m depthor_models.export --variant mcu --out models/mcu`)",
            model_path.display()
        );
        return;
    }
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(golden.join("index.json")).unwrap()).unwrap();
    let (rgb, rgb_shape) = golden_tensor(&golden, &index, "rgb");
    let (sparse, _) = golden_tensor(&golden, &index, "sparse");
    let (want, _) = golden_tensor(&golden, &index, "depth");
    let (h, w) = (rgb_shape[2] as u32, rgb_shape[3] as u32);

    let start = std::time::Instant::now();
    let model = FloatReference::load(&model_path, h, w).unwrap();
    let load = start.elapsed();
    let got = model.run_planar(&rgb, &sparse).unwrap();
    assert_eq!(got.len(), want.len());
    let max_abs = got
        .iter()
        .zip(&want)
        .map(|(g, w)| (g - w).abs())
        .fold(0.0f32, f32::max);
    let mean_abs = got
        .iter()
        .zip(&want)
        .map(|(g, w)| f64::from((g - w).abs()))
        .sum::<f64>()
        / got.len() as f64;
    let (lo, hi) = want
        .iter()
        .fold((f32::MAX, f32::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    println!(
        "mcu {h}x{w}: max |tract - torch| = {max_abs:.3e} m, mean {mean_abs:.3e} m \
         (golden depth {lo:.3}..{hi:.3} m), load+optimise {load:?}"
    );
    assert!(got.iter().all(|v| v.is_finite()));
    assert!(max_abs <= 1e-4, "max abs diff {max_abs} > 1e-4");
}

/// Single-thread time per frame of the `mcu` model (`cargo test --release -p depthor-host --test
/// reference -- --ignored --nocapture mcu_time`): slow in debug builds, so not run by default.
#[test]
#[ignore]
fn mcu_time_per_frame() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/mcu/depthor.nnef.tgz");
    if !path.exists() {
        eprintln!("SKIPPED: {} is absent", path.display());
        return;
    }
    let model = FloatReference::load(&path, 120, 160).unwrap();
    let runs = 30;
    let t = model.time_per_frame(runs).unwrap();
    println!("mcu 120x160 tract f32, one thread: median {t:?} per frame over {runs} runs");
}
