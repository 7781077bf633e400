//! A file's bytes to a glTF document: the JSON read leniently where real exporters stray
//! from the schema, checked, and its buffers loaded.

use super::*;

/// The document and GLB binary chunk of `bytes`. Where the gltf crate's reading refuses the
/// JSON, it is read again without `animations`, which strahl does not read and where the crate
/// is stricter than the specification (a channel's `target.node` may be absent where an
/// extension names the animated object).
pub(super) fn parse(bytes: &[u8]) -> Res<(gltf::Gltf, Vec<String>)> {
    let mut notes = Vec::new();
    // A GLB whose header gives a length shorter than the file: the rest is not the file's
    // (the specification defines the length as the whole GLB's).
    let mut bytes = bytes;
    if bytes.len() >= 12 && bytes.starts_with(b"glTF") {
        let length = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
        if length < 12 {
            return Err(format!("broken GLB container: its header gives a length of {length} bytes"));
        }
        if length < bytes.len() {
            notes.push(format!("{} bytes after the GLB's length ({length}) are ignored", bytes.len() - length));
            bytes = &bytes[..length];
        }
    }
    let refused = match gltf::Gltf::from_slice_without_validation(bytes) {
        Ok(g) => return Ok((g, notes)),
        Err(e @ gltf::Error::Deserialize(_)) => describe_error(e),
        Err(e) => return Err(describe_error(e)),
    };
    let (json, blob) = if bytes.starts_with(b"glTF") {
        let glb = gltf::binary::Glb::from_slice(bytes).map_err(describe_error)?;
        (glb.json.into_owned(), glb.bin.map(|b| b.into_owned()))
    } else {
        (bytes.to_vec(), None)
    };
    let mut value: serde_json::Value = serde_json::from_slice(&json).map_err(|_| refused.clone())?;
    if !lenient(&mut value) {
        return Err(refused);
    }
    let root: gltf::json::Root =
        serde_json::from_value(value).map_err(|e| describe_error(gltf::Error::Deserialize(e)))?;
    Ok((gltf::Gltf { document: gltf::Document::from_json_without_validation(root), blob }, notes))
}

/// Rewrites in `value` (a glTF file's JSON) what the specification allows and the crate's
/// reading refuses: animations (which strahl does not read; the crate requires a channel
/// target's `node`, which the specification does not), a scene without `nodes`, integers
/// written as floats (`1.0`, `1e0`; the specification allows them). Returns whether anything
/// changed.
pub(super) fn lenient(value: &mut serde_json::Value) -> bool {
    use serde_json::Value;
    let mut changed = false;
    if let Some(root) = value.as_object_mut() {
        changed |= root.remove("animations").is_some();
        if let Some(Value::Array(scenes)) = root.get_mut("scenes") {
            for scene in scenes.iter_mut().filter_map(Value::as_object_mut) {
                if !scene.contains_key("nodes") {
                    scene.insert("nodes".into(), Value::Array(Vec::new()));
                    changed = true;
                }
            }
        }
    }
    pub(super) fn integers(v: &mut Value, changed: &mut bool) {
        match v {
            Value::Number(n) if !n.is_i64() && !n.is_u64() => {
                if let Some(f) = n.as_f64()
                    && f.fract() == 0.0
                    && f.abs() <= 9_007_199_254_740_992.0
                {
                    *v = Value::from(f as i64);
                    *changed = true;
                }
            }
            Value::Array(a) => a.iter_mut().for_each(|x| integers(x, changed)),
            Value::Object(o) => o.values_mut().for_each(|x| integers(x, changed)),
            _ => {}
        }
    }
    // Every whole float: where the crate wants a float it reads an integer as one.
    integers(value, &mut changed);
    changed
}

/// The crate's validation (index ranges, required extensions...), after the one check it
/// relies on without making (a primitive's POSITION accessor exists). POSITION's `min` and
/// `max`, which the specification requires and strahl does not use, may be missing; so may an
/// accessor's `bufferView` without `sparse`, which the specification allows (its values are
/// zeros, and `read_accessor` reads them so).
pub(super) fn validate(root: &gltf::json::Root) -> Res<()> {
    use gltf::json::validation::{Checked, Error, Validate};
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(a) = prim.attributes.get(&Checked::Valid(gltf::Semantic::Positions))
                && a.value() >= root.accessors.len()
            {
                return Err(format!("meshes[{m}].primitives[{p}].attributes.POSITION: index out of range"));
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        let path = path();
        let p = path.as_str();
        let allowed_missing = p.ends_with(".min")
            || p.ends_with(".max")
            || (p.starts_with("accessors[") && p.ends_with("].bufferView"))
            // A primitive without POSITION is skipped (the specification: clients should).
            || (p.starts_with("meshes[") && p.ends_with(".attributes[\"POSITION\"]"));
        // Enumerations the specification leaves open: an accessor type or a light type strahl
        // does not know is an error only where it is used.
        let allowed_invalid = (p.starts_with("accessors[") && p.ends_with("].type"))
            || (p.contains("khrLightsPunctual.lights[") && p.ends_with("].type"));
        // The crate's path reads `extensionsRequired[N] = "NAME"`: the extensions strahl reads
        // that the crate has no feature for (quantization, clear coat, sheen) may be required.
        let required_read = p.starts_with("extensionsRequired[")
            && SUPPORTED_EXTENSIONS.iter().any(|e| p.ends_with(&format!("= \"{e}\"")));
        let allowed = match error {
            Error::Missing => allowed_missing,
            Error::Invalid => allowed_invalid,
            Error::Unsupported => required_read,
            _ => false,
        };
        if !allowed {
            errors.push((path, error));
        }
    });
    if errors.is_empty() { Ok(()) } else { Err(describe_error(gltf::Error::Validation(errors))) }
}

