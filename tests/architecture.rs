//! ARCHITECTURE.md's table of WGSL files and their Rust twins agrees with the shaders: every
//! WGSL file has a row, each row names the Rust files that the shader's first comment names
//! (its twin, or "none" where the comment says it has no CPU twin, with its host), and every
//! named file exists.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Rust source paths in `text` (`src/...rs` or `crates/NAME/src/...rs`), in order of first appearance.
fn rust_paths(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut from = 0;
    while let Some(i) = text[from..].find("src/").map(|i| i + from) {
        let tail = &text[i..];
        let end =
            tail.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '/' || c == '.')).unwrap_or(tail.len());
        let path = tail[..end].trim_end_matches('.');
        // The crate folder in front, if the path is written from the repository root.
        let head = &text[..i];
        let start = head
            .rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '/'))
            .map_or(0, |j| j + head[j..].chars().next().map_or(1, char::len_utf8));
        let prefix = &head[start..];
        if path.ends_with(".rs") && (prefix.is_empty() || prefix.starts_with("crates/")) {
            out.insert(format!("{prefix}{path}"));
        }
        from = i + 4;
    }
    out
}

/// Every `.wgsl` file under `crates/gpu/shaders/`, as a path from the repository root.
fn wgsl_files() -> Vec<String> {
    fn walk(dir: &Path, out: &mut Vec<String>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "wgsl") {
                out.push(p.strip_prefix(root()).unwrap().to_string_lossy().replace('\\', "/"));
            }
        }
    }
    let mut v = Vec::new();
    walk(&root().join("crates/gpu/shaders"), &mut v);
    v.sort();
    v
}

/// The leading `//` comment of a WGSL file, joined into one line.
fn header(file: &str) -> String {
    let text = std::fs::read_to_string(root().join(file)).unwrap();
    text.lines()
        .take_while(|l| l.starts_with("//"))
        .map(|l| l.trim_start_matches('/').trim())
        .collect::<Vec<_>>()
        .join(" ")
}

/// ARCHITECTURE.md's rows: WGSL file → (Rust files named, "none" row).
fn table() -> BTreeMap<String, (BTreeSet<String>, bool)> {
    let text = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let mut rows = BTreeMap::new();
    for line in text.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 4 || !cells[1].starts_with("`crates/gpu/shaders/") {
            continue;
        }
        let wgsl = cells[1].trim_matches('`').to_string();
        let none = cells[2].starts_with("none");
        assert!(rows.insert(wgsl.clone(), (rust_paths(cells[2]), none)).is_none(), "{wgsl} has two rows");
    }
    rows
}

#[test]
fn the_twin_table_matches_the_shader_headers_and_the_files_exist() {
    let rows = table();
    let files = wgsl_files();
    assert!(files.len() >= 20, "found only {files:?}");
    for f in &files {
        let h = header(f);
        let named = rust_paths(&h);
        let no_twin = h.contains("No CPU twin") || h.contains("no CPU twin");
        assert!(no_twin || h.contains("twin of") || h.contains("twins of"), "{f}: its first comment names no twin");
        assert!(!named.is_empty(), "{f}: its first comment names no Rust file (twin or host)");
        for p in &named {
            assert!(root().join(p).is_file(), "{f} names {p}, which does not exist");
        }
        let Some((listed, none)) = rows.get(f) else { panic!("ARCHITECTURE.md has no row for {f}") };
        assert_eq!(listed, &named, "{f}: ARCHITECTURE.md lists other files than its header");
        assert_eq!(*none, no_twin, "{f}: ARCHITECTURE.md and the header disagree on whether it has a CPU twin");
    }
    let extra: Vec<_> = rows.keys().filter(|k| !files.contains(k)).collect();
    assert!(extra.is_empty(), "rows for WGSL files that do not exist: {extra:?}");
}

#[test]
fn the_path_finder_reads_paths_as_written() {
    let got = rust_paths(
        "twin of crates/core/src/render/path.rs (radiance) and src/main.rs. Also src/x/, `crates/gpu/src/lib.rs`.",
    );
    let want = ["crates/core/src/render/path.rs", "crates/gpu/src/lib.rs", "src/main.rs"];
    assert_eq!(got, want.iter().map(|s| s.to_string()).collect::<BTreeSet<_>>());
}
