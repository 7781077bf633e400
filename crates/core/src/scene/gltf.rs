//! glTF 2.0 files (`.gltf` with external or embedded buffers, `.glb`) read with the `gltf`
//! crate: the node hierarchy with its transforms, triangle meshes with `TEXCOORD_0`,
//! materials, perspective cameras and `KHR_lights_punctual` lights.
//!
//! The crate parses and validates the JSON (index ranges, required extensions); the bytes are
//! read here, every accessor checked against its buffer view and buffer before it is read, so
//! a broken file gives an error naming its glTF path (`meshes[2].primitives[0].indices`),
//! never a panic.
//!
//! **Handedness.** glTF is right-handed (+y up, a camera looks along its −z with +x on its
//! right); strahl's screen is left-handed (+x right looking along +z). Everything read is
//! mirrored by z → −z — geometry, cameras and lights alike — and each triangle's last two
//! vertices (with their texture coordinates) are swapped, so front faces stay front faces and
//! the image is the one a glTF viewer shows, not its mirror image. A model authored facing +z
//! (glTF's "front") then faces −z, towards a strahl camera at −z looking along +z.
//!
//! One file of some 860 lines: the import is one walk over the document (nodes, meshes,
//! materials, textures, cameras, lights) that threads one state and one kind of located error
//! (the glTF path) through every part; split, that state would cross files at every step.

use super::mesh::Transform;
use super::texture::{IDENTITY_UV, ImageKind, Texels, Texture, Wrap};
use super::{AlphaMode, LoadOptions, RenderSettings, Scene, SceneError};
use super::{
    Camera, Environment, Geometry, ImageSize, Light, Material, MaterialKind, MeshAttributes, Object, RenderMode,
};
use crate::geometry::Triangle;
use crate::math::V3;
use glam::{DMat3, DMat4, DVec3};
use gltf::accessor::{DataType, Dimensions};
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Largest `.gltf` (JSON) or `.glb` file read.
pub const MAX_GLTF_FILE_BYTES: u64 = 2 << 30;
/// Largest external buffer read.
pub const MAX_BUFFER_BYTES: u64 = 2 << 30;
/// Deepest node hierarchy followed.
const MAX_NODE_DEPTH: usize = 1024;
/// The extensions whose contents are read (the crate refuses files that require others).
pub const SUPPORTED_EXTENSIONS: [&str; 7] = [
    "KHR_mesh_quantization",
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_unlit",
    "KHR_texture_transform",
];
/// A glTF file given on its own renders this tall (and as wide as its camera's aspect ratio
/// asks, else 4:3).
pub const DEFAULT_HEIGHT: u32 = 480;
/// Vertical field of view of the camera made for files that have none.
pub const DEFAULT_FOV_Y: f64 = 40.0;

/// Whether `path` names a glTF file (by its extension).
pub fn is_gltf_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// A perspective camera placed by a node.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedCamera {
    /// Index in the file's `cameras`.
    pub index: usize,
    pub name: Option<String>,
    pub camera: Camera,
    pub aspect: Option<f64>,
}

/// What a glTF file holds, in strahl's (mirrored) space. Material and texture indices are
/// local to this import.
#[derive(Clone, Debug, Default)]
pub struct Import {
    pub triangles: Vec<Triangle<f64>>,
    /// Per triangle: texture coordinates, normals, colours (each list empty when no
    /// primitive has it).
    pub attrs: MeshAttributes,
    /// Per triangle, an index into `materials`.
    pub triangle_materials: Vec<u32>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub cameras: Vec<PlacedCamera>,
    pub lights: Vec<Light>,
    /// Things read but not used, one line each.
    pub warnings: Vec<String>,
}

/// Loads a glTF file given on its own as a whole scene: its camera (the first perspective
/// camera, or `options.camera`; else one framing the model's bounds), its lights (else a
/// constant white sky), path tracing at 16 samples per pixel.
pub fn load_scene(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    let err = |message: String| SceneError::Gltf { path: path.to_path_buf(), message };
    let imp = import(path, &Transform::default(), super::mesh::MAX_MESH_TRIANGLES).map_err(err)?;
    let placed = match options.camera {
        Some(n) => Some(imp.cameras.iter().find(|c| c.index == n).ok_or_else(|| {
            let list: Vec<String> = imp
                .cameras
                .iter()
                .map(|c| format!("{} ({})", c.index, c.name.as_deref().unwrap_or("unnamed")))
                .collect();
            err(format!(
                "--camera {n}: no perspective camera {n} is placed in the scene (placed: {})",
                if list.is_empty() { "none".to_string() } else { list.join(", ") }
            ))
        })?),
        None => imp.cameras.first(),
    };
    let (camera, aspect) = match placed {
        Some(c) => (c.camera.clone(), c.aspect.unwrap_or(4.0 / 3.0)),
        None => (framing_camera(&imp.triangles), 4.0 / 3.0),
    };
    let width = ((DEFAULT_HEIGHT as f64 * aspect).round() as u32).clamp(1, super::file::MAX_IMAGE_SIDE as u32);
    let mut warnings = imp.warnings;
    if placed.is_none() {
        warnings.push("the file has no perspective camera: a camera frames the model from the front".into());
    }
    // Emissive materials do not count: on most assets they are small details (lamps, screens)
    // that glTF viewers show under their environment light too.
    let lit = !imp.lights.is_empty();
    let environment = (!lit).then(|| {
        warnings.push("the file has no punctual lights: a constant white sky (radiance 1) lights it".into());
        Environment::constant([1.0; 3])
    });
    let render = RenderSettings {
        mode: RenderMode::Path,
        spp: 16,
        ambient: if environment.is_some() { [0.0; 3] } else { RenderSettings::default().ambient },
        ..RenderSettings::default()
    };
    let material = imp.triangle_materials.first().copied().unwrap_or(0);
    Ok(Scene {
        camera,
        image: ImageSize { width, height: DEFAULT_HEIGHT },
        render,
        materials: imp.materials,
        objects: vec![Object {
            geometry: Geometry::Mesh {
                file: path.to_path_buf(),
                triangles: imp.triangles,
                attrs: imp.attrs,
                materials: imp.triangle_materials,
            },
            material,
        }],
        lights: imp.lights,
        textures: imp.textures,
        environment,
        warnings,
    })
}

