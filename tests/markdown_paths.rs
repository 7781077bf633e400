//! Every repository path the Markdown files name exists. Files move (a module split into a
//! folder, a tool renamed) and the prose that named them goes stale with no compiler to say so.
//!
//! A path counts as named where a word of an inline code span or of a fenced code block
//! starts with one of the repository's top-level entries (`src/`, `tools/`, `Cargo.toml`, ...,
//! read from the root itself, so a new folder is covered without editing this test), and
//! where a link's target is relative (resolved from the Markdown file's folder). Words that
//! start elsewhere (`-o seed.png`, `/out/part-K.exr`) are no repository paths and are left
//! alone; so are paths that leave the repository (`../shared/...`), and globs and
//! placeholders (`tests/*.rs`, `crates/core/src/geometry/<kind>.rs`, `SCENE.toml`), which stand for many
//! files.
//!
//! Links are checked further, since a renamed heading breaks them as silently as a moved file:
//! a relative link's `#fragment` into a Markdown file (or `#fragment` alone, into its own file)
//! must be the id of one of that file's headings, by the slug rule mdBook and GitHub share
//! ([`slug`]). The book in `docs/` (mdBook) has two rules of its own: its chapters link only
//! within `docs/src/` (mdBook publishes nothing else, and turns every `.md` link into `.html`),
//! and `docs/src/SUMMARY.md` lists every chapter there is, each of which exists.
//! `tools/check-docs` runs this test after building the book.

use std::collections::HashSet;
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

/// A relative link of a Markdown file.
#[derive(Debug)]
struct Link {
    line: usize,
    /// The target from the repository root; empty for a link to a heading of the file itself.
    path: String,
    /// What follows `#`, if anything.
    fragment: Option<String>,
}

/// What one Markdown file names.
#[derive(Debug, Default)]
struct Scan {
    named: Vec<Named>,
    /// Paths outside the repository: not this repository's to check.
    outside: Vec<Named>,
    /// Every relative link (within the repository), in line order.
    links: Vec<Link>,
}

/// The book's sources: mdBook publishes this folder and nothing else.
const BOOK_SRC: &str = "docs/src";
/// mdBook's output folder (`build-dir` in `docs/book.toml`), whatever git makes of it.
const BOOK_OUT: &str = "docs/book";

/// The Markdown files git tracks or would add (new files that no `.gitignore` rule covers),
/// from the root, and every one under [`BOOK_SRC`], so that a chapter written but not yet
/// added is checked too; without git (or outside a work tree), those found in the tree,
/// leaving out build output and git's own folder. Never the book's build output.
fn markdown_files() -> Vec<PathBuf> {
    let mut files = git_or_walked_markdown_files();
    let book = root().join(BOOK_SRC);
    if book.is_dir() {
        walk(&book, &mut files);
    }
    files.retain(|f| !f.starts_with(BOOK_OUT));
    files.sort();
    files.dedup();
    files
}

/// The Markdown files below `dir` (absolute), from the root, leaving out build output and
/// git's own folder.
fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for path in entries {
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

fn git_or_walked_markdown_files() -> Vec<PathBuf> {
    let tracked = Command::new("git")
        .args(["ls-files", "-z", "--cached", "--others", "--exclude-standard", "--", "*.md"])
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
    let mut found = Vec::new();
    walk(&root(), &mut found);
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
        let fragment = target.split_once('#').map(|(_, f)| f.to_string());
        if target.contains("://") || target.starts_with("mailto:") || placeholder(file) {
            return;
        }
        if file.is_empty() {
            // `#heading`: within the file itself.
            if fragment.is_some() {
                self.links.push(Link { line, path: String::new(), fragment });
            }
            return;
        }
        let joined = match file.strip_prefix('/') {
            Some(from_root) => PathBuf::from(from_root),
            None => dir.join(file),
        };
        match normalize(&joined) {
            Some(path) => {
                self.links.push(Link { line, path: path.clone(), fragment });
                self.named.push(Named { line, path });
            }
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
    scan.links.sort_by_key(|n| n.line);
    scan
}

/// A heading's id, as mdBook (`id_from_content`) and GitHub make it from the heading's text:
/// lowercase; letters, digits, `_` and `-` kept; each whitespace character a `-`; everything
/// else (punctuation, symbols) dropped. Markup is gone before: see [`heading_text`].
fn slug(text: &str) -> String {
    text.trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| {
            if c.is_alphanumeric() || c == '_' || c == '-' {
                Some(c)
            } else if c.is_whitespace() {
                Some('-')
            } else {
                None
            }
        })
        .collect()
}

/// The text of an ATX heading's content as rendered: code spans' backticks, links' and
/// images' targets and brackets, and emphasis asterisks taken off. (Underscore emphasis and
/// inline HTML are not undone: headings here do not use them.)
fn heading_text(content: &str) -> String {
    let b = content.as_bytes();
    let mut out = String::new();
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'\\' if i + 1 < b.len() => {
                out.push(content[i + 1..].chars().next().unwrap());
                i += 1 + content[i + 1..].chars().next().unwrap().len_utf8();
            }
            b'`' => {
                let n = backticks(b, i);
                match content[i + n..].find(&"`".repeat(n)) {
                    Some(j) => {
                        out.push_str(&content[i + n..i + n + j]);
                        i += n + j + n;
                    }
                    None => {
                        out.push_str(&content[i..i + n]);
                        i += n;
                    }
                }
            }
            b'*' => i += 1,
            b'!' if b.get(i + 1) == Some(&b'[') => i += 1,
            b']' if b.get(i + 1) == Some(&b'(') => {
                // The link's text is out already; its destination (and title) is not text.
                let end = link_end(b, i + 2);
                i = content[end..].find(')').map_or(b.len(), |k| end + k + 1);
            }
            b'[' | b']' => {
                // Brackets of a link's text vanish; other brackets are text (and the slug
                // drops them anyway).
                i += 1;
            }
            _ => {
                let c = content[i..].chars().next().unwrap();
                out.push(c);
                i += c.len_utf8();
            }
        }
    }
    out
}

