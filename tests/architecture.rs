//! ARCHITECTURE.md's table of WGSL files and their Rust twins agrees with the shaders: every
//! WGSL file has a row, each row names the Rust files that the shader's first comment names
//! (its twin, or "none" where the comment says it has no CPU twin, with its host), and every
//! named file exists. It also checks the layering: no import circles within a crate, and no
//! source file outside `tests/` over 800 lines; and the Python package builds its dependencies
//! with the features the workspace builds them with, so that its build reuses theirs.

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

/// The Rust modules of one crate's `src/` folder: module path (`accel::bvh`, "" for the crate
/// root) → the file's text before its first `#[cfg(test)]` module, without comment lines.
/// Files named `tests.rs` are test modules and left out.
fn crate_modules(src: &Path) -> BTreeMap<String, String> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    walk(src, &mut files);
    let mut mods = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(src).unwrap().with_extension("");
        let mut segs: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
        if segs.last().is_some_and(|s| s == "tests") {
            continue;
        }
        if segs.last().is_some_and(|s| s == "mod" || s == "lib" || s == "main") {
            segs.pop();
        }
        let text = std::fs::read_to_string(&f).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let end = (0..lines.len())
            .find(|&i| lines[i].trim() == "#[cfg(test)]" && lines.get(i + 1).is_some_and(|l| l.contains("mod ")))
            .unwrap_or(lines.len());
        let code: Vec<&str> = lines[..end].iter().copied().filter(|l| !l.trim_start().starts_with("//")).collect();
        mods.insert(segs.join("::"), code.join("\n"));
    }
    mods
}

/// The identifier path that starts at `s` (`a::b::{c, d::e}` gives `a::b::c` and `a::b::d::e`).
fn paths_at(s: &str) -> Vec<String> {
    let ident = |t: &str| t.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(t.len());
    let mut base = Vec::new();
    let mut rest = s;
    loop {
        let n = ident(rest);
        if n == 0 {
            break;
        }
        base.push(&rest[..n]);
        rest = &rest[n..];
        if let Some(r) = rest.strip_prefix("::") {
            rest = r;
        } else {
            break;
        }
    }
    let joined = base.join("::");
    if !rest.starts_with('{') {
        return vec![joined];
    }
    let inner = &rest[1..rest.find('}').unwrap_or(rest.len())];
    let mut out: Vec<String> = inner
        .split(',')
        .map(str::trim)
        .filter(|i| !i.is_empty() && *i != "self" && !i.starts_with('{'))
        .map(|i| format!("{joined}::{}", &i[..ident(i)]))
        .collect();
    out.push(joined);
    out
}

/// Which modules each module of `mods` names through `crate::` or `super::` paths, resolved
/// to the longest module prefix; a module's own ancestors are not counted (a file sits in
/// its folder's module).
fn import_graph(mods: &BTreeMap<String, String>) -> BTreeMap<String, BTreeSet<String>> {
    let resolve = |path: &str| {
        let segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
        (1..=segs.len()).rev().map(|i| segs[..i].join("::")).find(|m| mods.contains_key(m))
    };
    let mut graph = BTreeMap::new();
    for (m, code) in mods {
        let mut to = BTreeSet::new();
        let parent = m.rsplit_once("::").map_or("", |(p, _)| p);
        for (prefix, base) in [("crate::", String::new()), ("super::", parent.to_string())] {
            let mut from = 0;
            while let Some(i) = code[from..].find(prefix).map(|i| i + from) {
                from = i + prefix.len();
                if code[..i].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_') {
                    continue;
                }
                for p in paths_at(&code[from..]) {
                    let full = if base.is_empty() { p } else { format!("{base}::{p}") };
                    if let Some(r) = resolve(&full) {
                        let ancestor = r.is_empty() || m.starts_with(&format!("{r}::"));
                        if r != *m && !ancestor {
                            to.insert(r);
                        }
                    }
                }
            }
        }
        graph.insert(m.clone(), to);
    }
    graph
}