/// A camera that sees the whole of `triangles` (their bounding sphere fits the vertical field
/// of view) from the model's front (−z in strahl's space, +z in the file's) and a little above.
pub fn framing_camera(triangles: &[Triangle<f64>]) -> Camera {
    let mut lo = V3::splat(f64::INFINITY);
    let mut hi = V3::splat(f64::NEG_INFINITY);
    for t in triangles {
        for v in t.v {
            lo = V3::new(lo.x.min(v.x), lo.y.min(v.y), lo.z.min(v.z));
            hi = V3::new(hi.x.max(v.x), hi.y.max(v.y), hi.z.max(v.z));
        }
    }
    let (centre, radius) = if lo.x <= hi.x { ((lo + hi) * 0.5, ((hi - lo) * 0.5).length()) } else { (V3::zero(), 1.0) };
    let radius = if radius > 0.0 { radius } else { 1.0 };
    let dist = radius / (DEFAULT_FOV_Y.to_radians() * 0.5).sin() * 1.05;
    let dir = V3::new(0.0, 0.25, -1.0).normalize();
    Camera { eye: centre + dir * dist, look_at: centre, up: V3::new(0.0, 1.0, 0.0), fov_y: DEFAULT_FOV_Y }
}

type Res<T> = Result<T, String>;

/// Reads the glTF file at `path` placed by `placement` (after the mirroring into strahl's
/// space); at most `triangle_limit` triangles, counted from the accessors before any is read.
/// Errors read `GLTF_PATH: message`.
pub fn import(path: &Path, placement: &Transform, triangle_limit: usize) -> Res<Import> {
    // The crate's validation indexes some arrays unchecked (a primitive's attribute naming a
    // missing accessor can panic in it): a panic there, or in what it let through, is an error
    // about the file too.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| import_checked(path, placement, triangle_limit)))
        .unwrap_or_else(|payload| {
            let what = payload
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| payload.downcast_ref::<&str>().copied())
                .unwrap_or("");
            Err(format!("malformed glTF file (reading it failed: {what})"))
        })
}

fn import_checked(path: &Path, placement: &Transform, triangle_limit: usize) -> Res<Import> {
    let bytes = crate::input::read_bytes(path, MAX_GLTF_FILE_BYTES).map_err(|e| match e {
        crate::input::ReadError::Io(e) => format!("cannot open: {e}"),
        e => format!("cannot read: {e}"),
    })?;
    let (gltf, leniencies) = parse(&bytes)?;
    drop(bytes);
    validate(gltf.document.as_json())?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut reader = Reader {
        doc: &gltf.document,
        buffers: Vec::new(),
        images: HashMap::new(),
        dir,
        out: Import::default(),
        warned: BTreeSet::new(),
    };
    reader.out.warnings.extend(leniencies);
    reader.buffers = load_buffers(&gltf.document, gltf.blob.as_deref(), &reader.dir);
    reader.unsupported_extensions();
    reader.materials()?;
    reader.scene(placement, triangle_limit)?;
    if reader.out.triangles.is_empty() {
        let meshes = gltf.document.meshes().len();
        let placed = gltf.document.nodes().any(|n| n.mesh().is_some());
        return Err(if meshes > 0 && !placed {
            format!("the scene has no triangles: no node places any of the file's {meshes} meshes")
        } else {
            "the scene has no triangles (no mesh with TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN)".into()
        });
    }
    Ok(reader.out)
}

