//! The flat layout both backends read: the scene as `#[repr(C)]` + [`bytemuck::Pod`] records
//! ([`FlatScene`]: `Flat*` structs), whose layout equals the WGSL structs in
//! `shaders/modules/types.wgsl` (a test checks every size and offset through naga's layouter),
//! so that the GPU's storage buffers and the CPU's tracers shade from identical f32 data. The
//! scene is flattened into them by [`crate::render::flatten`].
//!
//! WGSL's `vec3<f32>` is 16-byte aligned with size 12: every `[f32; 3]` here is followed by a
//! 4-byte field that fills the rest of its 16 bytes.

use crate::accel::gpu_bvh::{GpuLeafTriangle, GpuNode};
use crate::scene::MaterialKind;
use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatSphere {
    pub center: [f32; 3],
    pub radius: f32,
    pub object: u32,
    pub face: u32,
    pub material: u32,
    pub _pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatCylinder {
    /// p1 of the lecture (WGSL member names may not end in a digit).
    pub pa: [f32; 3],
    pub radius: f32,
    /// p2 of the lecture.
    pub pb: [f32; 3],
    /// 1: closed by end caps; 0: open tube.
    pub caps: u32,
    pub object: u32,
    pub face: u32,
    pub material: u32,
    pub _pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatPlane {
    pub point: [f32; 3],
    pub object: u32,
    pub normal: [f32; 3],
    pub material: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatTriangle {
    pub va: [f32; 3],
    pub object: u32,
    pub vb: [f32; 3],
    pub face: u32,
    pub vc: [f32; 3],
    pub material: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct FlatMaterial {
    pub color: [f32; 3],
    /// [`crate::scene::MaterialKind`] as u32.
    pub kind: u32,
    pub radiance: [f32; 3],
    pub ior: f32,
    /// GGX α of a mirror (path mode), 0 for smooth.
    pub roughness: f32,
    /// [`MATERIAL_TWO_SIDED`].
    pub flags: u32,
    /// 1 + the index in [`FlatScene::textures`] of the image that multiplies `color`; 0 for none.
    pub color_texture: u32,
    /// 1 + the index of the image that multiplies `radiance`; 0 for none.
    pub radiance_texture: u32,
    /// pbr: metalness (glTF `metallicFactor`); `roughness` is then perceptual (α = its square).
    pub metallic: f32,
    /// pbr: 1 + the index of the metallic-roughness image (blue: metal, green: roughness).
    pub metal_rough_texture: u32,
    /// pbr: 1 + the index of the tangent-space normal map; 0 for none.
    pub normal_texture: u32,
    /// pbr: the normal map's scale (glTF `normalTexture.scale`).
    pub normal_scale: f32,
    /// Alpha factor (base colour alpha), which textures and vertex colours multiply.
    pub alpha: f32,
    /// [`MATERIAL_ALPHA_MASK`]: alpha below this lets rays through.
    pub alpha_cutoff: f32,
    /// pbr: `KHR_materials_clearcoat`'s factor (the coat layer of [`crate::render::layers`]).
    pub clearcoat: f32,
    /// pbr: the clear coat's perceptual roughness (α = its square).
    pub clearcoat_roughness: f32,
    /// Absorption coefficient per unit length inside the material (Beer–Lambert), applied to
    /// the segment a path ends on the back face ([`crate::render::bsdf`]); 0: clear.
    pub absorption: [f32; 3],
    /// pbr: `KHR_materials_transmission`'s factor ([`crate::render::bsdf::glass_share`]).
    pub transmission: f32,
    /// pbr: the dielectric's reflectance at normal incidence, per channel: ((η − 1)/(η + 1))²
    /// with `KHR_materials_ior`'s η, times `KHR_materials_specular`'s colour (at most 1) and
    /// factor; 0.04 by default.
    pub spec_at_normal: [f32; 3],
    /// pbr: its reflectance at grazing incidence (`KHR_materials_specular`'s factor; 1 by
    /// default).
    pub spec_at_grazing: f32,
    /// pbr: `KHR_materials_sheen`'s colour (the sheen layer of [`crate::render::layers`]);
    /// black: no sheen.
    pub sheen_color: [f32; 3],
    /// pbr: the sheen's roughness (its α is the square).
    pub sheen_roughness: f32,
}

impl Default for FlatMaterial {
    /// Every field 0 except the dielectric's default reflectance (F0 0.04, F90 1).
    fn default() -> Self {
        FlatMaterial { spec_at_normal: [DEFAULT_F0; 3], spec_at_grazing: 1.0, ..Zeroable::zeroed() }
    }
}

/// The dielectric's reflectance at normal incidence without `KHR_materials_ior` and
/// `KHR_materials_specular`: index of refraction 1.5.
pub const DEFAULT_F0: f32 = 0.04;

impl FlatMaterial {
    /// Whether a pbr material has a layer above its base (a clear coat or sheen), which the
    /// CPU's lanes leave to the one-path code.
    pub fn is_layered(&self) -> bool {
        self.clearcoat > 0.0 || self.sheen_color.iter().any(|&c| c > 0.0)
    }

    /// What the material is. A kind the shaders do not know shades as diffuse there (their
    /// default branch), so it does here too; the scene loader writes only known kinds.
    pub fn kind(&self) -> MaterialKind {
        match self.kind {
            k if k == MaterialKind::Mirror as u32 => MaterialKind::Mirror,
            k if k == MaterialKind::Dielectric as u32 => MaterialKind::Dielectric,
            k if k == MaterialKind::Emissive as u32 => MaterialKind::Emissive,
            k if k == MaterialKind::Pbr as u32 => MaterialKind::Pbr,
            _ => MaterialKind::Diffuse,
        }
    }

    /// Whether its emission is sampled as a light (emissive and pbr kinds with radiance, not
    /// unlit ones).
    pub fn is_light(&self) -> bool {
        matches!(self.kind(), MaterialKind::Emissive | MaterialKind::Pbr)
            && self.flags & MATERIAL_UNLIT == 0
            && self.radiance.iter().any(|&c| c > 0.0)
    }
}

/// Material flag: an emissive surface emits from both faces.
pub const MATERIAL_TWO_SIDED: u32 = 1;
/// Material flag: shows its radiance and lights nothing (`KHR_materials_unlit`).
pub const MATERIAL_UNLIT: u32 = 2;
/// Material flag: rays pass where alpha < `alpha_cutoff` (glTF MASK).
pub const MATERIAL_ALPHA_MASK: u32 = 4;
/// Material flag: rays pass with probability 1 − alpha (glTF BLEND).
pub const MATERIAL_ALPHA_BLEND: u32 = 8;
/// Either alpha flag.
pub const MATERIAL_ALPHA: u32 = MATERIAL_ALPHA_MASK | MATERIAL_ALPHA_BLEND;
/// Material flag: a rough dielectric scatters once, its lost energy not made up (Mitsuba's
/// `roughdielectric`, pbrt's `DielectricBxDF`; [`crate::render::dielectric`]).
pub const MATERIAL_SINGLE_SCATTERING: u32 = 16;

pub const LIGHT_POINT: u32 = 0;
pub const LIGHT_DIRECTIONAL: u32 = 1;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatLight {
    /// Position (point light) or unit direction of travel (directional light).
    pub vector: [f32; 3],
    pub kind: u32,
    pub intensity: [f32; 3],
    /// [`LIGHT_STAND_IN`].
    pub flags: u32,
    /// A spot light's axis ([`LIGHT_SPOT`]), the unit direction it shines along.
    pub axis: [f32; 3],
    /// `KHR_lights_punctual`'s cone ([`LIGHT_SPOT`]): the intensity is scaled by
    /// clamp(cos θ · `cone_scale` + `cone_offset`, 0, 1)², θ from the axis.
    pub cone_scale: f32,
    pub cone_offset: f32,
    /// Beyond this distance the light reaches nothing, with `KHR_lights_punctual`'s smooth
    /// window before it; 0: unlimited.
    pub range: f32,
    pub _pad: [u32; 2],
}

/// Light flag: a point light standing in for an emissive object in Whitted mode (which has no
/// area lights); path mode samples the object itself and skips it.
pub const LIGHT_STAND_IN: u32 = 1;
/// Light flag: a point light shines within a cone (a spot light: `axis`, `cone_scale`,
/// `cone_offset`).
pub const LIGHT_SPOT: u32 = 2;

/// Emitter kind: an emissive triangle or sphere, `source` its [`crate::primitives::PrimRef`]
/// (the only kind: point and directional lights are evaluated at every vertex, not chosen).
pub const EMITTER_AREA: u32 = 0;

/// One area light path mode samples for next-event estimation, chosen with probability `pdf`
/// (proportional to its power) by inverting the cumulative `cdf`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatEmitter {
    pub source: u32,
    /// [`EMITTER_AREA`].
    pub kind: u32,
    /// Σ pdf of this emitter and those before it (the last is 1).
    pub cdf: f32,
    pub pdf: f32,
}

/// One use of an image in [`FlatScene::texels`], 48 bytes (`TextureInfo` in
/// `shaders/modules/types.wgsl`): uses of one image share its texels.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatTexture {
    pub width: u32,
    pub height: u32,
    /// The word of texel (0, 0) in the texel buffer; texel (x, y) follows at y·width + x
    /// words (8-bit RGBA) or three times that (linear RGB).
    pub offset: u32,
    /// Wrap modes (2 bits each, [`crate::scene::texture::Wrap`]) at [`TEXTURE_WRAP_U_SHIFT`]
    /// and [`TEXTURE_WRAP_V_SHIFT`], [`TEXTURE_NEAREST`], [`TEXTURE_LINEAR_RGB`],
    /// [`TEXTURE_DATA`], [`TEXTURE_UV1`].
    pub flags: u32,
    /// The texture-coordinate transform (u, v) → (a·u + b·v + c, d·u + e·v + f): [a, b, d, e]
    /// and [c, f] (`KHR_texture_transform`).
    pub linear: [f32; 4],
    pub offset_uv: [f32; 2],
    pub _pad: [u32; 2],
}

pub const TEXTURE_WRAP_U_SHIFT: u32 = 0;
pub const TEXTURE_WRAP_V_SHIFT: u32 = 2;
/// Texture flag: nearest-texel lookups (else bilinear).
pub const TEXTURE_NEAREST: u32 = 1 << 4;
/// Texture flag: three f32 words of linear RGB per texel (else one word of 8-bit RGBA codes,
/// red in the low byte).
pub const TEXTURE_LINEAR_RGB: u32 = 1 << 5;
/// Texture flag: 8-bit codes are data, read as code / 255 (else colour codes are sRGB).
pub const TEXTURE_DATA: u32 = 1 << 6;
/// Texture flag: the lookup reads the second set of texture coordinates.
pub const TEXTURE_UV1: u32 = 1 << 7;
/// Words at the start of the texel buffer: the sRGB → linear table of the 256 codes, as f32
/// bits, which every 8-bit texel is read through.
pub const SRGB_TABLE_WORDS: u32 = 256;

/// What one triangle's vertices carry besides positions (scene order, as `triangles`), 80
/// bytes (`TriangleAttrs` in `shaders/modules/types.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatTriangleAttrs {
    /// Texture coordinates (`TEXCOORD_0`) of vertices a, b, c.
    pub uv: [[f32; 2]; 3],
    /// The second set (`TEXCOORD_1`).
    pub second_uv: [[f32; 2]; 3],
    /// Unit shading normals, octahedral in two 16-bit snorms ([`encode_octahedral`]).
    pub normal: [u32; 3],
    /// Linear RGBA colours, four 8-bit unorms (red in the low byte).
    pub color: [u32; 3],
    /// [`ATTR_NORMALS`] | [`ATTR_COLORS`].
    pub flags: u32,
    pub _pad: u32,
}

/// Triangle attribute flag: `normal` holds shading normals (else the face's normal shades).
pub const ATTR_NORMALS: u32 = 1;
/// Triangle attribute flag: `color` holds vertex colours (else white).
pub const ATTR_COLORS: u32 = 2;

/// A unit vector as an octahedral map point in two 16-bit snorms, x in the low half
/// (Cigolle et al., "A Survey of Efficient Representations for Independent Unit Vectors",
/// JCGT 2014): error below 10⁻⁴ rad (measured 6·10⁻⁵) with rounding to the nearest code. Zero maps to zero,
/// which decodes to +z.
pub fn encode_octahedral(n: [f32; 3]) -> u32 {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    if !(l1 > 0.0) {
        return 0;
    }
    let (mut x, mut y) = (n[0] / l1, n[1] / l1);
    if n[2] < 0.0 {
        let (ox, oy) = (x, y);
        x = (1.0 - oy.abs()) * if ox >= 0.0 { 1.0 } else { -1.0 };
        y = (1.0 - ox.abs()) * if oy >= 0.0 { 1.0 } else { -1.0 };
    }
    let q = |v: f32| ((v.clamp(-1.0, 1.0) * 32767.0).round() as i32 as i16) as u16 as u32;
    q(x) | q(y) << 16
}

/// Four components in [0, 1] as 8-bit unorms, the first in the low byte.
pub fn encode_unorm8x4(c: [f32; 4]) -> u32 {
    c.iter().enumerate().fold(0, |w, (i, v)| w | (((v.clamp(0.0, 1.0) * 255.0).round() as u32) << (8 * i)))
}

/// The environment (`[environment]`), 192 bytes (`Environment` in `shaders/modules/types.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FlatEnvironment {
    /// The constant radiance, or what multiplies the map (its strength), per channel.
    pub radiance: [f32; 3],
    /// [`ENV_MAP`] | [`ENV_UNIFORM`].
    pub flags: u32,
    /// cos and sin of the rotation about +y.
    pub rot_cos: f32,
    pub rot_sin: f32,
    /// Index in [`FlatScene::textures`] of the map.
    pub texture: u32,
    /// Probability that next-event estimation samples the environment rather than an area
    /// emitter (1 without area emitters).
    pub select_prob: f32,
    /// Size of the sampling distribution (the map's texels) in
    /// [`FlatScene::env_distribution`].
    pub width: u32,
    pub height: u32,
    pub _pad: [u32; 2],
    /// Whitted's diffuse light from the environment: 9 spherical-harmonic coefficients
    /// (rgb, and a pad word) of its irradiance / π.
    pub sh: [[f32; 4]; 9],
}

