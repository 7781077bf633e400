//! The scene flattened into the buffers both backends read ([`FlatScene`], laid out in
//! [`crate::layout`]): primitives with their object, index and material, materials, lights
//! (with the point lights that stand in for emissive objects in Whitted mode), the BVH in the
//! GPU's layout, the area emitters path tracing samples, packed textures and the environment.
//! [`super::Prepared`] holds the result beside the primitives and the BVH it was made from.

use crate::accel::Bvh;
use crate::accel::gpu_bvh::GpuBvh;
use crate::layout::*;
use crate::math::V3;
use crate::primitives::{PrimKind, PrimRef, Primitives, Tagged};
use crate::scene::{AlphaMode, Geometry, Light, Scene};

const PI: f64 = std::f64::consts::PI;

fn rgb(v: [f64; 3]) -> [f32; 3] {
    v.map(|c| c as f32)
}

/// A material's dielectric reflectance at normal incidence: ((η − 1)/(η + 1))² (Fresnel at
/// normal incidence, glTF's `dielectric_brdf`), tinted by `KHR_materials_specular`'s colour,
/// each channel at most 1, times its factor (the extension's `fresnel_mix`); 0.04 exactly for
/// η = 1.5 and the defaults. Only a pbr material reads it.
fn spec_at_normal(m: &crate::scene::Material) -> [f32; 3] {
    if m.kind != crate::scene::MaterialKind::Pbr {
        return [DEFAULT_F0; 3];
    }
    let r = (m.ior - 1.0) / (m.ior + 1.0);
    m.specular_color.map(|c| ((r * r * c).min(1.0) * m.specular) as f32)
}

impl FlatScene {
    /// Flattens `scene`, whose primitives are `prims` and whose BVH over them is `bvh`.
    pub fn new(scene: &Scene, prims: &Primitives<f32>, bvh: &Bvh) -> Self {
        let tag = |t: &crate::primitives::Tag| (t.object, t.face, t.material);
        let mut g = Self {
            spheres: prims
                .spheres
                .iter()
                .map(|Tagged { shape: s, tag: t }| {
                    let (object, face, material) = tag(t);
                    FlatSphere { center: s.center.to_array(), radius: s.radius, object, face, material, _pad: 0 }
                })
                .collect(),
            cylinders: prims
                .cylinders
                .iter()
                .map(|Tagged { shape: c, tag: t }| {
                    let (object, face, material) = tag(t);
                    FlatCylinder {
                        pa: c.p1.to_array(),
                        radius: c.radius,
                        pb: c.p2.to_array(),
                        caps: c.caps as u32,
                        object,
                        face,
                        material,
                        _pad: 0,
                    }
                })
                .collect(),
            planes: prims
                .planes
                .iter()
                .map(|Tagged { shape: p, tag: t }| FlatPlane {
                    point: p.point.to_array(),
                    object: t.object,
                    normal: p.normal.to_array(),
                    material: t.material,
                })
                .collect(),
            triangles: prims
                .triangles
                .iter()
                .map(|Tagged { shape: tri, tag: t }| FlatTriangle {
                    va: tri.v[0].to_array(),
                    object: t.object,
                    vb: tri.v[1].to_array(),
                    face: t.face,
                    vc: tri.v[2].to_array(),
                    material: t.material,
                })
                .collect(),
            nodes: Vec::new(),
            shape_refs: Vec::new(),
            leaf_triangles: Vec::new(),
            materials: scene
                .materials
                .iter()
                .map(|m| FlatMaterial {
                    color: rgb(m.color),
                    kind: m.kind as u32,
                    radiance: rgb(m.radiance),
                    ior: m.ior as f32,
                    roughness: m.roughness as f32,
                    flags: if m.two_sided { MATERIAL_TWO_SIDED } else { 0 }
                        | if m.single_scattering { MATERIAL_SINGLE_SCATTERING } else { 0 }
                        | if m.unlit { MATERIAL_UNLIT } else { 0 }
                        | match m.alpha_mode {
                            AlphaMode::Opaque => 0,
                            AlphaMode::Mask(_) => MATERIAL_ALPHA_MASK,
                            AlphaMode::Blend => MATERIAL_ALPHA_BLEND,
                        },
                    color_texture: m.color_texture.map_or(0, |t| t + 1),
                    radiance_texture: m.radiance_texture.map_or(0, |t| t + 1),
                    metallic: m.metallic as f32,
                    metal_rough_texture: m.metal_rough_texture.map_or(0, |t| t + 1),
                    normal_texture: m.normal_texture.map_or(0, |t| t + 1),
                    normal_scale: m.normal_scale as f32,
                    alpha: m.alpha as f32,
                    alpha_cutoff: match m.alpha_mode {
                        AlphaMode::Mask(c) => c as f32,
                        _ => 0.0,
                    },
                    clearcoat: m.clearcoat as f32,
                    clearcoat_roughness: m.clearcoat_roughness as f32,
                    absorption: rgb(m.absorption),
                    transmission: m.transmission as f32,
                    spec_at_normal: spec_at_normal(m),
                    spec_at_grazing: m.specular as f32,
                    sheen_color: rgb(m.sheen_color),
                    sheen_roughness: m.sheen_roughness as f32,
                })
                .collect(),
            lights: scene.lights.iter().map(flat_light).collect(),
            emitters: Vec::new(),
            emitter_norm: 0.0,
            textures: Vec::new(),
            texels: Vec::new(),
            triangle_attrs: Vec::new(),
            environment: Vec::new(),
            env_distribution: Vec::new(),
            alpha: false,
        };
        g.alpha = g.materials.iter().any(|m| m.flags & MATERIAL_ALPHA != 0);
        if let Ok(tree) = GpuBvh::collapse(bvh, prims) {
            (g.nodes, g.shape_refs, g.leaf_triangles) = (tree.nodes, tree.shape_refs, tree.triangles);
        }
        g.lights.extend(stand_in_lights(scene));
        let (emitters, norm) = build_emitters(&g);
        g.emitters = emitters;
        g.emitter_norm = norm;
        let map = scene.environment.as_ref().and_then(|e| e.map.as_ref());
        if !scene.textures.is_empty() || map.is_some() {
            (g.textures, g.texels) = super::texture::pack(scene.textures.iter().chain(map));
        }
        if needs_attributes(scene) {
            g.triangle_attrs = super::texture::triangle_attrs(scene, prims);
        }
        if let Some(env) = &scene.environment {
            let (e, distribution) = super::environment::build(env, scene.textures.len() as u32, !g.emitters.is_empty());
            // Area emitters are chosen with probability 1 − select: their densities shrink so.
            g.emitter_norm *= 1.0 - e.select_prob;
            g.environment = vec![e];
            g.env_distribution = distribution;
        }
        g
    }
}

