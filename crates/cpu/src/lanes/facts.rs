//! What the lanes may take for granted in a scene, found once per render ([`Facts`]): whether
//! the lanes shade at all (no point or directional lights), which materials they shade and
//! how ([`Material`], [`Kind`]), and the tables and decoded textures their searches and
//! lookups read.

use super::emitters as lights;
use super::environment as lane_env;
use super::guide::Guides;
use super::texels::{self, Texels};
use strahl_core::layout::{ATTR_NORMALS, FlatScene, LIGHT_STAND_IN, MATERIAL_ALPHA, MATERIAL_UNLIT, TEXTURE_NEAREST};
use strahl_core::render::bsdf::MIN_ROUGHNESS;
use strahl_core::render::pbr::PBR_F0;
use strahl_core::scene::MaterialKind;

/// What the lanes' shading may take for granted in a scene, found once per render.
pub struct Facts {
    /// The scene has no point or directional light.
    pub lanes_ok: bool,
    /// Per material: what the lanes read of it, where they shade it (kind [`Kind`]; colour
    /// and metallic-roughness textures without nearest filtering, on diffuse and pbr
    /// materials only; no emission or normal texture, no alpha, not unlit).
    pub materials: Vec<Option<Material>>,
    /// Area lights are sampled in lanes ([`lights::in_lanes`]).
    pub lights_in_lanes: bool,
    /// The guides of the searches that pick an emitter and an environment map's cell.
    pub(super) guides: Guides,
    /// The colour, metallic-roughness and environment textures the lanes read, decoded.
    pub(super) texels: Texels,
    /// The lanes shade pbr materials, textures, vertex normals or an environment here: a
    /// scene without them is shaded by code compiled without them (the Cornell box 0.555 s
    /// against 0.58 s with them compiled in).
    pub rich: bool,
    /// The render's choice of walks, measured as it goes.
    choice: std::sync::Mutex<super::Choice>,
}

/// What the lanes read of a material, side by side.
#[derive(Clone, Copy, Debug)]
pub struct Material {
    pub kind: Kind,
    pub flags: u32,
    /// Emissive (its emission is added where a path meets it).
    pub emits: bool,
    /// [`strahl_core::layout::FlatMaterial::is_light`].
    pub light: bool,
    pub color: [f32; 3],
    pub radiance: [f32; 3],
    pub ior: f32,
    pub metallic: f32,
    pub roughness: f32,
    /// 1 + the colour texture's index (0: none).
    pub color_texture: u32,
    /// 1 + the metallic-roughness texture's index (0: none; pbr only).
    pub metal_rough_texture: u32,
}

/// The materials the lanes shade.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Diffuse, and emissive (Lambertian beneath its emission).
    Lambert = 0,
    Mirror = 1,
    Glass = 2,
    /// glTF's metallic-roughness material ([`pbr`]).
    Pbr = 3,
    /// A rough (GGX) mirror.
    Rough = 4,
}

impl Facts {
    /// The facts of `g` with `num_lights` lights; `walk`: the walk every ray after the camera's
    /// takes (None: the faster, measured).
    pub fn new(g: &FlatScene, num_lights: u32, walk: Option<super::Walk>) -> Self {
        let delta = g.lights[..num_lights as usize].iter().any(|l| l.flags & LIGHT_STAND_IN == 0);
        let materials: Vec<Option<Material>> = g
            .materials
            .iter()
            .map(|m| {
                let bilinear = |t: u32| t == 0 || g.textures[t as usize - 1].flags & TEXTURE_NEAREST == 0;
                let plain = m.radiance_texture == 0
                    && m.normal_texture == 0
                    && m.flags & (MATERIAL_ALPHA | MATERIAL_UNLIT) == 0
                    && bilinear(m.color_texture)
                    && bilinear(m.metal_rough_texture);
                let untextured = m.color_texture == 0 && m.metal_rough_texture == 0;
                let clear = m.absorption == [0.0; 3];
                let kind = match m.kind() {
                    MaterialKind::Diffuse | MaterialKind::Emissive => Some(Kind::Lambert),
                    MaterialKind::Mirror if untextured => {
                        Some(if m.roughness < MIN_ROUGHNESS { Kind::Mirror } else { Kind::Rough })
                    }
                    // Rough glass, absorbing glass, pbr glass and pbr materials with layers or
                    // their own specular reflectance are shaded one path at a time (the
                    // render's summary counts their vertices).
                    MaterialKind::Dielectric if untextured && m.roughness < MIN_ROUGHNESS && clear => Some(Kind::Glass),
                    MaterialKind::Pbr
                        if m.transmission <= 0.0
                            && clear
                            && !m.is_layered()
                            && m.spec_at_normal == [PBR_F0; 3]
                            && m.spec_at_grazing == 1.0 =>
                    {
                        Some(Kind::Pbr)
                    }
                    _ => None,
                };
                kind.filter(|_| plain).map(|kind| Material {
                    kind,
                    flags: m.flags,
                    emits: matches!(m.kind(), MaterialKind::Emissive | MaterialKind::Pbr),
                    light: m.is_light(),
                    color: m.color,
                    radiance: m.radiance,
                    ior: m.ior,
                    metallic: m.metallic,
                    roughness: m.roughness,
                    color_texture: m.color_texture,
                    metal_rough_texture: if kind == Kind::Pbr { m.metal_rough_texture } else { 0 },
                })
            })
            .collect();
        let rich = !g.environment.is_empty()
            || g.triangle_attrs.iter().any(|a| a.flags & ATTR_NORMALS != 0)
            || materials
                .iter()
                .flatten()
                .any(|m| m.kind == Kind::Pbr || m.color_texture != 0 || m.metal_rough_texture != 0);
        let map = lane_env::map(g).map(|e| e.texture as usize);
        let used = materials.iter().flatten().flat_map(|m| [m.color_texture, m.metal_rough_texture]);
        let used = used.filter(|&t| t != 0).map(|t| t as usize - 1).chain(map);
        Self {
            texels: Texels::new(g, used, texels::BUDGET),
            lanes_ok: !delta,
            rich,
            materials,
            lights_in_lanes: lights::in_lanes(g),
            guides: Guides::new(g, lane_env::map(g)),
            choice: std::sync::Mutex::new(super::Choice::forced(walk)),
        }
    }

    /// The render's choice of walks so far.
    pub(super) fn walks(&self) -> super::Choice {
        *self.choice.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Adds a measurement of `walk` for rays of `kind` to the render's choice.
    pub(super) fn record_walk(&self, kind: usize, walk: super::Walk, spent: std::time::Duration, rays: usize) {
        self.choice.lock().unwrap_or_else(|e| e.into_inner()).record(kind, walk, spent, rays);
    }
}
