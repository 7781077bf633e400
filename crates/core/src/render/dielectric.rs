//! Dielectric interfaces (`dielectric.wgsl` is the twin): the Fresnel reflectance of a smooth
//! one, the directions it reflects and refracts into, and a rough one, GGX microfacets that
//! reflect and transmit (Walter, Marschner, Li and Torrance, "Microfacet Models for
//! Refraction through Rough Surfaces", EGSR 2007), sampled through the visible normals (Heitz,
//! JCGT 2018), in the form pbrt-v4 writes them (`DielectricBxDF`, section 9.7).
//!
//! The rough interface works in the local frame of the normal on `wo`'s side (z up,
//! `wo.z > 0`); `eta` is the ratio of the indices, the side `wo` does not lie on over the one
//! it lies on (the material's `ior` arriving from outside, 1/ior from inside).
//!
//! **Energy.** Single scattering loses the light that meets a second microfacet: with GGX α = 1
//! about a fifth at grazing angles. The lobe is divided by its own directional albedo
//! E(α, μo, η), the mean weight G2/G1 of its samples, reflection and transmission together
//! (the 1/η² by which transmitted radiance is compressed left out: it is not lost), which
//! [`TABLE`] holds. The weights of [`rough_sample`] then average to 1 at every angle (a white
//! furnace, to the table's interpolation error, at most 0.5 %: `rough_white_furnace`), as
//! Turquin's compensation does for the conductor (`pbr.rs`). The price: the compensated lobe
//! is reciprocal only up to E(μo)/E(μi), 1 where α is small and up to 1.25 at α = 1 and
//! grazing angles (the uncompensated lobe is, `rough_lobe_is_reciprocal`).

use super::microfacet::{ggx_d, ggx_lambda, ggx_sample_visible};
use crate::math::V3;
use crate::math::lanes::{F, V};

/// Unpolarised Fresnel reflectance of a dielectric interface (pbrt-v4 `FrDielectric`):
/// `cos_i` of the incident side, `eta` = n_transmitted / n_incident. Returns 1 for total
/// internal reflection.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    fresnel_dielectric_lanes::<1>(cos_i.into(), eta.into()).into()
}

/// [`fresnel_dielectric`] in every lane.
#[inline(always)]
pub fn fresnel_dielectric_lanes<const N: usize>(cos_i: F<N>, eta: F<N>) -> F<N> {
    let one = F::splat(1.0);
    let sin2_t = (one - cos_i * cos_i) / (eta * eta);
    let cos_t = (one - sin2_t).max(F::splat(0.0)).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    sin2_t.ge(one).select(one, F::splat(0.5) * (r_parl * r_parl + r_perp * r_perp))
}

/// Mirror direction of `d` about the unit normal `n`.
#[inline]
pub fn reflect(d: V3<f32>, n: V3<f32>) -> V3<f32> {
    reflect_lanes::<1>(d.into(), n.into()).into()
}

/// [`reflect`] in every lane.
#[inline(always)]
pub fn reflect_lanes<const N: usize>(d: V<N>, n: V<N>) -> V<N> {
    d - n.scale(F::splat(2.0) * d.dot(n))
}

/// Refracted direction for incident `d`, normal `n` on the incident side, cos θ_i = −d·n and
/// the ratio `eta_ratio` = n_incident / n_transmitted (no total internal reflection).
#[inline]
pub fn refract(d: V3<f32>, n: V3<f32>, cos_i: f32, eta_ratio: f32) -> V3<f32> {
    refract_lanes::<1>(d.into(), n.into(), cos_i.into(), eta_ratio.into()).into()
}

/// [`refract`] in every lane.
#[inline(always)]
pub fn refract_lanes<const N: usize>(d: V<N>, n: V<N>, cos_i: F<N>, eta_ratio: F<N>) -> V<N> {
    let one = F::splat(1.0);
    let sin2_t = eta_ratio * eta_ratio * (one - cos_i * cos_i);
    let cos_t = (one - sin2_t).max(F::splat(0.0)).sqrt();
    (d.scale(eta_ratio) + n.scale(eta_ratio * cos_i - cos_t)).normalize()
}

