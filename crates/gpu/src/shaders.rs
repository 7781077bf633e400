//! WGSL sources, composed per scene with naga_oil: a scene's [`FeatureKey`] picks the shader
//! defs, so a variant contains only the primitive, material and light code the scene uses.

use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, ComposerError, NagaModuleDescriptor, ShaderDefValue, ShaderLanguage,
    ShaderType,
};
use std::collections::HashMap;

use strahl_core::layout::{ENV_MAP, FlatScene, LIGHT_DIRECTIONAL, LIGHT_POINT};
use strahl_core::primitives::Primitives;
use strahl_core::scene::{Light, MaterialKind, Scene};

/// The shared modules, in import order (each may import only those before it).
pub const MODULES: &[(&str, &str)] = &[
    ("shaders/modules/types.wgsl", include_str!("../shaders/modules/types.wgsl")),
    ("shaders/modules/bindings.wgsl", include_str!("../shaders/modules/bindings.wgsl")),
    ("shaders/modules/roots.wgsl", include_str!("../shaders/modules/roots.wgsl")),
    ("shaders/modules/sphere.wgsl", include_str!("../shaders/modules/sphere.wgsl")),
    ("shaders/modules/cylinder.wgsl", include_str!("../shaders/modules/cylinder.wgsl")),
    ("shaders/modules/plane.wgsl", include_str!("../shaders/modules/plane.wgsl")),
    ("shaders/modules/triangle.wgsl", include_str!("../shaders/modules/triangle.wgsl")),
    ("shaders/modules/traverse.wgsl", include_str!("../shaders/modules/traverse.wgsl")),
    ("shaders/modules/spawn.wgsl", include_str!("../shaders/modules/spawn.wgsl")),
    ("shaders/modules/camera.wgsl", include_str!("../shaders/modules/camera.wgsl")),
    ("shaders/modules/texture.wgsl", include_str!("../shaders/modules/texture.wgsl")),
    ("shaders/modules/surface.wgsl", include_str!("../shaders/modules/surface.wgsl")),
    ("shaders/modules/microfacet.wgsl", include_str!("../shaders/modules/microfacet.wgsl")),
    ("shaders/modules/pbr.wgsl", include_str!("../shaders/modules/pbr.wgsl")),
    ("shaders/modules/environment.wgsl", include_str!("../shaders/modules/environment.wgsl")),
    ("shaders/modules/shade.wgsl", include_str!("../shaders/modules/shade.wgsl")),
    ("shaders/modules/sampler.wgsl", include_str!("../shaders/modules/sampler.wgsl")),
    ("shaders/modules/bsdf.wgsl", include_str!("../shaders/modules/bsdf.wgsl")),
    ("shaders/modules/emitters.wgsl", include_str!("../shaders/modules/emitters.wgsl")),
    ("shaders/modules/path.wgsl", include_str!("../shaders/modules/path.wgsl")),
];

/// A top-level shader and its entry points.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Program {
    /// `whitted.wgsl`: Whitted image, one invocation per pixel.
    Whitted,
    /// `megakernel.wgsl`: one path-traced sample per pixel (progressive passes).
    Path,
    /// `trace.wgsl`: ray queries.
    Trace,
    /// `wavefront.wgsl`: path tracing as separate kernels over queues of paths.
    Wavefront,
    /// `view.wgsl`: the viewer's debug images (normals, depth, BVH cost) of primary rays;
    /// composed with `COUNT_VISITS`, which makes the traversal count its work.
    View,
}

impl Program {
    pub fn source(self) -> (&'static str, &'static str) {
        match self {
            Program::Whitted => ("shaders/whitted.wgsl", include_str!("../shaders/whitted.wgsl")),
            Program::Path => ("shaders/megakernel.wgsl", include_str!("../shaders/megakernel.wgsl")),
            Program::Trace => ("shaders/trace.wgsl", include_str!("../shaders/trace.wgsl")),
            Program::Wavefront => ("shaders/wavefront.wgsl", include_str!("../shaders/wavefront.wgsl")),
            Program::View => ("shaders/view.wgsl", include_str!("../shaders/view.wgsl")),
        }
    }
}

/// Which code a scene needs. Each flag is a shader def of the same name; the bits above the
/// flags ([`FeatureKey::SPLIT`]) say how the scene's largest arrays are split across bindings
/// ([`super::split`]), as the defs `TRIANGLE_PARTS`, `NODE_PARTS`, `LEAF_TRIANGLE_PARTS` and
/// the elements per part.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FeatureKey(pub u32);

