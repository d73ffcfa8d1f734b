//! CLI-level mutation test: `depthor info` on recordings whose `recording.json` or
//! `frames/<id>/dtof.json` has one value replaced, one field removed or added, or bytes
//! overwritten. Every run ends in exit 0 (the mutation was still valid) or exit 2 with one line
//! naming the file; where the faulty field is known, the line must name it too. Prints the
//! fraction of clean errors that name both (target ≥ 95 %).

mod common;

use serde_json::Value;
use std::path::Path;

/// A small deterministic generator (xorshift64*).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Every value of `v` with its path (`camera.fx`, `frames[0].id`, `distance_mm[3]`) and JSON
/// pointer, containers included.
fn values(v: &Value, path: &str, ptr: &str, out: &mut Vec<(String, String)>) {
    if !path.is_empty() {
        out.push((path.to_string(), ptr.to_string()));
    }
    match v {
        Value::Object(m) => {
            for (k, c) in m {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                values(c, &p, &format!("{ptr}/{k}"), out);
            }
        }
        Value::Array(a) => {
            for (i, c) in a.iter().enumerate() {
                values(c, &format!("{path}[{i}]"), &format!("{ptr}/{i}"), out);
            }
        }
        _ => {}
    }
}

/// One mutation: the new file text and the field it touched, if one.
fn mutate(doc: &Value, text: &str, rng: &mut Lcg) -> (String, Option<String>) {
    let mut leaves = Vec::new();
    values(doc, "", "", &mut leaves);
    // Named members (`camera.fx`) as often as array elements, which would otherwise dominate
    // (a recording header has 256 zone-rectangle numbers).
    let named: Vec<&(String, String)> = leaves.iter().filter(|(p, _)| !p.contains('[')).collect();
    let (path, ptr) = if rng.below(3) > 0 && !named.is_empty() {
        named[rng.below(named.len())].clone()
    } else {
        leaves[rng.below(leaves.len())].clone()
    };
    let mut d = doc.clone();
    match rng.below(10) {
        // Replace the value by one of the wrong type or an absurd size.
        0..=5 => {
            let bad = [
                Value::from("x"),
                Value::Null,
                Value::from(-1),
                Value::from(1e39),
                Value::from(-1e39),
                Value::from(0),
                Value::from(1.5),
                Value::from(65536),
                Value::Array(vec![]),
                Value::Object(Default::default()),
                Value::from(true),
            ];
            *d.pointer_mut(&ptr).unwrap() = bad[rng.below(bad.len())].clone();
            (d.to_string(), Some(path))
        }
        // Remove a member or an array element.
        6 | 7 => {
            let (parent_ptr, last) = ptr.rsplit_once('/').unwrap();
            let parent_path = parent_of(&path);
            match d.pointer_mut(parent_ptr).unwrap() {
                Value::Object(m) => {
                    m.remove(last);
                    (d.to_string(), Some(path))
                }
                Value::Array(a) => {
                    a.remove(last.parse::<usize>().unwrap());
                    (d.to_string(), parent_path)
                }
                _ => unreachable!(),
            }
        }
        // Add a member the format does not have.
        8 => {
            let obj_ptr = leaves
                .iter()
                .filter(|(_, p)| d.pointer(p).is_some_and(Value::is_object))
                .map(|(path, p)| (path.clone(), p.clone()))
                .collect::<Vec<_>>();
            if obj_ptr.is_empty() || rng.below(3) == 0 {
                d.as_object_mut().unwrap().insert("colour".into(), 1.into());
                (d.to_string(), Some("colour".into()))
            } else {
                let (opath, op) = &obj_ptr[rng.below(obj_ptr.len())];
                d.pointer_mut(op)
                    .unwrap()
                    .as_object_mut()
                    .unwrap()
                    .insert("colour".into(), 1.into());
                (d.to_string(), Some(format!("{opath}.colour")))
            }
        }
        // Overwrite a few bytes: the field is not known.
        _ => {
            let mut bytes = text.as_bytes().to_vec();
            let at = rng.below(bytes.len());
            let len = 1 + rng.below(4);
            for b in bytes.iter_mut().skip(at).take(len) {
                *b = b"{}[],:\"0-9eZ \n"[rng.below(14)];
            }
            (String::from_utf8_lossy(&bytes).into_owned(), None)
        }
    }
}

/// `a.b[3]` → `a.b`, `a.b` → `a`, `a` → none.
fn parent_of(path: &str) -> Option<String> {
    path.rfind(['.', '[']).map(|i| path[..i].to_string())
}

/// Whether `msg` names `field` or, for an element, its array (`distance_mm` for
/// `distance_mm[5]`).
fn names_field(msg: &str, field: &str) -> bool {
    let mut f = Some(field.to_string());
    // The field, or its array for an element ("expected 64 values").
    while let Some(p) = f {
        // The field itself, or a member of it (`frames[0].id` for a replaced `frames[0]`).
        if [":", " ", ".", "["]
            .iter()
            .any(|end| msg.contains(&format!(" {p}{end}")))
        {
            return true;
        }
        if !p.ends_with(']') {
            break;
        }
        f = parent_of(&p);
    }
    false
}

