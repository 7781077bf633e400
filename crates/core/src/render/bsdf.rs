//! Scattering at a surface for the path tracer (`bsdf.wgsl` is the twin): Lambertian diffuse,
//! smooth and GGX-rough conductors, smooth and rough dielectrics ([`super::dielectric`]), and
//! glTF's metallic-roughness material ([`MaterialKind::Pbr`], its lobes from [`super::pbr`]),
//! which `KHR_materials_transmission` mixes with a rough dielectric ([`glass_share`]) and
//! which a clear coat and sheen may cover ([`super::layers`]).
//!
//! **Transmission and next-event estimation.** Light is sampled above the surface's face only
//! (`path::eval_above`), so [`eval`] gives the reflection of the dielectric lobes, and a
//! direction refracted through the surface ([`BsdfSample::through`]) is marked specular: the
//! light it finds counts in full, as no light sample could have found it.
//!
//! Directions are world-space unit vectors; `wo` points away from the surface towards where
//! the light goes (back along the incoming ray) and `ns` is the normal on `wo`'s side.
//! "Weight" is f·|cos θ_i| / pdf, the factor a sampled direction multiplies the path by.

pub use super::dielectric::{
    fresnel_dielectric, fresnel_dielectric_lanes, reflect, reflect_lanes, refract, refract_lanes,
};
use super::dielectric::{rough_eval, rough_sample};
use super::layers::{Layers, coat_eval, layers, sheen_eval};
use super::microfacet::{ggx_d, ggx_lambda, ggx_sample_visible, schlick};
use super::pbr::{MIN_PBR_ALPHA, pbr_fresnel, pbr_lobes};
use crate::layout::{FlatMaterial, MATERIAL_SINGLE_SCATTERING};
use crate::math::V3;
use crate::math::lanes::{F, V};
use crate::scene::MaterialKind;

const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
/// Mirrors with a GGX α below this are perfectly smooth: the microfacet terms lose all
/// precision in f32 (D ~ 1/α² overflows the useful range) long before they matter visually.
pub const MIN_ROUGHNESS: f32 = 1e-3;

/// A direction chosen by [`sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub dir: V3<f32>,
    /// f·|cos θ_i| / pdf.
    pub weight: V3<f32>,
    /// Solid-angle density of `dir` (0 for a specular choice, which has no density).
    pub pdf: f32,
    pub specular: bool,
    /// Refracted through the surface (a dielectric's transmission).
    pub through: bool,
}

/// f·cos θ_i and the density of the pbr material (both lobes); 0 where it has no lobe (black
/// metal, or a black base without specular reflection), which [`pbr_sample`] never samples:
/// the density of a mixture that holds it ([`layered_eval`]) must not count it.
fn pbr_eval(m: &FlatMaterial, wo: V3<f32>, wi: V3<f32>, ns: V3<f32>) -> (V3<f32>, f32) {
    let (cos_o, cos_i) = (wo.dot(ns), wi.dot(ns));
    if cos_o <= 0.0 || cos_i <= 0.0 {
        return (V3::zero(), 0.0);
    }
    let l = pbr_lobes(m, cos_o);
    if l.p_spec <= 0.0 && l.diffuse.max_component() <= 0.0 {
        return (V3::zero(), 0.0);
    }
    let mut f_cos = l.diffuse * (cos_i * INV_PI);
    let mut pdf = (1.0 - l.p_spec) * cos_i * INV_PI;
    let h = (wo + wi).normalize();
    let cos_h = h.dot(ns);
    if cos_h > 0.0 {
        let d = ggx_d(l.alpha, cos_h);
        let (lo, li) = (ggx_lambda(l.alpha, cos_o), ggx_lambda(l.alpha, cos_i));
        let k = d / (4.0 * cos_o);
        let f = pbr_fresnel(&l, wo.dot(h));
        f_cos += f * (k / (1.0 + lo + li));
        pdf += l.p_spec * k / (1.0 + lo);
    }
    (f_cos, pdf)
}

/// A direction from the pbr material: `u[0]` picks the lobe, `u[1]`, `u[2]` the direction.
fn pbr_sample(m: &FlatMaterial, wo: V3<f32>, ns: V3<f32>, u: [f32; 3]) -> Option<BsdfSample> {
    let cos_o = wo.dot(ns);
    if cos_o <= 0.0 {
        return None;
    }
    let l = pbr_lobes(m, cos_o);
    if l.p_spec <= 0.0 && l.diffuse.max_component() <= 0.0 {
        return None;
    }
    let dir = if u[0] < l.p_spec {
        let h = to_world(ggx_sample_visible(l.alpha, to_local(wo, ns), u[1], u[2]), ns);
        reflect(-wo, h)
    } else {
        to_world(cosine_hemisphere(u[1], u[2]), ns).normalize()
    };
    let (f_cos, pdf) = pbr_eval(m, wo, dir, ns);
    if !(pdf > 0.0) {
        return None;
    }
    Some(BsdfSample { dir, weight: f_cos / pdf, pdf, specular: false, through: false })
}

