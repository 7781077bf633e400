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

mod materials;
mod nodes;
mod parse;
mod reader;

use parse::*;
use reader::*;

/// Largest `.gltf` (JSON) or `.glb` file read.
pub const MAX_GLTF_FILE_BYTES: u64 = 2 << 30;
/// Largest external buffer read.
pub const MAX_BUFFER_BYTES: u64 = 2 << 30;
/// Deepest node hierarchy followed.
const MAX_NODE_DEPTH: usize = 1024;
/// The extensions whose contents are read (the crate refuses files that require others).
pub const SUPPORTED_EXTENSIONS: [&str; 11] = [
    "KHR_mesh_quantization",
    "KHR_lights_punctual",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_volume",
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
    scene_of(path, imp, options)
}

/// [`load_scene`] of a file's bytes, as a web page has them (dropped, or fetched from a URL):
/// a `.glb`, or a `.gltf` whose buffers and images are `data:` URIs; `path` names it in
/// messages, and other URIs are looked up beside it.
pub fn load_scene_bytes(path: &Path, bytes: &[u8], options: &LoadOptions) -> Result<Scene, SceneError> {
    let err = |message: String| SceneError::Gltf { path: path.to_path_buf(), message };
    let dir = path.parent().unwrap_or(Path::new(""));
    let imp = import_bytes(bytes, dir, &Transform::default(), super::mesh::MAX_MESH_TRIANGLES).map_err(err)?;
    scene_of(path, imp, options)
}

/// The scene of a glTF file given on its own, `imp` its contents ([`load_scene`]).
fn scene_of(path: &Path, imp: Import, options: &LoadOptions) -> Result<Scene, SceneError> {
    let err = |message: String| SceneError::Gltf { path: path.to_path_buf(), message };
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
    let bytes = crate::input::read_bytes(path, MAX_GLTF_FILE_BYTES).map_err(|e| match e {
        crate::input::ReadError::Io(e) => format!("cannot open: {e}"),
        e => format!("cannot read: {e}"),
    })?;
    import_bytes(&bytes, path.parent().unwrap_or(Path::new("")), placement, triangle_limit)
}

/// [`import`] of a file's bytes; relative URIs are looked up in `dir`.
pub fn import_bytes(bytes: &[u8], dir: &Path, placement: &Transform, triangle_limit: usize) -> Res<Import> {
    if bytes.len() as u64 > MAX_GLTF_FILE_BYTES {
        return Err(format!("cannot read: {}", crate::input::ReadError::TooLarge { limit: MAX_GLTF_FILE_BYTES }));
    }
    // The crate's validation indexes some arrays unchecked (a primitive's attribute naming a
    // missing accessor can panic in it): a panic there, or in what it let through, is an error
    // about the file too.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| import_checked(bytes, dir, placement, triangle_limit)))
        .unwrap_or_else(|payload| {
            let what = payload
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| payload.downcast_ref::<&str>().copied())
                .unwrap_or("");
            Err(format!("malformed glTF file (reading it failed: {what})"))
        })
}

fn import_checked(bytes: &[u8], dir: &Path, placement: &Transform, triangle_limit: usize) -> Res<Import> {
    let (gltf, leniencies) = parse(bytes)?;
    validate(gltf.document.as_json())?;
    let dir = dir.to_path_buf();
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
