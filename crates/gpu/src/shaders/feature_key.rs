//! [`FeatureKey`]: which code a scene needs, and the shader defs that select it.

use naga_oil::compose::ShaderDefValue;
use std::collections::HashMap;

use super::Program;
use crate::split::{Split, SplitArray};
use strahl_core::layout::{ENV_MAP, FlatScene, LIGHT_DIRECTIONAL, LIGHT_POINT};
use strahl_core::primitives::Primitives;
use strahl_core::render::bsdf::MIN_ROUGHNESS;
use strahl_core::scene::{AlphaMode, Light, MaterialKind, Scene};

bitflags::bitflags! {
    /// Which code a scene needs. Each flag is a shader def of the same name; the bits above the
    /// flags ([`FeatureKey::SPLIT`], unnamed) say how the scene's largest arrays are split across
    /// bindings ([`crate::split`]), as the defs `TRIANGLE_PARTS`, `NODE_PARTS`,
    /// `LEAF_TRIANGLE_PARTS` and the elements per part.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
    pub struct FeatureKey: u32 {
        const SPHERES = 1 << 0;
        const CYLINDERS = 1 << 1;
        const TRIANGLES = 1 << 2;
        const PLANES = 1 << 3;
        /// Walk the BVH (else test every bounded primitive: tiny scenes).
        const BVH = 1 << 4;
        const POINT_LIGHTS = 1 << 5;
        const DIRECTIONAL_LIGHTS = 1 << 6;
        const MIRROR = 1 << 7;
        const DIELECTRIC = 1 << 8;
        const EMISSIVE = 1 << 9;
        /// The device reads 64-bit words (`SHADER_INT64`): a flag of the device, not of the
        /// scene, which [`GpuContext::pipeline`](crate::GpuContext::pipeline) adds.
        const LOAD64 = 1 << 10;
        /// Triangles carry attributes (per-triangle texture coordinates, normals, colours: a
        /// material has an image texture, or a mesh has normals or colours).
        const TEXTURES = 1 << 11;
        /// The scene has an `[environment]`.
        const ENVIRONMENT = 1 << 12;
        /// The environment is a map (implies ENVIRONMENT).
        const ENV_MAP = 1 << 13;
        /// glTF's metallic-roughness material.
        const PBR = 1 << 14;
        /// A material lets rays through by its alpha (glTF MASK or BLEND).
        const ALPHA = 1 << 15;
        /// A rough dielectric, or a pbr material with transmission (`modules/dielectric.wgsl`).
        const ROUGH_GLASS = 1 << 16;
        /// A material absorbs inside (Beer–Lambert).
        const ABSORPTION = 1 << 17;
        /// A pbr material has a clear coat or sheen (`modules/layers.wgsl`, `sheen.wgsl`).
        const LAYERS = 1 << 18;
    }
}

/// What a scene's key is read from: the same facts whether they come from the scene itself
/// ([`FeatureKey::of_scene`]) or from its flattened buffers ([`FeatureKey::for_scene`]), so
/// that one rule ([`FeatureKey::of_facts`]) turns both into flags.
struct Facts {
    spheres: bool,
    cylinders: bool,
    triangles: bool,
    planes: bool,
    /// Spheres, cylinders and triangles.
    bounded: usize,
    point_lights: bool,
    directional_lights: bool,
    /// Each material's kind, and whether it is a light.
    materials: Vec<(MaterialKind, bool)>,
    /// A rough dielectric or a pbr material with transmission.
    rough_glass: bool,
    /// A material that absorbs inside.
    absorption: bool,
    /// A pbr material with a clear coat or sheen.
    layers: bool,
    alpha: bool,
    /// Per-triangle attributes.
    attributes: bool,
    environment: bool,
    env_map: bool,
}