/// Whether the material scatters only into isolated directions (no next-event estimation).
#[inline]
pub fn is_specular(m: &FlatMaterial) -> bool {
    matches!(m.kind(), MaterialKind::Dielectric | MaterialKind::Mirror) && m.roughness < MIN_ROUGHNESS
}

/// Whether `m` has a rough dielectric lobe: rough glass, or a pbr material with transmission
/// (its shaders read `dielectric`'s albedo table).
#[inline]
pub fn is_rough_glass(m: &FlatMaterial) -> bool {
    (m.kind() == MaterialKind::Dielectric && m.roughness >= MIN_ROUGHNESS)
        || (m.kind() == MaterialKind::Pbr && m.transmission > 0.0)
}

/// The share of a pbr material that is glass (`KHR_materials_transmission`): its
/// transmission factor times what is not metal. glTF mixes the dielectric's diffuse base with
/// a specular transmission under the same coat; the whole material is then the mixture
/// `glass_share`·(rough dielectric of the base colour's tint) + (1 − `glass_share`)·(the pbr
/// material of metalness metallic / (1 − `glass_share`)), the coat's reflection shared by
/// both (glTF's `fresnel_mix` is linear in its base).
#[inline]
pub fn glass_share(m: &FlatMaterial) -> f32 {
    (1.0 - m.metallic.clamp(0.0, 1.0)) * m.transmission.clamp(0.0, 1.0)
}

/// The GGX α of a rough dielectric: the scene file's α, or a pbr material's perceptual
/// roughness squared.
#[inline]
fn glass_alpha(m: &FlatMaterial) -> f32 {
    if m.kind() == MaterialKind::Pbr {
        let r = m.roughness.clamp(0.0, 1.0);
        (r * r).max(MIN_PBR_ALPHA)
    } else {
        m.roughness
    }
}

/// Whether the rough dielectric lobe of `m` makes up the energy single scattering loses.
#[inline]
fn compensates(m: &FlatMaterial) -> bool {
    m.flags & MATERIAL_SINGLE_SCATTERING == 0
}

/// The pbr material under the glass share `t` of `m` (its metalness renormalised).
#[inline]
fn opaque_part(m: &FlatMaterial, t: f32) -> FlatMaterial {
    FlatMaterial { metallic: m.metallic.clamp(0.0, 1.0) / (1.0 - t), transmission: 0.0, ..*m }
}

/// The reflection of the rough dielectric lobe of `m` from `wo` into `wi` (f·cos θ_i, pdf).
fn glass_eval(m: &FlatMaterial, wo: V3<f32>, wi: V3<f32>, ns: V3<f32>, front: bool) -> (f32, f32) {
    if wi.dot(ns) <= 0.0 {
        return (0.0, 0.0);
    }
    let eta = if front { m.ior } else { 1.0 / m.ior };
    rough_eval(glass_alpha(m), eta, to_local(wo, ns), to_local(wi, ns), compensates(m))
}

/// A direction from the rough dielectric lobe of `m`: its world direction, f·cos/pdf (tinted
/// by `color` through the surface) and density, and whether it went through.
///
/// A pbr material's transmission (glTF) follows what glTF viewers and Cycles show, not the
/// interface taken alone: its radiance is not scaled by 1/η² on the way through (on a closed
/// mesh the scalings in and out cancel, and an open surface, thin-walled as glTF reads glass
/// without `KHR_materials_volume`, passes all light), and each crossing tints by √colour, so a
/// closed mesh shows its base colour once (as Blender's Principled BSDF since 4.0 does).
fn glass_sample(m: &FlatMaterial, wo: V3<f32>, ns: V3<f32>, front: bool, u: [f32; 3]) -> Option<BsdfSample> {
    let eta = if front { m.ior } else { 1.0 / m.ior };
    let s = rough_sample(glass_alpha(m), eta, to_local(wo, ns), u, compensates(m))?;
    let dir = to_world(s.wi, ns).normalize();
    let weight = if !s.through {
        V3::splat(s.weight)
    } else if m.kind() == MaterialKind::Pbr {
        V3::from_array(m.color.map(f32::sqrt)) * (s.weight * (eta * eta))
    } else {
        V3::from_array(m.color) * s.weight
    };
    Some(BsdfSample { dir, weight, pdf: s.pdf, specular: s.through, through: s.through })
}