/// A direction chosen by [`rough_sample`], in the local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughSample {
    pub wi: V3<f32>,
    /// f·|cos θ_i| / pdf, compensated; transmission includes 1/η².
    pub weight: f32,
    pub pdf: f32,
    /// Refracted into the other side.
    pub through: bool,
}

/// What the lobe is divided by: its albedo where `compensate`, else 1 (single scattering).
#[inline]
fn compensation(alpha: f32, cos_o: f32, eta: f32, compensate: bool) -> f32 {
    if compensate { albedo(alpha, cos_o, eta) } else { 1.0 }
}

/// f·|cos θ_i| and the density [`rough_sample`] chooses `wi` with, of the rough interface of
/// GGX `alpha` and index ratio `eta`, from `wo` (local, `wo.z > 0`); `wi` on either side;
/// `compensate`: divided by the albedo (else single scattering, as Mitsuba and pbrt have it).
pub fn rough_eval(alpha: f32, eta: f32, wo: V3<f32>, wi: V3<f32>, compensate: bool) -> (f32, f32) {
    let e = compensation(alpha, wo.z, eta, compensate);
    let (f_cos, pdf) = rough_eval_single(alpha, eta, wo, wi);
    (f_cos / e, pdf)
}

/// [`rough_eval`] without the compensation (single scattering).
fn rough_eval_single(alpha: f32, eta: f32, wo: V3<f32>, wi: V3<f32>) -> (f32, f32) {
    let cos_o = wo.z;
    if cos_o <= 0.0 || wi.z == 0.0 {
        return (0.0, 0.0);
    }
    let lo = ggx_lambda(alpha, cos_o);
    let li = ggx_lambda(alpha, wi.z);
    if wi.z > 0.0 {
        // Reflection: f cos θ_i = F D G2 / (4 cos θ_o); pdf = F D G1(wo) / (4 cos θ_o).
        let h = (wo + wi).normalize();
        let f = fresnel_dielectric(wo.dot(h), eta);
        let k = f * ggx_d(alpha, h.z) / (4.0 * cos_o);
        return (k / (1.0 + lo + li), k / (1.0 + lo));
    }
    // Transmission through the generalised half vector h ∝ wo + η wi (Walter et al., eq. 16),
    // turned to wo's side.
    let mut h = (wo + wi * eta).normalize();
    if h.z < 0.0 {
        h = -h;
    }
    let (cos_oh, cos_ih) = (wo.dot(h), wi.dot(h));
    if !(cos_oh > 0.0 && cos_ih < 0.0) {
        return (0.0, 0.0);
    }
    let f = fresnel_dielectric(cos_oh, eta);
    let s = cos_ih + cos_oh / eta;
    // D(h) G1(wo) (wo·h) / cos θ_o: the visible normals' density; |wi·h| / s²: dh/dwi.
    let k = (1.0 - f) * ggx_d(alpha, h.z) * cos_oh * -cos_ih / (cos_o * s * s);
    (k / ((1.0 + lo + li) * eta * eta), k / (1.0 + lo))
}

/// A direction from the rough interface: `u[0]` chooses reflection with the Fresnel
/// reflectance of the visible normal `u[1]`, `u[2]` choose. None: the chosen direction lies
/// on the wrong side (the light single scattering loses).
pub fn rough_sample(alpha: f32, eta: f32, wo: V3<f32>, u: [f32; 3], compensate: bool) -> Option<RoughSample> {
    let s = rough_sample_single(alpha, eta, wo, u)?;
    let e = compensation(alpha, wo.z, eta, compensate);
    Some(RoughSample { weight: s.weight / e, ..s })
}

