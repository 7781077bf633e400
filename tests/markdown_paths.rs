//! Every repository path the Markdown files name exists. Files move (a module split into a
//! folder, a tool renamed) and the prose that named them goes stale with no compiler to say so.
//!
//! A path counts as named where a word of an inline code span or of a fenced code block
//! starts with one of the repository's top-level entries (`src/`, `tools/`, `Cargo.toml`, ...,
//! read from the root itself, so a new folder is covered without editing this test), and
//! where a link's target is relative (resolved from the Markdown file's folder). Words that
//! start elsewhere (`-o seed.png`, `/out/part-K.exr`) are no repository paths and are left
//! alone; so are paths that leave the repository (`../shared/...`), and globs and
//! placeholders (`tests/*.rs`, `src/geometry/<kind>.rs`, `SCENE.toml`), which stand for many
//! files.

use std::fs;
use std::io::ErrorKind;
use std::path::{Component, Path, PathBuf};
use std::process::Command;

/// Fewer paths than this means the scan has stopped finding them, not that the docs are right.
const MIN_NAMED: usize = 20;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A path named at a line of a Markdown file.
#[derive(Debug)]
struct Named {
    line: usize,
    /// From the repository root (a link's target resolved), or as written where it leaves
    /// the repository.
    path: String,
}

/// What one Markdown file names.
#[derive(Debug, Default)]
struct Scan {
    named: Vec<Named>,
    /// Paths outside the repository: not this repository's to check.
    outside: Vec<Named>,
}

/// The Markdown files git tracks, from the root; without git (or outside a work tree), those
/// found in the tree, leaving out build output and git's own folder.
fn markdown_files() -> Vec<PathBuf> {
    let tracked = Command::new("git")
        .args(["ls-files", "-z", "--", "*.md"])
        .current_dir(root())
        .output()
        .ok()
        .filter(|out| out.status.success())
        .map(|out| {
            out.stdout
                .split(|&b| b == 0)
                .filter(|name| !name.is_empty())
                .map(|name| PathBuf::from(String::from_utf8_lossy(name).as_ref()))
                .collect::<Vec<_>>()
        })
        .unwrap_or_default();
    if !tracked.is_empty() {
        return tracked;
    }
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap_or_default();
            if path.is_dir() {
                if name != "target" && name != ".git" {
                    walk(&path, out);
                }
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path.strip_prefix(root()).unwrap().to_path_buf());
            }
        }
    }
    let mut found = Vec::new();
    walk(&root(), &mut found);
    found.sort();
    found
}

/// The root's entries a repository path starts with: all but build output, git's folder and
/// what git ignores (renders, `.device/`), whose contents differ from one checkout to the next.
fn top_level() -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(root())
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name != "target" && name != ".git")
        .collect();
    let ignored = Command::new("git").arg("check-ignore").arg("-z").args(&names).current_dir(root()).output();
    // Status 1: none of them is ignored; anything but 0 or 1: no git, or no work tree.
    if let Ok(out) = ignored
        && out.status.code() == Some(0)
    {
        let ignored: Vec<&[u8]> = out.stdout.split(|&b| b == 0).collect();
        names.retain(|name| !ignored.contains(&name.as_bytes()));
    }
    names.sort();
    names
}

/// The fence character and length a line of backticks or tildes starts with.
fn fence(line: &str) -> Option<(char, usize)> {
    let line = line.trim_start();
    let c = line.chars().next().filter(|&c| c == '`' || c == '~')?;
    let n = line.chars().take_while(|&x| x == c).count();
    (n >= 3).then_some((c, n))
}

/// The words of `s` with their byte offsets: split at whitespace and at `=`, so that
/// `STRAHL_SHADER_DIR=shaders/` and `path = "assets/..."` give their paths on their own.
fn words(s: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, c) in s.char_indices().chain([(s.len(), ' ')]) {
        let separator = c.is_whitespace() || c == '=';
        match (start, separator) {
            (None, false) => start = Some(i),
            (Some(s0), true) => {
                out.push((s0, &s[s0..i]));
                start = None;
            }
            _ => {}
        }
    }
    out
}

/// The number of backticks in the run starting at `i`.
fn backticks(b: &[u8], i: usize) -> usize {
    b[i..].iter().take_while(|&&c| c == b'`').count()
}

/// Where the run of exactly `n` backticks that closes a code span opened before `from`
/// starts; `None` where a blank line (the paragraph's end) or the text's end comes first.
fn closing(b: &[u8], from: usize, n: usize) -> Option<usize> {
    let mut j = from;
    while j < b.len() {
        match b[j] {
            b'`' => {
                let m = backticks(b, j);
                if m == n {
                    return Some(j);
                }
                j += m;
            }
            b'\n' if b[j + 1..].iter().take_while(|&&c| c != b'\n').all(|c| c.is_ascii_whitespace()) => {
                return None;
            }
            _ => j += 1,
        }
    }
    None
}

