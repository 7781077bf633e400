//! Errors and where they are: byte offsets to line and column, `toml`'s own errors mapped to
//! the path of the key or value they are about (`objects[2].radius`), and the messages tidied.

use super::*;

pub(super) struct Cx<'a> {
    pub(super) src: &'a str,
    pub(super) path: &'a Path,
    pub(super) base_dir: &'a Path,
}

pub(super) type Res<T> = Result<T, SceneError>;

impl Cx<'_> {
    /// 1-based line and column (in characters) of a byte offset.
    pub(super) fn line_col(&self, offset: usize) -> (usize, usize) {
        let mut off = offset.min(self.src.len());
        while !self.src.is_char_boundary(off) {
            off -= 1;
        }
        let before = &self.src[..off];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before[line_start..].chars().count() + 1;
        (line, column)
    }

    pub(super) fn at(&self, span: Range<usize>, field: impl Into<String>, message: impl Into<String>) -> SceneError {
        let (line, column) = self.line_col(span.start);
        SceneError::At { path: self.path.to_path_buf(), line, column, field: field.into(), message: message.into() }
    }

    pub(super) fn too_large(&self, message: String) -> SceneError {
        SceneError::TooLarge { path: self.path.to_path_buf(), message }
    }

    /// A `toml` syntax or deserialization error in our format. With the parsed document, the
    /// field is the path of the innermost key or value at the error's position.
    pub(super) fn toml_error(&self, e: &toml::de::Error, doc: Option<&Spanned<toml::de::DeTable>>) -> SceneError {
        let span = e.span().unwrap_or(0..0);
        let message = tidy_toml_message(e.message());
        let field = match doc {
            None => "toml".to_string(),
            Some(doc) => {
                let missing = message.strip_prefix("missing field `").and_then(|m| m.split('`').next());
                let field = if let Some(key) = missing {
                    // The span is that of the table lacking the key (empty for the root).
                    let mut table = None;
                    find_table(doc.get_ref(), &span, "", &mut table);
                    join(&table.unwrap_or_default(), key)
                } else {
                    let mut best: Option<(usize, usize, String)> = None;
                    find_path(doc.get_ref(), span.start, "", &mut best);
                    best.map(|(_, _, p)| p).unwrap_or_default()
                };
                if field.is_empty() { "toml".to_string() } else { field }
            }
        };
        let message = doc.and_then(|doc| unknown_key_of_type(doc.get_ref(), &field, &message)).unwrap_or(message);
        self.at(span, field, message)
    }

    /// Refuses a file with more `[[objects]]`, `[[materials]]` or `[[lights]]` tables than
    /// accepted by counting their headers, before the document is parsed (parsing a million
    /// objects takes seconds and gigabytes). Lists written inline (`objects = [...]`) are
    /// counted after parsing.
    pub(super) fn prescan_counts(&self) -> Res<()> {
        let limits = [("objects", MAX_OBJECTS), ("materials", MAX_MATERIALS), ("lights", MAX_LIGHTS)];
        let mut counts = [0usize; 3];
        for (i, line) in self.src.lines().enumerate() {
            let t = line.trim();
            let Some(inner) = t.strip_prefix("[[").and_then(|t| t.split_once("]]")).map(|(k, _)| k) else {
                continue;
            };
            let key = inner.trim().trim_matches('"');
            if let Some(k) = limits.iter().position(|(name, _)| *name == key) {
                counts[k] += 1;
                let (name, max) = limits[k];
                if counts[k] > max {
                    return Err(self.too_large(format!(
                        "too many {name}: more than {max} ([[{name}]] table number {} is on line {})",
                        counts[k],
                        i + 1
                    )));
                }
            }
        }
        Ok(())
    }
}

