//! The scene: what a scene file describes, validated, in f64.
//!
//! Data flows one way: scene file ([`file`]) → [`Scene`] → flat primitive arrays
//! ([`crate::primitives`]) → BVH ([`crate::accel`]) → a backend → image.

pub mod environment;
pub mod error;
pub mod file;
pub mod gltf;
pub mod mesh;
pub mod polygon;
pub mod procedural;
pub mod texture;

pub use environment::{EnvSampling, Environment};
pub use error::SceneError;
pub use texture::Texture;

use crate::geometry::{Cylinder, Plane, Sphere, Triangle};
use crate::math::V3;
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// The viewpoint p_v.
    pub eye: V3<f64>,
    pub look_at: V3<f64>,
    pub up: V3<f64>,
    /// Vertical field of view in degrees.
    pub fov_y: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageSize {
    pub width: u32,
    pub height: u32,
}

/// How light transport is computed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RenderMode {
    /// Whitted ray tracing: point/directional lights with hard shadows, perfect mirrors and
    /// refraction. Deterministic; emissive primitives light the scene as point-light stand-ins.
    #[default]
    Whitted,
    /// Monte Carlo path tracing: area lights, next-event estimation with MIS, progressive.
    Path,
}

impl RenderMode {
    pub const ALL: [RenderMode; 2] = [Self::Whitted, Self::Path];
    pub fn name(self) -> &'static str {
        match self {
            Self::Whitted => "whitted",
            Self::Path => "path",
        }
    }
}

/// How images are formed: settings under `[render]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub mode: RenderMode,
    /// Whitted: longest chain of reflections/refractions followed. Path: longest path in
    /// segments from the camera to a light, as Mitsuba counts it (1: emitters seen directly,
    /// 2: direct light only).
    pub max_depth: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Radiance of rays that leave the scene.
    pub background: [f64; 3],
    /// Constant light added to every diffuse surface, so shadows are not black (Whitted only).
    pub ambient: [f64; 3],
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            mode: RenderMode::Whitted,
            max_depth: 5,
            spp: 1,
            background: [0.05, 0.05, 0.08],
            ambient: [0.03, 0.03, 0.03],
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum MaterialKind {
    Diffuse = 0,
    Mirror = 1,
    Dielectric = 2,
    Emissive = 3,
    /// glTF's metallic-roughness material: a diffuse base under a GGX dielectric coat
    /// (F0 0.04), blended by `metallic` with a GGX conductor of the base colour, plus any
    /// emission ([`crate::render::bsdf`]).
    Pbr = 4,
}

impl MaterialKind {
    pub const ALL: [MaterialKind; 5] = [Self::Diffuse, Self::Mirror, Self::Dielectric, Self::Emissive, Self::Pbr];
    pub fn name(self) -> &'static str {
        match self {
            Self::Diffuse => "diffuse",
            Self::Mirror => "mirror",
            Self::Dielectric => "dielectric",
            Self::Emissive => "emissive",
            Self::Pbr => "pbr",
        }
    }
}

/// What a material's alpha (base colour alpha × texture alpha × vertex alpha) does: glTF's
/// `alphaMode`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored.
    #[default]
    Opaque,
    /// Rays pass where alpha is below the cut-off; elsewhere the surface is opaque.
    Mask(f64),
    /// A ray passes with probability 1 − alpha (path mode); Whitted blends the surface over
    /// what lies behind it by alpha.
    Blend,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub kind: MaterialKind,
    /// Albedo (diffuse, and the reflecting part of an emissive surface), reflectance at normal
    /// incidence (mirror) or transmission tint (dielectric).
    pub color: [f64; 3],
    /// Index of refraction (dielectric).
    pub ior: f64,
    /// Emitted radiance (emissive; added to the scattering of a pbr material).
    pub radiance: [f64; 3],
    /// GGX α of a mirror or a dielectric (0: perfectly smooth); path mode only, Whitted treats
    /// every mirror and dielectric as smooth. A pbr material's perceptual roughness (glTF's `roughnessFactor`: α is its
    /// square).
    pub roughness: f64,
    /// pbr: metalness in [0, 1] (glTF's `metallicFactor`).
    pub metallic: f64,
    /// An emissive surface emits from both faces (else from its front face only); a pbr
    /// surface is seen from both faces (glTF's `doubleSided`), else camera rays pass through
    /// its back faces.
    pub two_sided: bool,
    /// Index into [`Scene::textures`] of an image that multiplies `color` where the surface
    /// has texture coordinates.
    pub color_texture: Option<u32>,
    /// Index into [`Scene::textures`] of an image that multiplies `radiance` (emissive).
    pub radiance_texture: Option<u32>,
    /// pbr: glTF's `metallicRoughnessTexture` (linear; blue multiplies `metallic`, green
    /// `roughness`).
    pub metal_rough_texture: Option<u32>,
    /// pbr: glTF's `normalTexture`, a tangent-space normal map, and its `scale`.
    pub normal_texture: Option<u32>,
    pub normal_scale: f64,
    /// Shows `radiance` (glTF `KHR_materials_unlit`: its base colour) and lights nothing: not
    /// an area light, no stand-in.
    pub unlit: bool,
    /// Alpha factor (glTF's base colour alpha) and what alpha does.
    pub alpha: f64,
    pub alpha_mode: AlphaMode,
    /// Absorption coefficient per unit length inside (dielectric, pbr with transmission:
    /// Beer–Lambert, as `KHR_materials_volume`'s −ln(attenuationColor) / attenuationDistance);
    /// path mode only.
    pub absorption: [f64; 3],
    /// pbr: `KHR_materials_transmission`'s factor in [0, 1].
    pub transmission: f64,
    /// A rough dielectric scatters once (Mitsuba's and pbrt's model), its lost energy not made
    /// up ([`crate::render::dielectric`]).
    pub single_scattering: bool,
    /// pbr: `KHR_materials_specular`'s factor (scales the dielectric's reflection and its
    /// grazing reflectance; 1: glTF's default) and colour (tints its reflectance at normal
    /// incidence).
    pub specular: f64,
    pub specular_color: [f64; 3],
    /// pbr: `KHR_materials_clearcoat`'s factor and perceptual roughness: a smooth or rough
    /// dielectric coat (F0 0.04) over everything else ([`crate::render::layers`]).
    pub clearcoat: f64,
    pub clearcoat_roughness: f64,
    /// pbr: `KHR_materials_sheen`'s colour (black: none) and roughness: a cloth-like sheen
    /// over the base, under the clear coat.
    pub sheen_color: [f64; 3],
    pub sheen_roughness: f64,
}