/// f·cos θ_i and density of the pbr material `m` with a glass share: the mixture's
/// reflection.
fn pbr_glass_eval(m: &FlatMaterial, wo: V3<f32>, wi: V3<f32>, ns: V3<f32>, front: bool) -> (V3<f32>, f32) {
    let t = glass_share(m);
    let (gf, gp) = glass_eval(m, wo, wi, ns, front);
    if t >= 1.0 {
        return (V3::splat(gf), gp);
    }
    let (pf, pp) = pbr_eval(&opaque_part(m, t), wo, wi, ns);
    (pf * (1.0 - t) + V3::splat(gf * t), pp * (1.0 - t) + gp * t)
}

/// A direction from the pbr material `m` with a glass share: `u[0]` chooses the glass or the
/// opaque part (and is stretched back to [0, 1) for the part's own choice); reflections are
/// weighed by the mixture, transmissions (the glass's alone) by the glass.
fn pbr_glass_sample(m: &FlatMaterial, wo: V3<f32>, ns: V3<f32>, front: bool, u: [f32; 3]) -> Option<BsdfSample> {
    let t = glass_share(m);
    let s = if u[0] < t {
        glass_sample(m, wo, ns, front, [u[0] / t, u[1], u[2]])?
    } else {
        pbr_sample(&opaque_part(m, t), wo, ns, [(u[0] - t) / (1.0 - t), u[1], u[2]])?
    };
    if s.through {
        return Some(s);
    }
    let (f_cos, pdf) = pbr_glass_eval(m, wo, s.dir, ns, front);
    if !(pdf > 0.0) {
        return None;
    }
    Some(BsdfSample { weight: f_cos / pdf, pdf, ..s })
}

/// f·cos θ_i and density of the pbr material `m` without its layers.
fn base_eval(m: &FlatMaterial, wo: V3<f32>, wi: V3<f32>, ns: V3<f32>, front: bool) -> (V3<f32>, f32) {
    if m.transmission > 0.0 { pbr_glass_eval(m, wo, wi, ns, front) } else { pbr_eval(m, wo, wi, ns) }
}

/// A direction from the pbr material `m` without its layers.
fn base_sample(m: &FlatMaterial, wo: V3<f32>, ns: V3<f32>, front: bool, u: [f32; 3]) -> Option<BsdfSample> {
    if m.transmission > 0.0 { pbr_glass_sample(m, wo, ns, front, u) } else { pbr_sample(m, wo, ns, u) }
}

/// Whether the layers of `m` cover the side `wo` lies on: a coat and sheen are on the outside
/// of glass, and on both sides of an opaque surface.
#[inline]
fn has_layers(m: &FlatMaterial, front: bool) -> bool {
    m.is_layered() && (front || m.transmission <= 0.0)
}

/// f·cos θ_i and density of the layered pbr material `m` whose layers seen from `wo` are `l`.
fn layered_eval(m: &FlatMaterial, l: &Layers, wo: V3<f32>, wi: V3<f32>, ns: V3<f32>, front: bool) -> (V3<f32>, f32) {
    let (bf, bp) = base_eval(m, wo, wi, ns, front);
    let (lo, li) = (to_local(wo, ns), to_local(wi, ns));
    let (cf, cp) = coat_eval(l, lo, li);
    let (sf, sp) = sheen_eval(l, lo, li);
    (bf * l.base + V3::splat(cf) + sf, bp * l.base + cp * l.p_coat + sp * l.p_sheen)
}

/// A direction from the layered pbr material `m`: `u[0]` chooses the coat, the sheen or the
/// base by [`Layers`]' probabilities (stretched back to [0, 1) for the base's own choice);
/// reflections are weighed by the whole stack, a transmission by the base, the layers
/// having passed it on in proportion to the probability of choosing it.
fn layered_sample(m: &FlatMaterial, wo: V3<f32>, ns: V3<f32>, front: bool, u: [f32; 3]) -> Option<BsdfSample> {
    let l = layers(m, wo.dot(ns));
    let dir = if u[0] < l.p_coat {
        let h = to_world(ggx_sample_visible(l.coat_alpha, to_local(wo, ns), u[1], u[2]), ns);
        reflect(-wo, h)
    } else if u[0] < l.p_coat + l.p_sheen {
        to_world(cosine_hemisphere(u[1], u[2]), ns).normalize()
    } else {
        let s = base_sample(m, wo, ns, front, [((u[0] - l.p_coat - l.p_sheen) / l.base).min(ONE_BELOW), u[1], u[2]])?;
        if s.through {
            return Some(s);
        }
        s.dir
    };
    let (f_cos, pdf) = layered_eval(m, &l, wo, dir, ns, front);
    if !(pdf > 0.0) {
        return None;
    }
    Some(BsdfSample { dir, weight: f_cos / pdf, pdf, specular: false, through: false })
}