/// Where a link's destination that starts at `start` (just after `](`) ends: at whitespace
/// (a title follows) or at the `)` that closes the link; after the `>` of `<...>`.
fn link_end(b: &[u8], start: usize) -> usize {
    let mut j = start;
    if b.get(j) == Some(&b'<') {
        while j < b.len() && b[j] != b'>' && b[j] != b'\n' {
            j += 1;
        }
        return (j + 1).min(b.len());
    }
    let mut depth = 0;
    while j < b.len() {
        match b[j] {
            b'(' => depth += 1,
            b')' if depth == 0 => break,
            b')' => depth -= 1,
            c if c.is_ascii_whitespace() => break,
            _ => {}
        }
        j += 1;
    }
    j
}

/// A word as the path it names: quotes and brackets around it, a trailing `#anchor`,
/// `:LINE` or `:LINE:COLUMN` and trailing punctuation taken off.
fn trim(word: &str) -> &str {
    const TRAILING: [char; 10] = ['.', ',', ';', ':', ')', ']', '"', '\'', '!', '?'];
    let mut p = word.trim_start_matches(['"', '\'', '(', '[']);
    p = p.strip_prefix("./").unwrap_or(p);
    if let Some(i) = p.find('#') {
        p = &p[..i];
    }
    p = p.trim_end_matches(TRAILING);
    while let Some((head, tail)) = p.rsplit_once(':')
        && tail.starts_with(|c: char| c.is_ascii_digit())
        && tail.chars().all(|c| c.is_ascii_digit() || c == '-')
    {
        p = head;
    }
    p.trim_end_matches(TRAILING)
}

/// Whether `path` stands for many files: a glob, an ellipsis, or a placeholder such as
/// `<kind>`, `{a,b}`, `$OUT` or a word in capitals (`NAME`, `DIR`, `SCENE.toml`; not the
/// conventional capitalised file names, which are real files).
fn placeholder(path: &str) -> bool {
    const REAL: [&str; 7] = ["README", "LICENSE", "ARCHITECTURE", "CHANGELOG", "CONTRIBUTING", "COPYING", "NOTICE"];
    let capitals = |part: &str| {
        let stem = part.split('.').next().unwrap_or_default();
        stem.chars().any(|c| c.is_ascii_uppercase())
            && stem.chars().all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_' || c == '-')
            && !REAL.iter().any(|r| stem.starts_with(r))
    };
    path.contains(['*', '?', '{', '}', '<', '>', '[', ']', '$', '…'])
        || path.contains("...")
        || path.split('/').skip(1).any(capitals)
}