/// Environment flag: radiance comes from the map (else it is constant).
pub const ENV_MAP: u32 = 1;
/// Environment flag: next-event estimation samples directions uniformly (a constant sky, or
/// for comparison), else by the map's distribution.
pub const ENV_UNIFORM: u32 = 2;

/// Per-dispatch parameters: the camera frame, image and tile, and render settings (bound as a
/// read-only storage buffer, see `shaders/modules/bindings.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FrameParams {
    pub eye: [f32; 3],
    pub width: u32,
    /// Unit view direction.
    pub forward: [f32; 3],
    pub height: u32,
    /// Image-plane right vector at distance 1, scaled by tan(fov_y/2)·aspect.
    pub right: [f32; 3],
    pub spp: u32,
    /// Image-plane up vector at distance 1, scaled by tan(fov_y/2).
    pub up: [f32; 3],
    pub max_depth: u32,
    pub background: [f32; 3],
    /// Padding: `ambient` starts a 16-byte slot as WGSL's vec3 does.
    pub _pad: u32,
    pub ambient: [f32; 3],
    pub num_lights: u32,
    /// First pixel (x, y) of the tile this dispatch renders.
    pub tile_origin: [u32; 2],
    /// Size (width, height) of the tile this dispatch renders.
    pub tile_size: [u32; 2],
    /// Index of the first sample this dispatch adds (progressive rendering).
    pub sample_base: u32,
    /// Row pitch, in pixels, of the output buffer.
    pub out_pitch: u32,
    /// First image row held by the output buffer.
    pub out_first_row: u32,
    /// [`FRAME_ACCUMULATE`]: add to the output instead of overwriting it.
    pub flags: u32,
    /// Path mode: number of entries in the emitter buffer.
    pub num_emitters: u32,
    /// Path mode: 1 / Σ emitter power weights, so that an area emitter of radiance L is
    /// chosen, per unit of its area, with density mean(L) · `emitter_norm`.
    pub emitter_norm: f32,
    /// Path mode: Russian roulette may end a path once it has this many segments.
    pub rr_depth: u32,
    /// Path mode: seed of the random numbers (renders with different seeds are independent).
    pub seed: u32,
}

