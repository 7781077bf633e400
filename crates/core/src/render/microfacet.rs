//! GGX microfacet reflection (Walter et al. 2007; Heitz 2014, 2018) and its directional
//! albedo (`microfacet.wgsl` is the twin).
//!
//! **The albedo table**: what the pbr material needs to make up for the energy single
//! scattering loses (multiple scattering between microfacets) and to weigh its diffuse base
//! under the dielectric coat. The table is integrated here, stored with the code
//! (`microfacet_albedo.in`, checked against the integral by a test) and given to the shaders as a shared constant (`#{GGX_ALBEDO}` in `backend/gpu/shared.rs`), so both
//! backends interpolate the same numbers (`ggx_albedo` in `shaders/modules/microfacet.wgsl`).
//!
//! With Schlick's Fresnel F = F0 + (1 − F0)(1 − cos θ_h)⁵ the albedo is linear in F0:
//! E(F0, μ) = F0·E₁(μ) + (1 − F0)·E₅(μ), where E₁ is the albedo with F = 1 and E₅ that with
//! F = (1 − cos θ_h)⁵. Both are tabulated over perceptual roughness r (α = r²) and μ = cos θ_o,
//! each entry the mean of [`STRATA`]² stratified samples of the visible normals (Heitz 2018),
//! whose weight G2/G1 is the exact single-scattering albedo estimator: relative error below
//! 10⁻³ against 10⁶ random samples; bilinear interpolation adds at most 2·10⁻³ where the
//! albedo bends fastest (grazing μ at r = 1).

use crate::math::V3;
use crate::math::lanes::{F, V, clamp01};

const PI: f32 = std::f32::consts::PI;

/// Schlick's approximation of a conductor's Fresnel reflectance with reflectance `f0` at
/// normal incidence (the material's colour).
#[inline]
pub fn schlick(f0: V3<f32>, cos: f32) -> V3<f32> {
    schlick_lanes::<1>(f0.into(), cos.into()).into()
}

/// [`schlick`] in every lane.
#[inline(always)]
pub fn schlick_lanes<const N: usize>(f0: V<N>, cos: F<N>) -> V<N> {
    let m = clamp01(F::splat(1.0) - cos);
    let m5 = m * m * m * m * m;
    f0 + (V::splat([1.0; 3]) - f0).scale(m5)
}

/// Schlick's Fresnel between reflectance `f0` at normal and `f90` at grazing incidence,
/// f0 + (f90 − f0)(1 − cos)⁵ (`KHR_materials_specular`'s form; [`schlick_lanes`] for f90 = 1),
/// in every lane.
#[inline(always)]
pub fn schlick_grazing_lanes<const N: usize>(f0: V<N>, f90: F<N>, cos: F<N>) -> V<N> {
    let m = clamp01(F::splat(1.0) - cos);
    let m5 = m * m * m * m * m;
    f0 + (V::new(f90, f90, f90) - f0).scale(m5)
}

/// GGX normal distribution D(h) for cos θ_h = `cos_h` (Walter et al. 2007, eq. 33).
#[inline]
pub fn ggx_d(alpha: f32, cos_h: f32) -> f32 {
    ggx_d_lanes::<1>(alpha.into(), cos_h.into()).into()
}

/// [`ggx_d`] in every lane.
#[inline(always)]
pub fn ggx_d_lanes<const N: usize>(alpha: F<N>, cos_h: F<N>) -> F<N> {
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let den = c2 * (a2 - F::splat(1.0)) + F::splat(1.0);
    a2 / (F::splat(PI) * den * den)
}

/// Smith's Λ for GGX at a direction with cos θ = `cos` (Heitz 2014, eq. 72).
#[inline]
pub fn ggx_lambda(alpha: f32, cos: f32) -> f32 {
    ggx_lambda_lanes::<1>(alpha.into(), cos.into()).into()
}

/// [`ggx_lambda`] in every lane.
#[inline(always)]
pub fn ggx_lambda_lanes<const N: usize>(alpha: F<N>, cos: F<N>) -> F<N> {
    let one = F::splat(1.0);
    let c2 = (cos * cos).max(F::splat(1e-12));
    let a2_tan2 = alpha * alpha * (one - c2).max(F::splat(0.0)) / c2;
    F::splat(0.5) * ((one + a2_tan2).sqrt() - one)
}

/// A visible normal of the GGX surface seen from `wo` (local, z up): Heitz, "Sampling the GGX
/// Distribution of Visible Normals", JCGT 2018, listing 1 (isotropic α).
#[inline]
pub fn ggx_sample_visible(alpha: f32, wo: V3<f32>, u1: f32, u2: f32) -> V3<f32> {
    ggx_sample_visible_lanes::<1>(alpha.into(), wo.into(), u1.into(), u2.into()).into()
}

