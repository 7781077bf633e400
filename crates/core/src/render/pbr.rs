//! glTF's metallic-roughness material (`pbr.wgsl` is the twin): its two lobes as seen from a
//! viewing angle, which the path tracer's BSDF ([`super::bsdf`]) and Whitted's approximation
//! ([`super::shade`]) both start from.
//!
//! The model is what glTF's specification (appendix B) and Blender's Principled BSDF
//! describe: one GGX specular lobe of perceptual roughness r (α = r²) with Schlick's Fresnel
//! of F0 = mix(0.04, base, metallic), over a Lambertian base of colour (1 − metallic)·base,
//! weighted by what the coat lets through at the viewing angle, 1 − c₀·E(0.04, μo). The lobe
//! is scaled by c = 1 + F0·(1 − E₁)/E₁ (Turquin 2019, "Practical multiple scattering
//! compensation for microfacet models"), which gives back the energy single scattering loses
//! on rough surfaces; E comes from [`super::microfacet`]'s table. A white base then reflects
//! all light at every angle and roughness (the furnace test in `bsdf.rs`) to within the
//! table's 0.2 %. Sampling picks the lobe or the base in proportion to their albedos at μo.

use super::microfacet;
use crate::layout::FlatMaterial;
use crate::math::V3;

/// The pbr material's α is at least this (perceptual roughness 0.032): its lobe stays a
/// density (next-event estimation and MIS work on it) and is a mirror to the eye.
pub const MIN_PBR_ALPHA: f32 = microfacet::MIN_ALPHA;
/// The dielectric coat's reflectance at normal incidence (index of refraction 1.5).
pub const PBR_F0: f32 = 0.04;

/// What the pbr material's parts reflect seen from μo. The metal and the coat share one GGX
/// distribution, so their lobes add into one whose Fresnel term is
/// `metal_weight`·F(base) + `coat_weight`·F(0.04), each weight the part's share times its own
/// compensation (the blend of two energy-conserving lobes conserves energy; one lobe with a
/// blended F0 would not, compensation being quadratic in F0).
#[derive(Clone, Copy, Debug)]
pub struct PbrLobes {
    pub alpha: f32,
    /// The metal's reflectance at normal incidence (the base colour).
    pub reflectance: V3<f32>,
    /// metallic × Turquin's factor of the metal, per channel.
    pub metal_weight: V3<f32>,
    /// (1 − metallic) × Turquin's factor of the coat.
    pub coat_weight: f32,
    /// (1 − metallic)·base·(1 − c₀E(0.04, μo)).
    pub diffuse: V3<f32>,
    /// The lobe's albedo at μo, compensated.
    pub spec_albedo: V3<f32>,
    pub p_spec: f32,
}

#[inline]
fn luminance(c: V3<f32>) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The lobes of pbr material `m` seen at cos θ_o = `cos_o`.
pub fn pbr_lobes(m: &FlatMaterial, cos_o: f32) -> PbrLobes {
    let base = V3::from_array(m.color);
    let metal = m.metallic.clamp(0.0, 1.0);
    let r = m.roughness.clamp(0.0, 1.0);
    let alpha = (r * r).max(MIN_PBR_ALPHA);
    let (e1, e5) = microfacet::lookup(r, cos_o);
    let e1 = e1.max(1e-3);
    let lost = (1.0 - e1) / e1;
    let metal_weight = (V3::splat(1.0) + base * lost) * metal;
    let coat_comp = 1.0 + PBR_F0 * lost;
    let coat_weight = (1.0 - metal) * coat_comp;
    // The coat's albedo, compensated: what the base below does not receive.
    let coat = coat_comp * (PBR_F0 * e1 + (1.0 - PBR_F0) * e5);
    let diffuse = base * ((1.0 - metal) * (1.0 - coat).max(0.0));
    let metal_albedo = (base * e1 + (V3::splat(1.0) - base) * e5).mul_elem(metal_weight);
    let spec_albedo = metal_albedo + V3::splat((1.0 - metal) * coat);
    let (ls, ld) = (luminance(spec_albedo), luminance(diffuse));
    let p_spec = if ls + ld > 0.0 { ls / (ls + ld) } else { 0.0 };
    PbrLobes { alpha, reflectance: base, metal_weight, coat_weight, diffuse, spec_albedo, p_spec }
}

/// The lobe's Fresnel term at cos θ between wo and the microfacet normal.
#[inline]
pub fn pbr_fresnel(l: &PbrLobes, cos: f32) -> V3<f32> {
    microfacet::schlick(l.reflectance, cos).mul_elem(l.metal_weight)
        + microfacet::schlick(V3::splat(PBR_F0), cos) * l.coat_weight
}
