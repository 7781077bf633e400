//! The TOML scene file → a validated [`Scene`].
//!
//! The file is deserialized into the serde structs below, whose fields are `Spanned` so that
//! every semantic check can point at the offending value. When `toml` itself fails (syntax,
//! wrong type, unknown or missing key), the document is parsed once more into `toml`'s
//! spanned tree to find the path of the key or value at the error's position.
//! Every error reads `FILE:LINE:COLUMN: FIELD: message` (line and column 1-based, the column
//! counted in characters), FIELD being a path such as `objects[2].radius`.

use super::mesh::{self, Transform};
use super::polygon;
use super::texture::{self, ImageKind, Texture};
use super::{
    Camera, Environment, Geometry, ImageSize, Light, Material, MaterialKind, Object, RenderMode, RenderSettings, Scene,
    SceneError,
};
use crate::geometry::{Cylinder, Plane, Sphere, Triangle};
use crate::math::V3;
use serde::Deserialize;
use std::collections::HashMap;
use std::fmt;
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: i64 = 16384;
/// Largest accepted image, in pixels (8192 × 8192).
pub const MAX_IMAGE_PIXELS: u64 = 67_108_864;
pub const MAX_OBJECTS: usize = 1_000_000;
pub const MAX_MATERIALS: usize = 4096;
pub const MAX_LIGHTS: usize = 1024;
/// Most triangles (triangles, polygons and meshes together) in one scene.
pub const MAX_SCENE_TRIANGLES: usize = 64_000_000;
/// Largest scene file read: a million small objects take about 70 MB of TOML (and parsing
/// needs some 40 bytes of memory per byte of it).
pub const MAX_SCENE_FILE_BYTES: u64 = 256 << 20;
pub const MAX_DEPTH: i64 = 64;
pub const MAX_SPP: i64 = 65536;
/// Most texels of an environment map as rendered (4096 × 2048): its linear RGB texels take 12
/// bytes each, 96 MiB, which fits one GPU storage buffer on lavapipe (128 MiB). Larger maps are
/// halved (2 × 2 box filter) until they fit, with a warning.
pub const MAX_ENVIRONMENT_TEXELS: u64 = 4096 * 2048;

/// What a glTF object adds to the scene besides its geometry.
struct GltfLoaded<'a> {
    materials: &'a mut Vec<Material>,
    textures: &'a mut Vec<Texture>,
    lights: &'a mut Vec<Light>,
    warnings: &'a mut Vec<String>,
}

/// Reads and validates the scene file at `path`; relative mesh paths are resolved against
/// the file's directory.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let src = crate::input::read_text(path, MAX_SCENE_FILE_BYTES)
        .map_err(|e| SceneError::Io { path: path.to_path_buf(), message: e.to_string() })?;
    let base_dir = path.parent().unwrap_or(Path::new(""));
    parse(&src, path, base_dir)
}

/// Parses and validates scene source `src`. `path` names the file in error messages only;
/// mesh files are looked up relative to `base_dir`.
pub fn parse(src: &str, path: &Path, base_dir: &Path) -> Result<Scene, SceneError> {
    let cx = Cx { src, path, base_dir };
    cx.prescan_counts()?;
    let def: SceneDef = toml::from_str(src).map_err(|e| {
        // Only on error is the document parsed again, to name the field at the error's span
        // (a syntax error fails this parse too and is reported as such).
        match toml::de::DeTable::parse(src) {
            Ok(doc) => cx.toml_error(&e, Some(&doc)),
            Err(syntax) => cx.toml_error(&syntax, None),
        }
    })?;
    cx.build(def)
}

// ---------------------------------------------------------------------------------------
// The file's shape.