/// Frame flag: the dispatch adds its samples' sum to the output buffer.
pub const FRAME_ACCUMULATE: u32 = 1;
/// Frame flag: the scene has an environment ([`FlatScene::environment`]): shader variants
/// compiled with the environment's code read it only then.
pub const FRAME_ENVIRONMENT: u32 = 2;
/// Where `shaders/view.wgsl` finds the viewer's debug mode in [`FrameParams::flags`] (the mode
/// shifted left by this), and the modes: the numbers of `ViewMode` in the viewer, shared with
/// `view.wgsl` and `present.wgsl`.
pub const VIEW_MODE_SHIFT: u32 = 8;
pub const VIEW_WHITTED: u32 = 0;
pub const VIEW_NORMALS: u32 = 1;
pub const VIEW_DEPTH: u32 = 2;
pub const VIEW_COST: u32 = 3;
pub const VIEW_PATH: u32 = 4;

/// Everything a backend needs, flattened: the GPU's storage buffers hold it as it is, and the
/// CPU's tracers read it in place.
#[derive(Clone, Debug, Default)]
pub struct FlatScene {
    pub spheres: Vec<FlatSphere>,
    pub cylinders: Vec<FlatCylinder>,
    pub planes: Vec<FlatPlane>,
    pub triangles: Vec<FlatTriangle>,
    /// The BVH as the GPU walks it ([`crate::accel::gpu_bvh`]); empty without bounded
    /// primitives, or with more than [`crate::accel::gpu_bvh::MAX_PRIMS`] of them (which no GPU buffer holds).
    pub nodes: Vec<GpuNode>,
    /// Sphere and cylinder references in leaf order.
    pub shape_refs: Vec<u32>,
    /// Triangles in leaf order.
    pub leaf_triangles: Vec<GpuLeafTriangle>,
    pub materials: Vec<FlatMaterial>,
    pub lights: Vec<FlatLight>,
    /// Path mode's sampled light sources: emissive triangles and spheres.
    pub emitters: Vec<FlatEmitter>,
    /// 1 / Σ emitter weights ([`FrameParams::emitter_norm`]) times the probability of choosing
    /// an area emitter rather than the environment; 0 without emitters.
    pub emitter_norm: f32,
    /// Images ([`crate::render::texture`]), the environment map last.
    pub textures: Vec<FlatTexture>,
    /// The sRGB table ([`SRGB_TABLE_WORDS`]) followed by every image's texels; empty when
    /// no material has a texture and the environment no map.
    pub texels: Vec<u32>,
    /// Per triangle, in `triangles` order; empty when no material has a texture and no mesh
    /// has normals or colours.
    pub triangle_attrs: Vec<FlatTriangleAttrs>,
    /// The environment, when the scene has one (one element).
    pub environment: Vec<FlatEnvironment>,
    /// The environment map's sampling distribution ([`crate::render::environment`]).
    pub env_distribution: Vec<f32>,
    /// Some material lets rays through by its alpha ([`MATERIAL_ALPHA`]): shadow rays towards
    /// point and directional lights then look at what they cross.
    pub alpha: bool,
}