impl FeatureKey {
    /// Flags: the bits below the split.
    pub const FLAG_COUNT: u32 = u32::BITS - Self::all().bits().leading_zeros();
    /// Flags that describe the device rather than the scene.
    pub const DEVICE: FeatureKey = Self::LOAD64;
    /// The split of the scene's arrays across bindings ([`Split`]): not a flag, set only where
    /// an array exceeds one binding.
    pub const SPLIT: FeatureKey = FeatureKey::from_bits_retain(crate::split::MASK);
    /// Flags that change the trace and closest-point programs (they have no shading code).
    pub const GEOMETRY: FeatureKey = Self::SPHERES
        .union(Self::CYLINDERS)
        .union(Self::TRIANGLES)
        .union(Self::PLANES)
        .union(Self::BVH)
        .union(Self::DEVICE)
        .union(Self::SPLIT);
    /// Flags of the textures and the environment, which only the shading programs (render,
    /// path) read.
    pub const ASSETS: FeatureKey = Self::TEXTURES
        .union(Self::ENVIRONMENT)
        .union(Self::ENV_MAP)
        .union(Self::PBR)
        .union(Self::ALPHA)
        .union(Self::ROUGH_GLASS)
        .union(Self::ABSORPTION)
        .union(Self::LAYERS);
    /// The materials that bend a ray without scattering it (the AOV program follows them).
    pub const SPECULAR: FeatureKey = Self::MIRROR.union(Self::DIELECTRIC);
    /// Every scene feature: the one shader that renders any scene.
    pub const ALL: FeatureKey = Self::all().difference(Self::DEVICE);

    /// Scenes with at most this many bounded primitives test them all instead of walking a BVH.
    pub const BRUTE_FORCE_MAX: usize = 8;

    /// The key of `scene`, whose primitives are `prims`, read from the scene itself: what
    /// [`FeatureKey::for_scene`] gives for its flattened buffers, without building a BVH or
    /// packing textures (the viewer keys its shader by the whole scene while objects are
    /// hidden).
    pub fn of_scene(scene: &Scene, prims: &Primitives<f32>) -> FeatureKey {
        use strahl_core::render::flatten::{needs_attributes, stand_in_lights};
        Self::of_facts(Facts {
            spheres: !prims.spheres.is_empty(),
            cylinders: !prims.cylinders.is_empty(),
            triangles: !prims.triangles.is_empty(),
            planes: !prims.planes.is_empty(),
            bounded: prims.bounded_count(),
            // Emissive objects light Whitted renders through point lights that stand in for them.
            point_lights: scene.lights.iter().any(|l| matches!(l, Light::Point { .. } | Light::Spot { .. }))
                || !stand_in_lights(scene).is_empty(),
            directional_lights: scene.lights.iter().any(|l| matches!(l, Light::Directional { .. })),
            materials: scene.materials.iter().map(|m| (m.kind, m.is_light())).collect(),
            rough_glass: scene.materials.iter().any(|m| {
                (m.kind == MaterialKind::Dielectric && m.roughness as f32 >= MIN_ROUGHNESS)
                    || (m.kind == MaterialKind::Pbr && m.transmission as f32 > 0.0)
            }),
            absorption: scene.materials.iter().any(|m| m.absorption.iter().any(|&a| a as f32 != 0.0)),
            layers: scene.materials.iter().any(|m| {
                m.kind == MaterialKind::Pbr
                    && (m.clearcoat as f32 > 0.0 || m.sheen_color.iter().any(|&c| c as f32 > 0.0))
            }),
            alpha: scene.materials.iter().any(|m| m.alpha_mode != AlphaMode::Opaque),
            attributes: needs_attributes(scene),
            environment: scene.environment.is_some(),
            env_map: scene.environment.as_ref().is_some_and(|e| e.map.is_some()),
        })
    }