/// The largest f32 below 1.
const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// An orthonormal basis (t, b) around unit `n`, branchless (Duff et al., "Building an
/// Orthonormal Basis, Revisited", JCGT 2017).
#[inline]
pub fn basis(n: V3<f32>) -> (V3<f32>, V3<f32>) {
    let (t, b) = basis_lanes::<1>(n.into());
    (t.into(), b.into())
}

/// [`basis`] in every lane.
#[inline(always)]
pub fn basis_lanes<const N: usize>(n: V<N>) -> (V<N>, V<N>) {
    let one = F::splat(1.0);
    // (n.z ≥ 0 rather than copysign: -0 takes the + branch, as in the WGSL twin.)
    let sign = n.z.ge(F::splat(0.0)).select(one, -one);
    let a = -one / (sign + n.z);
    let b = n.x * n.y * a;
    (V::new(one + sign * n.x * n.x * a, sign * b, -sign * n.x), V::new(b, sign + n.y * n.y * a, -n.y))
}

#[inline]
fn to_world(v: V3<f32>, n: V3<f32>) -> V3<f32> {
    let (t, b) = basis(n);
    t * v.x + b * v.y + n * v.z
}

#[inline]
fn to_local(v: V3<f32>, n: V3<f32>) -> V3<f32> {
    let (t, b) = basis(n);
    V3::new(v.dot(t), v.dot(b), v.dot(n))
}

/// Cosine-weighted direction around +z (Malley's method: a uniform disk point lifted).
#[inline]
pub fn cosine_hemisphere(u1: f32, u2: f32) -> V3<f32> {
    let r = u1.sqrt();
    let (sin_phi, cos_phi) = crate::math::sin_cos_turns(u2);
    V3::new(r * cos_phi, r * sin_phi, (1.0 - u1).max(0.0).sqrt())
}

/// f·cos θ_i and the density [`sample`] would choose `wi` with, for a non-specular material
/// and `wi` on the side of `ns` (reflection); `front`: `wo` lies on the front face's side.
pub fn eval(m: &FlatMaterial, wo: V3<f32>, wi: V3<f32>, ns: V3<f32>, front: bool) -> (V3<f32>, f32) {
    let cos_i = wi.dot(ns);
    if cos_i <= 0.0 {
        return (V3::zero(), 0.0);
    }
    if m.kind() == MaterialKind::Pbr {
        if has_layers(m, front) {
            return layered_eval(m, &layers(m, wo.dot(ns)), wo, wi, ns, front);
        }
        return base_eval(m, wo, wi, ns, front);
    }
    if m.kind() == MaterialKind::Dielectric {
        let (f, pdf) = glass_eval(m, wo, wi, ns, front);
        return (V3::splat(f), pdf);
    }
    let color = V3::from_array(m.color);
    if m.kind() == MaterialKind::Mirror {
        let alpha = m.roughness;
        let cos_o = wo.dot(ns);
        let h = (wo + wi).normalize();
        let cos_h = h.dot(ns);
        if cos_o <= 0.0 || cos_h <= 0.0 {
            return (V3::zero(), 0.0);
        }
        let d = ggx_d(alpha, cos_h);
        let (lo, li) = (ggx_lambda(alpha, cos_o), ggx_lambda(alpha, cos_i));
        let g2 = 1.0 / (1.0 + lo + li);
        let g1 = 1.0 / (1.0 + lo);
        let f = schlick(color, wo.dot(h));
        // f cos θ_i = D G2 F / (4 cos θ_o); pdf = D G1(wo) / (4 cos θ_o) (VNDF, reflected).
        let k = d / (4.0 * cos_o);
        return (f * (k * g2), k * g1);
    }
    // Lambertian (diffuse and emissive surfaces).
    (color * (cos_i * INV_PI), cos_i * INV_PI)
}