/// [`ggx_sample_visible`] in every lane.
#[inline(always)]
pub fn ggx_sample_visible_lanes<const N: usize>(alpha: F<N>, wo: V<N>, u1: F<N>, u2: F<N>) -> V<N> {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let vh = V::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let len = lensq.sqrt();
    let has = lensq.gt(zero);
    let t1 = V::new(has.select(-vh.y / len, one), has.select(vh.x / len, zero), has.select(zero / len, zero));
    let t2 = V::new(vh.y * t1.z - vh.z * t1.y, vh.z * t1.x - vh.x * t1.z, vh.x * t1.y - vh.y * t1.x);
    let r = u1.sqrt();
    let (sin, cos) = u2.sin_cos_turns();
    let p1 = r * cos;
    let s = F::splat(0.5) * (one + vh.z);
    let p2 = (one - s) * (one - p1 * p1).max(zero).sqrt() + s * (r * sin);
    let nh = t1.scale(p1) + t2.scale(p2) + vh.scale((one - p1 * p1 - p2 * p2).max(zero).sqrt());
    V::new(alpha * nh.x, alpha * nh.y, nh.z.max(zero)).normalize()
}

/// Samples along perceptual roughness r ∈ [0, 1] (r_i = i / (R − 1)).
pub const ROUGHNESS_STEPS: usize = 16;
/// Samples along μ = cos θ_o ∈ [0, 1] (μ_j = j / (M − 1), the first evaluated at 10⁻³).
pub const COS_STEPS: usize = 32;
/// Strata per axis of the visible-normal samples behind each entry.
#[cfg(test)]
const STRATA: usize = 48;
/// The smallest α tabulated: below it GGX is a mirror whose albedo is 1 in the table's
/// resolution.
pub const MIN_ALPHA: f32 = 1e-3;

/// E₁ then E₅, each `ROUGHNESS_STEPS` rows of `COS_STEPS` values (row r, column μ): the
/// integrals of [`integrate`], stored with the code (computing them took about 35 ms of the
/// first render of every process with a pbr material). `the_stored_table_is_the_integral`
/// checks every bit; after a change to the integration,
/// `STRAHL_BLESS=1 cargo test --release -p strahl-core the_stored_table` writes it anew.
static TABLE: [f32; 2 * ROUGHNESS_STEPS * COS_STEPS] = include!("microfacet_albedo.in");

/// The albedo table ([`TABLE`]).
#[inline]
pub fn table() -> &'static [f32] {
    &TABLE
}

/// The table [`TABLE`] stores, computed.
#[cfg(test)]
fn integrate_table() -> Vec<f32> {
    let mut e1 = Vec::with_capacity(ROUGHNESS_STEPS * COS_STEPS);
    let mut e5 = Vec::with_capacity(ROUGHNESS_STEPS * COS_STEPS);
    for i in 0..ROUGHNESS_STEPS {
        let r = i as f64 / (ROUGHNESS_STEPS - 1) as f64;
        let alpha = ((r * r) as f32).max(MIN_ALPHA);
        for j in 0..COS_STEPS {
            let mu = (j as f64 / (COS_STEPS - 1) as f64).max(1e-3);
            let (a, b) = integrate(alpha, mu);
            e1.push(a as f32);
            e5.push(b as f32);
        }
    }
    e1.extend(e5);
    e1
}

/// (E₁, E₅) at α and μ, by stratified visible-normal samples (in f64 where it sums).
#[cfg(test)]
fn integrate(alpha: f32, mu: f64) -> (f64, f64) {
    let wo = V3::new((1.0 - mu * mu).max(0.0).sqrt() as f32, 0.0, mu as f32);
    let lo = ggx_lambda(alpha, wo.z) as f64;
    let (mut s1, mut s5) = (0.0f64, 0.0f64);
    for a in 0..STRATA {
        for b in 0..STRATA {
            let u1 = (a as f32 + 0.5) / STRATA as f32;
            let u2 = (b as f32 + 0.5) / STRATA as f32;
            let h = ggx_sample_visible(alpha, wo, u1, u2);
            let cos_oh = wo.dot(h) as f64;
            let cos_i = 2.0 * cos_oh * h.z as f64 - mu;
            if cos_i <= 0.0 {
                continue;
            }
            let li = ggx_lambda(alpha, cos_i as f32) as f64;
            let w = (1.0 + lo) / (1.0 + lo + li);
            s1 += w;
            s5 += w * (1.0 - cos_oh).clamp(0.0, 1.0).powi(5);
        }
    }
    let n = (STRATA * STRATA) as f64;
    (s1 / n, s5 / n)
}

/// (E₁, E₅) at perceptual roughness `r` and μ = `cos_o`, bilinear in the table (the same
/// operations as `ggx_albedo` in `bsdf.wgsl`).
#[inline]
pub fn lookup(r: f32, cos_o: f32) -> (f32, f32) {
    let (e1, e5) = lookup_lanes::<1>(r.into(), cos_o.into());
    (e1.into(), e5.into())
}

