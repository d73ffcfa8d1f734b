//! Every `*.md` file that the code or the docs cite exists in the repository: a clone resolves
//! every contract it is pointed to (`docs/graph.md`, `docs/blob.md`, …), and nothing points
//! outside the repository (the shared folder).
//!
//! A cited path resolves against the citing file's folder (Markdown links) or the repository
//! root (`docs/blob.md` in a doc comment); `*` in a path matches any one folder or file name.
//! Names of files that tools write (`report.md`) are not cites.

use std::path::{Path, PathBuf};

/// Files the tools write into their output folders; a mention of one is not a cite.
const WRITTEN: &[&str] = &[
    "report.md",
    "table.md",
    "MODEL_CARD.md",
    "gap_bench.md",
    "bench/gap_bench.md",
];
/// Folders that hold no source: build outputs, environments, VCS data.
const SKIP_DIRS: &[&str] = &[
    "target",
    ".git",
    ".venv",
    "node_modules",
    "__pycache__",
    ".pytest_cache",
    ".onnx_cache",
];
/// File kinds searched for cites.
const EXTENSIONS: &[&str] = &["rs", "py", "md", "sh", "toml"];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The files git tracks or would track (untracked, not ignored); without git, every file below
/// `root` outside [`SKIP_DIRS`].
fn source_files(root: &Path) -> Vec<PathBuf> {
    let listed = std::process::Command::new("git")
        .args(["ls-files", "-co", "--exclude-standard"])
        .current_dir(root)
        .output()
        .ok()
        .filter(|o| o.status.success());
    let mut out = Vec::new();
    match listed {
        Some(o) => {
            for line in String::from_utf8_lossy(&o.stdout).lines() {
                let p = root.join(line);
                if has_source_extension(&p) && p.is_file() {
                    out.push(p);
                }
            }
        }
        None => walk(root, &mut out),
    }
    out
}

fn has_source_extension(p: &Path) -> bool {
    p.extension()
        .and_then(|x| x.to_str())
        .is_some_and(|x| EXTENSIONS.contains(&x))
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        let Ok(kind) = e.file_type() else { continue };
        if kind.is_dir() {
            if !SKIP_DIRS.contains(&name.as_str()) {
                walk(&p, out);
            }
        } else if kind.is_file() && has_source_extension(&p) {
            out.push(p);
        }
    }
}

/// The `….md` tokens of `text`: runs of path characters ending in `.md` at a word end.
fn md_tokens(text: &str) -> Vec<String> {
    let b = text.as_bytes();
    let path_char = |c: u8| c.is_ascii_alphanumeric() || b"_./*-".contains(&c);
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(k) = text[i..].find(".md") {
        let end = i + k + 3;
        i = end;
        if end < b.len() && (b[end].is_ascii_alphanumeric() || b[end] == b'_') {
            continue; // `.mdx`, `.md_old`
        }
        let mut start = end - 3;
        while start > 0 && path_char(b[start - 1]) {
            start -= 1;
        }
        let run = &text[start..end];
        // Keep a leading `../` (a relative cite); drop lone punctuation before a name.
        let token = if run.starts_with("../") {
            run.to_string()
        } else {
            run.trim_start_matches(['.', '/']).to_string()
        };
        if token.len() > 3 && !token.starts_with(".md") {
            out.push(token);
        }
    }
    out
}

/// Whether `pattern` (a relative path, `*` matching one name) names an existing file below `base`.
fn resolves(base: &Path, pattern: &str) -> bool {
    let mut here = vec![base.to_path_buf()];
    for part in pattern.split('/').filter(|p| !p.is_empty() && *p != ".") {
        let mut next = Vec::new();
        for dir in &here {
            if part.contains('*') {
                let (pre, post) = part.split_once('*').unwrap_or((part, ""));
                if let Ok(entries) = std::fs::read_dir(dir) {
                    for e in entries.flatten() {
                        let n = e.file_name().to_string_lossy().into_owned();
                        if n.len() >= pre.len() + post.len()
                            && n.starts_with(pre)
                            && n.ends_with(post)
                        {
                            next.push(e.path());
                        }
                    }
                }
            } else {
                let p = dir.join(part);
                if p.exists() {
                    next.push(p);
                }
            }
        }
        here = next;
    }
    here.iter().any(|p| p.is_file())
}

#[test]
fn every_cited_md_file_exists_in_the_repository() {
    let root = root();
    let files = source_files(&root);
    assert!(
        files.len() > 50,
        "only {} source files found under {}",
        files.len(),
        root.display()
    );
    let mut cites = 0;
    let mut missing = Vec::new();
    let mut outside = Vec::new();
    for f in &files {
        let Ok(text) = std::fs::read_to_string(f) else {
            continue;
        };
        let rel = f.strip_prefix(&root).unwrap_or(f).display().to_string();
        if Path::new(&rel) == Path::new(file!()) {
            continue; // this file's own examples
        }
        for token in md_tokens(&text) {
            if WRITTEN.contains(&token.as_str()) {
                continue;
            }
            cites += 1;
            if token.contains("shared/") {
                outside.push(format!("{rel}: {token}"));
                continue;
            }
            let dir = f.parent().unwrap_or(&root);
            if !(resolves(dir, &token) || resolves(&root, &token)) {
                missing.push(format!("{rel}: {token}"));
            }
        }
    }
    assert!(cites > 20, "only {cites} cites found: the scan is broken");
    assert!(
        outside.is_empty(),
        "cites outside the repository (move the content into docs/):\n{}",
        outside.join("\n")
    );
    assert!(
        missing.is_empty(),
        "cited files that do not exist:\n{}",
        missing.join("\n")
    );
}

#[test]
fn the_scan_finds_cites_and_resolves_globs() {
    assert_eq!(
        md_tokens("see `docs/graph.md`, [blob](blob.md) and ../x/README.md; not a.mdx"),
        vec!["docs/graph.md", "blob.md", "../x/README.md"]
    );
    let root = root();
    assert!(resolves(&root, "models/*/MODEL_CARD.md"));
    assert!(resolves(&root, "docs/graph.md"));
    assert!(!resolves(&root, "docs/no_such_contract.md"));
}