/// For "unknown field `k`, expected one of ..." in `objects[i]` or `lights[i]`: the keys of
/// that object's or light's own type (serde lists every key of every type).
pub(super) fn unknown_key_of_type(doc: &toml::de::DeTable, field: &str, message: &str) -> Option<String> {
    let key = message.strip_prefix("unknown field `")?.split('`').next()?;
    let (list, rest) = field.split_once('[')?;
    let index: usize = rest.split_once(']')?.0.parse().ok()?;
    let entry = match doc.get(list)?.get_ref() {
        toml::de::DeValue::Array(a) => a.get(index)?,
        _ => return None,
    };
    let toml::de::DeValue::Table(t) = entry.get_ref() else { return None };
    let type_name = match t.get("type")?.get_ref() {
        toml::de::DeValue::String(s) => s.to_string(),
        _ => return None,
    };
    let keys: &[&str] = match list {
        "objects" => OBJECT_TYPES.iter().find(|(t, _)| *t == type_name)?.1,
        "lights" => LIGHT_TYPES.iter().find(|(t, _)| *t == type_name)?.1,
        _ => return None,
    };
    let what = if list == "lights" { format!("{type_name} light") } else { type_name };
    let known: Vec<String> = std::iter::once("type").chain(keys.iter().copied()).map(|k| format!("`{k}`")).collect();
    Some(format!("unknown key `{key}` for a {what}; it takes {}", known.join(", ")))
}

pub(super) fn join(path: &str, key: &str) -> String {
    if path.is_empty() { key.to_string() } else { format!("{path}.{key}") }
}

pub(super) fn contains(span: &Range<usize>, off: usize) -> bool {
    (span.start <= off && off < span.end) || (span.start == off && span.end == off)
}

/// Records in `best` the path of the smallest key or value span holding `off` (deeper wins
/// a tie).
pub(super) fn find_path(table: &toml::de::DeTable, off: usize, path: &str, best: &mut Option<(usize, usize, String)>) {
    for (key, value) in table {
        let p = join(path, key.get_ref());
        consider(key.span(), off, &p, best);
        find_in_value(value, off, &p, best);
    }
}

pub(super) fn find_in_value(
    value: &Spanned<toml::de::DeValue>,
    off: usize,
    path: &str,
    best: &mut Option<(usize, usize, String)>,
) {
    consider(value.span(), off, path, best);
    match value.get_ref() {
        toml::de::DeValue::Table(t) => find_path(t, off, path, best),
        toml::de::DeValue::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                find_in_value(v, off, &format!("{path}[{i}]"), best);
            }
        }
        _ => {}
    }
}

/// The path of the (non-root) table whose span is exactly `span`.
pub(super) fn find_table(table: &toml::de::DeTable, span: &Range<usize>, path: &str, found: &mut Option<String>) {
    for (key, value) in table {
        let p = join(path, key.get_ref());
        find_table_in_value(value, span, &p, found);
    }
}

pub(super) fn find_table_in_value(
    value: &Spanned<toml::de::DeValue>,
    span: &Range<usize>,
    path: &str,
    found: &mut Option<String>,
) {
    if found.is_some() {
        return;
    }
    match value.get_ref() {
        toml::de::DeValue::Table(t) => {
            if value.span() == *span && !span.is_empty() {
                *found = Some(path.to_string());
                return;
            }
            find_table(t, span, path, found);
        }
        toml::de::DeValue::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                find_table_in_value(v, span, &format!("{path}[{i}]"), found);
            }
        }
        _ => {}
    }
}

pub(super) fn consider(span: Range<usize>, off: usize, path: &str, best: &mut Option<(usize, usize, String)>) {
    if !contains(&span, off) {
        return;
    }
    let len = span.end - span.start;
    let depth = path.matches(['.', '[']).count();
    let better = match best {
        None => true,
        Some((blen, bdepth, _)) => len < *blen || (len == *blen && depth > *bdepth),
    };
    if better {
        *best = Some((len, depth, path.to_string()));
    }
}

/// Rust type names in serde's messages mean little to someone writing a scene file.
pub(super) fn tidy_toml_message(m: &str) -> String {
    let mut m = m
        .replace("expected f64", "expected a number")
        .replace("expected i64", "expected an integer")
        .replace("expected a sequence", "expected an array");
    for name in
        ["SceneDef", "CameraDef", "ImageDef", "RenderDef", "MaterialDef", "ObjectDef", "LightDef", "EnvironmentDef"]
    {
        m = m.replace(&format!("struct {name}"), "a table");
    }
    m
}

pub(super) fn known_list<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let v: Vec<&str> = names.collect();
    if v.is_empty() { "(none)".to_string() } else { v.join(", ") }
}