impl FeatureKey {
    pub const SPHERES: u32 = 1 << 0;
    pub const CYLINDERS: u32 = 1 << 1;
    pub const TRIANGLES: u32 = 1 << 2;
    pub const PLANES: u32 = 1 << 3;
    /// Walk the BVH (else test every bounded primitive: tiny scenes).
    pub const BVH: u32 = 1 << 4;
    pub const POINT_LIGHTS: u32 = 1 << 5;
    pub const DIRECTIONAL_LIGHTS: u32 = 1 << 6;
    pub const MIRROR: u32 = 1 << 7;
    pub const DIELECTRIC: u32 = 1 << 8;
    pub const EMISSIVE: u32 = 1 << 9;
    /// The device reads 64-bit words (`SHADER_INT64`): a flag of the device, not of the scene,
    /// which [`GpuContext::pipeline`](super::GpuContext::pipeline) adds.
    pub const LOAD64: u32 = 1 << 10;
    /// Triangles carry attributes (per-triangle texture coordinates, normals, colours: a
    /// material has an image texture, or a mesh has normals or colours).
    pub const TEXTURES: u32 = 1 << 11;
    /// The scene has an `[environment]`.
    pub const ENVIRONMENT: u32 = 1 << 12;
    /// The environment is a map (implies ENVIRONMENT).
    pub const ENV_MAP: u32 = 1 << 13;
    /// glTF's metallic-roughness material.
    pub const PBR: u32 = 1 << 14;
    /// A material lets rays through by its alpha (glTF MASK or BLEND).
    pub const ALPHA: u32 = 1 << 15;
    pub const FLAG_COUNT: u32 = 16;
    pub const NAMES: [&'static str; 16] = [
        "SPHERES",
        "CYLINDERS",
        "TRIANGLES",
        "PLANES",
        "BVH",
        "POINT_LIGHTS",
        "DIRECTIONAL_LIGHTS",
        "MIRROR",
        "DIELECTRIC",
        "EMISSIVE",
        "LOAD64",
        "TEXTURES",
        "ENVIRONMENT",
        "ENV_MAP",
        "PBR",
        "ALPHA",
    ];
    /// Flags that describe the device rather than the scene.
    pub const DEVICE: u32 = Self::LOAD64;
    /// The split of the scene's arrays across bindings ([`super::split::Split`]): not a flag,
    /// set only where an array exceeds one binding.
    pub const SPLIT: u32 = super::split::MASK;
    /// Flags that change the trace program (it has no shading code).
    pub const GEOMETRY: u32 =
        Self::SPHERES | Self::CYLINDERS | Self::TRIANGLES | Self::PLANES | Self::BVH | Self::DEVICE | Self::SPLIT;
    /// Flags of the textures and the environment, which only the shading programs (render,
    /// path) read.
    pub const ASSETS: u32 = Self::TEXTURES | Self::ENVIRONMENT | Self::ENV_MAP | Self::PBR | Self::ALPHA;
    /// Every scene feature: the one shader that renders any scene.
    pub const ALL: FeatureKey = FeatureKey(((1 << Self::FLAG_COUNT) - 1) & !Self::DEVICE);

    /// Scenes with at most this many bounded primitives test them all instead of walking a BVH.
    pub const BRUTE_FORCE_MAX: usize = 8;

    /// The key of `scene`, whose primitives are `prims`, read from the scene itself: what
    /// [`FeatureKey::for_scene`] gives for its flattened buffers, without building a BVH or
    /// packing textures (the viewer keys its shader by the whole scene while objects are
    /// hidden).
    pub fn of_scene(scene: &Scene, prims: &Primitives<f32>) -> FeatureKey {
        let mut k = 0;
        let mut set = |cond: bool, flag: u32| {
            if cond {
                k |= flag
            }
        };
        set(!prims.spheres.is_empty(), Self::SPHERES);
        set(!prims.cylinders.is_empty(), Self::CYLINDERS);
        set(!prims.triangles.is_empty(), Self::TRIANGLES);
        set(!prims.planes.is_empty(), Self::PLANES);
        set(prims.bounded_count() > Self::BRUTE_FORCE_MAX, Self::BVH);
        // Emissive objects light Whitted renders through point lights that stand in for them.
        let point = |l: &Light| matches!(l, Light::Point { .. });
        set(
            scene.lights.iter().any(point) || !strahl_core::render::flatten::stand_in_lights(scene).is_empty(),
            Self::POINT_LIGHTS,
        );
        set(scene.lights.iter().any(|l| matches!(l, Light::Directional { .. })), Self::DIRECTIONAL_LIGHTS);
        let has = |m: MaterialKind| scene.materials.iter().any(|x| x.kind == m);
        set(has(MaterialKind::Mirror), Self::MIRROR);
        set(has(MaterialKind::Dielectric), Self::DIELECTRIC);
        // pbr emission is added under EMISSIVE, which has the emitters' code.
        set(has(MaterialKind::Emissive) || scene.materials.iter().any(|m| m.is_light()), Self::EMISSIVE);
        set(has(MaterialKind::Pbr), Self::PBR);
        set(scene.materials.iter().any(|m| m.alpha_mode != strahl_core::scene::AlphaMode::Opaque), Self::ALPHA);
        set(strahl_core::render::flatten::needs_attributes(scene), Self::TEXTURES);
        set(scene.environment.is_some(), Self::ENVIRONMENT);
        set(scene.environment.as_ref().is_some_and(|e| e.map.is_some()), Self::ENV_MAP);
        FeatureKey(k)
    }

