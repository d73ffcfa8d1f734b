//! `depthor import zjul5` on `.h5` files written here in the ZJU-L5 layout (rgb, depth,
//! hist_data, fr, mask, as the public Deltar and DEPTHOR loaders read them): the recording
//! keeps the RGB, the reference depth, the zone means and sigmas, the mask as status and the
//! rectangles as `zone_rects_px`; `depthor eval` runs on it; broken files name file and dataset.

mod common;

use common::{arg as s, depthor, depthor_ok};
use depthor_host::recording::Recording;
use std::path::Path;

const H: usize = 48;
const W: usize = 64;

/// Depth of the test scene at pixel (x, y): a slanted plane, 1.2–2.5 m.
fn depth_at(x: usize, y: usize, k: usize) -> f32 {
    1.2 + 0.015 * x as f32 + 0.005 * y as f32 + 0.05 * k as f32
}

/// Zone (r, c)'s rectangle `[y0, x0, y1, x1]`: an 8×8 tiling of the image.
fn rect(z: usize) -> [i64; 4] {
    let (r, c) = ((z / 8) as i64, (z % 8) as i64);
    [r * 6, c * 8, (r + 1) * 6, (c + 1) * 8]
}

/// Writes file `k` of the set; zone 5 is masked out.
fn write_h5(path: &Path, k: usize) {
    let mut b = hdf5_pure::FileBuilder::new();
    let rgb: Vec<u8> = (0..H * W * 3)
        .map(|i| ((i * 7 + k * 31) % 251) as u8)
        .collect();
    b.create_dataset("rgb")
        .with_u8_data(&rgb)
        .with_shape(&[H as u64, W as u64, 3]);
    let depth: Vec<f32> = (0..H * W).map(|i| depth_at(i % W, i / W, k)).collect();
    b.create_dataset("depth")
        .with_f32_data(&depth)
        .with_shape(&[H as u64, W as u64]);
    let mut hist = Vec::new();
    let mut fr = Vec::new();
    for z in 0..64 {
        let [y0, x0, y1, x1] = rect(z);
        let (cx, cy) = ((x0 + x1) as usize / 2, (y0 + y1) as usize / 2);
        hist.extend_from_slice(&[depth_at(cx, cy, k) as f64, 0.01 + 0.001 * z as f64]);
        fr.extend_from_slice(&rect(z));
    }
    b.create_dataset("hist_data")
        .with_f64_data(&hist)
        .with_shape(&[64, 2]);
    b.create_dataset("fr")
        .with_i64_data(&fr)
        .with_shape(&[64, 4]);
    let mask: Vec<u8> = (0..64).map(|z| u8::from(z != 5)).collect();
    b.create_dataset("mask").with_u8_data(&mask);
    b.write(path).unwrap();
}

#[test]
fn zjul5_h5_files_round_trip_and_eval_runs_on_them() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path().join("ZJUL5");
    std::fs::create_dir_all(src.join("scene_a")).unwrap();
    for k in 0..3 {
        write_h5(&src.join(format!("scene_a/{k}.h5")), k);
    }
    let rec = tmp.path().join("rec");
    let out = depthor_ok(&["import", "zjul5", s(&src), "--out", s(&rec)]);
    assert!(
        out.contains("imported 3 frames") && out.contains("zones valid 189/192"),
        "{out}"
    );

    let r = Recording::open(&rec).unwrap();
    assert_eq!(r.len(), 3);
    let ids: Vec<&str> = r.meta().frames.iter().map(|f| f.id.as_str()).collect();
    assert_eq!(ids, ["scene_a_0", "scene_a_1", "scene_a_2"]);
    let geo = r.meta().dtof.as_ref().unwrap();
    assert_eq!((geo.rows, geo.cols), (8, 8));
    let rects = geo.zone_rects_px.as_ref().unwrap();
    assert_eq!(rects[9], [6.0, 8.0, 12.0, 16.0]);
    for k in 0..3 {
        let f = r.read_frame(k).unwrap();
        assert_eq!(f.rgb.dimensions(), (W as u32, H as u32));
        assert_eq!(
            f.rgb.as_raw()[..3],
            [
                (k * 31 % 251) as u8,
                ((7 + k * 31) % 251) as u8,
                ((14 + k * 31) % 251) as u8
            ]
        );
        let d = f.depth_m.unwrap();
        // depth.png holds millimetres.
        assert!((d[W + 3] - depth_at(3, 1, k)).abs() < 6e-4, "{}", d[W + 3]);
        let z = f.dtof.unwrap();
        assert_eq!(z.status[5], 255);
        assert_eq!(z.status[6], 5);
        let [y0, x0, y1, x1] = rect(9);
        let want = 1000.0 * depth_at((x0 + x1) as usize / 2, (y0 + y1) as usize / 2, k);
        assert!(
            (z.distance_mm[9] - want).abs() < 1e-2,
            "{} vs {want}",
            z.distance_mm[9]
        );
        let sigma = z.sigma_mm.unwrap();
        assert!((sigma[9] - 19.0).abs() < 1e-3, "{}", sigma[9]);
    }

    // The zones project into their rectangles (z distance at the rectangle centre).
    let proj = tmp.path().join("proj");
    let o = depthor_ok(&[
        "project",
        "--recording",
        s(&rec),
        "--frame",
        "1",
        "--out",
        s(&proj),
    ]);
    assert!(
        o.contains("zones 64  projected 63  invalid_status 1"),
        "{o}"
    );

    // eval runs on it (int8 and the zone baselines, at the model's size).
    let ev = tmp.path().join("ev");
    depthor_ok(&[
        "eval",
        "--no-float",
        "--mosaics",
        "1",
        "--recording",
        s(&rec),
        "--out",
        s(&ev),
    ]);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ev.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["frames"], 3);
    assert!(summary["methods"]["bilinear"]["rmse"].as_f64().unwrap() < 0.5);
}

