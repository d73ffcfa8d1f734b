//! Importers against the real sets in `/work/shared/data/real` (or `$DEPTHOR_REAL_DATA`): every
//! kind loads, depth ranges and valid fractions agree with each folder's README.txt, and malformed
//! copies give one-line errors naming the file. Tests skip, with a message, when data is absent.

use std::fs;
use std::path::{Path, PathBuf};

use depthor_host::import::{load, DepthStats, ImportError, ImportKind, ImportedSet};

/// The set folder, or `None` (and a message) when it is not on this machine.
fn real(folder: &str) -> Option<PathBuf> {
    let root = std::env::var_os("DEPTHOR_REAL_DATA")
        .map_or_else(|| PathBuf::from("/work/shared/data/real"), PathBuf::from);
    let p = root.join(folder);
    if p.is_dir() {
        Some(p)
    } else {
        println!("skipping: {} is absent", p.display());
        None
    }
}

/// Loads `kind` and checks the frame invariants every importer promises.
fn load_ok(kind: ImportKind, src: &Path) -> ImportedSet {
    let set = load(kind, src).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
    assert!(!set.frames.is_empty());
    for f in &set.frames {
        let (w, h) = f.rgb.dimensions();
        assert_eq!((f.camera.width, f.camera.height), (w, h), "{}", f.id);
        assert_eq!(f.depth_m.len(), (w * h) as usize, "{}", f.id);
        assert!(
            f.depth_m.iter().all(|z| z.is_finite() && *z >= 0.0),
            "{}: depth must be finite and ≥ 0",
            f.id
        );
        assert!(f.camera.fx > 0.0 && f.camera.fy > 0.0);
    }
    println!(
        "{}: {} frame(s); notes: {:#?}",
        set.name,
        set.frames.len(),
        set.notes
    );
    set
}

/// Checks min/max (metres, within `tol_m`) and, if given, the valid fraction (within its tolerance).
#[track_caller]
fn check(what: &str, s: DepthStats, min_m: f32, max_m: f32, tol_m: f32, frac: Option<(f64, f64)>) {
    println!(
        "{what}: {:.4}..{:.4} m, {:.2} % valid",
        s.min_m,
        s.max_m,
        100.0 * s.valid_fraction()
    );
    assert!(
        (s.min_m - min_m).abs() <= tol_m,
        "{what}: min {} vs README {min_m}",
        s.min_m
    );
    assert!(
        (s.max_m - max_m).abs() <= tol_m,
        "{what}: max {} vs README {max_m}",
        s.max_m
    );
    if let Some((f, tol)) = frac {
        let got = s.valid_fraction();
        assert!((got - f).abs() <= tol, "{what}: valid {got} vs README {f}");
    }
}

// Tolerances: README figures in whole millimetres within 0.6 mm (rounding plus f32), figures
// given to 0.01 m within 6 mm, percentages given to 0.1 % within 0.06 points (rounding);
// Middlebury's mm come out of the disparity formula, so ±1 mm.
const MM: f32 = 0.000_6;
const CM: f32 = 0.006;
const PCT: f64 = 0.000_6;

#[test]
fn middlebury_scenes() {
    let Some(src) = real("middlebury2014-Q") else {
        return;
    };
    let set = load_ok(ImportKind::Middlebury, &src);
    assert_eq!(set.frames.len(), 8);
    let get = |id: &str| {
        set.frames
            .iter()
            .find(|f| f.id == id)
            .unwrap_or_else(|| panic!("no scene {id}"))
    };
    let a = get("Adirondack");
    assert_eq!(a.rgb.dimensions(), (718, 496));
    assert_eq!(
        (a.camera.fx, a.camera.cx, a.camera.cy),
        (1038.018, 322.037, 243.393)
    );
    check(
        "Adirondack",
        a.depth_stats(),
        1.573,
        2.916,
        0.001,
        Some((0.997, PCT)),
    );
    check(
        "Teddy",
        get("Teddy").depth_stats(),
        1.146,
        1.791,
        0.001,
        None,
    );
    assert_eq!(get("Teddy").rgb.dimensions(), (450, 375));
    check(
        "Motorcycle",
        get("Motorcycle").depth_stats(),
        2.017,
        4.597,
        0.001,
        None,
    );
    assert_eq!(get("Motorcycle").rgb.dimensions(), (741, 497));
    check(
        "Vintage",
        get("Vintage").depth_stats(),
        0.980,
        3.951,
        0.001,
        None,
    );
    assert_eq!(get("Vintage").rgb.dimensions(), (722, 480));
}