struct Tally {
    runs: usize,
    accepted: usize,
    errors: usize,
    known: usize,
    both: usize,
    misses: Vec<String>,
}

/// Runs `args` (`depthor …`) on `cases` mutations of `file`, tallying into `t`; `file` is
/// restored afterwards.
fn campaign(args: &[&str], file: &Path, cases: usize, seed: u64, t: &mut Tally) {
    let original = std::fs::read_to_string(file).unwrap();
    let doc: Value = serde_json::from_str(&original).unwrap();
    let name = file.file_name().unwrap().to_string_lossy().into_owned();
    let mut rng = Lcg(seed);
    for _ in 0..cases {
        let (text, field) = mutate(&doc, &original, &mut rng);
        std::fs::write(file, &text).unwrap();
        let o = common::depthor(args);
        t.runs += 1;
        let err = String::from_utf8_lossy(&o.stderr).trim().to_string();
        match o.status.code() {
            Some(0) => {
                t.accepted += 1;
                continue;
            }
            Some(2) => {}
            other => panic!("exit {other:?} on {name} ({field:?}): {err}\n{text}"),
        }
        t.errors += 1;
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(&name), "file not named: {err}");
        if let Some(f) = field {
            t.known += 1;
            if names_field(&err, &f) {
                t.both += 1;
                if t.both % 25 == 1 {
                    println!("  e.g. {f}: {err}");
                }
            } else {
                t.misses.push(format!("{name} {f}: {err}"));
            }
        }
    }
    std::fs::write(file, original).unwrap();
}

#[test]
fn mutated_recordings_exit_2_naming_file_and_field() {
    let t = recordings_campaign();
    report("recordings", &t);
}

fn report(what: &str, t: &Tally) {
    let fraction = t.both as f64 / t.known.max(1) as f64;
    println!(
        "mutation campaign ({what}): {} runs, {} still valid, {} clean errors (exit 2, file \
         named), {} with the field known, {} of them name it: {:.1} %",
        t.runs,
        t.accepted,
        t.errors,
        t.known,
        t.both,
        100.0 * fraction
    );
    for m in t.misses.iter().take(30) {
        println!("  miss: {m}");
    }
    assert!(t.known >= 100, "{}", t.known);
    assert!(
        fraction >= 0.95,
        "{what}: {:.1} % name file and field",
        100.0 * fraction
    );
}

/// Mutated simulator and scene configurations through `depthor sim` (tiny images, one scene).
#[test]
fn mutated_sim_and_scene_configs_exit_2_naming_file_and_field() {
    let tmp = tempfile::tempdir().unwrap();
    let mut t = Tally {
        runs: 0,
        accepted: 0,
        errors: 0,
        known: 0,
        both: 0,
        misses: Vec::new(),
    };
    let cfg = tmp.path().join("sim.json");
    std::fs::write(&cfg, depthor_host::sim::preset("l5").unwrap().to_json()).unwrap();
    let out = tmp.path().join("out");
    let sim = [
        "sim",
        "--config",
        common::arg(&cfg),
        "--scenes",
        "1",
        "--width",
        "32",
        "--height",
        "24",
        "--overwrite",
        "--out",
        common::arg(&out),
    ];
    campaign(&sim, &cfg, 150, 0x2545_f491_4f6c_dd1d, &mut t);
    let scene = tmp.path().join("scene.json");
    std::fs::copy(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../models/scenes/close_range.json"
        ),
        &scene,
    )
    .unwrap();
    let with_scene = [
        "sim",
        "--preset",
        "mcu",
        "--scene-config",
        common::arg(&scene),
        "--scenes",
        "1",
        "--width",
        "32",
        "--height",
        "24",
        "--overwrite",
        "--out",
        common::arg(&out),
    ];
    campaign(&with_scene, &scene, 150, 0x94d0_49bb_1331_11eb, &mut t);
    report("sim and scene configs", &t);
}

fn recordings_campaign() -> Tally {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec");
    common::depthor_ok(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "1",
        "--out",
        common::arg(&rec),
    ]);
    let mut t = Tally {
        runs: 0,
        accepted: 0,
        errors: 0,
        known: 0,
        both: 0,
        misses: Vec::new(),
    };
    let info = ["info", common::arg(&rec)];
    campaign(
        &info,
        &rec.join("recording.json"),
        300,
        0x9e37_79b9_7f4a_7c15,
        &mut t,
    );
    campaign(
        &info,
        &rec.join("frames/000000/dtof.json"),
        300,
        0xd1b5_4a32_d192_ed03,
        &mut t,
    );
    t
}