    /// The key of a flattened scene: the features its buffers hold.
    pub fn for_scene(g: &FlatScene) -> FeatureKey {
        let mut k = 0;
        let mut set = |cond: bool, flag: u32| {
            if cond {
                k |= flag
            }
        };
        set(!g.spheres.is_empty(), Self::SPHERES);
        set(!g.cylinders.is_empty(), Self::CYLINDERS);
        set(!g.triangles.is_empty(), Self::TRIANGLES);
        set(!g.planes.is_empty(), Self::PLANES);
        set(g.bounded_count() > Self::BRUTE_FORCE_MAX, Self::BVH);
        set(g.lights.iter().any(|l| l.kind == LIGHT_POINT), Self::POINT_LIGHTS);
        set(g.lights.iter().any(|l| l.kind == LIGHT_DIRECTIONAL), Self::DIRECTIONAL_LIGHTS);
        let has = |m: MaterialKind| g.materials.iter().any(|x| x.kind == m as u32);
        set(has(MaterialKind::Mirror), Self::MIRROR);
        set(has(MaterialKind::Dielectric), Self::DIELECTRIC);
        set(has(MaterialKind::Emissive) || g.materials.iter().any(|m| m.is_light()), Self::EMISSIVE);
        set(has(MaterialKind::Pbr), Self::PBR);
        set(g.alpha, Self::ALPHA);
        set(!g.triangle_attrs.is_empty(), Self::TEXTURES);
        set(!g.environment.is_empty(), Self::ENVIRONMENT);
        set(g.environment.iter().any(|e| e.flags & ENV_MAP != 0), Self::ENV_MAP);
        FeatureKey(k)
    }

    pub fn has(self, flag: u32) -> bool {
        self.0 & flag != 0
    }

    /// The key as the program sees it: the trace and view programs ignore shading flags.
    pub fn for_program(self, p: Program) -> FeatureKey {
        match p {
            Program::Whitted | Program::Path | Program::Wavefront => self,
            Program::Trace | Program::View => FeatureKey(self.0 & Self::GEOMETRY),
        }
    }

    pub fn shader_defs(self) -> HashMap<String, ShaderDefValue> {
        let mut defs: HashMap<String, ShaderDefValue> = (0..Self::FLAG_COUNT)
            .filter(|i| self.0 & (1 << i) != 0)
            .map(|i| (Self::NAMES[i as usize].to_string(), ShaderDefValue::Bool(true)))
            .collect();
        if self.has(Self::POINT_LIGHTS | Self::DIRECTIONAL_LIGHTS) {
            defs.insert("LIGHTS".into(), ShaderDefValue::Bool(true));
        }
        if self.has(Self::DIELECTRIC | Self::EMISSIVE | Self::ALPHA) {
            defs.insert("SHADOW_CROSSING".into(), ShaderDefValue::Bool(true));
        }
        if self.has(Self::ENV_MAP) {
            defs.insert("ENVIRONMENT".into(), ShaderDefValue::Bool(true));
        }
        // The texture table and texels are bound for textures and for an environment map.
        if self.has(Self::TEXTURES | Self::ENV_MAP) {
            defs.insert("TEXELS".into(), ShaderDefValue::Bool(true));
        }
        // Parts per splittable array (1: whole), defined for every key (the shaders compare
        // them), and the elements per part where there are several.
        let split = super::split::Split::of_key(self);
        for array in super::split::SplitArray::ALL {
            let (parts, per_part) = array.defs();
            defs.insert(parts.into(), ShaderDefValue::UInt(split.parts(array)));
            if split.parts(array) > 1 {
                defs.insert(per_part.into(), ShaderDefValue::UInt(split.per_part(array)));
            }
        }
        defs
    }

    /// Readable form, e.g. `SPHERES+BVH+POINT_LIGHTS`, with the split where there is one
    /// (`TRIANGLES+BVH+TRIANGLE_PARTS=2+NODE_PARTS=1+LEAF_TRIANGLE_PARTS=2 of 134217728 bytes`).
    pub fn label(self) -> String {
        let mut names: Vec<String> = (0..Self::FLAG_COUNT)
            .filter(|i| self.0 & (1 << i) != 0)
            .map(|i| Self::NAMES[i as usize].to_string())
            .collect();
        let split = super::split::Split::of_key(self);
        if split.is_split() {
            names.push(split.label());
        }
        if names.is_empty() { "EMPTY".into() } else { names.join("+") }
    }
}

/// What the shaders may use beyond core WGSL: 64-bit integers, in LOAD64 variants only (which
/// run on devices with `SHADER_INT64`).
const CAPABILITIES: naga::valid::Capabilities = naga::valid::Capabilities::SHADER_INT64;

#[derive(Debug, thiserror::Error)]
pub enum ShaderError {
    #[error("composing {file}: {message}")]
    Compose { file: String, message: String },
    #[error("validating the {program:?} shader for {key}: {message}")]
    Validate { program: Program, key: String, message: String },
}

/// naga_oil's message for `e`, located in the source it names (file, line, column and the
/// line itself), its decorated names undone.
fn compose_error(e: &ComposerError, composer: &Composer) -> String {
    e.emit_to_string(composer).trim_end().to_string()
}

