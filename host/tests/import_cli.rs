//! `depthor import` + `depthor info` on every real set: the recording written by the CLI reports
//! the depth ranges given in each set's README.txt.

use std::path::PathBuf;
use std::process::Command;

fn real_root() -> PathBuf {
    std::env::var_os("DEPTHOR_REAL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real"))
}

fn depthor(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_depthor"))
        .args(args)
        .output()
        .expect("run depthor");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// (kind, folder, frame id or "" for the only frame, min m, max m) from the README.txt files.
const CASES: &[(&str, &str, &str, f32, f32)] = &[
    ("middlebury", "middlebury2014-Q", "Adirondack", 1.573, 2.916),
    ("middlebury", "middlebury2014-Q", "Teddy", 1.146, 1.791),
    ("middlebury", "middlebury2014-Q", "Motorcycle", 2.017, 4.597),
    ("nyu", "metric3d-nyu-demo", "", 0.713, 8.266),
    ("redwood", "open3d-rgbd-testdata", "", 0.955, 2.702),
    ("tum", "open3d-rgbd-testdata", "", 1.46, 9.33),
    ("sun", "open3d-rgbd-testdata", "", 1.057, 9.870),
    ("nyu-raw", "open3d-rgbd-testdata", "", 1.39, 6.69),
    ("arkit", "promptda-iphone-lidar", "", 1.566, 3.512),
];

/// Parses `min A median B max C m` from an `info` line.
fn min_max(line: &str) -> (f32, f32) {
    let word_after = |key: &str| -> f32 {
        let rest = &line[line.find(key).expect(key) + key.len()..];
        rest.split_whitespace().next().unwrap().parse().unwrap()
    };
    (word_after(" min "), word_after(" max "))
}

#[test]
fn every_real_set_imports_and_info_reports_its_readme_ranges() {
    let root = real_root();
    if !root.is_dir() {
        eprintln!("skipping: {} is absent", root.display());
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    for (kind, folder, frame, lo, hi) in CASES {
        let out = tmp.path().join(kind);
        let src = root.join(folder);
        let (code, _, err) = depthor(&[
            "import",
            kind,
            src.to_str().unwrap(),
            out.to_str().unwrap(),
            "--overwrite",
        ]);
        assert_eq!(code, 0, "{kind}: {err}");
        let (code, info, err) = depthor(&["info", out.to_str().unwrap()]);
        assert_eq!(code, 0, "{kind}: {err}");
        let lines: Vec<&str> = info.lines().filter(|l| l.contains(" min ")).collect();
        assert!(!lines.is_empty(), "{kind}: no depth lines in\n{info}");
        let (mut min, mut max) = (f32::INFINITY, 0f32);
        for l in lines
            .iter()
            .filter(|l| frame.is_empty() || l.trim_start().starts_with(frame))
        {
            let (a, b) = min_max(l);
            min = min.min(a);
            max = max.max(b);
        }
        // info prints millimetre precision; the READMEs give mm or cm.
        assert!(
            (min - lo).abs() <= 0.006,
            "{kind} {frame}: min {min} vs README {lo}"
        );
        assert!(
            (max - hi).abs() <= 0.006,
            "{kind} {frame}: max {max} vs README {hi}"
        );
    }
}