impl Material {
    /// The material of objects that name none.
    pub fn default_grey() -> Self {
        Self {
            name: "default".into(),
            kind: MaterialKind::Diffuse,
            color: [0.7, 0.7, 0.7],
            ior: 1.0,
            radiance: [0.0; 3],
            roughness: 0.0,
            metallic: 0.0,
            two_sided: false,
            color_texture: None,
            radiance_texture: None,
            metal_rough_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            unlit: false,
            alpha: 1.0,
            alpha_mode: AlphaMode::Opaque,
            absorption: [0.0; 3],
            transmission: 0.0,
            single_scattering: false,
            specular: 1.0,
            specular_color: [1.0; 3],
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            sheen_color: [0.0; 3],
            sheen_roughness: 0.0,
        }
    }

    /// Whether the material emits light other surfaces receive (emissive kinds and pbr
    /// materials with emission; not unlit ones).
    pub fn is_light(&self) -> bool {
        !self.unlit
            && (self.kind == MaterialKind::Emissive
                || (self.kind == MaterialKind::Pbr && self.radiance.iter().any(|&c| c > 0.0)))
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// Radiant intensity `intensity` (W/sr per channel) from `position`; falls off as 1/r².
    /// `range` > 0 limits its reach as a spot light's (0: unlimited).
    Point { position: V3<f64>, intensity: [f64; 3], range: f64 },
    /// Light travelling along the unit vector `direction`, irradiance `intensity` on a surface
    /// facing it.
    Directional { direction: V3<f64>, intensity: [f64; 3] },
    /// A point light within a cone about the unit vector `direction`: full intensity within
    /// `inner` radians of it, none beyond `outer`, `KHR_lights_punctual`'s smooth falloff
    /// between; `range` > 0 limits its reach (0: unlimited).
    Spot { position: V3<f64>, direction: V3<f64>, intensity: [f64; 3], inner: f64, outer: f64, range: f64 },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ObjectKind {
    Sphere,
    Cylinder,
    Plane,
    Triangle,
    Polygon,
    Mesh,
}

impl ObjectKind {
    pub fn name(self) -> &'static str {
        match self {
            Self::Sphere => "sphere",
            Self::Cylinder => "cylinder",
            Self::Plane => "plane",
            Self::Triangle => "triangle",
            Self::Polygon => "polygon",
            Self::Mesh => "mesh",
        }
    }
}

/// The geometry of one `[[objects]]` entry.
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    Sphere(Sphere<f64>),
    Cylinder(Cylinder<f64>),
    Plane(Plane<f64>),
    Triangle(Triangle<f64>),
    /// A planar, simple polygon and its triangulation (a primitive's `face` indexes these triangles).
    Polygon {
        vertices: Vec<V3<f64>>,
        triangles: Vec<Triangle<f64>>,
    },
    /// A triangle mesh loaded from `file` (OBJ or glTF), already transformed.
    Mesh {
        file: PathBuf,
        triangles: Vec<Triangle<f64>>,
        /// What the file gives at each triangle's vertices besides positions.
        attrs: MeshAttributes,
        /// Material of each triangle (indices into [`Scene::materials`]); empty when every
        /// triangle has the object's material (glTF files bring one per primitive).
        materials: Vec<u32>,
    },
}

