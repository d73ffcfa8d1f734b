//! `include/depthor.h` is written by hand; this test keeps it equal to the Rust side:
//!
//! - every `pub const DEPTHOR_*` of `src/lib.rs` is `#define`d in the header with the same
//!   value, and the header defines no other `DEPTHOR_*` constant (values are also compared
//!   with the compiled constants for the status codes);
//! - every `#[no_mangle] extern "C" fn` of `src/lib.rs` has a prototype in the header whose
//!   return and parameter types are the C spelling of the Rust types, and the header declares
//!   no other function.
//!
//! Struct layouts are checked by `tests/c_api.rs` (a compiled C program prints `sizeof` and
//! `offsetof`). Run: `cargo test -p depthor-ffi --test header`.

use std::collections::BTreeMap;
use std::path::Path;

fn read(rel: &str) -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join(rel);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The text without `/* … */` and `// …` comments.
fn strip_comments(s: &str) -> String {
    let mut out = String::new();
    let mut rest = s;
    loop {
        let block = rest.find("/*");
        let line = rest.find("//");
        match (block, line) {
            (Some(b), l) if l.is_none_or(|l| b < l) => {
                out.push_str(&rest[..b]);
                let end = rest[b..].find("*/").expect("unterminated comment") + b + 2;
                rest = &rest[end..];
            }
            (_, Some(l)) => {
                out.push_str(&rest[..l]);
                rest = rest[l..].find('\n').map_or("", |e| &rest[l + e..]);
            }
            _ => {
                out.push_str(rest);
                return out;
            }
        }
    }
}

fn parse_int(v: &str) -> i64 {
    let v = v.trim().trim_start_matches('(').trim_end_matches(')');
    let v = v.trim_end_matches('u').trim().replace('_', "");
    v.parse().unwrap_or_else(|e| panic!("{v:?}: {e}"))
}

fn header_defines(h: &str) -> BTreeMap<String, i64> {
    let mut m = BTreeMap::new();
    for line in strip_comments(h).lines() {
        let mut it = line.split_whitespace();
        if it.next() != Some("#define") {
            continue;
        }
        let Some(name) = it.next() else { continue };
        let value: Vec<&str> = it.collect();
        if !name.starts_with("DEPTHOR_") || value.is_empty() {
            continue;
        }
        let value = value.join(" ");
        // `DEPTHOR_ENGINE_STORAGE_BYTES` names the `_32` or `_64` value per pointer width.
        if let Some(alias) = value.strip_prefix("DEPTHOR_") {
            let width = if cfg!(target_pointer_width = "32") {
                "_32"
            } else {
                "_64"
            };
            if alias.ends_with(width) {
                let v = *m
                    .get(&format!("DEPTHOR_{alias}"))
                    .expect("alias defined before");
                assert!(m.insert(name.to_owned(), v).is_none(), "{name} twice");
            }
            continue;
        }
        assert!(
            m.insert(name.to_owned(), parse_int(&value)).is_none(),
            "{name} twice"
        );
    }
    m
}

fn rust_consts(src: &str) -> BTreeMap<String, i64> {
    let mut m = BTreeMap::new();
    for line in src.lines() {
        let Some(rest) = line.trim().strip_prefix("pub const DEPTHOR_") else {
            continue;
        };
        let (name, rest) = rest.split_once(':').expect("typed const");
        let value = rest
            .split_once('=')
            .expect("const value")
            .1
            .trim_end_matches(';');
        if value.trim_start().starts_with("if cfg!") {
            continue; // a per-target choice: compared through its compiled value below
        }
        m.insert(format!("DEPTHOR_{name}"), parse_int(value));
    }
    m
}

/// `(return type, [parameter types])` by function name, C spelling, single spaces.
type Protos = BTreeMap<String, (String, Vec<String>)>;