/// `path` with `.` and `..` resolved, from the root; `None` where it leaves the repository.
fn normalize(path: &Path) -> Option<String> {
    let mut parts: Vec<&str> = Vec::new();
    for c in path.components() {
        match c {
            Component::Normal(part) => parts.push(part.to_str()?),
            Component::ParentDir => {
                parts.pop()?;
            }
            Component::CurDir => {}
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(parts.join("/"))
}

impl Scan {
    /// A word of a code span or fenced block at `line`: a repository path where it starts
    /// with one of `top`.
    fn word(&mut self, word: &str, line: usize, top: &[String]) {
        let path = trim(word);
        if path.starts_with("../") {
            self.outside.push(Named { line, path: path.to_string() });
            return;
        }
        let first = path.split('/').next().unwrap_or_default();
        if top.iter().any(|t| t == first) && !placeholder(path) {
            self.named.push(Named { line, path: path.to_string() });
        }
    }

    /// A link's destination at `line` of a file in `dir`: a repository path where it is
    /// relative (no web address, no anchor within the file alone).
    fn link(&mut self, target: &str, line: usize, dir: &Path) {
        let target = target.strip_prefix('<').and_then(|t| t.strip_suffix('>')).unwrap_or(target);
        let file = target.split(['#', '?']).next().unwrap_or_default();
        if file.is_empty() || target.contains("://") || target.starts_with("mailto:") || placeholder(file) {
            return;
        }
        let joined = match file.strip_prefix('/') {
            Some(from_root) => PathBuf::from(from_root),
            None => dir.join(file),
        };
        match normalize(&joined) {
            Some(path) => self.named.push(Named { line, path }),
            None => self.outside.push(Named { line, path: target.to_string() }),
        }
    }
}

/// The paths the Markdown `text` of a file in `dir` (from the root) names, in line order.
fn scan(text: &str, dir: &Path, top: &[String]) -> Scan {
    let mut scan = Scan::default();
    // The text outside fenced blocks, a line for each line so that offsets give line numbers.
    let mut prose = String::with_capacity(text.len());
    let mut open: Option<(char, usize)> = None;
    for (i, line) in text.lines().enumerate() {
        match (open, fence(line)) {
            (None, Some(f)) => open = Some(f),
            (Some((c, n)), Some((c2, n2))) if c == c2 && n2 >= n && line.trim().chars().all(|x| x == c) => open = None,
            (Some(_), _) => {
                for (_, word) in words(line) {
                    scan.word(word, i + 1, top);
                }
            }
            (None, None) => {
                // A reference definition, `[label]: target`.
                if let Some(rest) = line.trim_start().strip_prefix('[')
                    && let Some((label, dest)) = rest.split_once("]:")
                    && !label.contains(']')
                    && !label.starts_with('^')
                    && let Some(dest) = dest.split_whitespace().next()
                {
                    scan.link(dest, i + 1, dir);
                }
                prose.push_str(line);
            }
        }
        prose.push('\n');
    }
    let starts: Vec<usize> = std::iter::once(0).chain(prose.match_indices('\n').map(|(i, _)| i + 1)).collect();
    let line_of = |offset: usize| starts.partition_point(|&s| s <= offset);
    let b = prose.as_bytes();
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            // An escaped character opens nothing.
            b'\\' => i += 2,
            b'`' => {
                let n = backticks(b, i);
                match closing(b, i + n, n) {
                    Some(j) => {
                        for (offset, word) in words(&prose[i + n..j]) {
                            scan.word(word, line_of(i + n + offset), top);
                        }
                        i = j + n;
                    }
                    // Unmatched backticks are literal text.
                    None => i += n,
                }
            }
            b']' if b.get(i + 1) == Some(&b'(') => {
                let start = i + 2;
                let end = link_end(b, start);
                scan.link(&prose[start..end], line_of(start), dir);
                i = end;
            }
            _ => i += 1,
        }
    }
    scan.named.sort_by_key(|n| n.line);
    scan.outside.sort_by_key(|n| n.line);
    scan
}

#[test]
fn the_scan_reads_code_spans_fenced_blocks_and_links() {
    let top = ["src".to_string(), "README.md".to_string()];
    let text = "See `src/a.rs:12:5`, `src/b.rs#x`.\n\
                A span over `two\n\
                src/c.rs` lines; [up](../README.md \"title\") and [web](https://example.org/src/x.rs).\n\
                \n\
                ```sh\n\
                strahl render src/d.toml -o seed.png\n\
                ```\n\
                `src/*.rs`, `src/NAME.toml`, `src/{a,b}.rs`, `../shared/x`, \\`src/e.rs\\`; `README.md`.\n\
                [out](../../y)\n";
    let scan = scan(text, Path::new("docs"), &top);
    let named: Vec<(usize, &str)> = scan.named.iter().map(|n| (n.line, n.path.as_str())).collect();
    assert_eq!(
        named,
        [(1, "src/a.rs"), (1, "src/b.rs"), (3, "src/c.rs"), (3, "README.md"), (6, "src/d.toml"), (8, "README.md")]
    );
    let outside: Vec<(usize, &str)> = scan.outside.iter().map(|n| (n.line, n.path.as_str())).collect();
    assert_eq!(outside, [(8, "../shared/x"), (9, "../../y")]);
}

#[test]
fn every_repository_path_the_markdown_files_name_exists() {
    let root = root();
    let top = top_level();
    let mut checked = 0;
    let mut missing = Vec::new();
    let mut outside = Vec::new();
    for file in markdown_files() {
        let text = match fs::read_to_string(root.join(&file)) {
            Ok(text) => text,
            // Tracked but deleted in the work tree: it names nothing any more.
            Err(e) if e.kind() == ErrorKind::NotFound => continue,
            Err(e) => panic!("{}: {e}", file.display()),
        };
        let scan = scan(&text, file.parent().unwrap_or(Path::new("")), &top);
        checked += scan.named.len();
        for n in scan.named {
            if !root.join(&n.path).exists() {
                missing.push(format!("{}:{}: {}", file.display(), n.line, n.path));
            }
        }
        outside.extend(scan.outside.iter().map(|n| format!("{}:{}: {}", file.display(), n.line, n.path)));
    }
    if !outside.is_empty() {
        eprintln!("named outside the repository, not checked:\n  {}", outside.join("\n  "));
    }
    assert!(missing.is_empty(), "{} named paths do not exist:\n  {}", missing.len(), missing.join("\n  "));
    assert!(checked >= MIN_NAMED, "only {checked} repository paths found in {top:?}-rooted Markdown text");
}
