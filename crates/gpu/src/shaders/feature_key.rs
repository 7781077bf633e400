//! [`FeatureKey`]: which code a scene needs, and the shader defs that select it.

use naga_oil::compose::ShaderDefValue;
use std::collections::HashMap;

use super::Program;
use strahl_core::layout::{ENV_MAP, FlatScene, LIGHT_DIRECTIONAL, LIGHT_POINT};
use strahl_core::primitives::Primitives;
use strahl_core::scene::{Light, MaterialKind, Scene};

/// Which code a scene needs. Each flag is a shader def of the same name; the bits above the
/// flags ([`FeatureKey::SPLIT`]) say how the scene's largest arrays are split across bindings
/// ([`crate::split`]), as the defs `TRIANGLE_PARTS`, `NODE_PARTS`, `LEAF_TRIANGLE_PARTS` and
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
    /// which [`GpuContext::pipeline`](crate::GpuContext::pipeline) adds.
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
    /// The split of the scene's arrays across bindings ([`crate::split::Split`]): not a flag,
    /// set only where an array exceeds one binding.
    pub const SPLIT: u32 = crate::split::MASK;
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
        let split = crate::split::Split::of_key(self);
        for array in crate::split::SplitArray::ALL {
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
        let split = crate::split::Split::of_key(self);
        if split.is_split() {
            names.push(split.label());
        }
        if names.is_empty() { "EMPTY".into() } else { names.join("+") }
    }
}