fn norm(s: &str) -> String {
    s.replace('*', " * ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

fn header_protos(h: &str) -> Protos {
    let text = strip_comments(h);
    let mut m = Protos::new();
    for decl in text.split(';') {
        let decl = decl.trim();
        let Some(open) = decl.find('(') else { continue };
        if decl.starts_with('#') || decl.contains("typedef") || !decl.contains("depthor_") {
            continue;
        }
        // Preprocessor lines and `extern "C" {` may precede the first prototype.
        let decl = decl.rsplit(['{', '}']).next().unwrap().trim();
        let decl = decl
            .lines()
            .filter(|l| !l.trim_start().starts_with('#'))
            .collect::<Vec<_>>()
            .join(" ");
        let open = decl.find('(').unwrap_or(open);
        let head = norm(&decl[..open]);
        let (ret, name) = head.rsplit_once(' ').expect("return type and name");
        let params = decl[open + 1..decl.rfind(')').expect("closing paren")].trim();
        let types = if params == "void" {
            Vec::new()
        } else {
            params
                .split(',')
                .map(|p| {
                    let p = norm(p);
                    // Drop the parameter name (the last word).
                    p.rsplit_once(' ').expect("type and name").0.to_owned()
                })
                .collect()
        };
        assert!(
            m.insert(name.to_owned(), (ret.to_owned(), types)).is_none(),
            "{name} twice"
        );
    }
    m
}

/// The C spelling of a Rust parameter or return type used by the ABI.
fn c_type(rust: &str) -> String {
    let rust = rust.trim();
    if let Some(t) = rust.strip_prefix("*const ") {
        return format!("const {} *", c_type(t));
    }
    if let Some(t) = rust.strip_prefix("*mut ") {
        return format!("{} *", c_type(t));
    }
    match rust {
        "u8" => "uint8_t",
        "u16" => "uint16_t",
        "u32" => "uint32_t",
        "i32" => "int32_t",
        "usize" => "size_t",
        "f32" => "float",
        "c_char" => "char",
        t if t.starts_with("depthor_") => t,
        t => panic!("no C spelling for Rust type {t:?}: extend c_type"),
    }
    .to_owned()
}

fn rust_protos(src: &str) -> Protos {
    let mut m = Protos::new();
    let mut rest = src;
    while let Some(at) = rest.find("#[no_mangle]") {
        rest = &rest[at..];
        let start = rest
            .find("extern \"C\" fn ")
            .expect("extern fn after no_mangle")
            + 14;
        let open = start + rest[start..].find('(').unwrap();
        let name = rest[start..open].trim().to_owned();
        let close = open + rest[open..].find(')').unwrap();
        let params: Vec<String> = rest[open + 1..close]
            .split(',')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(|p| norm(&c_type(p.split_once(':').expect("name: type").1)))
            .collect();
        let after = rest[close + 1..].trim_start();
        let ret = match after.strip_prefix("->") {
            Some(r) => norm(&c_type(r[..r.find('{').unwrap()].trim())),
            None => "void".to_owned(),
        };
        m.insert(name, (ret, params));
        rest = &rest[close..];
    }
    m
}

#[test]
fn header_constants_equal_the_rust_constants() {
    let h = header_defines(&read("include/depthor.h"));
    let mut r = rust_consts(&read("src/lib.rs"));
    r.insert(
        "DEPTHOR_ENGINE_STORAGE_BYTES".to_owned(),
        depthor_ffi::DEPTHOR_ENGINE_STORAGE_BYTES as i64,
    );
    assert!(r.len() >= 16, "parsed {r:?}");
    assert_eq!(h, r, "header #defines (left) vs lib.rs consts (right)");
    // The parsed source text is what was compiled.
    for (name, v) in [
        ("DEPTHOR_OK", depthor_ffi::DEPTHOR_OK),
        ("DEPTHOR_E_NULL", depthor_ffi::DEPTHOR_E_NULL),
        ("DEPTHOR_E_INTERNAL", depthor_ffi::DEPTHOR_E_INTERNAL),
    ] {
        assert_eq!(h[name], i64::from(v), "{name}");
    }
    assert_eq!(
        h["DEPTHOR_ENGINE_STORAGE_BYTES"],
        depthor_ffi::DEPTHOR_ENGINE_STORAGE_BYTES as i64
    );
    let codes: Vec<i64> = depthor_ffi::ALL_STATUS
        .iter()
        .map(|&c| i64::from(c))
        .collect();
    let mut in_header: Vec<i64> = h
        .iter()
        .filter(|(k, _)| *k == "DEPTHOR_OK" || k.starts_with("DEPTHOR_E_"))
        .map(|(_, &v)| v)
        .collect();
    in_header.sort();
    let mut sorted = codes.clone();
    sorted.sort();
    assert_eq!(
        in_header, sorted,
        "ALL_STATUS lists every code of the header"
    );
}

#[test]
fn header_prototypes_equal_the_rust_signatures() {
    let h = header_protos(&read("include/depthor.h"));
    let r = rust_protos(&read("src/lib.rs"));
    assert!(r.len() >= 8, "parsed {r:?}");
    for (name, sig) in &r {
        assert_eq!(h.get(name), Some(sig), "{name}: header vs Rust");
    }
    assert_eq!(
        h.keys().collect::<Vec<_>>(),
        r.keys().collect::<Vec<_>>(),
        "the same functions on both sides"
    );
    // The API the issue names, with its exact C types.
    let want =
        |ret: &str, params: &[&str]| (ret.to_owned(), params.iter().map(|p| norm(p)).collect());
    assert_eq!(h["depthor_engine_size"], want("size_t", &[]));
    assert_eq!(h["depthor_engine_align"], want("size_t", &[]));
    assert_eq!(
        h["depthor_arena_bytes"],
        want(
            "int32_t",
            &[
                "const uint8_t *",
                "size_t",
                "uint32_t",
                "uint32_t",
                "size_t *"
            ]
        )
    );
    assert_eq!(
        h["depthor_engine_init"],
        want(
            "int32_t",
            &[
                "depthor_engine *",
                "const uint8_t *",
                "size_t",
                "uint8_t *",
                "size_t",
                "uint32_t",
                "uint32_t"
            ]
        )
    );
    assert_eq!(
        h["depthor_engine_run"],
        want(
            "int32_t",
            &[
                "depthor_engine *",
                "const uint8_t *",
                "size_t",
                "const float *",
                "size_t",
                "float *",
                "size_t"
            ]
        )
    );
    assert_eq!(
        h["depthor_status_message"],
        want("const char *", &["int32_t"])
    );
}

#[test]
fn the_parsers_see_a_difference() {
    // Guards the guards: an edited prototype or value must not compare equal.
    let h = read("include/depthor.h");
    let edited = h.replace(
        "uint32_t width, size_t *out_bytes",
        "uint16_t width, size_t *out_bytes",
    );
    assert_ne!(header_protos(&edited), header_protos(&h));
    let edited = h.replace(
        "#define DEPTHOR_E_ARENA (-7)",
        "#define DEPTHOR_E_ARENA (-70)",
    );
    assert_ne!(header_defines(&edited), header_defines(&h));
}
