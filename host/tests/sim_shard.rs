//! `depthor sim --shard K/N` + `depthor merge`: the union of a run's shards is byte-identical to
//! the unsharded run (scenes and `--from`), and merge refuses shards given out of order or from
//! different runs.

mod common;

use common::tree;
use std::path::{Path, PathBuf};
use std::process::Command;

fn depthor(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_depthor"))
        .args(args)
        .output()
        .expect("run depthor");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn ok(args: &[&str]) {
    let (code, err) = depthor(args);
    assert_eq!(code, 0, "{args:?}: {err}");
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `sim` with `extra` arguments and each `--shard k/n`, then `merge` of the shards.
fn sharded(dir: &Path, name: &str, n: u32, extra: &[&str]) -> (PathBuf, Vec<PathBuf>) {
    let shards: Vec<PathBuf> = (0..n).map(|k| dir.join(format!("{name}-{k}"))).collect();
    for (k, out) in shards.iter().enumerate() {
        let shard = format!("{k}/{n}");
        let mut args = vec!["sim", "--shard", &shard, "--out", s(out)];
        args.extend_from_slice(extra);
        ok(&args);
    }
    let merged = dir.join(format!("{name}-merged"));
    let mut args = vec!["merge", "--out", s(&merged)];
    args.extend(shards.iter().map(|p| s(p)));
    ok(&args);
    (merged, shards)
}

#[test]
fn union_of_shards_is_byte_identical_to_the_unsharded_run() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let scenes = ["--preset", "mcu", "--scenes", "5", "--seed", "41"];
    let whole = t.join("whole");
    let mut args = vec!["sim", "--out", s(&whole)];
    args.extend_from_slice(&scenes);
    ok(&args);
    let want = tree(&whole);
    assert!(want.len() > 5 * 3, "{} files", want.len());
    for n in [2, 3] {
        let (merged, shards) = sharded(t, &format!("n{n}"), n, &scenes);
        assert!(
            tree(&merged) == want,
            "{n} shards: union differs from the unsharded run"
        );
        // shard 1/n holds frames 1, 1+n, … and nothing else
        let frames: Vec<String> = std::fs::read_dir(shards[1].join("frames"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        let expect: Vec<String> = (1..5)
            .step_by(n as usize)
            .map(|i| format!("{i:06}"))
            .collect();
        assert_eq!(frames, expect);
    }

    // Out of order: 5 frames in 2 shards are 3 + 2, so 1/2 first is refused, and nothing written.
    let bad = t.join("bad");
    let (code, err) = depthor(&[
        "merge",
        "--out",
        s(&bad),
        s(&t.join("n2-1")),
        s(&t.join("n2-0")),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("frames") && err.contains("in order"), "{err}");
    assert!(!bad.exists());
    // Shards of another run (other size) share no header.
    let other = t.join("other");
    ok(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "2",
        "--seed",
        "41",
        "--width",
        "80",
        "--height",
        "60",
        "--shard",
        "1/2",
        "--out",
        s(&other),
    ]);
    let (code, err) = depthor(&["merge", "--out", s(&bad), s(&t.join("n2-0")), s(&other)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("camera") && err.contains("differs"), "{err}");
    let (code, err) = depthor(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "2",
        "--shard",
        "2/2",
        "--out",
        s(&bad),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--shard") && err.contains("K < N"), "{err}");

    // --from: the sensor simulated over an existing recording, sharded the same way.
    let from = ["--preset", "mcu", "--from", s(&whole), "--seed", "3"];
    let resim = t.join("resim");
    let mut args = vec!["sim", "--out", s(&resim)];
    args.extend_from_slice(&from);
    ok(&args);
    let (merged, _) = sharded(t, "from", 2, &from);
    assert!(
        tree(&merged) == tree(&resim),
        "--from: union differs from the unsharded run"
    );
}