/// Per-vertex data of a mesh's triangles, each list in triangle order and each triple in the
/// order of the triangle's vertices; a list is empty when the file has none of it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshAttributes {
    /// Texture coordinates (glTF `TEXCOORD_0`, OBJ `vt`), v = 0 an image's top row.
    pub uvs: Vec<[[f32; 2]; 3]>,
    /// A second set (glTF `TEXCOORD_1`).
    pub uvs1: Vec<[[f32; 2]; 3]>,
    /// Unit shading normals (glTF `NORMAL`, OBJ `vn`), on the side of the triangle's front face
    /// where they agree with it.
    pub normals: Vec<[[f32; 3]; 3]>,
    /// Linear RGBA colours (glTF `COLOR_0`).
    pub colors: Vec<[[f32; 4]; 3]>,
}

impl Geometry {
    pub fn kind(&self) -> ObjectKind {
        match self {
            Self::Sphere(_) => ObjectKind::Sphere,
            Self::Cylinder(_) => ObjectKind::Cylinder,
            Self::Plane(_) => ObjectKind::Plane,
            Self::Triangle(_) => ObjectKind::Triangle,
            Self::Polygon { .. } => ObjectKind::Polygon,
            Self::Mesh { .. } => ObjectKind::Mesh,
        }
    }

    /// How many primitives the object becomes when flattened (its triangles, or one).
    pub fn primitive_count(&self) -> usize {
        match self {
            Self::Polygon { triangles, .. } | Self::Mesh { triangles, .. } => triangles.len(),
            _ => 1,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub geometry: Geometry,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// How a glTF file given on its own becomes a scene.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Which of the file's perspective cameras (in `cameras` order; default the first).
    pub camera: Option<usize>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub camera: Camera,
    pub image: ImageSize,
    pub render: RenderSettings,
    /// The file's materials in order, then the default grey if any object names none.
    pub materials: Vec<Material>,
    /// The file's `[[objects]]` in order: an object's index is its id in trace output.
    pub objects: Vec<Object>,
    pub lights: Vec<Light>,
    /// Decoded images that materials refer to.
    pub textures: Vec<Texture>,
    /// Light from infinitely far away in every direction (`[environment]`): the background
    /// of rays that leave the scene.
    pub environment: Option<Environment>,
    /// What was read but not used (skipped glTF primitives, unsupported extensions...), one
    /// line each, for the command line to print.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Loads and validates a scene file: TOML, or a glTF file (`.gltf`, `.glb`) on its own,
    /// with its first camera. Every error names the file and where in it (line, column and
    /// field of a TOML file; the glTF path such as `meshes[2].primitives[0].indices`).
    pub fn load(path: impl Into<PathBuf>) -> Result<Scene, SceneError> {
        Self::load_with(path, &LoadOptions::default())
    }

    /// [`Scene::load`] with options for glTF files.
    pub fn load_with(path: impl Into<PathBuf>, options: &LoadOptions) -> Result<Scene, SceneError> {
        let path = path.into();
        if gltf::is_gltf_path(&path) { gltf::load_scene(&path, options) } else { file::load(&path) }
    }

    /// [`Scene::load_with`] of a file's contents, `bytes`, as a web page has them: a glTF
    /// file where `path` (which names it in messages; files it refers to are looked up beside
    /// it) ends in `.gltf` or `.glb`, else a TOML scene file.
    pub fn from_bytes(path: &Path, bytes: &[u8], options: &LoadOptions) -> Result<Scene, SceneError> {
        if gltf::is_gltf_path(path) {
            return gltf::load_scene_bytes(path, bytes, options);
        }
        let src = crate::input::read_text_from(bytes, file::MAX_SCENE_FILE_BYTES)
            .map_err(|e| SceneError::Io { path: path.to_path_buf(), message: e.to_string() })?;
        file::parse(&src, path, path.parent().unwrap_or(Path::new("")))
    }

    /// A scene with nothing in it but one grey material ([`Material::default_grey`]), seen
    /// from `camera`: what procedural scenes and the Python package's scenes start from.
    pub fn empty(camera: Camera, image: ImageSize) -> Scene {
        Scene {
            camera,
            image,
            render: RenderSettings::default(),
            materials: vec![Material::default_grey()],
            objects: Vec::new(),
            lights: Vec::new(),
            textures: Vec::new(),
            environment: None,
            warnings: Vec::new(),
        }
    }

    /// Total triangle count over triangles, polygons and meshes.
    pub fn triangle_count(&self) -> usize {
        self.objects
            .iter()
            .filter(|o| matches!(o.geometry, Geometry::Triangle(_) | Geometry::Polygon { .. } | Geometry::Mesh { .. }))
            .map(|o| o.geometry.primitive_count())
            .sum()
    }
}