    /// The key of a flattened scene: the features its buffers hold.
    pub fn for_scene(g: &FlatScene) -> FeatureKey {
        Self::of_facts(Facts {
            spheres: !g.spheres.is_empty(),
            cylinders: !g.cylinders.is_empty(),
            triangles: !g.triangles.is_empty(),
            planes: !g.planes.is_empty(),
            bounded: g.bounded_count(),
            point_lights: g.lights.iter().any(|l| l.kind == LIGHT_POINT),
            directional_lights: g.lights.iter().any(|l| l.kind == LIGHT_DIRECTIONAL),
            materials: g.materials.iter().map(|m| (m.kind(), m.is_light())).collect(),
            rough_glass: g.materials.iter().any(strahl_core::render::bsdf::is_rough_glass),
            absorption: g.materials.iter().any(|m| m.absorption != [0.0; 3]),
            layers: g.materials.iter().any(|m| m.kind() == MaterialKind::Pbr && m.is_layered()),
            alpha: g.alpha,
            attributes: !g.triangle_attrs.is_empty(),
            environment: !g.environment.is_empty(),
            env_map: g.environment.iter().any(|e| e.flags & ENV_MAP != 0),
        })
    }

    /// The flags of a scene with the facts `f`.
    fn of_facts(f: Facts) -> FeatureKey {
        let has = |kind: MaterialKind| f.materials.iter().any(|&(k, _)| k == kind);
        [
            (f.spheres, Self::SPHERES),
            (f.cylinders, Self::CYLINDERS),
            (f.triangles, Self::TRIANGLES),
            (f.planes, Self::PLANES),
            (f.bounded > Self::BRUTE_FORCE_MAX, Self::BVH),
            (f.point_lights, Self::POINT_LIGHTS),
            (f.directional_lights, Self::DIRECTIONAL_LIGHTS),
            (has(MaterialKind::Mirror), Self::MIRROR),
            (has(MaterialKind::Dielectric), Self::DIELECTRIC),
            // pbr emission is added under EMISSIVE, which has the emitters' code.
            (has(MaterialKind::Emissive) || f.materials.iter().any(|&(_, light)| light), Self::EMISSIVE),
            (has(MaterialKind::Pbr), Self::PBR),
            (f.alpha, Self::ALPHA),
            (f.rough_glass, Self::ROUGH_GLASS),
            (f.absorption, Self::ABSORPTION),
            (f.layers, Self::LAYERS),
            (f.attributes, Self::TEXTURES),
            (f.environment, Self::ENVIRONMENT),
            (f.env_map, Self::ENV_MAP),
        ]
        .into_iter()
        .filter_map(|(set, flag)| set.then_some(flag))
        .collect()
    }

    /// The key as the program sees it: the trace, view and closest-point programs ignore
    /// shading flags, the AOV program the lights'.
    pub fn for_program(self, p: Program) -> FeatureKey {
        match p {
            Program::Whitted | Program::Path | Program::Wavefront => self,
            Program::Trace | Program::View | Program::Closest => self & Self::GEOMETRY,
            Program::Aov => self & Self::GEOMETRY.union(Self::SPECULAR).union(Self::PBR).union(Self::ASSETS),
        }
    }

    /// The flags without the split.
    pub fn flags(self) -> FeatureKey {
        self - Self::SPLIT
    }

    pub fn shader_defs(self) -> HashMap<String, ShaderDefValue> {
        let on = ShaderDefValue::Bool(true);
        let mut defs: HashMap<String, ShaderDefValue> = self.iter_names().map(|(name, _)| (name.into(), on)).collect();
        let mut derived = |name: &str, needed: bool| {
            if needed {
                defs.insert(name.into(), on);
            }
        };
        derived("LIGHTS", self.intersects(Self::POINT_LIGHTS | Self::DIRECTIONAL_LIGHTS));
        derived("SHADOW_CROSSING", self.intersects(Self::DIELECTRIC | Self::EMISSIVE | Self::ALPHA));
        derived("ENVIRONMENT", self.contains(Self::ENV_MAP));
        // The texture table and texels are bound for textures and for an environment map.
        derived("TEXELS", self.intersects(Self::TEXTURES | Self::ENV_MAP));
        // Parts per splittable array (1: whole), defined for every key (the shaders compare
        // them), and the elements per part where there are several.
        let split = Split::of_key(self);
        for array in SplitArray::ALL {
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
        let mut names: Vec<String> = self.iter_names().map(|(name, _)| name.to_string()).collect();
        let split = Split::of_key(self);
        if split.is_split() {
            names.push(split.label());
        }
        if names.is_empty() { "EMPTY".into() } else { names.join("+") }
    }
}