/// The text of shader `file` (a path like `shaders/modules/types.wgsl`) with the shared
/// values substituted ([`super::shared`]): the text built into the binary, or, when the
/// environment variable `STRAHL_SHADER_DIR` names a folder laid out like `shaders/`, the file
/// at the same place in it, so that shaders can be edited and measured without rebuilding.
fn source_text(file: &str, built_in: &'static str) -> Result<String, ShaderError> {
    let text = match std::env::var_os("STRAHL_SHADER_DIR") {
        None => built_in.to_string(),
        Some(dir) => {
            let name = file.strip_prefix("shaders/").expect("shader paths start with shaders/");
            let path = std::path::Path::new(&dir).join(name);
            std::fs::read_to_string(&path)
                .map_err(|e| ShaderError::Compose { file: path.display().to_string(), message: e.to_string() })?
        }
    };
    Ok(super::shared::substitute(&text))
}

/// Composes `program` for `key` into a naga module.
pub fn compose(program: Program, key: FeatureKey) -> Result<naga::Module, ShaderError> {
    let key = key.for_program(program);
    let mut defs = key.shader_defs();
    if program == Program::View {
        defs.insert("COUNT_VISITS".into(), ShaderDefValue::Bool(true));
    }
    let mut composer = Composer::default().with_capabilities(CAPABILITIES);
    // The composed module is validated once, where it is used: by wgpu when the pipeline is
    // created, and by `validate` in the tests, which cover every variant.
    composer.validate = false;
    for (file, src) in MODULES {
        let src = source_text(file, src)?;
        let added = composer
            .add_composable_module(ComposableModuleDescriptor {
                source: &src,
                file_path: file,
                language: ShaderLanguage::Wgsl,
                shader_defs: defs.clone(),
                ..Default::default()
            })
            .map(|_| ());
        added.map_err(|e| ShaderError::Compose { file: file.to_string(), message: compose_error(&e, &composer) })?;
    }
    let (file, src) = program.source();
    let src = source_text(file, src)?;
    let module = composer.make_naga_module(NagaModuleDescriptor {
        source: &src,
        file_path: file,
        shader_type: ShaderType::Wgsl,
        shader_defs: defs,
        ..Default::default()
    });
    module.map_err(|e| ShaderError::Compose { file: file.to_string(), message: compose_error(&e, &composer) })
}

/// Validates a composed module with every check naga has; returns its module info.
pub fn validate(
    program: Program,
    key: FeatureKey,
    module: &naga::Module,
) -> Result<naga::valid::ModuleInfo, ShaderError> {
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), CAPABILITIES)
        .validate(module)
        .map_err(|e| ShaderError::Validate { program, key: key.label(), message: format!("{:?}", e.into_inner()) })
}