/// Whether shading reads per-triangle attributes: a material has a texture, or a mesh has
/// normals or colours.
pub fn needs_attributes(scene: &Scene) -> bool {
    scene.materials.iter().any(|m| {
        m.color_texture.is_some()
            || m.radiance_texture.is_some()
            || m.metal_rough_texture.is_some()
            || m.normal_texture.is_some()
    }) || scene.objects.iter().any(|o| match &o.geometry {
        Geometry::Mesh { attrs, .. } => !attrs.normals.is_empty() || !attrs.colors.is_empty(),
        _ => false,
    })
}

/// Whitted mode has no area lights: each emissive object lights the scene as a point light
/// at its centre whose intensity is its radiance times its (projected) area, the on-axis
/// intensity of a Lambertian emitter. Shadow rays pass through emissive surfaces, so the
/// object does not hide its own stand-in. Planes have no finite area and get none.
pub fn stand_in_lights(scene: &Scene) -> Vec<FlatLight> {
    // The radiance each emissive material gives off on average (its texture's mean included),
    // computed once per material: a texture's mean reads every texel, and a mesh asks per
    // triangle.
    let per_material: Vec<Option<[f64; 3]>> = scene
        .materials
        .iter()
        .map(|m| {
            // pbr emission (a lit screen or lamp on an asset) shows where it is seen but is no
            // stand-in: the point would sit inside the model, shadowed by its own surface.
            if m.kind != crate::scene::MaterialKind::Emissive || !m.is_light() {
                return None;
            }
            let scale = m.radiance_texture.map_or([1.0; 3], |t| scene.textures[t as usize].mean());
            Some([0, 1, 2].map(|c| m.radiance[c] * scale[c]))
        })
        .collect();
    let emitted = |material: u32| per_material[material as usize];
    let mut out = Vec::new();
    let mut push = |centre: V3<f64>, area: f64, radiance: [f64; 3]| {
        if area > 0.0 {
            out.push(FlatLight {
                vector: centre.cast::<f32>().to_array(),
                kind: LIGHT_POINT,
                intensity: radiance.map(|c| (c * area) as f32),
                flags: LIGHT_STAND_IN,
                ..FlatLight::default()
            });
        }
    };
    for o in &scene.objects {
        if let Geometry::Mesh { triangles, materials, .. } = &o.geometry
            && !materials.is_empty()
        {
            // A glTF mesh: one stand-in per emissive material it uses.
            let mut groups: std::collections::BTreeMap<u32, Vec<crate::geometry::Triangle<f64>>> = Default::default();
            for (t, &m) in triangles.iter().zip(materials) {
                if emitted(m).is_some() {
                    groups.entry(m).or_default().push(*t);
                }
            }
            for (m, tris) in groups {
                let (centre, area) = area_centroid(&tris);
                push(centre, area, emitted(m).expect("grouped by emission"));
            }
            continue;
        }
        let Some(radiance) = emitted(o.material) else { continue };
        let (centre, area) = match &o.geometry {
            Geometry::Sphere(s) => (s.center, PI * s.radius * s.radius),
            Geometry::Cylinder(c) => ((c.p1 + c.p2) * 0.5, 2.0 * c.radius * (c.p2 - c.p1).length()),
            Geometry::Plane(_) => continue,
            Geometry::Triangle(t) => area_centroid(std::slice::from_ref(t)),
            Geometry::Polygon { triangles, .. } | Geometry::Mesh { triangles, .. } => area_centroid(triangles),
        };
        push(centre, area, radiance);
    }
    out
}