#[test]
fn nyu_demo_frames() {
    let Some(src) = real("metric3d-nyu-demo") else {
        return;
    };
    let set = load_ok(ImportKind::Nyu, &src);
    let want = [
        ("rgb_00000", 1.390, 6.625, 0.733),
        ("rgb_00050", 0.887, 8.266, 0.751),
        ("rgb_00100", 0.713, 6.446, 0.670),
    ];
    assert_eq!(set.frames.len(), want.len());
    for (f, (id, lo, hi, frac)) in set.frames.iter().zip(want) {
        assert_eq!(f.id, id);
        let c = f.camera;
        assert_eq!(
            (c.fx, c.fy, c.cx, c.cy),
            (518.8579, 519.469_6, 325.58245, 253.73617)
        );
        check(id, f.depth_stats(), lo, hi, MM, Some((frac, PCT)));
    }
}

#[test]
fn open3d_redwood_sequence() {
    let Some(src) = real("open3d-rgbd-testdata") else {
        return;
    };
    let set = load_ok(ImportKind::Redwood, &src);
    assert_eq!(set.frames.len(), 5);
    let c = set.frames[0].camera;
    assert_eq!((c.fx, c.fy, c.cx, c.cy), (525.0, 525.0, 319.5, 239.5));
    check(
        "redwood",
        set.depth_stats(),
        0.955,
        2.702,
        MM,
        Some((0.87, 0.01)),
    );
}

#[test]
fn open3d_single_frames() {
    let Some(src) = real("open3d-rgbd-testdata") else {
        return;
    };
    let tum = load_ok(ImportKind::Tum, &src);
    check("tum", tum.depth_stats(), 1.46, 9.33, CM, Some((0.808, PCT)));
    assert!(tum.notes.iter().any(|n| n.contains("Freiburg 1")));
    let sun = load_ok(ImportKind::Sun, &src);
    check(
        "sun",
        sun.depth_stats(),
        1.057,
        9.870,
        MM,
        Some((0.818, PCT)),
    );
    assert!(sun.notes.iter().any(|n| n.contains("assumed")));
    let raw = load_ok(ImportKind::NyuRaw, &src);
    check(
        "nyu-raw",
        raw.depth_stats(),
        1.39,
        6.69,
        CM,
        Some((0.928, PCT)),
    );
    assert!(
        raw.notes.iter().any(|n| n.contains("little-endian")),
        "this file is byte-swapped"
    );
    assert!(raw.notes.iter().any(|n| n.contains("NOT registered")));
}

#[test]
fn promptda_arkit_frame() {
    let Some(src) = real("promptda-iphone-lidar") else {
        return;
    };
    let set = load_ok(ImportKind::Arkit, &src);
    let f = &set.frames[0];
    assert_eq!(f.rgb.dimensions(), (640, 480));
    // Nearest-neighbour upsampling keeps the sensor's values: README 1566..3512 mm, 100 % nonzero.
    check("arkit", f.depth_stats(), 1.566, 3.512, MM, Some((1.0, 0.0)));
}

/// Copies the files of `from` (not sub-folders) into a new folder `to`.
fn copy_dir(from: &Path, to: &Path) {
    fs::create_dir_all(to).unwrap();
    for e in fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        if p.is_file() {
            fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
        }
    }
}