/// The ids of the headings of the Markdown `text`, in order: ATX headings (`#` to `######`)
/// outside fenced blocks, each the [`slug`] of its text or an explicit `{#id}` at its end; a
/// repeated id gets `-1`, `-2`, ... as in mdBook and GitHub. Setext headings (text underlined
/// with `===` or `---`) are not read: the files here do not use them.
fn heading_ids(text: &str) -> Vec<String> {
    let mut ids = Vec::new();
    let mut used = HashSet::new();
    let mut open: Option<(char, usize)> = None;
    for line in text.lines() {
        match (open, fence(line)) {
            (None, Some(f)) if line.len() - line.trim_start().len() < 4 => {
                open = Some(f);
                continue;
            }
            (Some((c, n)), Some((c2, n2))) if c == c2 && n2 >= n && line.trim().chars().all(|x| x == c) => {
                open = None;
                continue;
            }
            (Some(_), _) => continue,
            _ => {}
        }
        let indent = line.len() - line.trim_start_matches(' ').len();
        let rest = &line[indent..];
        let level = rest.chars().take_while(|&c| c == '#').count();
        if indent > 3 || !(1..=6).contains(&level) {
            continue;
        }
        let after = &rest[level..];
        if !after.is_empty() && !after.starts_with([' ', '\t']) {
            continue; // `#tag`, not a heading
        }
        // A closing run of `#`, where a space precedes it (or it is all there is).
        let mut content = after.trim();
        let stripped = content.trim_end_matches('#');
        if stripped.is_empty() || stripped.ends_with([' ', '\t']) {
            content = stripped.trim_end();
        }
        let base = match content.strip_suffix('}').and_then(|c| c.rsplit_once("{#")) {
            Some((_, attrs)) => attrs.split_whitespace().next().unwrap_or_default().to_string(),
            None => slug(&heading_text(content)),
        };
        let mut id = base.clone();
        let mut k = 0;
        while !used.insert(id.clone()) {
            k += 1;
            id = format!("{base}-{k}");
        }
        ids.push(id);
    }
    ids
}

/// The chapters `SUMMARY.md` lists (from the root), in its order.
fn summary_chapters(summary: &str) -> Vec<(usize, String)> {
    let top = top_level();
    scan(summary, Path::new(BOOK_SRC), &top)
        .links
        .into_iter()
        .filter(|l| !l.path.is_empty())
        .map(|l| (l.line, l.path))
        .collect()
}

