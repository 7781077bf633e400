//! The layers glTF puts over a pbr material's base (`layers.wgsl` is the twin), top down:
//! `KHR_materials_clearcoat`'s coat, `KHR_materials_sheen`'s sheen, then the base (the
//! metallic-roughness material with its transmission, [`super::bsdf`]). The extensions'
//! appendix writes the stack as albedo scaling: each layer reflects its own lobe and passes
//! on what its directional albedo leaves,
//!
//! f = c·f_coat + (1 − c·E_coat(μo))·[f_sheen + (1 − max(sheen)·E_sheen(μo))·f_base],
//!
//! with c the clear-coat factor. The coat is a GGX dielectric of F0 0.04 and perceptual
//! roughness r_c, compensated for multiple scattering as the pbr material's own lobe is
//! (Turquin 2019; [`super::pbr`]), so E_coat is its compensated albedo from
//! [`super::microfacet`]'s table; the sheen is [`super::sheen`]'s lobe. Over a white base a
//! white stack reflects everything (to the tables' accuracy: the furnace tests), which the
//! extension's own Fresnel-at-μo form of the coat's scaling does not. Scaling by μo alone is
//! what makes the stack lose reciprocity (as in Blender's Principled BSDF); each lobe by
//! itself is reciprocal.
//!
//! Left out: the coat's own normal map (`clearcoatNormalTexture`: the coat follows the
//! shading normal) and the layers' textures (their factors hold everywhere; the importer
//! warns).

use super::microfacet::{ggx_d, ggx_lambda, lookup, schlick};
use super::pbr::{MIN_PBR_ALPHA, PBR_F0};
use super::sheen;
use crate::layout::FlatMaterial;
use crate::math::V3;

/// The layers of a material seen from μo.
#[derive(Clone, Copy, Debug)]
pub struct Layers {
    /// The coat lobe's weight: the clear-coat factor times its compensation.
    pub coat: f32,
    pub coat_alpha: f32,
    /// The sheen lobe's colour weight: the sheen colour times what the coat passes.
    pub sheen: V3<f32>,
    pub sheen_alpha: f32,
    /// What reaches the base: (1 − c·E_coat)(1 − max(sheen)·E_sheen).
    pub base: f32,
    /// The probabilities of sampling the coat and the sheen (the base has `base`): each
    /// part's share of a white stack's albedo.
    pub p_coat: f32,
    pub p_sheen: f32,
}

/// The layers of `m` at cos θ_o = `cos_o`.
pub fn layers(m: &FlatMaterial, cos_o: f32) -> Layers {
    let cc = m.clearcoat.clamp(0.0, 1.0);
    let r = m.clearcoat_roughness.clamp(0.0, 1.0);
    let (e1, e5) = lookup(r, cos_o);
    let e1 = e1.max(1e-3);
    let coat = cc * (1.0 + PBR_F0 * (1.0 - e1) / e1);
    let coat_albedo = (coat * (PBR_F0 * e1 + (1.0 - PBR_F0) * e5)).min(1.0);
    let color = V3::from_array(m.sheen_color).max_elem(V3::zero()).min_elem(V3::splat(1.0));
    // Below sheen roughness 0.3 and near grazing the lobe reflects more than it receives
    // (E up to 6: its 1/(4μo) outgrows the visibility term); it is scaled down to reflect 1.
    let e = sheen::albedo(m.sheen_roughness, cos_o);
    let norm = if e > 1.0 { 1.0 / e } else { 1.0 };
    let sheen_albedo = color.max_component() * e * norm;
    let passed = 1.0 - coat_albedo;
    Layers {
        coat,
        coat_alpha: (r * r).max(MIN_PBR_ALPHA),
        sheen: color * (passed * norm),
        sheen_alpha: sheen::sheen_alpha(m.sheen_roughness),
        base: passed * (1.0 - sheen_albedo),
        p_coat: coat_albedo,
        p_sheen: passed * sheen_albedo,
    }
}

/// f·cos θ_i and density of the coat lobe for local directions `wo`, `wi` (z up); density
/// of its visible-normal sampling, reflected (pbrt-v4 9.6).
pub fn coat_eval(l: &Layers, wo: V3<f32>, wi: V3<f32>) -> (f32, f32) {
    if wo.z <= 0.0 || wi.z <= 0.0 || l.coat <= 0.0 {
        return (0.0, 0.0);
    }
    let h = (wo + wi).normalize();
    if h.z <= 0.0 {
        return (0.0, 0.0);
    }
    let d = ggx_d(l.coat_alpha, h.z);
    let (lo, li) = (ggx_lambda(l.coat_alpha, wo.z), ggx_lambda(l.coat_alpha, wi.z));
    let k = d / (4.0 * wo.z);
    let f = schlick(V3::splat(PBR_F0), wo.dot(h)).x;
    (l.coat * f * k / (1.0 + lo + li), k / (1.0 + lo))
}

/// f·cos θ_i (the sheen colour's) and density of the sheen lobe for local directions, which
/// is sampled by the cosine.
pub fn sheen_eval(l: &Layers, wo: V3<f32>, wi: V3<f32>) -> (V3<f32>, f32) {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return (V3::zero(), 0.0);
    }
    (l.sheen * sheen::sheen_eval(l.sheen_alpha, wo, wi), wi.z * std::f32::consts::FRAC_1_PI)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;

    /// The coat lobe is reciprocal: f(wo, wi) = f(wi, wo).
    #[test]
    fn the_coat_lobe_is_reciprocal() {
        let mut rng = Sampler::new(8, 8, 8);
        let m = FlatMaterial { clearcoat: 1.0, clearcoat_roughness: 0.4, ..Default::default() };
        let dir = |rng: &mut Sampler| {
            let z = rng.next_f32().max(0.02);
            let phi = 2.0 * std::f32::consts::PI * rng.next_f32();
            let s = (1.0 - z * z).sqrt();
            V3::new(s * phi.cos(), s * phi.sin(), z)
        };
        for _ in 0..2000 {
            let (wo, wi) = (dir(&mut rng), dir(&mut rng));
            // The lobe's weight depends on μo through the compensation: compare the bare lobe.
            let (lf, lb) = (layers(&m, wo.z), layers(&m, wi.z));
            let f = coat_eval(&lf, wo, wi).0 / wi.z / lf.coat;
            let b = coat_eval(&lb, wi, wo).0 / wo.z / lb.coat;
            assert!((f - b).abs() <= 2e-4 * f.max(1e-3), "{f} vs {b}");
        }
    }

    /// The shares: no layer, all base; a full white coat over a white sheen passes what
    /// their albedos leave.
    #[test]
    fn the_shares_add_up() {
        let plain = layers(&FlatMaterial::default(), 0.7);
        assert_eq!((plain.base, plain.p_coat, plain.p_sheen), (1.0, 0.0, 0.0));
        let m = FlatMaterial { clearcoat: 1.0, sheen_color: [1.0; 3], sheen_roughness: 0.5, ..Default::default() };
        for mu in [0.05f32, 0.4, 1.0] {
            let l = layers(&m, mu);
            assert!((l.base + l.p_coat + l.p_sheen - 1.0).abs() < 1e-6);
            assert!(l.p_coat > 0.03 && l.p_sheen > 0.0 && l.base > 0.0, "{l:?}");
        }
    }
}
