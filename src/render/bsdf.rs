//! Scattering at a surface for the path tracer (`bsdf.wgsl` is the twin): Lambertian diffuse,
//! smooth and GGX-rough conductors, smooth dielectrics.
//!
//! Directions are world-space unit vectors; `wo` points away from the surface towards where
//! the light goes (back along the incoming ray) and `ns` is the normal on `wo`'s side.
//! "Weight" is f·|cos θ_i| / pdf, the factor a sampled direction multiplies the path by.

use super::shade::{fresnel_dielectric, reflect, refract};
use crate::gpu_types::GpuMaterial;
use crate::math::V3;
use crate::scene::MaterialKind;

const PI: f32 = std::f32::consts::PI;
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
}

/// Whether the material scatters only into isolated directions (no next-event estimation).
#[inline]
pub fn is_specular(m: &GpuMaterial) -> bool {
    m.kind() == MaterialKind::Dielectric || (m.kind() == MaterialKind::Mirror && m.roughness < MIN_ROUGHNESS)
}

/// An orthonormal basis (t, b) around unit `n`, branchless (Duff et al., "Building an
/// Orthonormal Basis, Revisited", JCGT 2017).
#[inline]
pub fn basis(n: V3<f32>) -> (V3<f32>, V3<f32>) {
    // (n.z ≥ 0 rather than copysign: -0 takes the + branch, as in the WGSL twin.)
    let sign = if n.z >= 0.0 { 1.0f32 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (V3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), V3::new(b, sign + n.y * n.y * a, -n.y))
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
    let phi = 2.0 * PI * u2;
    V3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

/// Schlick's approximation of a conductor's Fresnel reflectance with reflectance `f0` at
/// normal incidence (the material's colour).
#[inline]
pub fn schlick(f0: V3<f32>, cos: f32) -> V3<f32> {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m5 = m * m * m * m * m;
    f0 + (V3::splat(1.0) - f0) * m5
}

/// GGX normal distribution D(h) for cos θ_h = `cos_h` (Walter et al. 2007, eq. 33).
#[inline]
pub fn ggx_d(alpha: f32, cos_h: f32) -> f32 {
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let den = c2 * (a2 - 1.0) + 1.0;
    a2 / (PI * den * den)
}

/// Smith's Λ for GGX at a direction with cos θ = `cos` (Heitz 2014, eq. 72).
#[inline]
pub fn ggx_lambda(alpha: f32, cos: f32) -> f32 {
    let c2 = (cos * cos).max(1e-12);
    let a2_tan2 = alpha * alpha * (1.0 - c2).max(0.0) / c2;
    0.5 * ((1.0 + a2_tan2).sqrt() - 1.0)
}

/// A visible normal of the GGX surface seen from `wo` (local, z up): Heitz, "Sampling the GGX
/// Distribution of Visible Normals", JCGT 2018, listing 1 (isotropic α).
#[inline]
pub fn ggx_sample_visible(alpha: f32, wo: V3<f32>, u1: f32, u2: f32) -> V3<f32> {
    let vh = V3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if lensq > 0.0 { V3::new(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { V3::new(1.0, 0.0, 0.0) };
    let t2 = vh.cross(t1);
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * (r * phi.sin());
    let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    V3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize()
}

/// f·cos θ_i and the density [`sample`] would choose `wi` with, for a non-specular material.
pub fn eval(m: &GpuMaterial, wo: V3<f32>, wi: V3<f32>, ns: V3<f32>) -> (V3<f32>, f32) {
    let cos_i = wi.dot(ns);
    if cos_i <= 0.0 {
        return (V3::zero(), 0.0);
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
pub fn sample(m: &GpuMaterial, wo: V3<f32>, ns: V3<f32>, front: bool, u: [f32; 3]) -> Option<BsdfSample> {
    let color = V3::from_array(m.color);
    if m.kind() == MaterialKind::Dielectric {
        let cos_i = wo.dot(ns);
        let eta = if front { m.ior } else { 1.0 / m.ior };
        let f = fresnel_dielectric(cos_i, eta);
        if u[0] < f {
            return Some(BsdfSample { dir: reflect(-wo, ns), weight: V3::splat(1.0), pdf: 0.0, specular: true });
        }
        // Snell; radiance is compressed into the smaller solid angle by 1/η² (pbrt-v4 9.5.2).
        let dir = refract(-wo, ns, cos_i, 1.0 / eta);
        return Some(BsdfSample { dir, weight: color / (eta * eta), pdf: 0.0, specular: true });
    }
    if m.kind() == MaterialKind::Mirror {
        let cos_o = wo.dot(ns);
        if m.roughness < MIN_ROUGHNESS {
            let dir = reflect(-wo, ns);
            return Some(BsdfSample { dir, weight: schlick(color, cos_o), pdf: 0.0, specular: true });
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
        return Some(BsdfSample { dir, weight, pdf, specular: false });
    }
    if color.max_component() <= 0.0 {
        return None;
    }
    let local = cosine_hemisphere(u[1], u[2]);
    let dir = to_world(local, ns).normalize();
    Some(BsdfSample { dir, weight: color, pdf: local.z * INV_PI, specular: false })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;

    fn material(kind: MaterialKind, color: f32, roughness: f32) -> GpuMaterial {
        GpuMaterial { color: [color; 3], kind: kind as u32, ior: 1.5, roughness, ..Default::default() }
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
                    let (_, pdf) = eval(&m, wo, s.dir, ns);
                    assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf.max(1.0), "pdf {pdf} vs {}", s.pdf);
                }
                // Uniform hemisphere directions: ∫ f cos dω = E[f cos · 2π].
                let z = rng.next_f32();
                let phi = 2.0 * PI * rng.next_f32();
                let r = (1.0 - z * z).max(0.0).sqrt();
                let wi = V3::new(r * phi.cos(), r * phi.sin(), z);
                by_uniform += eval(&m, wo, wi, ns).0.x as f64 * 2.0 * PI as f64;
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
