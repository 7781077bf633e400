//! glTF's metallic-roughness material (`pbr.wgsl` is the twin): its two lobes as seen from a
//! viewing angle, which the path tracer's BSDF ([`super::bsdf`]) and Whitted's approximation
//! ([`super::shade`]) both start from.
//!
//! The model is what glTF's specification (appendix B) and Blender's Principled BSDF
//! describe: one GGX specular lobe of perceptual roughness r (α = r²) with Schlick's Fresnel
//! of F0 = mix(F0ᵈ, base, metallic), over a Lambertian base of colour (1 − metallic)·base,
//! weighted by what the coat lets through at the viewing angle, 1 − max(c₀·E(F0ᵈ, F90, μo)).
//! The dielectric's F0ᵈ is 0.04 unless `KHR_materials_ior` and `KHR_materials_specular` say
//! otherwise (`FlatMaterial::spec_at_normal`, per channel; its grazing reflectance F90 is then the
//! specular factor, F = F0 + (F90 − F0)(1 − cos)⁵ as the extension writes it). The lobe
//! is scaled by c = 1 + F0·(1 − E₁)/E₁ (Turquin 2019, "Practical multiple scattering
//! compensation for microfacet models"), which gives back the energy single scattering loses
//! on rough surfaces; E comes from [`super::microfacet`]'s table. A white base then reflects
//! all light at every angle and roughness (the furnace test in `bsdf.rs`) to within the
//! table's 0.2 %; with a coloured F0ᵈ the base keeps what the most reflected channel leaves
//! (glTF's `max_value(fr)`), so the other channels lose a little. Sampling picks the lobe or
//! the base in proportion to their albedos at μo.

use super::microfacet;
use crate::layout::FlatMaterial;
use crate::math::V3;
use crate::math::lanes::{F, V, clamp01};

/// The pbr material's α is at least this (perceptual roughness 0.032): its lobe stays a
/// density (next-event estimation and MIS work on it) and is a mirror to the eye.
pub const MIN_PBR_ALPHA: f32 = microfacet::MIN_ALPHA;
/// The dielectric coat's reflectance at normal incidence (index of refraction 1.5).
pub const PBR_F0: f32 = crate::layout::DEFAULT_F0;

/// What the pbr material's parts reflect seen from μo. The metal and the coat share one GGX
/// distribution, so their lobes add into one whose Fresnel term is
/// `metal_weight`·F(base) + `coat_weight`·F(F0ᵈ, F90), each weight the part's share times its own
/// compensation (the blend of two energy-conserving lobes conserves energy; one lobe with a
/// blended F0 would not, compensation being quadratic in F0).
#[derive(Clone, Copy, Debug)]
pub struct PbrLobes {
    pub alpha: f32,
    /// The metal's reflectance at normal incidence (the base colour).
    pub reflectance: V3<f32>,
    /// metallic × Turquin's factor of the metal, per channel.
    pub metal_weight: V3<f32>,
    /// (1 − metallic) × Turquin's factor of the coat, per channel.
    pub coat_weight: V3<f32>,
    /// The coat's reflectance at normal and grazing incidence.
    pub coat_f0: V3<f32>,
    pub coat_f90: f32,
    /// (1 − metallic)·base·(1 − max c₀E(F0ᵈ, F90, μo)).
    pub diffuse: V3<f32>,
    /// The lobe's albedo at μo, compensated.
    pub spec_albedo: V3<f32>,
    pub p_spec: f32,
}

/// The lobes of pbr material `m` seen at cos θ_o = `cos_o`.
pub fn pbr_lobes(m: &FlatMaterial, cos_o: f32) -> PbrLobes {
    let base = V3::from_array(m.color);
    let l = pbr_lobes_spec_lanes::<1>(
        base.into(),
        m.metallic.into(),
        m.roughness.into(),
        cos_o.into(),
        V3::from_array(m.spec_at_normal).into(),
        m.spec_at_grazing.into(),
    );
    PbrLobes {
        alpha: l.alpha.into(),
        reflectance: l.reflectance.into(),
        metal_weight: l.metal_weight.into(),
        coat_weight: l.coat_weight.into(),
        coat_f0: l.coat_f0.into(),
        coat_f90: l.coat_f90.into(),
        diffuse: l.diffuse.into(),
        spec_albedo: l.spec_albedo.into(),
        p_spec: l.p_spec.into(),
    }
}