type SVec = Spanned<Vec<Spanned<f64>>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneDef {
    camera: Spanned<CameraDef>,
    image: Spanned<ImageDef>,
    #[serde(default)]
    render: Option<Spanned<RenderDef>>,
    #[serde(default)]
    materials: Vec<Spanned<MaterialDef>>,
    #[serde(default)]
    objects: Vec<Spanned<ObjectDef>>,
    #[serde(default)]
    lights: Vec<Spanned<LightDef>>,
    #[serde(default)]
    environment: Option<Spanned<EnvironmentDef>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvironmentDef {
    radiance: Option<SVec>,
    file: Option<Spanned<String>>,
    strength: Option<Spanned<f64>>,
    rotation: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraDef {
    eye: SVec,
    look_at: SVec,
    up: SVec,
    fov_y: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ImageDef {
    width: Spanned<i64>,
    height: Spanned<i64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderDef {
    mode: Option<Spanned<String>>,
    max_depth: Option<Spanned<i64>>,
    spp: Option<Spanned<i64>>,
    background: Option<SVec>,
    ambient: Option<SVec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialDef {
    name: Spanned<String>,
    #[serde(rename = "type")]
    kind: Spanned<String>,
    color: Option<SVec>,
    ior: Option<Spanned<f64>>,
    radiance: Option<SVec>,
    roughness: Option<Spanned<f64>>,
    two_sided: Option<Spanned<bool>>,
    texture: Option<Spanned<String>>,
    radiance_texture: Option<Spanned<String>>,
}

/// Every key any object type has; which belong to which type is checked in `object`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectDef {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    material: Option<Spanned<String>>,
    center: Option<SVec>,
    radius: Option<Spanned<f64>>,
    p1: Option<SVec>,
    p2: Option<SVec>,
    caps: Option<Spanned<bool>>,
    point: Option<SVec>,
    normal: Option<SVec>,
    vertices: Option<Spanned<Vec<SVec>>>,
    file: Option<Spanned<String>>,
    translate: Option<SVec>,
    scale: Option<Spanned<ScaleDef>>,
    rotate: Option<SVec>,
}

impl ObjectDef {
    /// The optional keys present, with their spans, in file order.
    fn present(&self) -> Vec<(&'static str, Range<usize>)> {
        fn s<T>(v: &Option<Spanned<T>>) -> Option<Range<usize>> {
            v.as_ref().map(Spanned::span)
        }
        let mut keys: Vec<_> = [
            ("material", s(&self.material)),
            ("center", s(&self.center)),
            ("radius", s(&self.radius)),
            ("p1", s(&self.p1)),
            ("p2", s(&self.p2)),
            ("caps", s(&self.caps)),
            ("point", s(&self.point)),
            ("normal", s(&self.normal)),
            ("vertices", s(&self.vertices)),
            ("file", s(&self.file)),
            ("translate", s(&self.translate)),
            ("scale", s(&self.scale)),
            ("rotate", s(&self.rotate)),
        ]
        .into_iter()
        .filter_map(|(k, sp)| sp.map(|sp| (k, sp)))
        .collect();
        keys.sort_by_key(|(_, sp)| sp.start);
        keys
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightDef {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    position: Option<SVec>,
    direction: Option<SVec>,
    intensity: Option<SVec>,
}

/// A mesh's `scale`: one number for all axes, or `[x, y, z]`.
enum ScaleDef {
    Uniform(f64),
    PerAxis(Vec<Spanned<f64>>),
}

impl<'de> Deserialize<'de> for ScaleDef {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = ScaleDef;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array [x, y, z]")
            }
            fn visit_i64<E>(self, v: i64) -> Result<ScaleDef, E> {
                Ok(ScaleDef::Uniform(v as f64))
            }
            fn visit_u64<E>(self, v: u64) -> Result<ScaleDef, E> {
                Ok(ScaleDef::Uniform(v as f64))
            }
            fn visit_f64<E>(self, v: f64) -> Result<ScaleDef, E> {
                Ok(ScaleDef::Uniform(v))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<ScaleDef, A::Error> {
                let mut out = Vec::new();
                while let Some(x) = seq.next_element::<Spanned<f64>>()? {
                    out.push(x);
                }
                Ok(ScaleDef::PerAxis(out))
            }
        }
        d.deserialize_any(Visit)
    }
}

const LIGHT_TYPES: [(&str, &[&str]); 2] =
    [("point", &["position", "intensity"]), ("directional", &["direction", "intensity"])];

const OBJECT_TYPES: [(&str, &[&str]); 7] = [
    ("sphere", &["center", "radius", "material"]),
    ("cylinder", &["p1", "p2", "radius", "caps", "material"]),
    ("plane", &["point", "normal", "material"]),
    ("triangle", &["vertices", "material"]),
    ("polygon", &["vertices", "material"]),
    ("mesh", &["file", "translate", "scale", "rotate", "material"]),
    ("gltf", &["file", "translate", "scale", "rotate"]),
];

// ---------------------------------------------------------------------------------------
// Errors and spans.

struct Cx<'a> {
    src: &'a str,
    path: &'a Path,
    base_dir: &'a Path,
}

type Res<T> = Result<T, SceneError>;

impl Cx<'_> {
    /// 1-based line and column (in characters) of a byte offset.
    fn line_col(&self, offset: usize) -> (usize, usize) {
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

    fn at(&self, span: Range<usize>, field: impl Into<String>, message: impl Into<String>) -> SceneError {
        let (line, column) = self.line_col(span.start);
        SceneError::At { path: self.path.to_path_buf(), line, column, field: field.into(), message: message.into() }
    }

    fn too_large(&self, message: String) -> SceneError {
        SceneError::TooLarge { path: self.path.to_path_buf(), message }
    }

    /// A `toml` syntax or deserialization error in our format. With the parsed document, the
    /// field is the path of the innermost key or value at the error's position.
    fn toml_error(&self, e: &toml::de::Error, doc: Option<&Spanned<toml::de::DeTable>>) -> SceneError {
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
    fn prescan_counts(&self) -> Res<()> {
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
fn unknown_key_of_type(doc: &toml::de::DeTable, field: &str, message: &str) -> Option<String> {
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

fn join(path: &str, key: &str) -> String {
    if path.is_empty() { key.to_string() } else { format!("{path}.{key}") }
}

fn contains(span: &Range<usize>, off: usize) -> bool {
    (span.start <= off && off < span.end) || (span.start == off && span.end == off)
}

/// Records in `best` the path of the smallest key or value span holding `off` (deeper wins
/// a tie).
fn find_path(table: &toml::de::DeTable, off: usize, path: &str, best: &mut Option<(usize, usize, String)>) {
    for (key, value) in table {
        let p = join(path, key.get_ref());
        consider(key.span(), off, &p, best);
        find_in_value(value, off, &p, best);
    }
}

fn find_in_value(
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
fn find_table(table: &toml::de::DeTable, span: &Range<usize>, path: &str, found: &mut Option<String>) {
    for (key, value) in table {
        let p = join(path, key.get_ref());
        find_table_in_value(value, span, &p, found);
    }
}

fn find_table_in_value(
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

fn consider(span: Range<usize>, off: usize, path: &str, best: &mut Option<(usize, usize, String)>) {
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
fn tidy_toml_message(m: &str) -> String {
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

fn known_list<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let v: Vec<&str> = names.collect();
    if v.is_empty() { "(none)".to_string() } else { v.join(", ") }
}

// ---------------------------------------------------------------------------------------
// Validation.

impl Cx<'_> {
    fn number(&self, v: &Spanned<f64>, field: &str) -> Res<f64> {
        let x = *v.get_ref();
        if x.is_finite() { Ok(x) } else { Err(self.at(v.span(), field, format!("must be finite, got {}", num(x)))) }
    }

    fn vec3(&self, v: &SVec, field: &str) -> Res<V3<f64>> {
        let comps = v.get_ref();
        if comps.len() != 3 {
            return Err(self.at(v.span(), field, format!("must have 3 components [x, y, z], got {}", comps.len())));
        }
        let mut out = [0.0; 3];
        for (k, c) in comps.iter().enumerate() {
            out[k] = self.number(c, &format!("{field}[{k}]"))?;
        }
        Ok(V3::from_array(out))
    }

    /// A colour or intensity: three finite components ≥ 0, and ≤ `max` if given.
    fn rgb(&self, v: &SVec, field: &str, max: Option<f64>) -> Res<[f64; 3]> {
        let c = self.vec3(v, field)?.to_array();
        for (k, &x) in c.iter().enumerate() {
            let span = v.get_ref()[k].span();
            if x < 0.0 {
                return Err(self.at(span, format!("{field}[{k}]"), format!("must be >= 0, got {x}")));
            }
            if let Some(m) = max
                && x > m
            {
                return Err(self.at(span, format!("{field}[{k}]"), format!("must be <= {m}, got {x}")));
            }
        }
        Ok(c)
    }

    /// A non-zero direction, normalised.
    fn direction(&self, v: &SVec, field: &str) -> Res<V3<f64>> {
        let d = self.vec3(v, field)?;
        unit(d).ok_or_else(|| self.at(v.span(), field, "must be non-zero"))
    }

    fn int_in(&self, v: &Spanned<i64>, field: &str, lo: i64, hi: i64) -> Res<i64> {
        let x = *v.get_ref();
        if (lo..=hi).contains(&x) {
            Ok(x)
        } else {
            Err(self.at(v.span(), field, format!("must be an integer in {lo}..={hi}, got {x}")))
        }
    }

    fn build(&self, def: SceneDef) -> Res<Scene> {
        // Sizes first, before anything is allocated for them.
        let image = self.image(&def.image)?;
        if def.materials.len() > MAX_MATERIALS {
            return Err(
                self.too_large(format!("too many materials: {} (at most {MAX_MATERIALS})", def.materials.len()))
            );
        }
        if def.objects.len() > MAX_OBJECTS {
            return Err(self.too_large(format!("too many objects: {} (at most {MAX_OBJECTS})", def.objects.len())));
        }
        if def.lights.len() > MAX_LIGHTS {
            return Err(self.too_large(format!("too many lights: {} (at most {MAX_LIGHTS})", def.lights.len())));
        }

        let camera = self.camera(def.camera.get_ref())?;
        let mut textures: Vec<Texture> = Vec::new();
        let mut texture_files: HashMap<std::path::PathBuf, u32> = HashMap::new();
        let mut warnings = Vec::new();
        let environment = match &def.environment {
            Some(e) => Some(self.environment(e, &mut warnings)?),
            None => None,
        };
        let render = match &def.render {
            Some(r) => self.render(r.get_ref(), environment.is_some())?,
            None => {
                RenderSettings { ambient: Self::default_ambient(environment.is_some()), ..RenderSettings::default() }
            }
        };

        let mut materials = Vec::with_capacity(def.materials.len() + 1);
        let mut by_name: HashMap<&str, usize> = HashMap::new();
        for (i, m) in def.materials.iter().enumerate() {
            let field = format!("materials[{i}]");
            let mat = self.material(m, &field, &mut textures, &mut texture_files)?;
            let name = m.get_ref().name.get_ref().as_str();
            if let Some(&first) = by_name.get(name) {
                return Err(self.at(
                    m.get_ref().name.span(),
                    format!("{field}.name"),
                    format!("duplicate material name \"{name}\" (also materials[{first}])"),
                ));
            }
            by_name.insert(name, i);
            materials.push(mat);
        }

        // Check the light list before loading any mesh: it is cheap.
        let mut lights = def
            .lights
            .iter()
            .enumerate()
            .map(|(i, l)| self.light(l, &format!("lights[{i}]")))
            .collect::<Res<Vec<_>>>()?;

        // Objects without a material get the grey default, appended after every other
        // material (glTF files add theirs as they load): its index is patched in at the end.
        const DEFAULT: u32 = u32::MAX;
        let mut triangles: usize = 0;
        let mut objects = Vec::with_capacity(def.objects.len());
        for (i, o) in def.objects.iter().enumerate() {
            let field = format!("objects[{i}]");
            let budget = MAX_SCENE_TRIANGLES - triangles;
            let (geometry, material) = if o.get_ref().kind.get_ref() == "gltf" {
                let mut loaded = GltfLoaded {
                    materials: &mut materials,
                    textures: &mut textures,
                    lights: &mut lights,
                    warnings: &mut warnings,
                };
                self.gltf_object(o, &field, budget, &mut loaded)?
            } else {
                let geometry = self.object(o, &field, budget)?;
                let material = match &o.get_ref().material {
                    Some(name) => match by_name.get(name.get_ref().as_str()) {
                        Some(&m) => m as u32,
                        None => {
                            return Err(self.at(
                                name.span(),
                                format!("{field}.material"),
                                format!(
                                    "unknown material \"{}\"; known: {}",
                                    name.get_ref(),
                                    known_list(def.materials.iter().map(|m| m.get_ref().name.get_ref().as_str()))
                                ),
                            ));
                        }
                    },
                    None => DEFAULT,
                };
                (geometry, material)
            };
            triangles += match &geometry {
                Geometry::Triangle(_) => 1,
                Geometry::Polygon { triangles, .. } | Geometry::Mesh { triangles, .. } => triangles.len(),
                _ => 0,
            };
            if triangles > MAX_SCENE_TRIANGLES {
                return Err(self.too_large(format!(
                    "the scene has more than {MAX_SCENE_TRIANGLES} triangles (reached at {field})"
                )));
            }
            if materials.len() > MAX_MATERIALS {
                return Err(self.too_large(format!(
                    "too many materials: more than {MAX_MATERIALS} (reached at {field}, a glTF file's materials count)"
                )));
            }
            objects.push(Object { geometry, material });
        }
        if objects.iter().any(|o| o.material == DEFAULT) {
            let index = materials.len() as u32;
            materials.push(Material::default_grey());
            for o in objects.iter_mut().filter(|o| o.material == DEFAULT) {
                o.material = index;
            }
        }
        self.texture_warnings(&objects, &materials, &mut warnings);

        Ok(Scene { camera, image, render, materials, objects, lights, textures, environment, warnings })
    }

    /// Textures that cannot show: on objects that are not meshes, or meshes without texture
    /// coordinates.
    fn texture_warnings(&self, objects: &[Object], materials: &[Material], warnings: &mut Vec<String>) {
        for (i, o) in objects.iter().enumerate() {
            let m = &materials[o.material as usize];
            if m.color_texture.is_none() && m.radiance_texture.is_none() {
                continue;
            }
            match &o.geometry {
                Geometry::Mesh { uvs, materials: per_triangle, .. } if uvs.is_empty() && per_triangle.is_empty() => {
                    warnings.push(format!(
                        "{}: objects[{i}]: material \"{}\" has a texture but the mesh has no texture coordinates (vt): \
                         it reads the texel at (0, 0)",
                        self.path.display(),
                        m.name
                    ))
                }
                Geometry::Mesh { .. } => {}
                g => warnings.push(format!(
                    "{}: objects[{i}]: material \"{}\" has a texture, which only meshes show (this is a {})",
                    self.path.display(),
                    m.name,
                    g.kind().name()
                )),
            }
        }
    }

    /// `[environment]`: exactly one of `radiance` and `file`.
    fn environment(&self, e: &Spanned<EnvironmentDef>, warnings: &mut Vec<String>) -> Res<Environment> {
        let d = e.get_ref();
        let mut env = match (&d.radiance, &d.file) {
            (Some(r), None) => Environment::constant(self.rgb(r, "environment.radiance", None)?),
            (None, Some(f)) => {
                if f.get_ref().is_empty() {
                    return Err(self.at(f.span(), "environment.file", "must not be empty"));
                }
                let path = self.base_dir.join(f.get_ref());
                let mut map = Texture::load(&path, ImageKind::Radiance)
                    .map_err(|m| self.at(f.span(), "environment.file", format!("{}: {m}", path.display())))?;
                while map.width as u64 * map.height as u64 > MAX_ENVIRONMENT_TEXELS {
                    let (w, h) = (map.width, map.height);
                    map = map.halved();
                    warnings.push(format!(
                        "{}: environment.file: {}: {w} x {h} texels halved to {} x {} (at most {MAX_ENVIRONMENT_TEXELS} \
                         texels are rendered)",
                        self.path.display(),
                        path.display(),
                        map.width,
                        map.height
                    ));
                }
                map.wrap = [texture::Wrap::Repeat, texture::Wrap::Clamp];
                Environment { map: Some(map), ..Environment::constant([1.0; 3]) }
            }
            (Some(_), Some(f)) => {
                return Err(self.at(f.span(), "environment.file", "give either radiance or file, not both"));
            }
            (None, None) => {
                return Err(self.at(e.span(), "environment", "needs radiance = [r, g, b] or file = \"map.exr\""));
            }
        };
        if let Some(s) = &d.strength {
            env.strength = self.number(s, "environment.strength")?;
            if env.strength < 0.0 {
                return Err(self.at(s.span(), "environment.strength", format!("must be >= 0, got {}", env.strength)));
            }
        }
        if let Some(r) = &d.rotation {
            env.rotation_deg = self.number(r, "environment.rotation")?;
        }
        Ok(env)
    }

    /// The image file `name` (relative to the scene's folder) as a colour texture: its index
    /// in `textures`, each file decoded once.
    fn color_texture(
        &self,
        name: &Spanned<String>,
        field: &str,
        textures: &mut Vec<Texture>,
        files: &mut HashMap<std::path::PathBuf, u32>,
    ) -> Res<u32> {
        if name.get_ref().is_empty() {
            return Err(self.at(name.span(), field, "must not be empty"));
        }
        let path = self.base_dir.join(name.get_ref());
        if let Some(&k) = files.get(&path) {
            return Ok(k);
        }
        if textures.len() >= texture::MAX_TEXTURES {
            return Err(self.at(name.span(), field, format!("more than {} textures", texture::MAX_TEXTURES)));
        }
        let t = Texture::load(&path, ImageKind::Color)
            .map_err(|m| self.at(name.span(), field, format!("{}: {m}", path.display())))?;
        let k = textures.len() as u32;
        textures.push(t);
        files.insert(path, k);
        Ok(k)
    }

    /// `[[objects]] type = "gltf"`: the file's triangles with their materials (appended to
    /// `loaded.materials`, their textures to `loaded.textures`) and its punctual lights, placed
    /// by the object's transform. Its cameras are not used (the scene file has its own).
    fn gltf_object(
        &self,
        o: &Spanned<ObjectDef>,
        field: &str,
        triangle_budget: usize,
        loaded: &mut GltfLoaded,
    ) -> Res<(Geometry, u32)> {
        let d = o.get_ref();
        let allowed = OBJECT_TYPES.iter().find(|(t, _)| *t == "gltf").expect("gltf is an object type").1;
        for (key, span) in d.present() {
            if !allowed.contains(&key) {
                let hint = if key == "material" { " (a glTF file brings its own materials)" } else { "" };
                return Err(self.at(
                    span,
                    format!("{field}.{key}"),
                    format!("not a field of a gltf (its fields: type, {}){hint}", allowed.join(", ")),
                ));
            }
        }
        let Some(file) = &d.file else {
            return Err(self.at(o.span(), format!("{field}.file"), "missing (a gltf needs file)"));
        };
        if file.get_ref().is_empty() {
            return Err(self.at(file.span(), format!("{field}.file"), "must not be empty"));
        }
        let t = self.placement(d, field)?;
        let path = self.base_dir.join(file.get_ref());
        let mesh_error = |mut message: String| {
            if triangle_budget < mesh::MAX_MESH_TRIANGLES && message.starts_with("more than") {
                message += &format!(" (a scene holds at most {MAX_SCENE_TRIANGLES} triangles in all)");
            }
            let (line, column) = self.line_col(file.span().start);
            SceneError::Mesh {
                path: self.path.to_path_buf(),
                line,
                column,
                field: format!("{field}.file"),
                mesh: path.clone(),
                message,
            }
        };
        let imp = super::gltf::import(&path, &t, triangle_budget.min(mesh::MAX_MESH_TRIANGLES)).map_err(mesh_error)?;
        if loaded.textures.len() + imp.textures.len() > texture::MAX_TEXTURES {
            return Err(mesh_error(format!("more than {} textures in the scene", texture::MAX_TEXTURES)));
        }
        let (m0, t0) = (loaded.materials.len() as u32, loaded.textures.len() as u32);
        let stem = path.file_name().map_or_else(|| path.display().to_string(), |f| f.to_string_lossy().into_owned());
        for mut m in imp.materials {
            m.name = format!("{stem}: {}", m.name);
            m.color_texture = m.color_texture.map(|k| k + t0);
            m.radiance_texture = m.radiance_texture.map(|k| k + t0);
            loaded.materials.push(m);
        }
        loaded.textures.extend(imp.textures);
        loaded.lights.extend(imp.lights);
        loaded
            .warnings
            .extend(imp.warnings.into_iter().map(|w| format!("{}: {field}: {stem}: {w}", self.path.display())));
        let materials: Vec<u32> = imp.triangle_materials.iter().map(|&m| m + m0).collect();
        let material = materials.first().copied().unwrap_or(m0);
        Ok((Geometry::Mesh { file: path, triangles: imp.triangles, uvs: imp.uvs, materials }, material))
    }

    /// A mesh's or glTF object's `translate`, `rotate`, `scale`.
    fn placement(&self, d: &ObjectDef, field: &str) -> Res<Transform> {
        let mut t = Transform::default();
        if let Some(v) = &d.translate {
            t.translate = self.vec3(v, &format!("{field}.translate"))?.to_array();
        }
        if let Some(v) = &d.rotate {
            t.rotate_deg = self.vec3(v, &format!("{field}.rotate"))?.to_array();
        }
        if let Some(s) = &d.scale {
            t.scale = self.scale(s, &format!("{field}.scale"))?;
        }
        Ok(t)
    }

    /// `[render] ambient` when the file gives none: with an environment, none (it lights
    /// Whitted's diffuse surfaces itself).
    fn default_ambient(environment: bool) -> [f64; 3] {
        if environment { [0.0; 3] } else { RenderSettings::default().ambient }
    }

    fn image(&self, im: &Spanned<ImageDef>) -> Res<ImageSize> {
        let d = im.get_ref();
        let w = self.int_in(&d.width, "image.width", 1, MAX_IMAGE_SIDE)?;
        let h = self.int_in(&d.height, "image.height", 1, MAX_IMAGE_SIDE)?;
        let pixels = (w as u64) * (h as u64);
        if pixels > MAX_IMAGE_PIXELS {
            return Err(self.at(
                im.span(),
                "image",
                format!("{w} × {h} = {pixels} pixels exceeds the limit of {MAX_IMAGE_PIXELS}"),
            ));
        }
        Ok(ImageSize { width: w as u32, height: h as u32 })
    }

    fn camera(&self, c: &CameraDef) -> Res<Camera> {
        let eye = self.vec3(&c.eye, "camera.eye")?;
        let look_at = self.vec3(&c.look_at, "camera.look_at")?;
        let up = self.vec3(&c.up, "camera.up")?;
        let fov_y = self.number(&c.fov_y, "camera.fov_y")?;
        if !(fov_y > 0.0 && fov_y < 180.0) {
            return Err(self.at(c.fov_y.span(), "camera.fov_y", format!("must be in (0, 180) degrees, got {fov_y}")));
        }
        let view = look_at - eye;
        if !view.is_finite() {
            return Err(self.at(c.look_at.span(), "camera.look_at", "is too far from eye (overflow)"));
        }
        let Some(view) = unit(view) else {
            return Err(self.at(c.look_at.span(), "camera.look_at", "must differ from eye"));
        };
        let Some(u) = unit(up) else {
            return Err(self.at(c.up.span(), "camera.up", "must be non-zero"));
        };
        if u.cross(view).length() <= 1e-9 {
            return Err(self.at(
                c.up.span(),
                "camera.up",
                "must not be parallel to the view direction (look_at - eye)",
            ));
        }
        Ok(Camera { eye, look_at, up, fov_y })
    }

    /// `[render]`; with an `[environment]` (`environment`), `background` is the environment and
    /// `ambient` defaults to none.
    fn render(&self, r: &RenderDef, environment: bool) -> Res<RenderSettings> {
        let mut s = RenderSettings { ambient: Self::default_ambient(environment), ..RenderSettings::default() };
        if let Some(v) = &r.mode {
            let name = v.get_ref().as_str();
            s.mode = RenderMode::ALL.into_iter().find(|m| m.name() == name).ok_or_else(|| {
                self.at(
                    v.span(),
                    "render.mode",
                    format!(
                        "unknown render mode \"{name}\"; known: {}",
                        known_list(RenderMode::ALL.iter().map(|m| m.name()))
                    ),
                )
            })?;
        }
        if let Some(v) = &r.max_depth {
            s.max_depth = self.int_in(v, "render.max_depth", 0, MAX_DEPTH)? as u32;
        }
        if let Some(v) = &r.spp {
            s.spp = self.int_in(v, "render.spp", 1, MAX_SPP)? as u32;
        }
        if let Some(v) = &r.background {
            if environment {
                return Err(self.at(
                    v.span(),
                    "render.background",
                    "not used with [environment]: the environment is what rays that leave the scene see",
                ));
            }
            s.background = self.rgb(v, "render.background", None)?;
        }
        if let Some(v) = &r.ambient {
            s.ambient = self.rgb(v, "render.ambient", None)?;
        }
        Ok(s)
    }

    fn material(
        &self,
        m: &Spanned<MaterialDef>,
        field: &str,
        textures: &mut Vec<Texture>,
        files: &mut HashMap<std::path::PathBuf, u32>,
    ) -> Res<Material> {
        let d = m.get_ref();
        let name = d.name.get_ref();
        if name.is_empty() {
            return Err(self.at(d.name.span(), format!("{field}.name"), "must not be empty"));
        }
        let tname = d.kind.get_ref().as_str();
        let Some(kind) = MaterialKind::ALL.into_iter().find(|k| k.name() == tname) else {
            return Err(self.at(
                d.kind.span(),
                format!("{field}.type"),
                format!(
                    "unknown material type \"{tname}\"; known: {}",
                    known_list(MaterialKind::ALL.iter().map(|k| k.name()))
                ),
            ));
        };
        let not_a_field = |key: &str, span: Range<usize>| {
            self.at(span, format!("{field}.{key}"), format!("not a field of a {tname} material"))
        };
        if kind != MaterialKind::Dielectric
            && let Some(ior) = &d.ior
        {
            return Err(not_a_field("ior", ior.span()));
        }
        if kind != MaterialKind::Emissive
            && let Some(r) = &d.radiance
        {
            return Err(not_a_field("radiance", r.span()));
        }
        if kind != MaterialKind::Emissive
            && let Some(r) = &d.two_sided
        {
            return Err(not_a_field("two_sided", r.span()));
        }
        if kind != MaterialKind::Mirror
            && let Some(r) = &d.roughness
        {
            return Err(not_a_field("roughness", r.span()));
        }
        if kind != MaterialKind::Emissive
            && let Some(r) = &d.radiance_texture
        {
            return Err(not_a_field("radiance_texture", r.span()));
        }
        let color_texture = match &d.texture {
            Some(t) => Some(self.color_texture(t, &format!("{field}.texture"), textures, files)?),
            None => None,
        };
        let radiance_texture = match &d.radiance_texture {
            Some(t) => Some(self.color_texture(t, &format!("{field}.radiance_texture"), textures, files)?),
            None => None,
        };
        // An emissive surface reflects like a diffuse one of albedo `color`: black by default,
        // a pure light.
        let default_color = match kind {
            MaterialKind::Dielectric => [1.0; 3],
            MaterialKind::Emissive => [0.0; 3],
            _ => [0.7; 3],
        };
        let max = Some(1.0);
        let color = match &d.color {
            Some(c) => self.rgb(c, &format!("{field}.color"), max)?,
            None => default_color,
        };
        let mut ior = 1.0;
        if kind == MaterialKind::Dielectric {
            ior = 1.5;
            if let Some(v) = &d.ior {
                ior = self.number(v, &format!("{field}.ior"))?;
                if ior <= 0.0 {
                    return Err(self.at(
                        v.span(),
                        format!("{field}.ior"),
                        format!("must be > 0 and finite, got {ior}"),
                    ));
                }
            }
        }
        let mut radiance = [0.0; 3];
        if kind == MaterialKind::Emissive {
            let Some(r) = &d.radiance else {
                return Err(self.at(
                    m.span(),
                    format!("{field}.radiance"),
                    "missing (an emissive material needs radiance)",
                ));
            };
            radiance = self.rgb(r, &format!("{field}.radiance"), None)?;
        }
        let mut roughness = 0.0;
        if let Some(v) = &d.roughness {
            roughness = self.number(v, &format!("{field}.roughness"))?;
            if !(0.0..=1.0).contains(&roughness) {
                return Err(self.at(
                    v.span(),
                    format!("{field}.roughness"),
                    format!("must be in [0, 1] (GGX alpha), got {roughness}"),
                ));
            }
        }
        let two_sided = d.two_sided.as_ref().is_some_and(|v| *v.get_ref());
        Ok(Material {
            name: name.clone(),
            kind,
            color,
            ior,
            radiance,
            roughness,
            two_sided,
            color_texture,
            radiance_texture,
        })
    }

    fn light(&self, l: &Spanned<LightDef>, field: &str) -> Res<Light> {
        let d = l.get_ref();
        let tname = d.kind.get_ref().as_str();
        let require = |v: &Option<SVec>, key: &str| -> Res<SVec> {
            v.clone().ok_or_else(|| {
                self.at(l.span(), format!("{field}.{key}"), format!("missing (a {tname} light needs {key})"))
            })
        };
        let not_a_field = |key: &str, span: Range<usize>| {
            self.at(span, format!("{field}.{key}"), format!("not a field of a {tname} light"))
        };
        let intensity = |this: &Self| -> Res<[f64; 3]> {
            this.rgb(&require(&d.intensity, "intensity")?, &format!("{field}.intensity"), None)
        };
        match tname {
            "point" => {
                if let Some(v) = &d.direction {
                    return Err(not_a_field("direction", v.span()));
                }
                let position = self.vec3(&require(&d.position, "position")?, &format!("{field}.position"))?;
                Ok(Light::Point { position, intensity: intensity(self)? })
            }
            "directional" => {
                if let Some(v) = &d.position {
                    return Err(not_a_field("position", v.span()));
                }
                let direction = self.direction(&require(&d.direction, "direction")?, &format!("{field}.direction"))?;
                Ok(Light::Directional { direction, intensity: intensity(self)? })
            }
            _ => Err(self.at(
                d.kind.span(),
                format!("{field}.type"),
                format!("unknown light type \"{tname}\"; known: point, directional"),
            )),
        }
    }

    /// Object `o`; a mesh may add at most `triangle_budget` triangles to the scene.
    fn object(&self, o: &Spanned<ObjectDef>, field: &str, triangle_budget: usize) -> Res<Geometry> {
        let d = o.get_ref();
        let tname = d.kind.get_ref().as_str();
        let Some((_, allowed)) = OBJECT_TYPES.iter().find(|(t, _)| *t == tname) else {
            return Err(self.at(
                d.kind.span(),
                format!("{field}.type"),
                format!("unknown object type \"{tname}\"; known: {}", known_list(OBJECT_TYPES.iter().map(|(t, _)| *t))),
            ));
        };
        for (key, span) in d.present() {
            if !allowed.contains(&key) {
                return Err(self.at(
                    span,
                    format!("{field}.{key}"),
                    format!("not a field of a {tname} (its fields: type, {})", allowed.join(", ")),
                ));
            }
        }
        let f = |key: &str| format!("{field}.{key}");
        let missing = |key: &str| {
            let needs: Vec<&str> = allowed
                .iter()
                .copied()
                .filter(|k| !matches!(*k, "material" | "caps" | "translate" | "scale" | "rotate"))
                .collect();
            self.at(o.span(), f(key), format!("missing (a {tname} needs {})", needs.join(", ")))
        };
        let req_vec = |v: &Option<SVec>, key: &str| -> Res<V3<f64>> {
            match v {
                Some(v) => self.vec3(v, &f(key)),
                None => Err(missing(key)),
            }
        };
        let radius = || -> Res<f64> {
            let Some(r) = &d.radius else {
                return Err(missing("radius"));
            };
            let x = self.number(r, &f("radius"))?;
            if x > 0.0 {
                Ok(x)
            } else {
                Err(self.at(r.span(), f("radius"), format!("must be > 0 and finite, got {x}")))
            }
        };
        let vertices = || -> Res<(Vec<V3<f64>>, Range<usize>)> {
            let Some(vs) = &d.vertices else {
                return Err(missing("vertices"));
            };
            let pts = vs
                .get_ref()
                .iter()
                .enumerate()
                .map(|(k, v)| self.vec3(v, &format!("{}[{k}]", f("vertices"))))
                .collect::<Res<Vec<_>>>()?;
            Ok((pts, vs.span()))
        };
        match tname {
            "sphere" => {
                let center = req_vec(&d.center, "center")?;
                let radius = radius()?;
                Ok(Geometry::Sphere(Sphere { center, radius }))
            }
            "cylinder" => {
                let p1 = req_vec(&d.p1, "p1")?;
                let p2 = req_vec(&d.p2, "p2")?;
                let radius = radius()?;
                let axis = p2 - p1;
                let p2_span = d.p2.as_ref().map_or(o.span(), Spanned::span);
                if axis == V3::zero() {
                    return Err(self.at(p2_span, f("p2"), "must differ from p1 (the cylinder has no axis)"));
                }
                if !axis.is_finite() {
                    return Err(self.at(p2_span, f("p2"), "is too far from p1 (overflow)"));
                }
                let caps = d.caps.as_ref().is_none_or(|c| *c.get_ref());
                Ok(Geometry::Cylinder(Cylinder { p1, p2, radius, caps }))
            }
            "plane" => {
                let point = req_vec(&d.point, "point")?;
                let Some(n) = &d.normal else {
                    return Err(missing("normal"));
                };
                let normal = self.direction(n, &f("normal"))?;
                Ok(Geometry::Plane(Plane { point, normal }))
            }
            "triangle" => {
                let (v, span) = vertices()?;
                if v.len() != 3 {
                    return Err(self.at(
                        span,
                        f("vertices"),
                        format!("a triangle needs exactly 3 vertices, got {}", v.len()),
                    ));
                }
                let longest = (v[1] - v[0])
                    .length_squared()
                    .max((v[2] - v[1]).length_squared())
                    .max((v[0] - v[2]).length_squared());
                let cross = (v[1] - v[0]).cross(v[2] - v[0]).length();
                if !longest.is_finite() || !cross.is_finite() {
                    return Err(self.at(span, f("vertices"), "the triangle is too large (overflow)"));
                }
                if cross.is_nan() || cross <= 1e-12 * longest {
                    return Err(self.at(span, f("vertices"), "degenerate triangle: its vertices are collinear"));
                }
                Ok(Geometry::Triangle(Triangle { v: [v[0], v[1], v[2]] }))
            }
            "polygon" => {
                let (vertices, span) = vertices()?;
                let triangles = polygon::triangulate(&vertices).map_err(|m| self.at(span, f("vertices"), m))?;
                Ok(Geometry::Polygon { vertices, triangles })
            }
            "mesh" => {
                let Some(file) = &d.file else {
                    return Err(missing("file"));
                };
                if file.get_ref().is_empty() {
                    return Err(self.at(file.span(), f("file"), "must not be empty"));
                }
                let t = self.placement(d, field)?;
                let mesh_path = self.base_dir.join(file.get_ref());
                let (triangles, uvs) =
                    mesh::load_obj_with_uvs(&mesh_path, &t, triangle_budget).map_err(|mut message| {
                        if triangle_budget < mesh::MAX_MESH_TRIANGLES {
                            message += &format!(" (a scene holds at most {MAX_SCENE_TRIANGLES} triangles in all)");
                        }
                        let (line, column) = self.line_col(file.span().start);
                        SceneError::Mesh {
                            path: self.path.to_path_buf(),
                            line,
                            column,
                            field: f("file"),
                            mesh: mesh_path.clone(),
                            message,
                        }
                    })?;
                Ok(Geometry::Mesh { file: mesh_path, triangles, uvs, materials: Vec::new() })
            }
            _ => unreachable!("object types are checked above"),
        }
    }

    fn scale(&self, s: &Spanned<ScaleDef>, field: &str) -> Res<[f64; 3]> {
        let check = |x: f64, span: Range<usize>, field: &str| -> Res<f64> {
            if !x.is_finite() {
                Err(self.at(span, field, format!("must be finite, got {}", num(x))))
            } else if x == 0.0 {
                Err(self.at(span, field, "must be non-zero and finite, got 0"))
            } else {
                Ok(x)
            }
        };
        match s.get_ref() {
            ScaleDef::Uniform(x) => {
                let x = check(*x, s.span(), field)?;
                Ok([x; 3])
            }
            ScaleDef::PerAxis(v) => {
                if v.len() != 3 {
                    return Err(self.at(
                        s.span(),
                        field,
                        format!("must be a number or have 3 components [x, y, z], got {}", v.len()),
                    ));
                }
                let mut out = [0.0; 3];
                for (k, c) in v.iter().enumerate() {
                    out[k] = check(*c.get_ref(), c.span(), &format!("{field}[{k}]"))?;
                }
                Ok(out)
            }
        }
    }
}

/// A number as TOML spells it (`nan`, not Rust's `NaN`).
fn num(x: f64) -> String {
    if x.is_nan() { "nan".to_string() } else { x.to_string() }
}

/// v / |v|, computed without overflow; None for the zero vector.
fn unit(v: V3<f64>) -> Option<V3<f64>> {
    let m = v.abs().max_component();
    if m.is_nan() || m <= 0.0 || !m.is_finite() {
        return None;
    }
    let w = v / m;
    Some(w / w.length())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    const HEAD: &str = "[camera]\neye = [0, 0, -10]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nfov_y = 45\n\
                        [image]\nwidth = 64\nheight = 48\n";

    fn parse_str(src: &str) -> Result<Scene, SceneError> {
        parse(src, Path::new("t.toml"), Path::new("."))
    }

    fn err(src: &str) -> String {
        match parse_str(src) {
            Ok(_) => panic!("expected an error for\n{src}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn minimal_scene_with_defaults() {
        let s = parse_str(HEAD).unwrap();
        assert_eq!(s.image, ImageSize { width: 64, height: 48 });
        assert_eq!(s.render, RenderSettings::default());
        assert!(s.objects.is_empty() && s.materials.is_empty() && s.lights.is_empty());
        assert_eq!(s.camera.fov_y, 45.0);
    }

    #[test]
    fn integers_are_accepted_as_floats_and_default_material_appended() {
        let src = format!(
            "{HEAD}[[materials]]\nname = \"red\"\ntype = \"diffuse\"\ncolor = [1, 0, 0]\n\
             [[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 8]\nradius = 5\n\
             [[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 8]\nradius = 1\nmaterial = \"red\"\n\
             [[lights]]\ntype = \"directional\"\ndirection = [0, -2, 0]\nintensity = [1, 1, 1]\n"
        );
        let s = parse_str(&src).unwrap();
        assert_eq!(s.materials.len(), 2);
        assert_eq!(s.materials[1], Material::default_grey());
        assert_eq!(s.objects[0].material, 1);
        assert_eq!(s.objects[1].material, 0);
        assert_eq!(s.objects[0].geometry, Geometry::Sphere(Sphere { center: V3::new(0.0, 0.0, 8.0), radius: 5.0 }));
        assert_eq!(s.lights[0], Light::Directional { direction: V3::new(0.0, -1.0, 0.0), intensity: [1.0; 3] });
    }

    #[test]
    fn errors_point_at_the_value() {
        let src = format!("{HEAD}[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 8]\nradius = -1\n");
        let e = err(&src);
        assert_eq!(e, "t.toml:12:10: objects[0].radius: must be > 0 and finite, got -1");
        let src = format!("{HEAD}[[objects]]\ntype = \"sphere\"\ncenter = [0, inf, 8]\nradius = 1\n");
        assert_eq!(err(&src), "t.toml:11:14: objects[0].center[1]: must be finite, got inf");
    }

    #[test]
    fn toml_errors_name_the_field() {
        let e = err(&format!("{HEAD}[[objects]]\ntype = \"sphere\"\nradiuss = 1\n"));
        assert_eq!(
            e,
            "t.toml:11:1: objects[0].radiuss: unknown key `radiuss` for a sphere; it takes `type`, `center`, `radius`, \
             `material`"
        );
        let e = err(&format!("{HEAD}[[lights]]\ntype = \"directional\"\ndirecton = [0, -1, 0]\n"));
        assert!(
            e.ends_with("unknown key `directon` for a directional light; it takes `type`, `direction`, `intensity`")
        );
        let e = err(&format!("{HEAD}[[objects]]\ntype = \"sphere\"\nradius = \"big\"\n"));
        assert!(e.starts_with("t.toml:11:10: objects[0].radius: invalid type"), "{e}");
        assert!(e.contains("expected a number"), "{e}");
        let e = err("[image]\nwidth = 1\nheight = 1\n");
        assert!(e.starts_with("t.toml:1:1: camera: missing field `camera`"), "{e}");
        let e = err(&format!("{HEAD}[[objects]]\nradius = 1\n"));
        assert!(e.starts_with("t.toml:9:1: objects[0].type: missing field `type`"), "{e}");
        let e = err("[camera\n");
        assert!(e.starts_with("t.toml:1:"), "{e}");
        assert!(e.contains(": toml: "), "{e}");
        let e = err(&format!("{HEAD}[camera]\n"));
        assert!(e.contains("t.toml:9:"), "{e}");
    }

    #[test]
    fn column_counts_characters() {
        let src = format!("# äöü\n{HEAD}[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 8]\nradius = 0 # ü\n");
        assert!(err(&src).starts_with("t.toml:13:10: objects[0].radius"));
        let src = format!("{HEAD}[[materials]]\nname = \"ü\"\ntype = \"glass\"\n");
        assert!(err(&src).starts_with("t.toml:11:8: materials[0].type: unknown material type"));
    }

    #[test]
    fn field_not_of_the_type() {
        let e =
            err(&format!("{HEAD}[[objects]]\ntype = \"triangle\"\nvertices = [[0,0,0],[1,0,0],[0,1,0]]\nradius = 1\n"));
        assert!(e.contains("objects[0].radius: not a field of a triangle"), "{e}");
        let e = err(&format!("{HEAD}[[materials]]\nname = \"m\"\ntype = \"diffuse\"\nior = 1.3\n"));
        assert!(e.contains("materials[0].ior: not a field of a diffuse material"), "{e}");
    }

    #[test]
    fn mesh_scale_forms() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let go = |scale: &str| {
            let src = format!("{HEAD}[[objects]]\ntype = \"mesh\"\nfile = \"t.obj\"\nscale = {scale}\n");
            parse(&src, Path::new("t.toml"), dir.path())
        };
        let s = go("2").unwrap();
        let Geometry::Mesh { triangles, file, .. } = &s.objects[0].geometry else { panic!() };
        assert_eq!(triangles[0].v[1], V3::new(2.0, 0.0, 0.0));
        assert_eq!(file, &dir.path().join("t.obj"));
        let s = go("[1, 3, 1.5]").unwrap();
        let Geometry::Mesh { triangles, .. } = &s.objects[0].geometry else { panic!() };
        assert_eq!(triangles[0].v[2], V3::new(0.0, 3.0, 0.0));
        assert!(go("0").unwrap_err().to_string().contains("objects[0].scale: must be non-zero"));
        assert!(go("[1, 0, 1]").unwrap_err().to_string().contains("objects[0].scale[1]: must be non-zero"));
        assert!(go("[1, 1]").unwrap_err().to_string().contains("objects[0].scale: must be a number or have 3"));
        assert!(go("\"x\"").unwrap_err().to_string().contains("objects[0].scale: invalid type"));
    }

    fn manifest() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
    }

    /// Every prefix of the seed scene parses to Ok or Err, never a panic. The mesh is swapped
    /// for a small one so the successful prefixes stay quick.
    #[test]
    fn truncated_seed_scene_never_panics() {
        let src = std::fs::read_to_string(manifest().join("assets/scenes/seed.toml")).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let scenes = dir.path().join("scenes");
        let meshes = dir.path().join("meshes");
        std::fs::create_dir_all(&scenes).unwrap();
        std::fs::create_dir_all(&meshes).unwrap();
        std::fs::copy(manifest().join("assets/meshes/cube.obj"), meshes.join("bumpy_torus.obj")).unwrap();
        let path = scenes.join("seed.toml");
        let mut ok = 0;
        for end in 0..=src.len() {
            if !src.is_char_boundary(end) {
                continue;
            }
            match parse(&src[..end], &path, &scenes) {
                Ok(_) => ok += 1,
                Err(e) => assert!(e.to_string().starts_with(&path.display().to_string())),
            }
        }
        assert!(parse(&src, &path, &scenes).is_ok());
        assert!(ok >= 1);
    }

    /// Junk in place of each line, and each byte replaced by a few others: no panics either.
    #[test]
    fn mangled_seed_scene_never_panics() {
        let src = std::fs::read_to_string(manifest().join("assets/scenes/seed.toml")).unwrap();
        let nowhere = Path::new("/nonexistent");
        let junk = ["", "=", "[", "]]", "\"", "x = 1", "nan", "-inf", "[[objects]]", "1e400", "{", "'''"];
        let lines: Vec<&str> = src.lines().collect();
        for i in 0..lines.len() {
            for j in junk {
                let mut l = lines.clone();
                l[i] = j;
                let _ = parse(&l.join("\n"), Path::new("m.toml"), nowhere);
            }
        }
        let bytes = src.as_bytes();
        for i in 0..bytes.len() {
            for b in [b'0', b'-', b'"', b']', b'n', b'\n', b'.'] {
                let mut m = bytes.to_vec();
                m[i] = b;
                if let Ok(m) = std::str::from_utf8(&m) {
                    let _ = parse(m, Path::new("m.toml"), nowhere);
                }
            }
        }
    }
}