/// The circles of `graph`: its strongly connected components of more than one module.
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    // Two modules are on a circle when each reaches the other.
    let reach = |start: &String| {
        let mut seen = BTreeSet::new();
        let mut stack = vec![start.clone()];
        while let Some(m) = stack.pop() {
            for n in &graph[&m] {
                if seen.insert(n.clone()) {
                    stack.push(n.clone());
                }
            }
        }
        seen
    };
    let reaches: BTreeMap<&String, BTreeSet<String>> = graph.keys().map(|m| (m, reach(m))).collect();
    let mut done = BTreeSet::new();
    let mut out = Vec::new();
    for m in graph.keys() {
        if done.contains(m) {
            continue;
        }
        let comp: Vec<String> =
            graph.keys().filter(|n| *n == m || (reaches[m].contains(*n) && reaches[n].contains(m))).cloned().collect();
        done.extend(comp.iter().cloned());
        if comp.len() > 1 {
            out.push(comp);
        }
    }
    out
}

fn crate_sources() -> Vec<PathBuf> {
    let mut v = vec![root().join("src")];
    for e in std::fs::read_dir(root().join("crates")).unwrap() {
        let p = e.unwrap().path().join("src");
        if p.is_dir() {
            v.push(p);
        }
    }
    v.sort();
    v
}

#[test]
fn no_module_imports_one_that_imports_it_back() {
    let sources = crate_sources();
    assert!(sources.len() >= 5, "found only {sources:?}");
    let mut found = Vec::new();
    for src in &sources {
        let mods = crate_modules(src);
        assert!(mods.contains_key(""), "{src:?} has no crate root");
        for c in circles(&import_graph(&mods)) {
            found.push(format!("{}: {}", src.strip_prefix(root()).unwrap().display(), c.join(" ⇄ ")));
        }
    }
    assert!(found.is_empty(), "import circles:\n{}", found.join("\n"));
}

#[test]
fn the_circle_finder_finds_circles_through_braces_and_super() {
    let mods: BTreeMap<String, String> = [
        ("", "pub mod a; pub mod b;"),
        ("a", "use crate::b::{x, c::y};"),
        ("b", "fn f() { super::a::g() }"),
        ("b::c", "use super::super::d;"),
        ("d", "use crate::b::c::Z;"),
        ("e", "use crate::{a, d};"),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v.to_string()))
    .collect();
    let g = import_graph(&mods);
    assert_eq!(g["a"], BTreeSet::from(["b".to_string(), "b::c".to_string()]));
    assert_eq!(g["e"], BTreeSet::from(["a".to_string(), "d".to_string()]));
    let c = circles(&g);
    assert_eq!(c, vec![vec!["a".to_string(), "b".to_string()]], "{g:?}");
}

/// No source file outside `tests/` is longer than this: a longer one holds more than one room.
const MAX_LINES: usize = 800;

#[test]
fn no_source_file_outside_tests_is_over_800_lines() {
    let out = std::process::Command::new("git").args(["ls-files", "-z"]).current_dir(root()).output().unwrap();
    assert!(out.status.success(), "git ls-files failed");
    let mut long = Vec::new();
    let mut checked = 0;
    for name in out.stdout.split(|&b| b == 0).filter(|n| !n.is_empty()) {
        let name = String::from_utf8_lossy(name).into_owned();
        let source = name.ends_with(".rs") || name.ends_with(".wgsl") || name.starts_with("tools/");
        if !source || name.starts_with("tests/") || !root().join(&name).is_file() {
            continue;
        }
        checked += 1;
        let lines = std::fs::read_to_string(root().join(&name)).map(|t| t.lines().count()).unwrap_or(0);
        if lines > MAX_LINES {
            long.push(format!("{name}: {lines} lines"));
        }
    }
    assert!(checked >= 100, "checked only {checked} files");
    assert!(long.is_empty(), "over {MAX_LINES} lines:\n{}", long.join("\n"));
}

/// No function outside tests is longer than this: a longer one is several steps that want
/// names of their own.
const MAX_FN_LINES: usize = 150;