/// [`rough_sample`] without the compensation.
fn rough_sample_single(alpha: f32, eta: f32, wo: V3<f32>, u: [f32; 3]) -> Option<RoughSample> {
    let cos_o = wo.z;
    if cos_o <= 0.0 {
        return None;
    }
    let h = ggx_sample_visible(alpha, wo, u[1], u[2]);
    let cos_oh = wo.dot(h);
    let f = fresnel_dielectric(cos_oh, eta);
    let lo = ggx_lambda(alpha, cos_o);
    let d = ggx_d(alpha, h.z);
    if u[0] < f {
        let wi = reflect(-wo, h);
        if wi.z <= 0.0 {
            return None;
        }
        let li = ggx_lambda(alpha, wi.z);
        // Weight G2 / G1(wo) (Heitz 2018, eq. 19).
        let weight = (1.0 + lo) / (1.0 + lo + li);
        let pdf = f * d / ((1.0 + lo) * 4.0 * cos_o);
        return Some(RoughSample { wi, weight, pdf, through: false });
    }
    let wi = refract(-wo, h, cos_oh, 1.0 / eta);
    let cos_ih = wi.dot(h);
    if wi.z >= 0.0 || cos_ih >= 0.0 {
        return None;
    }
    let li = ggx_lambda(alpha, wi.z);
    let weight = (1.0 + lo) / ((1.0 + lo + li) * eta * eta);
    let s = cos_ih + cos_oh / eta;
    let pdf = (1.0 - f) * d * cos_oh * -cos_ih / ((1.0 + lo) * cos_o * s * s);
    Some(RoughSample { wi, weight, pdf, through: true })
}

/// Samples along √α ∈ [0, 1].
pub const ROUGH_STEPS: usize = 16;
/// Samples along μ = cos θ_o ∈ [0, 1] (the first evaluated at 10⁻³).
pub const COS_STEPS: usize = 16;
/// Samples along ±√(|ln η| / ln [`ETA_MAX`]) ∈ [−1, 1]: η = 1 is the middle one, and the
/// steps are finest about it, where total internal reflection sets in at grazing angles.
pub const ETA_STEPS: usize = 17;
/// The table's largest index ratio (and 1 / it its smallest); beyond, its edge is read.
pub const ETA_MAX: f32 = 3.0;
/// Strata per axis of the visible-normal samples behind each entry.
#[cfg(test)]
const STRATA: usize = 32;

/// E(α, μ, η), `ETA_STEPS` blocks (η, as [`ETA_STEPS`] says) of `ROUGH_STEPS` rows (√α) of `COS_STEPS` values (μ):
/// the integrals of [`integrate`], stored with the code; `the_stored_table_is_the_integral`
/// checks every bit, and `STRAHL_BLESS=1 cargo test --release -p strahl-core
/// dielectric::tests::the_stored_table` writes it anew.
static TABLE: [f32; ETA_STEPS * ROUGH_STEPS * COS_STEPS] = include!("dielectric_albedo.in");

/// The albedo table ([`TABLE`]).
#[inline]
pub fn table() -> &'static [f32] {
    &TABLE
}

/// The rough interface's albedo E(α, μo, η) (weights of both lobes, without 1/η²), trilinear
/// in [`TABLE`] (the same operations as `dielectric_albedo` in `dielectric.wgsl`).
pub fn albedo(alpha: f32, cos_o: f32, eta: f32) -> f32 {
    let t = table();
    let x = alpha.max(0.0).sqrt().min(1.0) * (ROUGH_STEPS - 1) as f32;
    let y = cos_o.clamp(0.0, 1.0) * (COS_STEPS - 1) as f32;
    let l = eta.ln() / ETA_MAX.ln();
    let z = (0.5 + 0.5 * l.abs().sqrt().copysign(l)).clamp(0.0, 1.0) * (ETA_STEPS - 1) as f32;
    let x0 = x.floor().min((ROUGH_STEPS - 2) as f32);
    let y0 = y.floor().min((COS_STEPS - 2) as f32);
    let z0 = z.floor().min((ETA_STEPS - 2) as f32);
    let (fx, fy, fz) = (x - x0, y - y0, z - z0);
    let base = (z0 as usize * ROUGH_STEPS + x0 as usize) * COS_STEPS + y0 as usize;
    let mut e = [0.0f32; 2];
    for (k, plane) in [base, base + ROUGH_STEPS * COS_STEPS].into_iter().enumerate() {
        let top = t[plane] * (1.0 - fy) + t[plane + 1] * fy;
        let bottom = t[plane + COS_STEPS] * (1.0 - fy) + t[plane + COS_STEPS + 1] * fy;
        e[k] = top * (1.0 - fx) + bottom * fx;
    }
    (e[0] * (1.0 - fz) + e[1] * fz).max(1e-3)
}