impl FlatScene {
    /// Spheres, cylinders and triangles: the primitives the BVH holds.
    pub fn bounded_count(&self) -> usize {
        self.spheres.len() + self.cylinders.len() + self.triangles.len()
    }
}

/// One ray of a `trace` query, 32 bytes (`QueryRay` in `shaders/trace.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuQueryRay {
    pub origin: [f32; 3],
    pub tmin: f32,
    pub dir: [f32; 3],
    pub tmax: f32,
}

/// Hit flag: the record holds a hit (nearest mode: else the ray missed).
pub const QUERY_FOUND: u32 = 1;
/// Hit flag: the ray enters a solid or meets a front face.
pub const QUERY_ENTER: u32 = 2;

/// One hit of a `trace` query, 32 bytes (`QueryHit` in `shaders/trace.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuQueryHit {
    pub normal: [f32; 3],
    pub t: f32,
    pub object: u32,
    pub face: u32,
    /// The [`crate::primitives::PrimRef`] hit (orders hits at equal t).
    pub prim_ref: u32,
    /// [`QUERY_FOUND`] | [`QUERY_ENTER`] | part << 8.
    pub flags: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_material_reads_back_the_kind_it_was_written_with() {
        for k in MaterialKind::ALL {
            assert_eq!(FlatMaterial { kind: k as u32, ..Default::default() }.kind(), k);
        }
        assert_eq!(FlatMaterial { kind: 99, ..Default::default() }.kind(), MaterialKind::Diffuse);
    }
}