/// The document and GLB binary chunk of `bytes`. Where the gltf crate's reading refuses the
/// JSON, it is read again without `animations`, which strahl does not read and where the crate
/// is stricter than the specification (a channel's `target.node` may be absent where an
/// extension names the animated object).
fn parse(bytes: &[u8]) -> Res<(gltf::Gltf, Vec<String>)> {
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
fn lenient(value: &mut serde_json::Value) -> bool {
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
    fn integers(v: &mut Value, changed: &mut bool) {
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
fn validate(root: &gltf::json::Root) -> Res<()> {
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
        // The crate's path reads `extensionsRequired[N] = "NAME"`.
        let required_quantization = p.starts_with("extensionsRequired[") && p.ends_with("= \"KHR_mesh_quantization\"");
        let allowed = match error {
            Error::Missing => allowed_missing,
            Error::Invalid => allowed_invalid,
            Error::Unsupported => required_quantization,
            _ => false,
        };
        if !allowed {
            errors.push((path, error));
        }
    });
    if errors.is_empty() { Ok(()) } else { Err(describe_error(gltf::Error::Validation(errors))) }
}

/// The crate's error as a message naming the glTF path.
fn describe_error(e: gltf::Error) -> String {
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
fn load_buffers(doc: &gltf::Document, blob: Option<&[u8]>, dir: &Path) -> Vec<Res<Vec<u8>>> {
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
fn read_uri(uri: &str, dir: &Path, limit: u64) -> Res<Vec<u8>> {
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
fn percent_decode(s: &str) -> String {
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

/// One primitive's data as read, before placement.
struct PrimitiveData {
    positions: Vec<DVec3>,
    uvs: Option<Vec<[f32; 2]>>,
    uvs1: Option<Vec<[f32; 2]>>,
    normals: Option<Vec<DVec3>>,
    colors: Option<Vec<[f32; 4]>>,
    /// Vertex indices of the triangles.
    triangles: Vec<[u32; 3]>,
    material: u32,
}

/// A material's reference to a texture: which, through which texture coordinates, and the
/// `KHR_texture_transform` of them.
struct TextureUse {
    texture: usize,
    texcoord: u32,
    transform: [f32; 6],
}

/// What makes two uses the same: texture, coordinates, transform bits, data or colour.
type TextureKey = (usize, u32, [u32; 6], bool);

impl TextureUse {
    fn of_info(info: gltf::texture::Info) -> TextureUse {
        let mut u = TextureUse { texture: info.texture().index(), texcoord: info.tex_coord(), transform: IDENTITY_UV };
        if let Some(t) = info.texture_transform() {
            u.transform = uv_transform(t.offset(), t.rotation(), t.scale());
            if let Some(c) = t.tex_coord() {
                u.texcoord = c;
            }
        }
        u
    }

    fn of_normal(n: &gltf::material::NormalTexture) -> TextureUse {
        let mut u = TextureUse { texture: n.texture().index(), texcoord: n.tex_coord(), transform: IDENTITY_UV };
        if let Some(t) = n.extension_value("KHR_texture_transform") {
            let pair = |key: &str, default: [f32; 2]| {
                t.get(key).and_then(|v| v.as_array()).map_or(default, |a| {
                    [0, 1].map(|k| a.get(k).and_then(|x| x.as_f64()).map_or(default[k], |x| x as f32))
                })
            };
            let rotation = t.get("rotation").and_then(|v| v.as_f64()).unwrap_or(0.0) as f32;
            u.transform = uv_transform(pair("offset", [0.0; 2]), rotation, pair("scale", [1.0; 2]));
            if let Some(c) = t.get("texCoord").and_then(|v| v.as_u64()) {
                u.texcoord = c as u32;
            }
        }
        u
    }
}

/// `KHR_texture_transform`'s offset · rotation · scale as [a, b, c, d, e, f] of
/// (a·u + b·v + c, d·u + e·v + f); the rotation turns the coordinates counter-clockwise as
/// the extension's matrix does (u' = cos·u + sin·v, v' = −sin·u + cos·v, v running down).
fn uv_transform(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> [f32; 6] {
    let (s, c) = rotation.sin_cos();
    [c * scale[0], s * scale[1], offset[0], -s * scale[0], c * scale[1], offset[1]]
}

struct Reader<'a> {
    doc: &'a gltf::Document,
    /// Each buffer's bytes, or why it has none (an error only where a view reads it).
    buffers: Vec<Res<Vec<u8>>>,
    /// Each image decoded once, shared by its uses.
    images: HashMap<usize, (u32, u32, Arc<Texels>)>,
    dir: PathBuf,
    out: Import,
    /// Warnings already given (each once).
    warned: BTreeSet<String>,
}

/// The value of component `c` of a glTF accessor element as glTF defines it: floats as they
/// are, normalised integers mapped to [0, 1] or [−1, 1], other integers as integers.
fn component(bytes: &[u8], ty: DataType, normalized: bool) -> f64 {
    match ty {
        DataType::F32 => f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f64,
        DataType::U32 => u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f64,
        DataType::U8 => {
            let v = bytes[0] as f64;
            if normalized { v / 255.0 } else { v }
        }
        DataType::I8 => {
            let v = bytes[0] as i8 as f64;
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        DataType::U16 => {
            let v = u16::from_le_bytes([bytes[0], bytes[1]]) as f64;
            if normalized { v / 65535.0 } else { v }
        }
        DataType::I16 => {
            let v = i16::from_le_bytes([bytes[0], bytes[1]]) as f64;
            if normalized { (v / 32767.0).max(-1.0) } else { v }
        }
    }
}

fn type_name(d: Dimensions) -> &'static str {
    match d {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

impl Reader<'_> {
    fn warn(&mut self, message: String) {
        if self.warned.insert(message.clone()) {
            self.out.warnings.push(message);
        }
    }

    fn unsupported_extensions(&mut self) {
        let ignored: Vec<&str> = self.doc.extensions_used().filter(|e| !SUPPORTED_EXTENSIONS.contains(e)).collect();
        if !ignored.is_empty() {
            self.warn(format!("extensionsUsed: ignored (not read by strahl): {}", ignored.join(", ")));
        }
    }

    /// The bytes of buffer view `view`, checked to lie inside its buffer.
    fn view_bytes(&self, view: &gltf::buffer::View) -> Res<&[u8]> {
        let buf =
            self.buffers[view.buffer().index()].as_ref().map_err(|m| format!("bufferViews[{}]: {m}", view.index()))?;
        let (start, len) = (view.offset(), view.length());
        match start.checked_add(len) {
            Some(end) if end <= buf.len() => Ok(&buf[start..end]),
            _ => Err(format!(
                "bufferViews[{}]: bytes {start}..{} lie outside buffers[{}] ({} bytes)",
                view.index(),
                start as u128 + len as u128,
                view.buffer().index(),
                buf.len()
            )),
        }
    }

    /// `count` elements of `n` components from `bytes` at `offset` with `stride`, each checked
    /// to lie inside `bytes` before anything is read.
    fn elements(
        bytes: &[u8],
        offset: usize,
        stride: usize,
        count: usize,
        n: usize,
        ty: DataType,
        normalized: bool,
    ) -> Option<Vec<f64>> {
        let size = ty.size() * n;
        if count > 0 {
            let last = (count - 1).checked_mul(stride)?.checked_add(offset)?.checked_add(size)?;
            if last > bytes.len() {
                return None;
            }
        }
        let mut out = Vec::with_capacity(count * n);
        for i in 0..count {
            let base = offset + i * stride;
            for c in 0..n {
                let at = base + c * ty.size();
                out.push(component(&bytes[at..at + ty.size()], ty, normalized));
            }
        }
        Some(out)
    }

    /// Accessor `acc` (used as `what`) as a flat list of its components, after checking its
    /// type is one of `dims`; sparse substitutions applied.
    fn read_accessor(&self, acc: &gltf::Accessor, what: &str, dims: &[Dimensions]) -> Res<Vec<f64>> {
        let at = format!("{what} (accessors[{}])", acc.index());
        if !matches!(self.doc.as_json().accessors[acc.index()].type_, gltf::json::validation::Checked::Valid(_)) {
            return Err(format!("{at}: type is not one glTF defines"));
        }
        if !dims.contains(&acc.dimensions()) {
            let want: Vec<&str> = dims.iter().map(|&d| type_name(d)).collect();
            return Err(format!("{at}: type {} where {} is expected", type_name(acc.dimensions()), want.join(" or ")));
        }
        let n = acc.dimensions().multiplicity();
        let (ty, normalized, count) = (acc.data_type(), acc.normalized(), acc.count());
        let elem = ty.size() * n;
        let mut values = match acc.view() {
            None => vec![0.0; count * n],
            Some(view) => {
                let bytes = self.view_bytes(&view).map_err(|m| format!("{at}: {m}"))?;
                let stride = view.stride().unwrap_or(elem);
                if stride < elem {
                    return Err(format!(
                        "{at}: bufferViews[{}].byteStride {stride} is shorter than one element ({elem} bytes)",
                        view.index()
                    ));
                }
                Self::elements(bytes, acc.offset(), stride, count, n, ty, normalized).ok_or_else(|| {
                    format!(
                        "{at}: {count} elements of {elem} bytes from byteOffset {} (stride {stride}) do not fit bufferViews[{}] ({} bytes)",
                        acc.offset(),
                        view.index(),
                        bytes.len()
                    )
                })?
            }
        };
        if let Some(sparse) = acc.sparse() {
            let k = sparse.count();
            let iv = sparse.indices();
            let ity = match iv.index_type() {
                gltf::accessor::sparse::IndexType::U8 => DataType::U8,
                gltf::accessor::sparse::IndexType::U16 => DataType::U16,
                gltf::accessor::sparse::IndexType::U32 => DataType::U32,
            };
            let ibytes = self.view_bytes(&iv.view()).map_err(|m| format!("{at}.sparse.indices: {m}"))?;
            let idx = Self::elements(ibytes, iv.offset(), ity.size(), k, 1, ity, false)
                .ok_or_else(|| format!("{at}.sparse.indices: {k} indices do not fit their buffer view"))?;
            let vv = sparse.values();
            let vbytes = self.view_bytes(&vv.view()).map_err(|m| format!("{at}.sparse.values: {m}"))?;
            let vals = Self::elements(vbytes, vv.offset(), elem, k, n, ty, normalized)
                .ok_or_else(|| format!("{at}.sparse.values: {k} values do not fit their buffer view"))?;
            for (j, &i) in idx.iter().enumerate() {
                let i = i as usize;
                if i >= count {
                    return Err(format!("{at}.sparse.indices: index {i} out of range ({count} elements)"));
                }
                values[i * n..(i + 1) * n].copy_from_slice(&vals[j * n..(j + 1) * n]);
            }
        }
        if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("{at}: element {} is not finite", bad / n));
        }
        Ok(values)
    }

    /// Every material of the file, mapped onto strahl's kinds (see the README), with the
    /// textures they use; then the grey default for primitives without a material.
    fn materials(&mut self) -> Res<()> {
        let mut textures: HashMap<TextureKey, u32> = HashMap::new();
        let docs: Vec<gltf::Material> = self.doc.materials().collect();
        for m in docs {
            let i = m.index().expect("listed materials have an index");
            let at = format!("materials[{i}]");
            let pbr = m.pbr_metallic_roughness();
            let base = pbr.base_color_factor();
            let color = [base[0], base[1], base[2]].map(|c| (c as f64).clamp(0.0, 1.0));
            let strength = m.emissive_strength().unwrap_or(1.0) as f64;
            let radiance = m.emissive_factor().map(|c| (c as f64 * strength).max(0.0));
            let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
            let kind = if m.unlit() {
                MaterialKind::Emissive
            } else if transmission >= 0.5 {
                MaterialKind::Dielectric
            } else {
                MaterialKind::Pbr
            };
            let mut ior = 1.0;
            if kind == MaterialKind::Dielectric {
                ior = m.ior().unwrap_or(1.5) as f64;
                if !(ior >= 1.0 && ior.is_finite()) {
                    self.warn(format!("{at}: KHR_materials_ior ior {ior} is not a refractive index: 1.5 is used"));
                    ior = 1.5;
                }
            }
            let mut tex = |this: &mut Self, info: Option<TextureUse>, what: &str, data: bool| -> Res<Option<u32>> {
                match info {
                    Some(u) => this.texture(&u, &format!("{at}.{what}"), data, &mut textures),
                    None => Ok(None),
                }
            };
            let color_texture = tex(
                self,
                pbr.base_color_texture().map(TextureUse::of_info),
                "pbrMetallicRoughness.baseColorTexture",
                false,
            )?;
            let name = match m.name() {
                Some(n) => format!("{at} \"{n}\""),
                None => at.clone(),
            };
            let alpha_mode = match m.alpha_mode() {
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5) as f64),
                gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            };
            let alpha = (base[3] as f64).clamp(0.0, 1.0);
            let mut out = Material { name, kind, color, ior, alpha, alpha_mode, ..Material::default_grey() };
            match kind {
                MaterialKind::Emissive => {
                    // KHR_materials_unlit: the base colour shown as it is, from both sides.
                    // (The colour texture stays for its alpha; the colour it multiplies is black.)
                    out.color = [0.0; 3];
                    out.radiance = color;
                    out.radiance_texture = color_texture;
                    out.color_texture = color_texture;
                    out.two_sided = true;
                    out.unlit = true;
                }
                MaterialKind::Dielectric => out.color_texture = color_texture,
                _ => {
                    out.color_texture = color_texture;
                    out.metallic = (pbr.metallic_factor() as f64).clamp(0.0, 1.0);
                    out.roughness = (pbr.roughness_factor() as f64).clamp(0.0, 1.0);
                    out.radiance = radiance;
                    out.two_sided = m.double_sided();
                    if radiance.iter().any(|&c| c > 0.0) {
                        out.radiance_texture =
                            tex(self, m.emissive_texture().map(TextureUse::of_info), "emissiveTexture", false)?;
                    }
                    out.metal_rough_texture = tex(
                        self,
                        pbr.metallic_roughness_texture().map(TextureUse::of_info),
                        "pbrMetallicRoughness.metallicRoughnessTexture",
                        true,
                    )?;
                    if let Some(n) = m.normal_texture() {
                        out.normal_scale = n.scale() as f64;
                        out.normal_texture = tex(self, Some(TextureUse::of_normal(&n)), "normalTexture", true)?;
                    }
                }
            }
            self.out.materials.push(out);
        }
        self.out.materials.push(Material::default_grey());
        Ok(())
    }

    /// The local index of the texture use `u` (an image with its sampler, texture coordinates
    /// and transform; `data`: read linearly), made on first use, its image decoded once; None
    /// (with a warning) for a texture without `source`, which the specification allows where an
    /// extension strahl does not read gives the image.
    fn texture(
        &mut self,
        u: &TextureUse,
        at: &str,
        data: bool,
        cache: &mut HashMap<TextureKey, u32>,
    ) -> Res<Option<u32>> {
        let mut texcoord = u.texcoord;
        if texcoord > 1 {
            self.warn(format!("{at}: texCoord {texcoord} is not read (TEXCOORD_0 and _1 are): TEXCOORD_0 is used"));
            texcoord = 0;
        }
        let tex = self.doc.textures().nth(u.texture).ok_or_else(|| format!("{at}.index: out of range"))?;
        let key = (u.texture, texcoord, u.transform.map(f32::to_bits), data);
        if let Some(&k) = cache.get(&key) {
            return Ok(Some(k));
        }
        let Some(image) = tex.source() else {
            self.warn(format!(
                "{at}: textures[{}] has no source (an extension gives its image, which strahl does not read): \
                 the material is untextured",
                tex.index()
            ));
            return Ok(None);
        };
        let image_index = image.index();
        let (width, height, texels) = match self.images.get(&image_index) {
            Some(found) => found.clone(),
            None => {
                let decoded = self.decode_image(image_index)?;
                self.images.insert(image_index, decoded.clone());
                decoded
            }
        };
        let sampler = tex.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        let t = Texture {
            name: format!("images[{image_index}]"),
            width,
            height,
            texels,
            wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
            nearest: sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest),
            data,
            texcoord,
            transform: u.transform,
        };
        let k = self.out.textures.len() as u32;
        self.out.textures.push(t);
        cache.insert(key, k);
        Ok(Some(k))
    }

    /// Image `image_index` decoded: its size and texels.
    fn decode_image(&mut self, image_index: usize) -> Res<(u32, u32, Arc<Texels>)> {
        let iat = format!("images[{image_index}]");
        let json = &self.doc.as_json().images[image_index];
        let bytes = match (&json.buffer_view, &json.uri) {
            (Some(view), _) => {
                let view = self
                    .doc
                    .views()
                    .nth(view.value())
                    .ok_or_else(|| format!("{iat}.bufferView: index out of range"))?;
                self.view_bytes(&view).map_err(|m| format!("{iat}: {m}"))?.to_vec()
            }
            (None, Some(uri)) => read_uri(uri, &self.dir, super::texture::MAX_TEXTURE_FILE_BYTES)
                .map_err(|m| format!("{iat}.uri: {m}"))?,
            (None, None) => return Err(format!("{iat}: neither uri nor bufferView")),
        };
        let t = Texture::decode(&bytes, ImageKind::Color).map_err(|m| format!("{iat}: {m}"))?;
        Ok((t.width, t.height, t.texels))
    }

    /// Walks the default scene (else the first; else every root node) and places its meshes,
    /// cameras and lights.
    fn scene(&mut self, placement: &Transform, triangle_limit: usize) -> Res<()> {
        let roots: Vec<usize> = match self.doc.default_scene().or_else(|| self.doc.scenes().next()) {
            Some(s) => s.nodes().map(|n| n.index()).collect(),
            None => {
                let mut child = vec![false; self.doc.nodes().len()];
                for n in self.doc.nodes() {
                    for c in n.children() {
                        child[c.index()] = true;
                    }
                }
                (0..child.len()).filter(|&i| !child[i]).collect()
            }
        };
        // Triangles counted from the accessors of every placed primitive, before reading any.
        let mut instances: Vec<(usize, DMat4)> = Vec::new();
        let mut on_path = vec![false; self.doc.nodes().len()];
        for r in roots {
            self.collect(r, DMat4::IDENTITY, 0, &mut on_path, &mut instances)?;
        }
        let mut total: u64 = 0;
        for (node, _) in &instances {
            let Some(mesh) = self.doc.nodes().nth(*node).and_then(|n| n.mesh()) else { continue };
            for p in mesh.primitives() {
                let n = p.indices().or_else(|| p.get(&gltf::Semantic::Positions)).map_or(0, |a| a.count()) as u64;
                total += match p.mode() {
                    gltf::mesh::Mode::Triangles => n / 3,
                    gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan => n.saturating_sub(2),
                    _ => 0,
                };
            }
            if total > triangle_limit as u64 {
                return Err(format!("more than {triangle_limit} triangles, the most accepted here"));
            }
        }
        let mut cache: HashMap<(usize, usize), Option<PrimitiveData>> = HashMap::new();
        for (node, world) in instances {
            self.place_node(node, &world, placement, &mut cache)?;
        }
        Ok(())
    }

    /// Collects (node, world matrix) for `node` and its descendants.
    fn collect(
        &mut self,
        node: usize,
        parent: DMat4,
        depth: usize,
        on_path: &mut [bool],
        out: &mut Vec<(usize, DMat4)>,
    ) -> Res<()> {
        let at = format!("nodes[{node}]");
        if on_path[node] {
            return Err(format!("{at}: the node hierarchy has a cycle through this node"));
        }
        if depth > MAX_NODE_DEPTH {
            return Err(format!("{at}: the node hierarchy is deeper than {MAX_NODE_DEPTH}"));
        }
        let n = self.doc.nodes().nth(node).expect("validated node index");
        let local = DMat4::from_cols_array_2d(&n.transform().matrix().map(|c| c.map(|v| v as f64)));
        if !local.is_finite() {
            return Err(format!("{at}: its transform is not finite"));
        }
        let world = parent * local;
        if n.skin().is_some() {
            self.warn("skins are not read: skinned meshes are drawn in their bind pose".into());
        }
        out.push((node, world));
        on_path[node] = true;
        for c in n.children() {
            self.collect(c.index(), world, depth + 1, on_path, out)?;
        }
        on_path[node] = false;
        Ok(())
    }

    fn place_node(
        &mut self,
        node: usize,
        world: &DMat4,
        placement: &Transform,
        cache: &mut HashMap<(usize, usize), Option<PrimitiveData>>,
    ) -> Res<()> {
        let n = self.doc.nodes().nth(node).expect("validated node index");
        // strahl = placement ∘ mirror(z) ∘ world.
        let mirror = DMat4::from_scale(DVec3::new(1.0, 1.0, -1.0));
        let m = mirror * *world;
        let point = |p: DVec3| -> V3<f64> {
            let q = m.transform_point3(p);
            placement.apply(V3::new(q.x, q.y, q.z))
        };
        if let Some(mesh) = n.mesh() {
            let flip = (DMat3::from_mat4(m).determinant() < 0.0) != placement.mirrors();
            for p in mesh.primitives() {
                let key = (mesh.index(), p.index());
                if let std::collections::hash_map::Entry::Vacant(slot) = cache.entry(key) {
                    slot.insert(self.read_primitive(&mesh, &p)?);
                }
                let Some(data) = &cache[&key] else { continue };
                let placed: Vec<V3<f64>> = data.positions.iter().map(|&v| point(v)).collect();
                if let Some(bad) = placed.iter().position(|v| !v.is_finite()) {
                    return Err(format!(
                        "nodes[{node}]: vertex {bad} of meshes[{}] is not finite once placed",
                        mesh.index()
                    ));
                }
                // Normals by the inverse transpose of the node's (mirrored) matrix, then the
                // placement's.
                let normal_matrix = DMat3::from_mat4(m).inverse().transpose();
                let normals: Option<Vec<[f32; 3]>> = data.normals.as_ref().map(|ns| {
                    ns.iter()
                        .map(|&n| {
                            let q = normal_matrix * n;
                            placement.apply_normal(V3::new(q.x, q.y, q.z)).cast::<f32>().to_array()
                        })
                        .collect()
                });
                let n = self.out.triangles.len();
                let attrs = &mut self.out.attrs;
                // A list that earlier triangles lacked starts with defaults for them: texel
                // (0, 0), the face's normal (zero), white.
                fn open<T: Copy>(list: &mut Vec<[T; 3]>, here: bool, n: usize, default: T) -> bool {
                    if (here || !list.is_empty()) && list.len() < n {
                        list.resize(n, [default; 3]);
                    }
                    here || !list.is_empty()
                }
                let with_uvs = open(&mut attrs.uvs, data.uvs.is_some(), n, [0.0; 2]);
                let with_uvs1 = open(&mut attrs.uvs1, data.uvs1.is_some(), n, [0.0; 2]);
                let with_normals = open(&mut attrs.normals, normals.is_some(), n, [0.0; 3]);
                let with_colors = open(&mut attrs.colors, data.colors.is_some(), n, [1.0; 4]);
                fn corners<T: Copy>(list: &Option<Vec<T>>, t: &[u32; 3], default: T, flip: bool) -> [T; 3] {
                    let mut c = list.as_ref().map_or([default; 3], |l| t.map(|i| l[i as usize]));
                    if flip {
                        c.swap(1, 2);
                    }
                    c
                }
                for t in &data.triangles {
                    let mut v = t.map(|i| placed[i as usize]);
                    if flip {
                        v.swap(1, 2);
                    }
                    self.out.triangles.push(Triangle { v });
                    self.out.triangle_materials.push(data.material);
                    let attrs = &mut self.out.attrs;
                    if with_uvs {
                        attrs.uvs.push(corners(&data.uvs, t, [0.0; 2], flip));
                    }
                    if with_uvs1 {
                        attrs.uvs1.push(corners(&data.uvs1, t, [0.0; 2], flip));
                    }
                    if with_normals {
                        attrs.normals.push(corners(&normals, t, [0.0; 3], flip));
                    }
                    if with_colors {
                        attrs.colors.push(corners(&data.colors, t, [1.0; 4], flip));
                    }
                }
            }
        }
        if let Some(cam) = n.camera() {
            match cam.projection() {
                gltf::camera::Projection::Perspective(p) => {
                    let eye = point(DVec3::ZERO);
                    let ahead = point(DVec3::new(0.0, 0.0, -1.0));
                    let above = point(DVec3::new(0.0, 1.0, 0.0));
                    let fov_y = (p.yfov() as f64).to_degrees();
                    let camera = Camera { eye, look_at: ahead, up: above - eye, fov_y };
                    let at = format!("cameras[{}]", cam.index());
                    if !(fov_y > 0.0 && fov_y < 180.0) {
                        return Err(format!("{at}.perspective.yfov: {} radians is not a field of view", p.yfov()));
                    }
                    if (ahead - eye).length() == 0.0
                        || (above - eye).cross(ahead - eye).length()
                            <= 1e-9 * (above - eye).length() * (ahead - eye).length()
                    {
                        return Err(format!("nodes[{node}]: the transform of {at} is degenerate"));
                    }
                    let aspect = p.aspect_ratio().map(|a| a as f64).filter(|a| *a > 0.0 && a.is_finite());
                    self.out.cameras.push(PlacedCamera {
                        index: cam.index(),
                        name: cam.name().map(String::from),
                        camera,
                        aspect,
                    });
                }
                gltf::camera::Projection::Orthographic(_) => {
                    self.warn(format!("cameras[{}]: orthographic cameras are not read", cam.index()));
                }
            }
        }
        let known_type = |i: usize| {
            let json = self.doc.as_json().extensions.as_ref().and_then(|e| e.khr_lights_punctual.as_ref());
            json.and_then(|l| l.lights.get(i))
                .is_some_and(|l| matches!(l.type_, gltf::json::validation::Checked::Valid(_)))
        };
        if let Some(light) = n.light()
            && !known_type(light.index())
        {
            self.warn(format!(
                "KHR_lights_punctual.lights[{}]: a light type glTF does not define: skipped",
                light.index()
            ));
        } else if let Some(light) = n.light() {
            let c = light.color();
            let intensity = c.map(|c| (c as f64 * light.intensity() as f64).max(0.0));
            let at = format!("KHR_lights_punctual.lights[{}]", light.index());
            match light.kind() {
                gltf::khr_lights_punctual::Kind::Point => {
                    let position = point(DVec3::ZERO);
                    self.out.lights.push(Light::Point { position, intensity });
                }
                gltf::khr_lights_punctual::Kind::Directional => {
                    let d = point(DVec3::new(0.0, 0.0, -1.0)) - point(DVec3::ZERO);
                    if d.length() > 0.0 && d.is_finite() {
                        self.out.lights.push(Light::Directional { direction: d.normalize(), intensity });
                    } else {
                        return Err(format!("nodes[{node}]: the transform of {at} is degenerate"));
                    }
                }
                gltf::khr_lights_punctual::Kind::Spot { .. } => {
                    self.warn(format!("{at}: spot lights are not read: skipped"));
                }
            }
        }
        Ok(())
    }

    /// The data of one mesh primitive, or None (with a warning) when it is not made of
    /// triangles.
    fn read_primitive(&mut self, mesh: &gltf::Mesh, p: &gltf::Primitive) -> Res<Option<PrimitiveData>> {
        let at = format!("meshes[{}].primitives[{}]", mesh.index(), p.index());
        let named = match mesh.name() {
            Some(n) => format!("{at} (mesh \"{n}\")"),
            None => at.clone(),
        };
        let mode = p.mode();
        if !matches!(
            mode,
            gltf::mesh::Mode::Triangles | gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan
        ) {
            self.warn(format!("{named}: mode {mode:?} is not triangles: skipped"));
            return Ok(None);
        }
        if p.morph_targets().len() > 0 {
            self.warn(format!("{named}: morph targets are not read: the base shape is drawn"));
        }
        let Some(pos_acc) = p.get(&gltf::Semantic::Positions) else {
            self.warn(format!("{named}: no POSITION: skipped"));
            return Ok(None);
        };
        let pos = self.read_accessor(&pos_acc, &format!("{at}.attributes.POSITION"), &[Dimensions::Vec3])?;
        let positions: Vec<DVec3> = pos.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect();
        let nv = positions.len();
        let attribute = |this: &mut Self, semantic: gltf::Semantic, dims: &[Dimensions]| -> Res<Option<Vec<f64>>> {
            let Some(acc) = p.get(&semantic) else { return Ok(None) };
            let what = format!("{at}.attributes.{}", semantic.to_string());
            let values = this.read_accessor(&acc, &what, dims)?;
            let width = values.len().checked_div(nv).unwrap_or(0);
            if acc.count() != nv {
                return Err(format!("{what}: {} elements for {nv} vertices", acc.count()));
            }
            Ok(Some(if width == 3 && dims.contains(&Dimensions::Vec4) {
                // RGB colours: opaque.
                values.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 1.0]).collect()
            } else {
                values
            }))
        };
        let pairs = |v: Vec<f64>| -> Vec<[f32; 2]> { v.chunks_exact(2).map(|c| [c[0] as f32, c[1] as f32]).collect() };
        let uvs = attribute(self, gltf::Semantic::TexCoords(0), &[Dimensions::Vec2])?.map(pairs);
        let uvs1 = attribute(self, gltf::Semantic::TexCoords(1), &[Dimensions::Vec2])?.map(pairs);
        let normals = attribute(self, gltf::Semantic::Normals, &[Dimensions::Vec3])?
            .map(|v| v.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect());
        let colors = attribute(self, gltf::Semantic::Colors(0), &[Dimensions::Vec3, Dimensions::Vec4])?.map(|v| {
            v.chunks_exact(4)
                .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32].map(|x| x.clamp(0.0, 1.0)))
                .collect()
        });
        let indices: Vec<u32> = match p.indices() {
            Some(acc) => {
                let what = format!("{at}.indices");
                if !matches!(acc.data_type(), DataType::U8 | DataType::U16 | DataType::U32) {
                    return Err(format!("{what} (accessors[{}]): indices must be unsigned integers", acc.index()));
                }
                let raw = self.read_accessor(&acc, &what, &[Dimensions::Scalar])?;
                let mut out = Vec::with_capacity(raw.len());
                for (k, &i) in raw.iter().enumerate() {
                    if i as usize >= nv {
                        return Err(format!("{what}: index {i} at position {k} is out of range ({nv} vertices)"));
                    }
                    out.push(i as u32);
                }
                out
            }
            None => (0..nv as u32).collect(),
        };
        let triangles: Vec<[u32; 3]> = match mode {
            gltf::mesh::Mode::Triangles => {
                if !indices.len().is_multiple_of(3) {
                    self.warn(format!(
                        "{named}: {} indices are not a whole number of triangles: the rest is skipped",
                        indices.len()
                    ));
                }
                indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            }
            // Strips alternate their winding so that every triangle faces the same way.
            gltf::mesh::Mode::TriangleStrip => (2..indices.len())
                .map(|k| {
                    if k % 2 == 0 {
                        [indices[k - 2], indices[k - 1], indices[k]]
                    } else {
                        [indices[k - 1], indices[k - 2], indices[k]]
                    }
                })
                .collect(),
            _ => (2..indices.len()).map(|k| [indices[0], indices[k - 1], indices[k]]).collect(),
        };
        let material = match p.material().index() {
            Some(i) => i as u32,
            None => (self.out.materials.len() - 1) as u32,
        };
        Ok(Some(PrimitiveData { positions, uvs, uvs1, normals, colors, triangles, material }))
    }
}