/// The crate's error as a message naming the glTF path.
pub(super) fn describe_error(e: gltf::Error) -> String {
    match e {
        gltf::Error::Validation(errors) => {
            let shown: Vec<String> = errors
                .iter()
                .take(5)
                .map(|(path, err)| match err {
                    gltf::json::validation::Error::Unsupported => format!(
                        "{path}: a required extension strahl does not read (it reads {})",
                        SUPPORTED_EXTENSIONS.join(", ")
                    ),
                    gltf::json::validation::Error::IndexOutOfBounds => format!("{path}: index out of range"),
                    gltf::json::validation::Error::Missing => format!("{path}: missing"),
                    other => format!("{path}: {other}"),
                })
                .collect();
            let more = if errors.len() > 5 { format!(" (and {} more)", errors.len() - 5) } else { String::new() };
            format!("{}{more}", shown.join("; "))
        }
        gltf::Error::Deserialize(e) => format!("broken JSON: {e}"),
        gltf::Error::Binary(e) => format!("broken GLB container: {e:?}"),
        gltf::Error::Io(e) => format!("cannot read: {e}"),
    }
}

/// The bytes of every buffer: the GLB binary chunk, a `data:` URI, or a file next to the
/// glTF file. A buffer without a uri and without a binary chunk to stand for it is valid while
/// no view reads it, and so is one whose uri strahl cannot read (a URL) or whose data are short:
/// its entry is the error a view that does gets.
pub(super) fn load_buffers(doc: &gltf::Document, blob: Option<&[u8]>, dir: &Path) -> Vec<Res<Vec<u8>>> {
    let mut out = Vec::new();
    let mut blob_used = false;
    for b in doc.buffers() {
        let at = format!("buffers[{}]", b.index());
        let data = match b.source() {
            gltf::buffer::Source::Bin => {
                let Some(blob) = blob.filter(|_| !blob_used) else {
                    out.push(Err(format!("{at}: has no uri, and the file has no (unused) GLB binary chunk")));
                    continue;
                };
                blob_used = true;
                blob.to_vec()
            }
            gltf::buffer::Source::Uri(uri) => match read_uri(uri, dir, MAX_BUFFER_BYTES) {
                Ok(data) => data,
                Err(m) => {
                    out.push(Err(format!("{at}.uri: {m}")));
                    continue;
                }
            },
        };
        if data.len() < b.length() {
            out.push(Err(format!("{at}: byteLength is {} but its data holds {} bytes", b.length(), data.len())));
            continue;
        }
        out.push(Ok(data));
    }
    out
}

/// The bytes a relative file URI or a base64 `data:` URI names.
pub(super) fn read_uri(uri: &str, dir: &Path, limit: u64) -> Res<Vec<u8>> {
    use base64::Engine;
    if let Some(rest) = uri.strip_prefix("data:") {
        let (head, data) = rest.split_once(',').ok_or("a data: URI without a comma")?;
        if !head.ends_with(";base64") {
            return Err("a data: URI must be base64-encoded".into());
        }
        if data.len() as u64 / 4 * 3 > limit {
            return Err(format!("more than {} of data", crate::input::size_name(limit)));
        }
        return base64::engine::general_purpose::STANDARD.decode(data).map_err(|e| format!("bad base64 data: {e}"));
    }
    if uri.contains("://") || uri.starts_with("file:") {
        return Err(format!("\"{uri}\": only relative file names and data: URIs are read"));
    }
    let file = dir.join(percent_decode(uri));
    crate::input::read_bytes(&file, limit).map_err(|e| format!("\"{}\": {e}", file.display()))
}

/// `%20` → ` `: URIs in glTF are percent-encoded.
pub(super) fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%'
            && i + 2 < b.len()
            && let Ok(v) = u8::from_str_radix(std::str::from_utf8(&b[i + 1..i + 3]).unwrap_or("zz"), 16)
        {
            out.push(v);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}
