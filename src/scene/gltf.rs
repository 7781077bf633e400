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
use super::texture::{ImageKind, Texture, Wrap};
use super::{Camera, Environment, Geometry, ImageSize, Light, Material, MaterialKind, Object, RenderMode};
use super::{LoadOptions, RenderSettings, Scene, SceneError};
use crate::geometry::Triangle;
use crate::math::V3;
use glam::{DMat3, DMat4, DVec3};
use gltf::accessor::{DataType, Dimensions};
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

/// Largest `.gltf` (JSON) or `.glb` file read.
pub const MAX_GLTF_FILE_BYTES: u64 = 2 << 30;
/// Largest external buffer read.
pub const MAX_BUFFER_BYTES: u64 = 2 << 30;
/// Deepest node hierarchy followed.
const MAX_NODE_DEPTH: usize = 1024;
/// The extensions whose contents are read (the crate refuses files that require others).
pub const SUPPORTED_EXTENSIONS: [&str; 4] =
    ["KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_transmission", "KHR_materials_ior"];
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
    /// Per triangle; empty when no primitive has `TEXCOORD_0`.
    pub uvs: Vec<[[f32; 2]; 3]>,
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
    let lit = !imp.lights.is_empty() || imp.materials.iter().any(|m| m.kind == MaterialKind::Emissive);
    let environment = (!lit).then(|| {
        warnings.push("the file has no lights: a constant white sky (radiance 1) lights it".into());
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
                uvs: imp.uvs,
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
    let gltf = parse(&bytes)?;
    drop(bytes);
    validate(gltf.document.as_json())?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut reader =
        Reader { doc: &gltf.document, buffers: Vec::new(), dir, out: Import::default(), warned: BTreeSet::new() };
    reader.buffers = load_buffers(&gltf.document, gltf.blob.as_deref(), &reader.dir)?;
    reader.unsupported_extensions();
    reader.materials()?;
    reader.scene(placement, triangle_limit)?;
    if reader.out.triangles.is_empty() {
        return Err("the scene has no triangles (no mesh with TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN)".into());
    }
    Ok(reader.out)
}

/// The document and GLB binary chunk of `bytes`. Where the gltf crate's reading refuses the
/// JSON, it is read again without `animations`, which strahl does not read and where the crate
/// is stricter than the specification (a channel's `target.node` may be absent where an
/// extension names the animated object).
fn parse(bytes: &[u8]) -> Res<gltf::Gltf> {
    let refused = match gltf::Gltf::from_slice_without_validation(bytes) {
        Ok(g) => return Ok(g),
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
    match value.as_object_mut().and_then(|root| root.remove("animations")) {
        Some(_) => {
            let root: gltf::json::Root =
                serde_json::from_value(value).map_err(|e| describe_error(gltf::Error::Deserialize(e)))?;
            Ok(gltf::Gltf { document: gltf::Document::from_json_without_validation(root), blob })
        }
        None => Err(refused),
    }
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
        let allowed =
            p.ends_with(".min") || p.ends_with(".max") || (p.starts_with("accessors[") && p.ends_with("].bufferView"));
        if !(allowed && error == Error::Missing) {
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
/// no view reads it: its entry is the error a view that does gets.
fn load_buffers(doc: &gltf::Document, blob: Option<&[u8]>, dir: &Path) -> Res<Vec<Res<Vec<u8>>>> {
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
            gltf::buffer::Source::Uri(uri) => {
                read_uri(uri, dir, MAX_BUFFER_BYTES).map_err(|m| format!("{at}.uri: {m}"))?
            }
        };
        if data.len() < b.length() {
            return Err(format!("{at}: byteLength is {} but its data holds {} bytes", b.length(), data.len()));
        }
        out.push(Ok(data));
    }
    Ok(out)
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
    /// Vertex indices of the triangles.
    triangles: Vec<[u32; 3]>,
    material: u32,
}

struct Reader<'a> {
    doc: &'a gltf::Document,
    /// Each buffer's bytes, or why it has none (an error only where a view reads it).
    buffers: Vec<Res<Vec<u8>>>,
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
        let mut textures: HashMap<usize, u32> = HashMap::new();
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
            let kind = if radiance.iter().any(|&c| c > 0.0) {
                MaterialKind::Emissive
            } else if transmission >= 0.5 {
                MaterialKind::Dielectric
            } else if pbr.metallic_factor() >= 0.5 {
                MaterialKind::Mirror
            } else {
                MaterialKind::Diffuse
            };
            let mut ior = 1.0;
            if kind == MaterialKind::Dielectric {
                ior = m.ior().unwrap_or(1.5) as f64;
                if !(ior >= 1.0 && ior.is_finite()) {
                    self.warn(format!("{at}: KHR_materials_ior ior {ior} is not a refractive index: 1.5 is used"));
                    ior = 1.5;
                }
            }
            let roughness = if kind == MaterialKind::Mirror {
                // glTF's roughness is perceptual: GGX α = roughness².
                (pbr.roughness_factor() as f64).clamp(0.0, 1.0).powi(2)
            } else {
                0.0
            };
            let color_texture = match pbr.base_color_texture() {
                Some(info) => {
                    self.texture(&info, &format!("{at}.pbrMetallicRoughness.baseColorTexture"), &mut textures)?
                }
                None => None,
            };
            let radiance_texture = match m.emissive_texture() {
                Some(info) if kind == MaterialKind::Emissive => {
                    self.texture(&info, &format!("{at}.emissiveTexture"), &mut textures)?
                }
                _ => None,
            };
            let name = match m.name() {
                Some(n) => format!("{at} \"{n}\""),
                None => at.clone(),
            };
            self.out.materials.push(Material {
                name,
                kind,
                color,
                ior,
                radiance: if kind == MaterialKind::Emissive { radiance } else { [0.0; 3] },
                roughness,
                two_sided: m.double_sided(),
                color_texture,
                radiance_texture,
            });
        }
        self.out.materials.push(Material::default_grey());
        Ok(())
    }

    /// The local index of the texture `info` refers to, decoded on first use; None (with a
    /// warning) for a texture without `source`, which the specification allows where an
    /// extension strahl does not read gives the image.
    fn texture(&mut self, info: &gltf::texture::Info, at: &str, cache: &mut HashMap<usize, u32>) -> Res<Option<u32>> {
        if info.tex_coord() != 0 {
            self.warn(format!("{at}: texCoord {} is not read; TEXCOORD_0 is used", info.tex_coord()));
        }
        let tex = info.texture();
        if let Some(&k) = cache.get(&tex.index()) {
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
        let mut t = Texture::decode(&bytes, ImageKind::Color).map_err(|m| format!("{iat}: {m}"))?;
        t.name = iat;
        let sampler = tex.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        t.wrap = [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())];
        t.nearest = sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest);
        let k = self.out.textures.len() as u32;
        self.out.textures.push(t);
        cache.insert(tex.index(), k);
        Ok(Some(k))
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
                let any_uvs = data.uvs.is_some() || !self.out.uvs.is_empty();
                if any_uvs && self.out.uvs.len() < self.out.triangles.len() {
                    // Earlier triangles had none: they read texel (0, 0).
                    self.out.uvs.resize(self.out.triangles.len(), [[0.0; 2]; 3]);
                }
                for t in &data.triangles {
                    let mut v = t.map(|i| placed[i as usize]);
                    let mut uv = data.uvs.as_ref().map_or([[0.0; 2]; 3], |uvs| t.map(|i| uvs[i as usize]));
                    if flip {
                        v.swap(1, 2);
                        uv.swap(1, 2);
                    }
                    self.out.triangles.push(Triangle { v });
                    self.out.triangle_materials.push(data.material);
                    if any_uvs {
                        self.out.uvs.push(uv);
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
        if let Some(light) = n.light() {
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
        let pos_acc = p.get(&gltf::Semantic::Positions).ok_or_else(|| format!("{at}.attributes: no POSITION"))?;
        let pos = self.read_accessor(&pos_acc, &format!("{at}.attributes.POSITION"), &[Dimensions::Vec3])?;
        let positions: Vec<DVec3> = pos.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect();
        let nv = positions.len();
        let uvs = match p.get(&gltf::Semantic::TexCoords(0)) {
            Some(acc) => {
                let uv = self.read_accessor(&acc, &format!("{at}.attributes.TEXCOORD_0"), &[Dimensions::Vec2])?;
                if uv.len() / 2 != nv {
                    return Err(format!("{at}.attributes.TEXCOORD_0: {} elements for {nv} vertices", uv.len() / 2));
                }
                Some(uv.chunks_exact(2).map(|c| [c[0] as f32, c[1] as f32]).collect())
            }
            None => None,
        };
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
        Ok(Some(PrimitiveData { positions, uvs, triangles, material }))
    }
}