/// Checks the error is one line, names `file` first and contains `what`.
#[track_caller]
fn assert_names(e: ImportError, file: &Path, what: &str) {
    let msg = e.to_string();
    println!("{msg}");
    assert!(!msg.contains('\n'), "not one line: {msg}");
    assert_eq!(e.path(), file);
    assert!(msg.starts_with(&format!("{}: ", file.display())), "{msg}");
    assert!(msg.contains(what), "{msg} lacks {what:?}");
}

#[test]
fn malformed_middlebury_copies() {
    let Some(src) = real("middlebury2014-Q") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("Teddy");
    copy_dir(&src.join("Teddy"), &scene);
    assert_eq!(load_ok(ImportKind::Middlebury, dir.path()).frames.len(), 1);

    // Truncated PFM.
    let pfm = scene.join("disp0GT.pfm");
    let bytes = fs::read(&pfm).unwrap();
    fs::write(&pfm, &bytes[..bytes.len() - 100]).unwrap();
    let e = load(ImportKind::Middlebury, dir.path()).unwrap_err();
    assert_names(
        e,
        &pfm,
        "truncated: 450×375 floats need 675000 data bytes, found 674900",
    );
    fs::write(&pfm, &bytes).unwrap();

    // calib.txt without its baseline line.
    let calib = scene.join("calib.txt");
    let text = fs::read_to_string(&calib).unwrap();
    let cut: String = text
        .lines()
        .filter(|l| !l.contains("baseline"))
        .map(|l| format!("{l}\n"))
        .collect();
    fs::write(&calib, cut).unwrap();
    let e = load(ImportKind::Middlebury, dir.path()).unwrap_err();
    assert_names(e, &calib, "missing field baseline");

    // cam0 with a number missing.
    fs::write(&calib, text.replacen("0 0 1 ]", "0 1 ]", 1)).unwrap();
    let e = load(ImportKind::Middlebury, dir.path()).unwrap_err();
    assert_names(e, &calib, "cam0: expected 9 numbers, found 8");

    // No scene at all.
    let empty = tempfile::tempdir().unwrap();
    let e = load(ImportKind::Middlebury, empty.path()).unwrap_err();
    assert_names(e, empty.path(), "no scene folder");
}

#[test]
fn malformed_depth_images() {
    let Some(src) = real("open3d-rgbd-testdata") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let other = dir.path().join("other_formats");
    copy_dir(&src.join("other_formats"), &other);

    // An 8-bit depth PNG where 16-bit is expected.
    let depth = other.join("TUM_depth.png");
    image::GrayImage::from_pixel(640, 480, image::Luma([7]))
        .save(&depth)
        .unwrap();
    let e = load(ImportKind::Tum, dir.path()).unwrap_err();
    assert_names(
        e,
        &depth,
        "expected a 16-bit greyscale depth image, found L8",
    );

    // A missing file.
    let sun = other.join("SUN_depth.png");
    fs::remove_file(&sun).unwrap();
    assert_names(load(ImportKind::Sun, dir.path()).unwrap_err(), &sun, "");

    // A cut PGM.
    let nyu = other.join("NYU_depth.pgm");
    let b = fs::read(&nyu).unwrap();
    fs::write(&nyu, &b[..1000]).unwrap();
    assert_names(load(ImportKind::NyuRaw, dir.path()).unwrap_err(), &nyu, "");
}

#[test]
fn malformed_nyu_annotations() {
    let Some(src) = real("metric3d-nyu-demo") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let ann = dir.path().join("test_annotations.json");
    let text = fs::read_to_string(src.join("test_annotations.json")).unwrap();
    fs::write(&ann, text.replace("\"cam_in\"", "\"cam\"")).unwrap();
    let e = load(ImportKind::Nyu, dir.path()).unwrap_err();
    assert_names(e, &ann, "missing field `cam_in`");
}