/// The functions of Rust source `code` with their lengths in lines (from the line of `fn` to
/// the closing brace), up to the file's first `#[cfg(test)]`. Braces in strings, character
/// literals and comments are skipped.
fn function_lengths(code: &str) -> Vec<(String, usize)> {
    let code = code.split("#[cfg(test)]").next().unwrap_or("");
    // The code with strings, characters and comments blanked (newlines kept).
    let mut plain = String::with_capacity(code.len());
    let mut chars = code.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '/' if chars.peek() == Some(&'/') => {
                for d in chars.by_ref() {
                    if d == '\n' {
                        plain.push('\n');
                        break;
                    }
                }
            }
            '"' => {
                let mut escaped = false;
                for d in chars.by_ref() {
                    if d == '\n' {
                        plain.push('\n');
                    }
                    if !escaped && d == '"' {
                        break;
                    }
                    escaped = !escaped && d == '\\';
                }
                plain.push(' ');
            }
            // A character literal ('{', '\''), not a lifetime ('a).
            '\'' if chars.clone().take(2).collect::<String>().ends_with('\'') || chars.peek() == Some(&'\\') => {
                let mut escaped = false;
                for d in chars.by_ref() {
                    if !escaped && d == '\'' {
                        break;
                    }
                    escaped = !escaped && d == '\\';
                }
                plain.push(' ');
            }
            c => plain.push(c),
        }
    }
    let mut out = Vec::new();
    let bytes = plain.as_bytes();
    let mut from = 0;
    while let Some(i) = plain[from..].find("fn ").map(|i| i + from) {
        from = i + 3;
        if i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_') {
            continue;
        }
        let name: String = plain[from..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
        // The body: the first brace before any semicolon (none for a declaration).
        let (Some(open), semi) = (plain[from..].find('{'), plain[from..].find(';')) else { continue };
        if semi.is_some_and(|s| s < open) {
            continue;
        }
        let mut depth = 0;
        let mut end = from + open;
        for (j, b) in bytes[from + open..].iter().enumerate() {
            match b {
                b'{' => depth += 1,
                b'}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = from + open + j;
                        break;
                    }
                }
                _ => {}
            }
        }
        out.push((name, plain[i..=end].lines().count()));
    }
    out
}

#[test]
fn no_function_outside_tests_is_over_150_lines() {
    let out = std::process::Command::new("git").args(["ls-files", "-z"]).current_dir(root()).output().unwrap();
    let mut long = Vec::new();
    let mut checked = 0;
    for name in out.stdout.split(|&b| b == 0).filter(|n| !n.is_empty()) {
        let name = String::from_utf8_lossy(name).into_owned();
        let in_tests = name.starts_with("tests/") || name.contains("/tests/") || name.ends_with("/tests.rs");
        if !name.ends_with(".rs") || in_tests || name.starts_with("benches/") || !root().join(&name).is_file() {
            continue;
        }
        let code = std::fs::read_to_string(root().join(&name)).unwrap();
        for (f, lines) in function_lengths(&code) {
            checked += 1;
            if lines > MAX_FN_LINES {
                long.push(format!("{name}: fn {f}: {lines} lines"));
            }
        }
    }
    assert!(checked >= 1000, "checked only {checked} functions");
    assert!(long.is_empty(), "over {MAX_FN_LINES} lines:\n{}", long.join("\n"));
}

#[test]
fn function_lengths_count_from_fn_to_its_brace_past_braces_in_strings() {
    let code = "fn a() {\n    let s = \"}\";\n    let c = '{';\n    // }\n}\nfn b<'x>(v: &'x u8);\nimpl T { fn c(&self) {\n} }\n#[cfg(test)]\nfn d() {}";
    assert_eq!(function_lengths(code), vec![("a".to_string(), 5), ("c".to_string(), 2)]);
}

/// `cargo tree`'s lines (`name vX.Y.Z [features]`) for the given selection, host platform.
fn tree_lines(selection: &[&str], edges: &str) -> BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args(["tree", "--offline", "--locked", "-e", edges, "-f", "{p} [{f}]", "--prefix", "none"])
        .args(selection)
        .current_dir(root())
        .output()
        .expect("cargo tree runs");
    assert!(out.status.success(), "cargo tree {selection:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap().lines().map(|l| l.replace(" (*)", "").replace(" (proc-macro)", "")).collect()
}

/// `pip install ./python` builds strahl-python alone, and cargo turns on in each dependency only
/// the features that package's own graph asks for. Where that differs from the whole workspace's
/// test build (`cargo test --workspace --all-targets`, dev-dependencies included), every crate
/// above the dependency is built again: .ci/run once spent 14 minutes so. python/Cargo.toml names
/// the missing features; this checks that each package of its graph, with its features, is one
/// the workspace's build has too.
#[test]
fn the_python_package_builds_its_dependencies_as_the_workspace_does() {
    let workspace = tree_lines(&["--workspace"], "normal,build,dev");
    let python = tree_lines(&["-p", "strahl-python"], "normal,build");
    let differ: Vec<_> =
        python.iter().filter(|l| !l.starts_with("strahl-python ") && !workspace.contains(*l)).collect();
    assert!(
        differ.is_empty(),
        "these dependencies of strahl-python have other features than in the workspace's build; name the \
         workspace's features in python/Cargo.toml: {differ:#?}"
    );
}