/// The α, μ and η of table entry (i, j, k).
#[cfg(test)]
fn entry_point(i: usize, j: usize, k: usize) -> (f32, f32, f32) {
    let s = i as f32 / (ROUGH_STEPS - 1) as f32;
    let alpha = (s * s).max(super::microfacet::MIN_ALPHA);
    let mu = (j as f32 / (COS_STEPS - 1) as f32).max(1e-3);
    let v = 2.0 * k as f32 / (ETA_STEPS - 1) as f32 - 1.0;
    let eta = (ETA_MAX.ln() * v * v.abs()).exp();
    (alpha, mu, eta)
}

/// The table [`TABLE`] stores, computed.
#[cfg(test)]
fn integrate_table() -> Vec<f32> {
    let mut t = Vec::with_capacity(TABLE.len());
    for k in 0..ETA_STEPS {
        for i in 0..ROUGH_STEPS {
            for j in 0..COS_STEPS {
                let (alpha, mu, eta) = entry_point(i, j, k);
                t.push(integrate(alpha, mu, eta) as f32);
            }
        }
    }
    t
}

/// E(α, μ, η) by stratified visible normals, each weighed by both lobes (the Fresnel
/// reflectance F of the reflection, 1 − F of the transmission) instead of choosing one.
#[cfg(test)]
fn integrate(alpha: f32, mu: f32, eta: f32) -> f64 {
    let wo = V3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mut sum = 0.0f64;
    for a in 0..STRATA {
        for b in 0..STRATA {
            let u1 = (a as f32 + 0.5) / STRATA as f32;
            let u2 = (b as f32 + 0.5) / STRATA as f32;
            let f = fresnel_dielectric(wo.dot(ggx_sample_visible(alpha, wo, u1, u2)), eta) as f64;
            // u[0] just below F reflects; just above, refracts.
            let r = rough_sample_single(alpha, eta, wo, [0.0, u1, u2]).filter(|s| !s.through);
            let t = rough_sample_single(alpha, eta, wo, [1.0, u1, u2]).filter(|s| s.through);
            sum += f * r.map_or(0.0, |s| s.weight as f64);
            sum += (1.0 - f) * t.map_or(0.0, |s| (s.weight * eta * eta) as f64);
        }
    }
    sum / (STRATA * STRATA) as f64
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
            "src/render/dielectric_albedo.in",
            "E(alpha, mu, eta) of dielectric.rs, written by its test the_stored_table_is_the_integral.",
        );
    }

    fn direction(cos: f32) -> V3<f32> {
        V3::new((1.0 - cos * cos).max(0.0).sqrt(), 0.0, cos)
    }

    /// The mean weight of the compensated lobe's samples (without 1/η² for transmission) at
    /// α, μo, η, and the largest disagreement of a sample's density with [`rough_eval`]'s.
    fn furnace(alpha: f32, cos: f32, eta: f32, n: usize) -> f64 {
        let wo = direction(cos);
        let mut rng = Sampler::new(3, 1, 4);
        let mut sum = 0.0f64;
        for _ in 0..n {
            let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
            if let Some(s) = rough_sample(alpha, eta, wo, u, true) {
                sum += (if s.through { s.weight * eta * eta } else { s.weight }) as f64;
                let (f_cos, pdf) = rough_eval(alpha, eta, wo, s.wi, true);
                assert!((pdf - s.pdf).abs() <= 2e-3 * s.pdf.max(1e-3), "pdf {pdf} vs sampled {}", s.pdf);
                assert!((f_cos / pdf - s.weight).abs() <= 2e-3 * s.weight, "eval/pdf {} vs {}", f_cos / pdf, s.weight);
            }
        }
        sum / n as f64
    }

    /// The white furnace: from outside (η > 1) and inside (η < 1, where total internal
    /// reflection takes over), smooth to α = 1, normal to grazing incidence, the
    /// compensated lobe keeps all the energy to within 1 %; uncompensated it would not.
    #[test]
    fn rough_white_furnace() {
        for eta in [1.5f32, 1.0 / 1.5, 1.33, 2.4, 1.05] {
            for alpha in [0.05f32, 0.3, 0.6, 1.0] {
                for cos in [0.98f32, 0.6, 0.25, 0.08] {
                    let e = furnace(alpha, cos, eta, 60_000);
                    assert!((e - 1.0).abs() < 0.01, "η {eta} α {alpha} μ {cos}: albedo {e}");
                }
            }
        }
        // Single scattering alone loses much of it where the surface is rough and the light
        // grazing: the compensation is doing the work.
        let e = albedo(1.0, 0.08, 1.5);
        assert!(e < 0.9, "E(1, 0.08, 1.5) = {e}");
    }

    /// χ² test of sampling against evaluation (as Mitsuba's and pbrt's test suites do,
    /// [`crate::testutil::chi2_sphere`]): the counts of [`rough_sample`]'s directions in θ × φ
    /// cells of the sphere against the density of [`rough_eval`] integrated over them; the
    /// statistic must stay below the 99.9 % quantile, and the density integrate to the share
    /// of draws that gave a direction.
    #[test]
    fn rough_sampling_matches_evaluation_chi2() {
        let n = 400_000usize;
        for (alpha, eta, cos) in [(0.3f32, 1.5f32, 0.7f32), (0.6, 1.0 / 1.5, 0.8), (0.1, 1.33, 0.35), (1.0, 1.5, 0.2)] {
            let wo = direction(cos);
            let mut rng = Sampler::new(11, 12, 13);
            let samples: Vec<V3<f32>> = (0..n)
                .filter_map(|_| {
                    let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                    rough_sample(alpha, eta, wo, u, true).map(|s| s.wi)
                })
                .collect();
            crate::testutil::chi2_sphere_fn(samples, n, |d| rough_eval(alpha, eta, wo, d, true).1)
                .unwrap_or_else(|e| panic!("α {alpha} η {eta} μ {cos}: {e}"));
        }
    }

    /// Reciprocity of the single-scattering lobe: reflection is symmetric, f(wo, wi) =
    /// f(wi, wo); transmitted radiance obeys f(wo → wi; η) = f(wi → wo; 1/η) / η² (the 1/η²
    /// of radiance crossing into the denser side, Veach 1997, 5.2): to 2·10⁻³ (f32), except where
    /// the microfacet is seen at a grazing angle (at most 5 % of the random pairs).
    #[test]
    fn rough_lobe_is_reciprocal() {
        let mut rng = Sampler::new(7, 7, 7);
        let (mut checked, mut loose) = (0, 0);
        for _ in 0..2000 {
            let alpha = 0.05 + 0.95 * rng.next_f32();
            let eta = 1.1 + rng.next_f32();
            let wo = direction(0.05 + 0.95 * rng.next_f32());
            let (z, phi) = (rng.next_f32() * 2.0 - 1.0, 2.0 * std::f32::consts::PI * rng.next_f32());
            let r = (1.0 - z * z).max(0.0).sqrt();
            let wi = V3::new(r * phi.cos(), r * phi.sin(), z);
            if wi.z.abs() < 0.05 {
                continue;
            }
            let (f_fwd, _) = rough_eval_single(alpha, eta, wo, wi);
            let f_fwd = f_fwd / wi.z.abs();
            if wi.z > 0.0 {
                let (f_back, _) = rough_eval_single(alpha, eta, wi, wo);
                let f_back = f_back / wo.z;
                assert!((f_fwd - f_back).abs() <= 1e-4 * f_fwd.max(1e-3), "reflection {f_fwd} vs {f_back}");
            } else {
                // Seen from wi's side: the frame turned over, η inverted.
                let flip = |v: V3<f32>| V3::new(v.x, v.y, -v.z);
                let (f_back, _) = rough_eval_single(alpha, 1.0 / eta, flip(wi), flip(wo));
                let f_back = f_back / wo.z;
                let want = f_back / (eta * eta);
                // Where the microfacet is seen at a grazing angle (wo·h or wi·h below 0.05) f32
                // loses digits in 1 − F (the worst such case here agrees to 10 digits in f64).
                let h = (wo + wi * eta).normalize();
                let grazing = wo.dot(h).abs().min(wi.dot(h).abs()) < 0.05;
                let rel = (f_fwd - want).abs() / want.max(1e-6);
                assert!(
                    rel <= if grazing { 0.2 } else { 2e-3 },
                    "transmission {f_fwd} vs {want}: α {alpha} η {eta} wo {wo:?} wi {wi:?}"
                );
                loose += grazing as usize;
            }
            checked += 1;
        }
        assert!(checked > 1500);
        assert!(loose * 20 <= checked, "{loose} of {checked} at grazing microfacets");
    }
}