/// Chooses the next direction with three uniform numbers `u`; `front`: the ray arrived on the
/// front face (outside a dielectric). None: the path ends (absorbed, or a sampled direction
/// fell below the surface).
pub fn sample(m: &FlatMaterial, wo: V3<f32>, ns: V3<f32>, front: bool, u: [f32; 3]) -> Option<BsdfSample> {
    if m.kind() == MaterialKind::Pbr {
        if has_layers(m, front) {
            return layered_sample(m, wo, ns, front, u);
        }
        return base_sample(m, wo, ns, front, u);
    }
    let color = V3::from_array(m.color);
    if m.kind() == MaterialKind::Dielectric && m.roughness >= MIN_ROUGHNESS {
        return glass_sample(m, wo, ns, front, u);
    }
    if m.kind() == MaterialKind::Dielectric {
        let cos_i = wo.dot(ns);
        let eta = if front { m.ior } else { 1.0 / m.ior };
        let f = fresnel_dielectric(cos_i, eta);
        if u[0] < f {
            return Some(BsdfSample {
                dir: reflect(-wo, ns),
                weight: V3::splat(1.0),
                pdf: 0.0,
                specular: true,
                through: false,
            });
        }
        // Snell; radiance is compressed into the smaller solid angle by 1/η² (pbrt-v4 9.5.2).
        let dir = refract(-wo, ns, cos_i, 1.0 / eta);
        return Some(BsdfSample { dir, weight: color / (eta * eta), pdf: 0.0, specular: true, through: true });
    }
    if m.kind() == MaterialKind::Mirror {
        let cos_o = wo.dot(ns);
        if m.roughness < MIN_ROUGHNESS {
            let dir = reflect(-wo, ns);
            return Some(BsdfSample { dir, weight: schlick(color, cos_o), pdf: 0.0, specular: true, through: false });
        }
        let alpha = m.roughness;
        let h = to_world(ggx_sample_visible(alpha, to_local(wo, ns), u[1], u[2]), ns);
        let dir = reflect(-wo, h);
        let cos_i = dir.dot(ns);
        if cos_i <= 0.0 || cos_o <= 0.0 {
            return None;
        }
        let (lo, li) = (ggx_lambda(alpha, cos_o), ggx_lambda(alpha, cos_i));
        // Weight F G2 / G1(wo) (Heitz 2018, eq. 19); pdf D G1(wo) / (4 cos θ_o).
        let weight = schlick(color, wo.dot(h)) * ((1.0 + lo) / (1.0 + lo + li));
        let pdf = ggx_d(alpha, h.dot(ns)) / ((1.0 + lo) * 4.0 * cos_o);
        return Some(BsdfSample { dir, weight, pdf, specular: false, through: false });
    }
    if color.max_component() <= 0.0 {
        return None;
    }
    let local = cosine_hemisphere(u[1], u[2]);
    let dir = to_world(local, ns).normalize();
    Some(BsdfSample { dir, weight: color, pdf: local.z * INV_PI, specular: false, through: false })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;
    use std::f32::consts::PI;

    fn material(kind: MaterialKind, color: f32, roughness: f32) -> FlatMaterial {
        FlatMaterial { color: [color; 3], kind: kind as u32, ior: 1.5, roughness, ..Default::default() }
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [V3::new(0.0, 0.0, 1.0), V3::new(0.0, 0.0, -1.0), V3::new(0.6, 0.0, 0.8), V3::new(-0.48, 0.6, -0.64)] {
            let (t, b) = basis(n);
            for (x, y) in [(t, b), (t, n), (b, n)] {
                assert!(x.dot(y).abs() < 1e-6);
            }
            assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
        }
    }

    /// The weights of sampled directions average to the directional albedo; for the GGX
    /// conductor with F0 = 1 that is the Smith masking of its microfacets (< 1), and the
    /// estimator built from eval/pdf on uniformly drawn directions must agree with it.
    #[test]
    fn sampled_weights_agree_with_eval_over_pdf() {
        let ns = V3::new(0.0, 0.0, 1.0);
        let wo = V3::new(0.5, 0.0, 0.75f32.sqrt());
        for m in [material(MaterialKind::Diffuse, 0.8, 0.0), material(MaterialKind::Mirror, 1.0, 0.3)] {
            let mut rng = Sampler::new(1, 2, 3);
            let n = 200_000;
            let (mut by_sampling, mut by_uniform) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                if let Some(s) = sample(&m, wo, ns, true, u) {
                    by_sampling += s.weight.x as f64;
                    // The density the sampler reports is what eval reports for that direction.
                    let (_, pdf) = eval(&m, wo, s.dir, ns, true);
                    assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf.max(1.0), "pdf {pdf} vs {}", s.pdf);
                }
                // Uniform hemisphere directions: ∫ f cos dω = E[f cos · 2π].
                let z = rng.next_f32();
                let phi = 2.0 * PI * rng.next_f32();
                let r = (1.0 - z * z).max(0.0).sqrt();
                let wi = V3::new(r * phi.cos(), r * phi.sin(), z);
                by_uniform += eval(&m, wo, wi, ns, true).0.x as f64 * 2.0 * PI as f64;
            }
            let (a, b) = (by_sampling / n as f64, by_uniform / n as f64);
            assert!((a - b).abs() < 0.02, "kind {}: sampled {a} vs uniform {b}", m.kind);
            assert!(a <= 1.0 + 1e-3, "energy is conserved: {a}");
        }
        // Lambertian albedo is its colour exactly.
        let mut rng = Sampler::new(0, 0, 0);
        let d = material(MaterialKind::Diffuse, 0.8, 0.0);
        let s = sample(&d, wo, ns, true, [rng.next_f32(), rng.next_f32(), rng.next_f32()]).unwrap();
        assert_eq!(s.weight, V3::splat(0.8));
    }

    fn pbr(base: f32, metallic: f32, roughness: f32) -> FlatMaterial {
        FlatMaterial { color: [base; 3], kind: MaterialKind::Pbr as u32, roughness, metallic, ..Default::default() }
    }

    /// The albedo of the pbr material from `wo`, by sampling (mean weight), and by integrating
    /// eval over uniform directions; and the largest disagreement between a sample's density
    /// and what eval reports for its direction.
    fn pbr_albedo(m: &FlatMaterial, wo: V3<f32>, n: usize) -> (f64, f64) {
        let ns = V3::new(0.0, 0.0, 1.0);
        let mut rng = Sampler::new(9, 8, 7);
        let (mut by_sampling, mut by_uniform) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
            if let Some(s) = sample(m, wo, ns, true, u) {
                by_sampling += s.weight.x as f64;
                let (_, pdf) = eval(m, wo, s.dir, ns, true);
                assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf.max(1.0), "pdf {pdf} vs {}", s.pdf);
            }
            let z = rng.next_f32();
            let phi = 2.0 * PI * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            by_uniform += eval(m, wo, V3::new(r * phi.cos(), r * phi.sin(), z), ns, true).0.x as f64 * 2.0 * PI as f64;
        }
        (by_sampling / n as f64, by_uniform / n as f64)
    }

    /// The white furnace: a white pbr material, metal or not, smooth or rough, reflects all
    /// light at every angle (the compensation works), and its samples agree with eval.
    #[test]
    fn pbr_white_furnace_keeps_the_energy() {
        for (metallic, roughness) in [(0.0, 0.5), (1.0, 0.3), (1.0, 1.0), (0.0, 1.0), (0.5, 0.7), (0.0, 0.05)] {
            for cos in [0.95f32, 0.5, 0.15] {
                let wo = V3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let (a, b) = pbr_albedo(&pbr(1.0, metallic, roughness), wo, 100_000);
                assert!((a - 1.0).abs() < 0.02, "metal {metallic} r {roughness} μ {cos}: sampled albedo {a}");
                if roughness >= 0.5 {
                    // Uniform directions cannot resolve a sharp lobe; a wide one they can.
                    assert!((b - 1.0).abs() < 0.03, "metal {metallic} r {roughness} μ {cos}: integrated {b}");
                }
            }
        }
    }

    /// A black dielectric base keeps only the coat (a few per cent, more at grazing angles);
    /// a grey metal reflects about its colour; metalness blends continuously.
    #[test]
    fn pbr_albedo_follows_base_metal_and_angle() {
        let wo = V3::new(0.0, 0.0, 1.0);
        let (coat, _) = pbr_albedo(&pbr(0.0, 0.0, 0.5), wo, 50_000);
        assert!((0.03..0.06).contains(&coat), "coat at normal incidence: {coat}");
        let grazing = V3::new(0.99f32, 0.0, (1.0f32 - 0.98).sqrt());
        let (coat_grazing, _) = pbr_albedo(&pbr(0.0, 0.0, 0.5), grazing, 50_000);
        assert!(coat_grazing > 2.0 * coat, "Fresnel grows at grazing angles: {coat_grazing} vs {coat}");
        let (metal, _) = pbr_albedo(&pbr(0.5, 1.0, 0.5), wo, 50_000);
        assert!((metal - 0.5).abs() < 0.03, "grey metal: {metal}");
        let (half, _) = pbr_albedo(&pbr(0.5, 0.5, 0.5), wo, 50_000);
        let (dielectric, _) = pbr_albedo(&pbr(0.5, 0.0, 0.5), wo, 50_000);
        assert!((half - 0.5 * (metal + dielectric)).abs() < 0.02, "blend {half} of {metal} and {dielectric}");
    }

    /// The white furnace of the materials with a rough dielectric: rough glass of the scene
    /// file, glTF glass (a pbr material with transmission 1) and half-glass pbr (transmission
    /// ½ over a white base), from outside and inside: the weights average to 1 (transmitted
    /// ones without the radiance's 1/η²) within 1 %; reflected samples' densities are what
    /// `eval` gives (the mixture's).
    #[test]
    fn rough_glass_materials_keep_the_energy() {
        let ns = V3::new(0.0, 0.0, 1.0);
        let glass = FlatMaterial {
            color: [1.0; 3],
            kind: MaterialKind::Dielectric as u32,
            ior: 1.5,
            roughness: 0.4,
            ..Default::default()
        };
        let gltf = |t: f32, r: f32| FlatMaterial { transmission: t, ior: 1.5, ..pbr(1.0, 0.0, r) };
        for m in [glass, gltf(1.0, 0.6), gltf(0.5, 0.5), gltf(1.0, 0.05)] {
            for front in [true, false] {
                let eta = if front { m.ior } else { 1.0 / m.ior };
                for cos in [0.9f32, 0.5, 0.2] {
                    let wo = V3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                    let mut rng = Sampler::new(2, 4, 6);
                    let n = 60_000;
                    let mut sum = 0.0f64;
                    for _ in 0..n {
                        let Some(s) = sample(&m, wo, ns, front, [rng.next_f32(), rng.next_f32(), rng.next_f32()])
                        else {
                            continue;
                        };
                        assert_eq!(s.through, s.dir.z < 0.0);
                        // (A pbr material's transmission is not scaled by 1/η²: `glass_sample`.)
                        let undo = if s.through && m.kind() != MaterialKind::Pbr { eta * eta } else { 1.0 };
                        sum += (s.weight.x * undo) as f64;
                        if !s.through {
                            let (f, pdf) = eval(&m, wo, s.dir, ns, front);
                            assert!((pdf - s.pdf).abs() <= 2e-3 * s.pdf.max(1e-3), "pdf {pdf} vs {}", s.pdf);
                            assert!((f.x / pdf - s.weight.x).abs() <= 2e-3 * s.weight.x.max(1e-3));
                        }
                    }
                    let e = sum / n as f64;
                    assert!(
                        (e - 1.0).abs() < 0.01,
                        "t {} r {} front {front} μ {cos}: {e}",
                        m.transmission,
                        m.roughness
                    );
                }
            }
        }
    }

    /// The mean weight per channel of `n` samples of `m` from `wo` (transmitted weights without
    /// the radiance's 1/η²), checking that each reflected sample's density and weight are what
    /// `eval` gives for its direction.
    fn furnace(m: &FlatMaterial, wo: V3<f32>, front: bool, n: usize) -> [f64; 3] {
        let ns = V3::new(0.0, 0.0, 1.0);
        let eta = if front { m.ior } else { 1.0 / m.ior };
        let mut rng = Sampler::new(4, 5, 6);
        let mut sum = [0.0f64; 3];
        for _ in 0..n {
            let Some(s) = sample(m, wo, ns, front, [rng.next_f32(), rng.next_f32(), rng.next_f32()]) else {
                continue;
            };
            assert_eq!(s.through, s.dir.z < 0.0);
            let undo = if s.through && m.kind() != MaterialKind::Pbr { eta * eta } else { 1.0 };
            let w = s.weight * undo;
            if !s.through {
                let (f, pdf) = eval(m, wo, s.dir, ns, front);
                assert!((pdf - s.pdf).abs() <= 2e-3 * s.pdf.max(1e-3), "pdf {pdf} vs {}", s.pdf);
                assert!((f.x / pdf - s.weight.x).abs() <= 2e-3 * s.weight.x.max(1e-3));
            }
            for (c, v) in sum.iter_mut().zip(w.to_array()) {
                *c += v as f64;
            }
        }
        sum.map(|v| v / n as f64)
    }

    fn layered(coat: f32, coat_r: f32, sheen: [f32; 3], sheen_r: f32, transmission: f32) -> FlatMaterial {
        FlatMaterial {
            clearcoat: coat,
            clearcoat_roughness: coat_r,
            sheen_color: sheen,
            sheen_roughness: sheen_r,
            transmission,
            ior: 1.5,
            ..pbr(1.0, 0.0, 0.5)
        }
    }

    /// The white furnace of the layers (`KHR_materials_clearcoat`, `_sheen`): a white coat,
    /// smooth or rough, and a white sheen over a white base, opaque or glass, reflect (and
    /// pass) all light within 1 % at every angle; under glass's back face the layers are not
    /// seen.
    #[test]
    fn layered_materials_keep_the_energy() {
        let white = [1.0; 3];
        for m in [
            layered(1.0, 0.0, [0.0; 3], 0.0, 0.0),
            layered(1.0, 0.6, [0.0; 3], 0.0, 0.0),
            layered(0.0, 0.0, white, 0.3, 0.0),
            layered(0.0, 0.0, white, 1.0, 0.0),
            layered(1.0, 0.3, white, 0.5, 0.0),
            layered(0.7, 0.2, white, 0.6, 1.0),
            FlatMaterial { metallic: 1.0, ..layered(1.0, 0.1, white, 0.8, 0.0) },
        ] {
            for front in [true, false] {
                for cos in [0.9f32, 0.5, 0.2] {
                    let wo = V3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                    let e = furnace(&m, wo, front, 60_000);
                    assert!(
                        e.iter().all(|&c| (c - 1.0).abs() < 0.01),
                        "coat {} r {} sheen r {} t {} front {front} μ {cos}: {e:?}",
                        m.clearcoat,
                        m.clearcoat_roughness,
                        m.sheen_roughness,
                        m.transmission
                    );
                }
            }
        }
    }

    /// Where the layers do not conserve energy they lose what the model says: a coloured sheen
    /// scales the base by its largest channel, so a channel of colour c keeps
    /// 1 − (max − c)·E_sheen(μo); a coloured specular F0 likewise keeps 1 − (max − c) of the
    /// coat's albedo. The furnace measures the same.
    #[test]
    fn coloured_layers_lose_what_they_state() {
        let cos = 0.6f32;
        let wo = V3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
        let sheen = layered(0.0, 0.0, [1.0, 0.5, 0.0], 0.7, 0.0);
        let e_sheen = crate::render::sheen::albedo(0.7, cos) as f64;
        let e = furnace(&sheen, wo, true, 100_000);
        for (c, want) in e.iter().zip([1.0, 1.0 - 0.5 * e_sheen, 1.0 - e_sheen]) {
            assert!((c - want).abs() < 0.01, "sheen: {e:?}, want {want}");
        }
        let spec = FlatMaterial { spec_at_normal: [0.04, 0.008, 0.0], ..pbr(1.0, 0.0, 0.5) };
        let l = crate::render::pbr::pbr_lobes(&spec, cos);
        let e = furnace(&spec, wo, true, 100_000);
        for (k, c) in e.iter().enumerate() {
            let want = (l.spec_albedo.to_array()[k] + l.diffuse.to_array()[k]) as f64;
            assert!((c - want).abs() < 0.01, "specular: {e:?}, want {want} in channel {k}");
        }
        assert!(e[0] > e[2] + 0.01, "the blue channel loses what the red coat reflects: {e:?}");
    }

    /// χ² test of the layered materials' sampling against their evaluated density (the
    /// mixture of the coat's visible normals, the sheen's cosine and the base's lobes), over a
    /// white and a coloured base, metal and glass (its transmitted samples are draws that give
    /// no reflected direction: the reflected density integrates to their share).
    #[test]
    fn layered_sampling_matches_evaluation_chi2() {
        let ns = V3::new(0.0, 0.0, 1.0);
        let n = 300_000usize;
        for (m, cos) in [
            (layered(1.0, 0.1, [1.0, 0.8, 0.6], 0.5, 0.0), 0.7f32),
            (FlatMaterial { metallic: 1.0, color: [0.9, 0.6, 0.2], ..layered(0.8, 0.3, [0.0; 3], 0.0, 0.0) }, 0.3),
            (layered(0.0, 0.0, [0.3, 0.3, 1.0], 0.9, 0.0), 0.5),
            (layered(0.5, 0.2, [1.0; 3], 0.4, 1.0), 0.6),
        ] {
            let wo = V3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
            let mut rng = Sampler::new(21, 22, 23);
            let dirs: Vec<V3<f32>> = (0..n)
                .filter_map(|_| sample(&m, wo, ns, true, [rng.next_f32(), rng.next_f32(), rng.next_f32()]))
                .filter(|s| !s.through)
                .map(|s| s.dir)
                .collect();
            let r = crate::testutil::chi2_sphere_fn(dirs, n, |d| eval(&m, wo, d, ns, true).1);
            assert!(
                r.is_ok(),
                "coat {} sheen {:?} t {} μ {cos}: {}",
                m.clearcoat,
                m.sheen_color,
                m.transmission,
                r.unwrap_err()
            );
        }
    }

    #[test]
    fn dielectric_chooses_reflection_with_the_fresnel_probability() {
        let m = material(MaterialKind::Dielectric, 1.0, 0.0);
        let ns = V3::new(0.0, 0.0, 1.0);
        let wo = V3::new(0.0, 0.0, 1.0);
        // Normal incidence on glass reflects 4 %.
        let r = sample(&m, wo, ns, true, [0.03, 0.5, 0.5]).unwrap();
        assert_eq!(r.dir, V3::new(0.0, 0.0, 1.0));
        let t = sample(&m, wo, ns, true, [0.05, 0.5, 0.5]).unwrap();
        assert!((t.dir.z + 1.0).abs() < 1e-6, "straight through: {:?}", t.dir);
        assert!((t.weight.x - 1.0 / 2.25).abs() < 1e-6, "radiance compressed by 1/η²");
        // Leaving the glass expands it again.
        let out = sample(&m, wo, ns, false, [0.05, 0.5, 0.5]).unwrap();
        assert!((out.weight.x - 2.25).abs() < 1e-5);
    }
}