fn area_centroid(tris: &[crate::geometry::Triangle<f64>]) -> (V3<f64>, f64) {
    let mut sum = V3::zero();
    let mut area = 0.0;
    for t in tris {
        let a = 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length();
        sum += (t.v[0] + t.v[1] + t.v[2]) * (a / 3.0);
        area += a;
    }
    (if area > 0.0 { sum / area } else { V3::zero() }, area)
}

/// The area-emitter table of `g` and 1 / Σ weights.
pub fn build_emitters(g: &FlatScene) -> (Vec<FlatEmitter>, f32) {
    let emissive = |material: u32| {
        let m = &g.materials[material as usize];
        (m.is_light() && super::emitters::mean(m.radiance) > 0.0).then(|| super::emitters::mean(m.radiance) as f64)
    };
    let mut entries: Vec<(u32, u32, f64)> = Vec::new();
    for (i, t) in g.triangles.iter().enumerate() {
        if let Some(l) = emissive(t.material) {
            let (a, b, c) =
                (V3::from_array(t.va).to_f64(), V3::from_array(t.vb).to_f64(), V3::from_array(t.vc).to_f64());
            let area = 0.5 * (b - a).cross(c - a).length();
            if area > 0.0 {
                entries.push((PrimRef::new(PrimKind::Triangle, i).0, EMITTER_AREA, l * area));
            }
        }
    }
    for (i, s) in g.spheres.iter().enumerate() {
        if let Some(l) = emissive(s.material) {
            let r = s.radius as f64;
            entries.push((PrimRef::new(PrimKind::Sphere, i).0, EMITTER_AREA, l * 4.0 * PI * r * r));
        }
    }
    let total: f64 = entries.iter().map(|e| e.2).sum();
    if entries.is_empty() || total <= 0.0 || !total.is_finite() {
        return (Vec::new(), 0.0);
    }
    let mut cum = 0.0;
    let n = entries.len();
    let emitters = entries
        .into_iter()
        .enumerate()
        .map(|(k, (source, kind, w))| {
            cum += w;
            let cdf = if k + 1 == n { 1.0 } else { (cum / total) as f32 };
            FlatEmitter { source, kind, cdf, pdf: (w / total) as f32 }
        })
        .collect();
    (emitters, (1.0 / total) as f32)
}

/// A scene light as the shaders read it.
fn flat_light(l: &Light) -> FlatLight {
    match l {
        Light::Point { position, intensity, range } => FlatLight {
            vector: position.cast::<f32>().to_array(),
            kind: LIGHT_POINT,
            intensity: rgb(*intensity),
            range: *range as f32,
            ..FlatLight::default()
        },
        Light::Directional { direction, intensity } => FlatLight {
            vector: direction.cast::<f32>().normalize().to_array(),
            kind: LIGHT_DIRECTIONAL,
            intensity: rgb(*intensity),
            ..FlatLight::default()
        },
        &Light::Spot { position, direction, intensity, inner, outer, range } => {
            // KHR_lights_punctual's recommended falloff, in its own constants.
            let scale = 1.0 / (inner.cos() - outer.cos()).max(0.001);
            FlatLight {
                vector: position.cast::<f32>().to_array(),
                kind: LIGHT_POINT,
                intensity: rgb(intensity),
                axis: direction.cast::<f32>().normalize().to_array(),
                cone_scale: scale as f32,
                cone_offset: (-outer.cos() * scale) as f32,
                range: range as f32,
                flags: LIGHT_SPOT,
                ..FlatLight::default()
            }
        }
    }
}