/// The composed module as WGSL text (for inspection in tests).
#[cfg(test)]
pub fn to_wgsl(module: &naga::Module, info: &naga::valid::ModuleInfo) -> String {
    naga::back::wgsl::write_string(module, info, naga::back::wgsl::WriterFlags::empty())
        .unwrap_or_else(|e| format!("// cannot print this module as WGSL: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every key of the flags before [`FeatureKey::ASSETS`] (all programs), and the five valid
    /// combinations of the asset flags over the flags whose code the asset code meets
    /// (spheres and triangles: emitter sampling and texture lookups; BVH; point lights: the
    /// path tracer's light loop; emissive and dielectric: emitters and shadow crossing), for
    /// the shading programs that read them: 2048 + 5 × 64 keys instead of 2^14 (the other
    /// flags only change traversal and BSDF code, which the asset code does not touch).
    fn keys_to_validate() -> Vec<u32> {
        let base = FeatureKey::ASSETS.trailing_zeros();
        let mut keys: Vec<u32> = (0..(1u32 << base)).collect();
        let met = FeatureKey::SPHERES
            | FeatureKey::TRIANGLES
            | FeatureKey::BVH
            | FeatureKey::POINT_LIGHTS
            | FeatureKey::EMISSIVE
            | FeatureKey::DIELECTRIC;
        let skip = !met & ((1 << base) - 1);
        for assets in [
            FeatureKey::PBR | FeatureKey::ALPHA | FeatureKey::TEXTURES,
            FeatureKey::ALPHA,
            FeatureKey::PBR,
            FeatureKey::PBR | FeatureKey::TEXTURES,
            FeatureKey::TEXTURES,
            FeatureKey::ENVIRONMENT,
            FeatureKey::ENVIRONMENT | FeatureKey::ENV_MAP,
            FeatureKey::TEXTURES | FeatureKey::ENVIRONMENT,
            FeatureKey::ALL.0 & FeatureKey::ASSETS,
        ] {
            keys.extend((0..(1u32 << base)).filter(|k| k & skip == 0).map(|k| k | assets));
        }
        keys
    }

    #[test]
    fn every_feature_key_composes_and_validates() {
        use rayon::prelude::*;
        let failures: Vec<String> = keys_to_validate()
            .into_par_iter()
            .flat_map_iter(|bits| {
                let key = FeatureKey(bits);
                [Program::Whitted, Program::Path, Program::Wavefront, Program::Trace, Program::View]
                    .into_iter()
                    .filter(move |&p| key.for_program(p) == key)
                    .filter_map(move |p| match compose(p, key) {
                        Ok(m) => validate(p, key, &m).err().map(|e| e.to_string()),
                        Err(e) => Some(format!("{}: {e}", key.label())),
                    })
            })
            .collect();
        assert!(failures.is_empty(), "{} variants fail, first: {}", failures.len(), failures[0]);
    }

    /// Splits of every array alone into 2, 3 and 4 parts, and of all three into 2 and 4, with
    /// the geometry of a mesh and with every feature, with and without 64-bit loads.
    fn split_keys() -> Vec<FeatureKey> {
        use super::super::split::Split;
        let mut splits = vec![[2, 2, 2], [4, 4, 4]];
        for i in 0..3 {
            splits.extend((2..=4).map(|p| {
                let mut s = [1; 3];
                s[i] = p;
                s
            }));
        }
        let mesh = FeatureKey::TRIANGLES | FeatureKey::BVH | FeatureKey::POINT_LIGHTS;
        let mut keys = Vec::new();
        for parts in splits {
            let bits = Split::with_parts(parts, 27).key_bits();
            for base in [mesh, FeatureKey::ALL.0] {
                keys.extend([FeatureKey(base | bits), FeatureKey(base | bits | FeatureKey::LOAD64)]);
            }
        }
        keys
    }

    #[test]
    fn every_split_composes_and_validates() {
        use rayon::prelude::*;
        let failures: Vec<String> = split_keys()
            .into_par_iter()
            .flat_map_iter(|key| {
                [Program::Whitted, Program::Path, Program::Wavefront, Program::Trace, Program::View]
                    .into_iter()
                    .filter_map(move |p| match compose(p, key) {
                        Ok(m) => validate(p, key, &m).err().map(|e| e.to_string()),
                        Err(e) => Some(format!("{}: {e}", key.label())),
                    })
            })
            .collect();
        assert!(failures.is_empty(), "{} variants fail, first: {}", failures.len(), failures[0]);
    }

    /// A split variant declares each part after the first at the binding the host binds it
    /// to (split::extra_binding), and reads parts only through the part-selecting functions;
    /// an unsplit variant contains none of them.
    #[test]
    fn parts_are_declared_where_the_host_binds_them_and_only_in_split_variants() {
        use super::super::split::{Split, SplitArray, extra_binding};
        let names = |a: SplitArray| match a {
            SplitArray::Triangles => "triangles",
            SplitArray::Nodes => "nodes",
            SplitArray::LeafTriangles => "leaf_triangles",
        };
        for load64 in [0, FeatureKey::LOAD64] {
            let split = FeatureKey(FeatureKey::ALL.0 | load64 | Split::with_parts([4, 4, 4], 27).key_bits());
            let m = compose(Program::Path, split).unwrap();
            let bindings: HashMap<String, u32> = m
                .global_variables
                .iter()
                .filter_map(|(_, g)| {
                    let name = g.name.as_deref()?.split("X_naga_oil_mod_X").next()?.to_string();
                    Some((name, g.binding.as_ref()?.binding))
                })
                .collect();
            for array in SplitArray::ALL {
                for p in 1..super::super::split::MAX_PARTS {
                    let name = format!("{}_{p}", names(array));
                    assert_eq!(bindings.get(&name), Some(&extra_binding(array, p)), "{name}");
                }
            }
            let text = to_wgsl(&m, &validate(Program::Path, split, &m).unwrap());
            let unsplit = FeatureKey(FeatureKey::ALL.0 | load64);
            let plain = compose(Program::Path, unsplit).unwrap();
            let plain_text = to_wgsl(&plain, &validate(Program::Path, unsplit, &plain).unwrap());
            let selectors: &[&str] = if load64 != 0 {
                &["scene_triangle", "node_half", "leaf_word"]
            } else {
                &["scene_triangle", "node_at", "leaf_at"]
            };
            for f in selectors.iter().chain(&["triangles_1", "nodes_1", "leaf_triangles_1"]) {
                assert!(text.contains(f), "{f} missing from the split variant");
                assert!(!plain_text.contains(f), "{f} in the unsplit variant");
            }
        }
    }

    /// Scenes with what no shipped scene has, written to `dir`: an image texture on a mesh, an
    /// emission texture, an environment map, a constant environment, and emissive objects
    /// alone (lit in Whitted mode by their stand-in point lights).
    fn asset_scenes(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
        image::RgbImage::from_fn(4, 4, |x, y| image::Rgb([(x * 60) as u8, (y * 60) as u8, 90]))
            .save(dir.join("checker.png"))
            .unwrap();
        image::Rgb32FImage::from_fn(8, 4, |x, _| image::Rgb([0.2, 0.3, x as f32])).save(dir.join("sky.exr")).unwrap();
        let obj =
            "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
        std::fs::write(dir.join("quad.obj"), obj).unwrap();
        let head = "[camera]\neye = [0.0, 1.0, -4.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 50.0\n\
                    [image]\nwidth = 8\nheight = 6\n";
        let sphere = "[[objects]]\ntype = \"sphere\"\ncenter = [0.0, 0.5, 0.0]\nradius = 0.5\nmaterial = \"m\"\n";
        let quad =
            |material: &str| format!("[[objects]]\ntype = \"mesh\"\nfile = \"quad.obj\"\nmaterial = \"{material}\"\n");
        let light = "[[lights]]\ntype = \"point\"\nposition = [0.0, 3.0, 0.0]\nintensity = [5.0, 5.0, 5.0]\n";
        // A glTF triangle whose material blends by alpha (TOML materials have no alpha).
        let positions: Vec<u8> = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        use base64::Engine;
        let data = base64::engine::general_purpose::STANDARD.encode(&positions);
        let veil = format!(
            r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "material": 0}}]}}],
            "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [1, 1, 1, 0.5]}}, "alphaMode": "BLEND"}}],
            "buffers": [{{"uri": "data:application/octet-stream;base64,{data}", "byteLength": 36}}],
            "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                "min": [0, 0, 0], "max": [1, 1, 0]}}]}}"#
        );
        std::fs::write(dir.join("veil.gltf"), veil).unwrap();
        let scenes = [
            (
                "textured.toml",
                format!(
                    "{head}[[materials]]\nname = \"m\"\ntype = \"diffuse\"\ntexture = \"checker.png\"\n\
                     [[materials]]\nname = \"glow\"\ntype = \"emissive\"\nradiance = [2.0, 2.0, 2.0]\n\
                     radiance_texture = \"checker.png\"\n{}{light}[environment]\nfile = \"sky.exr\"\n",
                    quad("m") + &quad("glow")
                ),
            ),
            (
                "constant_sky.toml",
                format!(
                    "{head}[[materials]]\nname = \"m\"\ntype = \"mirror\"\n{sphere}{light}[environment]\nradiance = [0.5, 0.6, 0.7]\n"
                ),
            ),
            (
                "pbr.toml",
                format!(
                    "{head}[[materials]]\nname = \"m\"\ntype = \"pbr\"\nmetallic = 0.5\nroughness = 0.4\n\
                     radiance = [0.5, 0.5, 0.5]\n{sphere}{light}"
                ),
            ),
            ("alpha.toml", format!("{head}[[objects]]\ntype = \"gltf\"\nfile = \"veil.gltf\"\n{light}")),
            (
                "emitters_only.toml",
                format!(
                    "{head}[[materials]]\nname = \"m\"\ntype = \"emissive\"\nradiance = [4.0, 4.0, 4.0]\n{sphere}{}",
                    quad("m")
                ),
            ),
        ];
        scenes
            .into_iter()
            .map(|(name, text)| {
                let path = dir.join(name);
                std::fs::write(&path, text).unwrap();
                path
            })
            .collect()
    }

    /// The key read from a scene equals the key of its flattened buffers, for every shipped
    /// scene, for scenes with textures and environments, and for the viewer's way of keying a
    /// scene while objects are hidden.
    #[test]
    fn the_key_of_a_scene_is_the_key_of_its_buffers() {
        let dir = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/scenes"));
        let assets = tempfile::tempdir().unwrap();
        let mut paths: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
        paths.extend(asset_scenes(assets.path()));
        let mut seen = 0;
        let mut flags = 0;
        for path in paths {
            if path.extension().is_none_or(|x| x != "toml") {
                continue;
            }
            let scene = strahl_core::scene::Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let prep = strahl_core::render::Prepared::new(scene.clone());
            assert_eq!(
                FeatureKey::of_scene(&scene, &prep.prims),
                FeatureKey::for_scene(&prep.gpu),
                "{}",
                path.display()
            );
            flags |= FeatureKey::for_scene(&prep.gpu).0;
            seen += 1;
        }
        assert!(seen >= 11, "only {seen} scenes");
        // Every scene flag was met by some scene.
        let scene_flags = FeatureKey::ALL.0;
        assert_eq!(
            flags & scene_flags,
            scene_flags,
            "flags no scene had: {}",
            FeatureKey(scene_flags & !flags).label()
        );
    }

    #[test]
    fn a_sphere_only_shader_contains_no_other_primitive_code() {
        let key = FeatureKey(FeatureKey::SPHERES | FeatureKey::POINT_LIGHTS);
        let m = compose(Program::Whitted, key).unwrap();
        let text = to_wgsl(&m, &validate(Program::Whitted, key, &m).unwrap());
        assert!(text.contains("sphere_roots"), "the sphere code is there");
        // Case-sensitive identifiers of other primitives' code and types (naga_oil's name
        // decorations are upper-case base32 and cannot spell them).
        let absent_items = [
            "Cylinder",
            "cylinder_roots",
            "cap_root",
            "Triangle",
            "triangle_intersect",
            "Shear",
            "Plane",
            "plane_roots",
            "refract",
            "fresnel",
            "Node",
            "slab",
            "nodes",
            "texture_sample",
            "texels",
            "triangle_attrs",
            "env_background",
            "env_distribution",
            "Environment",
        ];
        for absent in absent_items {
            assert!(!text.contains(absent), "{absent} found in the sphere-only shader");
        }
        let all = compose(Program::Whitted, FeatureKey::ALL).unwrap();
        let all_text = to_wgsl(&all, &validate(Program::Whitted, FeatureKey::ALL, &all).unwrap());
        for present in [
            "cylinder_roots",
            "triangle_intersect",
            "plane_roots",
            "fresnel_dielectric",
            "slab",
            "texture_sample",
            "env_background",
        ] {
            assert!(all_text.contains(present), "{present} missing from the all-features shader");
        }
        assert!(text.len() * 2 < all_text.len(), "{} vs {} bytes", text.len(), all_text.len());
    }

    /// lavapipe 22 leaks a compiled shader per pipeline bind when a uniform steers control
    /// flow (shaders/modules/bindings.wgsl): no program binds a uniform buffer.
    #[test]
    fn no_program_binds_a_uniform_buffer() {
        for p in [Program::Whitted, Program::Path, Program::Wavefront, Program::Trace, Program::View] {
            let key = FeatureKey::ALL.for_program(p);
            let m = compose(p, key).unwrap();
            let uniforms: Vec<_> = m
                .global_variables
                .iter()
                .filter(|(_, g)| g.space == naga::AddressSpace::Uniform)
                .map(|(_, g)| g.name.clone())
                .collect();
            assert!(uniforms.is_empty(), "{p:?} binds uniforms {uniforms:?}");
        }
    }

    /// The constants of the composed shaders hold the values the host shares with them
    /// (super::shared), as naga evaluated them.
    #[test]
    fn shared_constants_reach_the_composed_shaders_exactly() {
        use super::super::shared::{Shared, constants};
        let shared: HashMap<&str, Shared> = constants().into_iter().collect();
        let mut seen = std::collections::HashSet::new();
        for p in [Program::Whitted, Program::Path, Program::Wavefront, Program::Trace, Program::View] {
            for key in [FeatureKey::ALL, FeatureKey(FeatureKey::ALL.0 | FeatureKey::LOAD64)] {
                let m = compose(p, key).unwrap();
                for (_, c) in m.constants.iter() {
                    let Some(name) = c.name.as_deref().and_then(|n| n.split("X_naga_oil_mod_X").next()) else {
                        continue;
                    };
                    let Some(&want) = shared.get(name) else { continue };
                    let literal = |e: &naga::Expression| match *e {
                        naga::Expression::Literal(naga::Literal::U32(v)) => Shared::U32(v),
                        naga::Expression::Literal(naga::Literal::F32(v)) => Shared::F32(v),
                        ref e => panic!("{name}: not a literal: {e:?}"),
                    };
                    let got = match (&m.global_expressions[c.init], want) {
                        (naga::Expression::Compose { components, .. }, Shared::F32s(values)) => {
                            let found: Vec<Shared> =
                                components.iter().map(|&h| literal(&m.global_expressions[h])).collect();
                            let wanted: Vec<Shared> = values.iter().map(|&v| Shared::F32(v)).collect();
                            assert_eq!(found, wanted, "the table {name} in the {p:?} shader");
                            want
                        }
                        (e, _) => literal(e),
                    };
                    assert_eq!(got, want, "{name} in the {p:?} shader");
                    seen.insert(name.to_string());
                }
            }
        }
        // Workgroup sizes are attributes and the stack depth an array length, not constants.
        let m = compose(Program::Path, FeatureKey::ALL).unwrap();
        let stack_len = m.types.iter().find_map(|(_, ty)| match &ty.inner {
            naga::TypeInner::Struct { members, .. } if ty.name.as_deref()?.starts_with("Stack") => {
                match m.types[members[0].ty].inner {
                    naga::TypeInner::Array { size: naga::ArraySize::Constant(n), .. } => Some(n.get()),
                    _ => None,
                }
            }
            _ => None,
        });
        assert_eq!(stack_len.map(Shared::U32), shared.get("GPU_STACK").copied(), "the traversal stack's length");
        // The table's length is its array's (checked with its values above); its row count
        // folds into the constant expressions that use it.
        let folded =
            |n: &str| n.ends_with("WORKGROUP") || ["GPU_STACK", "GGX_ALBEDO_LEN", "GGX_ROUGHNESS_STEPS"].contains(&n);
        let missing: Vec<_> = shared.keys().filter(|n| !seen.contains(**n) && !folded(n)).collect();
        assert!(missing.is_empty(), "not found as constants: {missing:?}");
    }

    /// Every struct the host writes into a GPU buffer has, in the composed WGSL module, the
    /// size and member offsets of its Rust twin (as naga's layouter computes them).
    #[test]
    fn wgsl_struct_layouts_equal_the_rust_structs() {
        use std::mem::{offset_of, size_of};
        use strahl_core::accel::gpu_bvh::{GpuLeafTriangle, GpuNode};
        use strahl_core::layout::*;
        macro_rules! layout {
            ($wgsl:literal, $t:ty, [$($f:ident),*]) => {
                ($wgsl, size_of::<$t>(), vec![$((stringify!($f), offset_of!($t, $f))),*])
            };
        }
        let expected = [
            layout!(
                "Frame",
                FrameParams,
                [
                    eye,
                    width,
                    forward,
                    height,
                    right,
                    spp,
                    up,
                    max_depth,
                    background,
                    _pad,
                    ambient,
                    num_lights,
                    tile_origin,
                    tile_size,
                    sample_base,
                    out_pitch,
                    out_first_row,
                    flags,
                    num_emitters,
                    emitter_norm,
                    rr_depth,
                    seed
                ]
            ),
            layout!("Sphere", GpuSphere, [center, radius, object, face, material, _pad]),
            layout!("Cylinder", GpuCylinder, [pa, radius, pb, caps, object, face, material, _pad]),
            layout!("Plane", GpuPlane, [point, object, normal, material]),
            layout!("Triangle", GpuTriangle, [va, object, vb, face, vc, material]),
            layout!("Node", GpuNode, [lo_a, link_a, hi_a, link_b, lo_b, _pad_a, hi_b, _pad_b]),
            layout!("LeafTriangle", GpuLeafTriangle, [va, index, vb, material, vc, _pad]),
            layout!(
                "Material",
                GpuMaterial,
                [
                    color,
                    kind,
                    radiance,
                    ior,
                    roughness,
                    flags,
                    color_texture,
                    radiance_texture,
                    metallic,
                    metal_rough_texture,
                    normal_texture,
                    normal_scale,
                    alpha,
                    alpha_cutoff,
                    _pad
                ]
            ),
            layout!("TextureInfo", GpuTexture, [width, height, offset, flags, linear, offset_uv, _pad]),
            layout!("TriangleAttrs", GpuTriangleAttrs, [uv, second_uv, normal, color, flags, _pad]),
            layout!(
                "Environment",
                GpuEnvironment,
                [radiance, flags, rot_cos, rot_sin, texture, select_prob, width, height, _pad, sh]
            ),
            layout!("Light", GpuLight, [vector, kind, intensity, flags]),
            layout!("Emitter", GpuEmitter, [source, kind, cdf, pdf]),
            layout!("QueryRay", GpuQueryRay, [origin, tmin, dir, tmax]),
            layout!("QueryHit", GpuQueryHit, [normal, t, object, face, prim_ref, flags]),
        ];
        // Every struct is used by one of these programs in its all-features variant.
        let modules = [
            compose(Program::Whitted, FeatureKey::ALL).unwrap(),
            compose(Program::Path, FeatureKey::ALL).unwrap(),
            compose(Program::Trace, FeatureKey::ALL).unwrap(),
        ];
        for (name, size, fields) in expected {
            let found = modules.iter().find_map(|m| {
                let mut layouter = naga::proc::Layouter::default();
                layouter.update(m.to_ctx()).unwrap();
                m.types.iter().find_map(|(h, ty)| {
                    let undecorated = ty.name.as_deref()?.split("X_naga_oil_mod_X").next()?;
                    match &ty.inner {
                        naga::TypeInner::Struct { members, .. } if undecorated == name => {
                            Some((layouter[h].size, members.clone()))
                        }
                        _ => None,
                    }
                })
            });
            let (wgsl_size, members) =
                found.unwrap_or_else(|| panic!("struct {name} not found in the composed shaders"));
            assert_eq!(wgsl_size as usize, size, "size of {name}");
            // Padding is `_pad` in Rust (unused) and `pad` in WGSL.
            let wgsl_name = |f: &str| f.trim_start_matches('_').to_string();
            // Every member on each side is in the list, so none is checked only through the size.
            let listed: Vec<String> = fields.iter().map(|(f, _)| wgsl_name(f)).collect();
            let in_wgsl: Vec<String> = members.iter().map(|m| m.name.clone().unwrap_or_default()).collect();
            assert_eq!(in_wgsl, listed, "the members of WGSL {name}, in order");
            let rust_name = rust_struct_of(name);
            let in_rust: Vec<String> = rust_fields(rust_name).iter().map(|f| wgsl_name(f)).collect();
            assert_eq!(in_rust, listed, "the fields of {rust_name}, in order");
            for ((field, offset), m) in fields.iter().zip(&members) {
                assert_eq!(m.offset as usize, *offset, "offset of {name}.{field}");
            }
        }
    }

    /// The Rust struct whose layout WGSL struct `name` shares.
    fn rust_struct_of(name: &str) -> &'static str {
        match name {
            "Frame" => "FrameParams",
            "Sphere" => "GpuSphere",
            "Cylinder" => "GpuCylinder",
            "Plane" => "GpuPlane",
            "Triangle" => "GpuTriangle",
            "Node" => "GpuNode",
            "LeafTriangle" => "GpuLeafTriangle",
            "Material" => "GpuMaterial",
            "Light" => "GpuLight",
            "Emitter" => "GpuEmitter",
            "QueryRay" => "GpuQueryRay",
            "QueryHit" => "GpuQueryHit",
            "TextureInfo" => "GpuTexture",
            "TriangleAttrs" => "GpuTriangleAttrs",
            "Environment" => "GpuEnvironment",
            _ => panic!("no Rust twin named for WGSL struct {name}"),
        }
    }

    /// The field names of `pub struct NAME` as written in the source of the buffer layouts,
    /// so that a field added to the Rust struct and not to the test's list is caught.
    fn rust_fields(name: &str) -> Vec<String> {
        let sources = [include_str!("../../core/src/layout.rs"), include_str!("../../core/src/accel/gpu_bvh.rs")];
        let start = format!("pub struct {name} {{");
        let text = sources.iter().find_map(|s| s.split_once(&start).map(|(_, rest)| rest));
        let text = text.unwrap_or_else(|| panic!("pub struct {name} not found"));
        let body = &text[..text.find("\n}").expect("the struct's closing brace")];
        body.lines()
            .filter_map(|l| l.trim().strip_prefix("pub ")?.split_once(':').map(|(f, _)| f.trim().to_string()))
            .collect()
    }
}