#[test]
fn broken_zjul5_files_name_the_file_and_the_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path().join("z");
    std::fs::create_dir_all(&src).unwrap();
    let mut b = hdf5_pure::FileBuilder::new();
    b.create_dataset("rgb")
        .with_u8_data(&vec![0u8; H * W * 3])
        .with_shape(&[H as u64, W as u64, 3]);
    b.create_dataset("depth")
        .with_f32_data(&vec![1.0f32; H * W])
        .with_shape(&[H as u64, W as u64]);
    b.create_dataset("hist_data").with_f32_data(&[1.0; 10]);
    b.write(src.join("bad.h5")).unwrap();
    let rec = tmp.path().join("rec");
    let o = depthor(&["import", "zjul5", s(&src), "--out", s(&rec)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("bad.h5") && err.contains("hist_data: shape [10]"),
        "{err}"
    );
    assert!(!rec.exists());
    std::fs::write(src.join("bad.h5"), b"not hdf5").unwrap();
    let o = depthor(&["import", "zjul5", s(&src), "--out", s(&rec)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.h5") && err.contains("HDF5"), "{err}");
}

#[test]
fn vl53l5cx_logs_become_zone_only_recordings() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path().join("logs");
    std::fs::create_dir_all(&src).unwrap();
    let frame = |d: i64| {
        (0..64)
            .map(|z| if z == 3 { -1 } else { d + z })
            .collect::<Vec<_>>()
    };
    let log =
        serde_json::json!({"pos": {"x": [0, 0]}, "tof": {"distances": [frame(500), frame(800)]}});
    std::fs::write(src.join("A0_ToF_data_pack.json"), log.to_string()).unwrap();
    let rec = tmp.path().join("rec");
    let out = depthor_ok(&["import", "vl53l5cx-log", s(&src), "--out", s(&rec)]);
    assert!(
        out.contains("no RGB") && out.contains("zones valid 126/128"),
        "{out}"
    );
    assert!(!rec.join("frames/A0_ToF_data_pack_000000/rgb.png").exists());
    let info = depthor_ok(&["info", "--recording", s(&rec)]);
    assert!(
        info.contains("rgb        none") && info.contains("zones valid 63/64"),
        "{info}"
    );
    let r = Recording::open(&rec).unwrap();
    let z = r.read_frame(1).unwrap().dtof.unwrap();
    assert_eq!((z.distance_mm[0], z.status[3]), (800.0, 255));
    // eval refuses it, naming why.
    let o = depthor(&["eval", "--no-float", "--recording", s(&rec)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("rgb: false"), "{err}");
    // The shared flight logs, when present.
    let real = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real/vecihi-vl53l5cx-flights");
    if real.is_dir() {
        let rec2 = tmp.path().join("flights");
        let out = depthor_ok(&["import", "vl53l5cx-log", s(&real), "--out", s(&rec2)]);
        println!("{out}");
        assert!(out.contains("no RGB"), "{out}");
    }
}

#[test]
fn uld_dumps_become_zone_only_recordings() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path().join("dumps");
    std::fs::create_dir_all(&src).unwrap();
    let list = |f: &dyn Fn(usize) -> String| (0..16).map(f).collect::<Vec<_>>().join(",");
    // One frame a line (4×4), as VL53L5CX_ResultsData fields; zone 2 has no target.
    let line = |d: usize| {
        format!(
            "distance_mm={} target_status={} nb_target_detected={} range_sigma_mm={}",
            list(&|z| (d + z).to_string()),
            list(&|_| "5".into()),
            list(&|z| if z == 2 { "0".into() } else { "1".into() }),
            list(&|z| (z % 3).to_string()),
        )
    };
    std::fs::write(
        src.join("run1.txt"),
        format!("# ULD 1.3.0\n{}\n{}\n", line(600), line(900)),
    )
    .unwrap();
    let rec = tmp.path().join("rec");
    let out = depthor_ok(&["import", "uld-dump", s(&src), "--out", s(&rec)]);
    assert!(
        out.contains("no RGB") && out.contains("zones valid 30/32"),
        "{out}"
    );
    let r = Recording::open(&rec).unwrap();
    let z = r.read_frame(1).unwrap().dtof.unwrap();
    assert_eq!(
        (z.distance_mm[0], z.status[2], z.status[3]),
        (900.0, 255, 5)
    );
    assert_eq!(z.sigma_mm.as_ref().unwrap()[4], 1.0);
    // A malformed dump names the file and the line.
    std::fs::write(src.join("run2.txt"), "distance_mm=1,2 target_status=5,5\n").unwrap();
    let o = depthor(&[
        "import",
        "uld-dump",
        s(&src),
        "--out",
        s(&tmp.path().join("rec2")),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("run2.txt") && err.contains("line 1"), "{err}");
}