/// Every Markdown file's text, by its path from the root, each read once.
fn read_all() -> Vec<(PathBuf, String)> {
    markdown_files()
        .into_iter()
        .filter_map(|file| match fs::read_to_string(root().join(&file)) {
            Ok(text) => Some((file, text)),
            Err(e) if e.kind() == ErrorKind::NotFound => None,
            Err(e) => panic!("{}: {e}", file.display()),
        })
        .collect()
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

#[test]
fn headings_get_the_ids_mdbook_and_github_give_them() {
    assert_eq!(slug("Choosing the backend"), "choosing-the-backend");
    assert_eq!(slug("glTF against Blender's Cycles"), "gltf-against-blenders-cycles");
    assert_eq!(slug("strahl bench: lavapipe, the CPU backend"), "strahl-bench-lavapipe-the-cpu-backend");
    assert_eq!(slug("  Big scenes: BVH, CPU traversal, memory "), "big-scenes-bvh-cpu-traversal-memory");
    assert_eq!(slug("a — b"), "a--b");
    assert_eq!(slug("snake_case and kebab-case"), "snake_case-and-kebab-case");
    assert_eq!(slug("Über 10⁶ × 2"), "über-10⁶--2");
    assert_eq!(
        heading_text("`[[objects]]` (optional, at most 1,000,000)"),
        "[[objects]] (optional, at most 1,000,000)"
    );
    assert_eq!(slug(&heading_text("`[[objects]]` (optional, at most 1,000,000)")), "objects-optional-at-most-1000000");
    assert_eq!(heading_text("See [the *book*](docs/x.md \"t\") and ![a](i.png)"), "See the book and a");
    assert_eq!(heading_text(r"a \# b"), "a # b");
    let text = "# Title\n\
                ## Files ##\n\
                ```md\n\
                # not a heading\n\
                ```\n\
                ## Files\n\
                #hashtag\n    # indented code\n\
                ### `strahl render`\n\
                ## Files\n\
                ## Custom {#my-id}\n\
                ##\n\
                ###### Six #\n";
    assert_eq!(heading_ids(text), ["title", "files", "files-1", "strahl-render", "files-2", "my-id", "", "six"]);
}

#[test]
fn the_scan_records_links_with_their_fragments() {
    let top = ["src".to_string()];
    let text = "[a](#here) [b](other.md#there) [c](../up.md) [d](img/x.png) [e](https://x.org/#y)\n";
    let scan = scan(text, Path::new("docs/src"), &top);
    let links: Vec<(&str, Option<&str>)> =
        scan.links.iter().map(|l| (l.path.as_str(), l.fragment.as_deref())).collect();
    assert_eq!(
        links,
        [("", Some("here")), ("docs/src/other.md", Some("there")), ("docs/up.md", None), ("docs/src/img/x.png", None)]
    );
}

#[test]
fn every_link_fragment_names_a_heading_of_its_file() {
    let root = root();
    let top = top_level();
    let files = read_all();
    let mut ids_of = std::collections::HashMap::new();
    let mut checked = 0;
    let mut broken = Vec::new();
    for (file, text) in &files {
        let scan = scan(text, file.parent().unwrap_or(Path::new("")), &top);
        for link in scan.links {
            let Some(fragment) = link.fragment.filter(|f| !f.is_empty()) else { continue };
            let target = if link.path.is_empty() { file.to_string_lossy().into_owned() } else { link.path };
            if !target.ends_with(".md") {
                continue; // a source file's `#L12` and the like: not headings
            }
            let ids = ids_of.entry(target.clone()).or_insert_with(|| {
                // A missing file is the path check's to report.
                fs::read_to_string(root.join(&target)).ok().map(|t| heading_ids(&t))
            });
            let Some(ids) = ids else { continue };
            checked += 1;
            if !ids.contains(&fragment) {
                broken.push(format!("{}:{}: {target}#{fragment}: no such heading", file.display(), link.line));
            }
        }
    }
    assert!(broken.is_empty(), "{} links name no heading:\n  {}", broken.len(), broken.join("\n  "));
    if root.join(BOOK_SRC).is_dir() {
        assert!(checked > 0, "no link with a #fragment found: the scan has stopped finding them");
    }
}

#[test]
fn the_book_links_only_within_itself_and_its_summary_lists_every_chapter() {
    let root = root();
    let book = root.join(BOOK_SRC);
    if !book.is_dir() {
        return;
    }
    let top = top_level();
    let mut wrong = Vec::new();
    for (file, text) in read_all().iter().filter(|(f, _)| f.starts_with(BOOK_SRC)) {
        for link in scan(text, file.parent().unwrap(), &top).links {
            if link.path.is_empty() {
                continue;
            }
            if !Path::new(&link.path).starts_with(BOOK_SRC) {
                wrong.push(format!(
                    "{}:{}: {}: outside {BOOK_SRC}, which is all mdBook publishes (name the file in a code span)",
                    file.display(),
                    link.line,
                    link.path
                ));
            } else if link.path.ends_with(".md") && !root.join(&link.path).is_file() {
                wrong.push(format!("{}:{}: {}: no such chapter", file.display(), link.line, link.path));
            }
        }
    }
    let summary_path = format!("{BOOK_SRC}/SUMMARY.md");
    let summary = fs::read_to_string(root.join(&summary_path)).expect("the book has a SUMMARY.md");
    let chapters = summary_chapters(&summary);
    assert!(!chapters.is_empty(), "{summary_path} lists no chapter");
    let mut listed = HashSet::new();
    for (line, chapter) in &chapters {
        if !chapter.ends_with(".md") || !root.join(chapter).is_file() {
            wrong.push(format!("{summary_path}:{line}: {chapter}: no such chapter"));
        }
        if !listed.insert(chapter.clone()) {
            wrong.push(format!("{summary_path}:{line}: {chapter}: listed twice"));
        }
    }
    let mut in_book = Vec::new();
    walk(&book, &mut in_book);
    for file in in_book {
        let name = file.to_string_lossy().into_owned();
        if name != summary_path && !listed.contains(&name) {
            wrong.push(format!("{name}: not listed in {summary_path}, so mdBook leaves it out"));
        }
    }
    assert!(wrong.is_empty(), "{} problems with the book:\n  {}", wrong.len(), wrong.join("\n  "));
}