/// [`PbrLobes`] in lanes.
#[derive(Clone, Copy)]
pub struct PbrLobesLanes<const N: usize> {
    pub alpha: F<N>,
    pub reflectance: V<N>,
    pub metal_weight: V<N>,
    pub coat_weight: V<N>,
    pub coat_f0: V<N>,
    pub coat_f90: F<N>,
    pub diffuse: V<N>,
    pub spec_albedo: V<N>,
    pub p_spec: F<N>,
}

#[inline(always)]
fn luminance<const N: usize>(c: V<N>) -> F<N> {
    F::splat(0.2126) * c.x + F::splat(0.7152) * c.y + F::splat(0.0722) * c.z
}

/// [`pbr_lobes`] in every lane, of base colour `base`, metalness `metallic` and roughness
/// `roughness` at cos θ_o = `cos_o`, the dielectric's reflectance the default (F0 0.04, F90 1:
/// the lanes shade no other, `FlatMaterial::spec_at_normal`).
#[inline(always)]
pub fn pbr_lobes_lanes<const N: usize>(base: V<N>, metallic: F<N>, roughness: F<N>, cos_o: F<N>) -> PbrLobesLanes<N> {
    pbr_lobes_spec_lanes(base, metallic, roughness, cos_o, V::splat([PBR_F0; 3]), F::splat(1.0))
}

/// [`pbr_lobes_lanes`] with the dielectric's reflectance `f0` at normal and `f90` at grazing
/// incidence.
#[inline(always)]
pub fn pbr_lobes_spec_lanes<const N: usize>(
    base: V<N>,
    metallic: F<N>,
    roughness: F<N>,
    cos_o: F<N>,
    f0: V<N>,
    f90: F<N>,
) -> PbrLobesLanes<N> {
    let one = F::splat(1.0);
    let metal = clamp01(metallic);
    let r = clamp01(roughness);
    let alpha = (r * r).max(F::splat(MIN_PBR_ALPHA));
    let (e1, e5) = microfacet::lookup_lanes(r, cos_o);
    let e1 = e1.max(F::splat(1e-3));
    let lost = (one - e1) / e1;
    let metal_weight = (V::splat([1.0; 3]) + base.scale(lost)).scale(metal);
    let coat_comp = V::splat([1.0; 3]) + f0.scale(lost);
    let coat_weight = coat_comp.scale(one - metal);
    // The coat's albedo, compensated: what the base below does not receive.
    let coat = coat_comp.mul_elem(f0.scale(e1) + (V::new(f90, f90, f90) - f0).scale(e5));
    let kept = one - coat.x.max(coat.y).max(coat.z);
    let diffuse = base.scale((one - metal) * kept.max(F::splat(0.0)));
    let metal_albedo = (base.scale(e1) + (V::splat([1.0; 3]) - base).scale(e5)).mul_elem(metal_weight);
    let spec_albedo = metal_albedo + coat.scale(one - metal);
    let (ls, ld) = (luminance(spec_albedo), luminance(diffuse));
    let p_spec = (ls + ld).gt(F::splat(0.0)).select(ls / (ls + ld), F::splat(0.0));
    PbrLobesLanes {
        alpha,
        reflectance: base,
        metal_weight,
        coat_weight,
        coat_f0: f0,
        coat_f90: f90,
        diffuse,
        spec_albedo,
        p_spec,
    }
}

/// The lobe's Fresnel term at cos θ between wo and the microfacet normal.
#[inline]
pub fn pbr_fresnel(l: &PbrLobes, cos: f32) -> V3<f32> {
    let cos: F<1> = cos.into();
    let metal = microfacet::schlick_lanes::<1>(l.reflectance.into(), cos).mul_elem(l.metal_weight.into());
    let coat = microfacet::schlick_grazing_lanes::<1>(l.coat_f0.into(), l.coat_f90.into(), cos);
    (metal + coat.mul_elem(l.coat_weight.into())).into()
}

/// [`pbr_fresnel`] in every lane, of lobes `l`.
#[inline(always)]
pub fn pbr_fresnel_lanes<const N: usize>(l: &PbrLobesLanes<N>, cos: F<N>) -> V<N> {
    microfacet::schlick_lanes(l.reflectance, cos).mul_elem(l.metal_weight)
        + microfacet::schlick_grazing_lanes(l.coat_f0, l.coat_f90, cos).mul_elem(l.coat_weight)
}