/// [`lookup`] in every lane: the table's entries read lane after lane, interpolated in lanes.
// (A lane loop over several arrays indexed by the lane.)
#[allow(clippy::needless_range_loop)]
#[inline(always)]
pub fn lookup_lanes<const N: usize>(r: F<N>, cos_o: F<N>) -> (F<N>, F<N>) {
    let t = table();
    let x = clamp01(r) * F::splat((ROUGHNESS_STEPS - 1) as f32);
    let y = clamp01(cos_o) * F::splat((COS_STEPS - 1) as f32);
    let x0 = x.map(f32::floor).min(F::splat((ROUGHNESS_STEPS - 2) as f32));
    let y0 = y.map(f32::floor).min(F::splat((COS_STEPS - 2) as f32));
    let (fx, fy) = (x - x0, y - y0);
    let mut e = [[0.0f32; N]; 8];
    for l in 0..N {
        let k = x0.0[l] as usize * COS_STEPS + y0.0[l] as usize;
        for (j, base) in [0, ROUGHNESS_STEPS * COS_STEPS].into_iter().enumerate() {
            let i = (base + k).min(t.len() - COS_STEPS - 2);
            e[4 * j][l] = t[i];
            e[4 * j + 1][l] = t[i + 1];
            e[4 * j + 2][l] = t[i + COS_STEPS];
            e[4 * j + 3][l] = t[i + COS_STEPS + 1];
        }
    }
    (bilerp(&e[..4], fx, fy), bilerp(&e[4..], fx, fy))
}

/// The four table entries `e` (the corners (0, 0), (0, 1), (1, 0), (1, 1)) interpolated at
/// (fx, fy). (A function, not a closure: the compiler left the closure out of line, in code
/// without the ISA's instructions.)
#[inline(always)]
fn bilerp<const N: usize>(e: &[[f32; N]], fx: F<N>, fy: F<N>) -> F<N> {
    let one = F::splat(1.0);
    let top = F(e[0]) * (one - fy) + F(e[1]) * fy;
    let bottom = F(e[2]) * (one - fy) + F(e[3]) * fy;
    top * (one - fx) + bottom * fx
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;

    /// The stored table is what [`integrate`] computes, bit for bit (with `STRAHL_BLESS=1`:
    /// written anew).
    #[test]
    fn the_stored_table_is_the_integral() {
        crate::testutil::bless_or_check(
            table(),
            &integrate_table(),
            "src/render/microfacet_albedo.in",
            "E₁ then E₅ of microfacet.rs, written by its test the_stored_table_is_the_integral.",
        );
    }

    /// Table entries against independent random estimates (10⁶ samples each): the
    /// stratified sums are as good as the claim in the header.
    #[test]
    fn entries_agree_with_random_estimates() {
        let mut rng = Sampler::new(5, 6, 7);
        for (i, j) in [(3usize, 1usize), (8, 10), (15, 0), (15, 31), (11, 4)] {
            let r = i as f32 / (ROUGHNESS_STEPS - 1) as f32;
            let alpha = (r * r).max(MIN_ALPHA);
            let mu = (j as f32 / (COS_STEPS - 1) as f32).max(1e-3);
            let wo = V3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let lo = ggx_lambda(alpha, mu) as f64;
            let n = 1_000_000;
            let mut s1 = 0.0f64;
            for _ in 0..n {
                let h = ggx_sample_visible(alpha, wo, rng.next_f32(), rng.next_f32());
                let cos_i = 2.0 * wo.dot(h) * h.z - mu;
                if cos_i > 0.0 {
                    s1 += (1.0 + lo) / (1.0 + lo + ggx_lambda(alpha, cos_i) as f64);
                }
            }
            let want = s1 / n as f64;
            let got = table()[i * COS_STEPS + j] as f64;
            assert!((got - want).abs() < 2e-3 * want.max(0.1), "r {r} μ {mu}: table {got} vs {want}");
        }
    }

    /// A smooth reflector keeps all its energy; a rough one at grazing angles loses much of it
    /// to single scattering (which is what the compensation restores); E₅ ≤ E₁.
    #[test]
    fn albedo_has_the_known_shape() {
        let (e1, e5) = lookup(0.0, 0.7);
        assert!((e1 - 1.0).abs() < 2e-3 && e5 < 0.01, "{e1} {e5}");
        let (rough_grazing, _) = lookup(1.0, 0.05);
        let (rough_normal, _) = lookup(1.0, 1.0);
        assert!(rough_grazing < 0.9 && rough_normal < 0.5 && rough_normal > 0.2, "{rough_grazing} {rough_normal}");
        for &v in &table()[ROUGHNESS_STEPS * COS_STEPS..] {
            assert!(v >= 0.0);
        }
        for k in 0..ROUGHNESS_STEPS * COS_STEPS {
            assert!(table()[ROUGHNESS_STEPS * COS_STEPS + k] <= table()[k]);
        }
    }
}
