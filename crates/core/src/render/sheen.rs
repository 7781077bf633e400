//! The sheen of cloth (`KHR_materials_sheen`; `sheen.wgsl` is the twin): the "Charlie"
//! microfacet distribution with the visibility term Estevez and Kulla fitted
//! ("Production Friendly Microfacet Sheen BRDF", Sony Pictures Imageworks 2017), as the
//! extension defines them, and the lobe's directional albedo, which scales what the base
//! below receives ([`super::layers`]).
//!
//! With α = r² (r the sheen roughness) and θ_h the half vector's angle from the normal:
//!
//! - D(h) = (2 + 1/α) sin^(1/α) θ_h / (2π) (their eq. 2);
//! - G₂ = 1 / (1 + Λ(μo) + Λ(μi)), Λ(μ) = exp(L(μ)) for μ < ½, else exp(2L(½) − L(1 − μ)),
//!   L(x) = a/(1 + b·x^c) + d·x + e with a…e interpolated in (1 − α)² between their two fits
//!   (their eq. 3–4 and table 1). Their "terminator softening" of Λ is left out, as the
//!   extension leaves it out: it would make the lobe non-reciprocal;
//! - f = sheen colour · D · G₂ / (4 μo μi), which is symmetric in wo and wi.
//!
//! The lobe is not energy conserving by itself: its albedo E(α, μo) (0.17 at normal incidence
//! and the roughest, 0.9 at grazing) is what the layer reflects, and the layers below receive
//! 1 − max(colour)·E(μo),
//! as Blender's Principled BSDF and the extension's albedo scaling do (the extension's
//! `min` over μi as well is dropped: that would lose energy a white furnace must keep). Below
//! roughness 0.3 and near grazing E exceeds 1 (up to 6 at μo = 0.001: the 1/(4μo) of the
//! lobe outgrows the visibility term); there [`super::layers`] scales the lobe to reflect 1.
//!
//! **The albedo table**: E over √r and √μo (it bends fastest at small roughness and grazing
//! angles), each entry the integral of D·G₂/(4μo) over the hemisphere by the midpoint rule on
//! [`GRID_MU`] × [`GRID_PHI`] cells in (μi, φ) (f64 sums), stored with the code
//! (`sheen_albedo.in`, checked bit for bit by a test) and shared with the shaders
//! (`#{SHEEN_ALBEDO}`). What an error in E costs a white furnace is |E − Ê|/max(Ê, 1) (the
//! layer reflects E·n and passes 1 − Ê·n, n = 1/max(Ê, 1)). Measured in the tests: entries
//! against a 4× finer grid, below 8·10⁻⁴; bilinear interpolation between entries, below
//! 6·10⁻³ for μo ≥ 0.01 and r ≥ 0.05, and up to 0.08 in the corner of smaller roughness or
//! more grazing angles (where E changes by orders of magnitude between entries).

use crate::math::V3;

const PI: f32 = std::f32::consts::PI;
/// Sheen roughness steps (r from 0 to 1) and μo steps (0 to 1) of the table.
pub const ROUGHNESS_STEPS: usize = 32;
pub const COS_STEPS: usize = 32;
/// The smallest α: below it the lobe is a thin rim of grazing light whose albedo is about
/// 0 in the table's resolution, and 1/α overflows the power's useful range.
pub const MIN_ALPHA: f32 = 1e-3;
#[cfg(test)]
const GRID_MU: usize = 512;
#[cfg(test)]
const GRID_PHI: usize = 256;

/// E(r, μo), `ROUGHNESS_STEPS` rows of `COS_STEPS` values, written by the test
/// `the_stored_table_is_the_integral` (`STRAHL_BLESS=1 cargo test --release -p strahl-core
/// sheen::tests::the_stored_table` writes it anew).
static TABLE: [f32; ROUGHNESS_STEPS * COS_STEPS] = include!("sheen_albedo.in");

/// The albedo table ([`TABLE`]).
#[inline]
pub fn table() -> &'static [f32] {
    &TABLE
}

/// α of sheen roughness `r`.
#[inline]
pub fn sheen_alpha(r: f32) -> f32 {
    let r = r.clamp(0.0, 1.0);
    (r * r).max(MIN_ALPHA)
}

/// The Charlie distribution D(h) at cos θ_h = `cos_h`.
#[inline]
pub fn charlie_d(alpha: f32, cos_h: f32) -> f32 {
    let inv = 1.0 / alpha;
    let sin2 = (1.0 - cos_h * cos_h).max(0.0);
    // sin^(1/α) as (sin²)^(1/(2α)): no square root, and 0 at cos_h = ±1.
    (2.0 + inv) * sin2.powf(0.5 * inv) / (2.0 * PI)
}

/// Estevez and Kulla's L(x) at α.
#[inline]
fn fit_l(alpha: f32, x: f32) -> f32 {
    let t = (1.0 - alpha) * (1.0 - alpha);
    let mix = |u: f32, v: f32| u + (v - u) * t;
    let (a, b, c, d, e) = (
        mix(21.5473, 25.3245),
        mix(3.82987, 3.32435),
        mix(0.19823, 0.16801),
        mix(-1.97760, -1.27393),
        mix(-4.32054, -4.85967),
    );
    a / (1.0 + b * x.powf(c)) + d * x + e
}

/// Λ(μ) of the sheen's visibility.
#[inline]
pub fn sheen_lambda(alpha: f32, mu: f32) -> f32 {
    let mu = mu.clamp(0.0, 1.0);
    if mu < 0.5 { fit_l(alpha, mu).exp() } else { (2.0 * fit_l(alpha, 0.5) - fit_l(alpha, 1.0 - mu)).exp() }
}

/// f·cos θ_i of the white lobe of α for local directions `wo`, `wi` (z up): D·G₂/(4μo); 0
/// where either lies below the surface.
pub fn sheen_eval(alpha: f32, wo: V3<f32>, wi: V3<f32>) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize();
    let g2 = 1.0 / (1.0 + sheen_lambda(alpha, wo.z) + sheen_lambda(alpha, wi.z));
    charlie_d(alpha, h.z) * g2 / (4.0 * wo.z)
}

/// The white lobe's albedo at sheen roughness `r` and μo = `cos_o`, bilinear in [`TABLE`]
/// (the same operations as `sheen_albedo` in `sheen.wgsl`).
pub fn albedo(r: f32, cos_o: f32) -> f32 {
    let t = table();
    let x = r.clamp(0.0, 1.0).sqrt() * (ROUGHNESS_STEPS - 1) as f32;
    // (√μ: the albedo bends fastest at grazing angles.)
    let y = cos_o.clamp(0.0, 1.0).sqrt() * (COS_STEPS - 1) as f32;
    let x0 = x.floor().min((ROUGHNESS_STEPS - 2) as f32);
    let y0 = y.floor().min((COS_STEPS - 2) as f32);
    let (fx, fy) = (x - x0, y - y0);
    let k = x0 as usize * COS_STEPS + y0 as usize;
    let top = t[k] * (1.0 - fy) + t[k + 1] * fy;
    let bottom = t[k + COS_STEPS] * (1.0 - fy) + t[k + COS_STEPS + 1] * fy;
    top * (1.0 - fx) + bottom * fx
}

/// The albedo of the white lobe at α and μo by the midpoint rule on `nm` × `np` cells of
/// (μi, φ) over the half sphere φ ∈ [0, π] (the lobe is symmetric about wo's plane), in f64.
#[cfg(test)]
fn integrate(alpha: f32, mu: f32, nm: usize, np: usize) -> f64 {
    let wo = V3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mut sum = 0.0f64;
    for i in 0..nm {
        let mu_i = (i as f64 + 0.5) / nm as f64;
        let s = (1.0 - mu_i * mu_i).sqrt();
        for j in 0..np {
            let phi = std::f64::consts::PI * (j as f64 + 0.5) / np as f64;
            let wi = V3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, mu_i as f32);
            // ∫ f cos θ_i dω with dω = dμ dφ.
            sum += sheen_eval(alpha, wo, wi) as f64;
        }
    }
    // Each cell measures (1/nm)·(π/np); the other half of the sphere mirrors this one.
    2.0 * sum * std::f64::consts::PI / (nm * np) as f64
}

/// The table [`TABLE`] stores, computed.
#[cfg(test)]
fn integrate_table() -> Vec<f32> {
    let mut t = Vec::with_capacity(ROUGHNESS_STEPS * COS_STEPS);
    for i in 0..ROUGHNESS_STEPS {
        let q = i as f32 / (ROUGHNESS_STEPS - 1) as f32;
        let alpha = sheen_alpha(q * q);
        for j in 0..COS_STEPS {
            let s = j as f32 / (COS_STEPS - 1) as f32;
            t.push(integrate(alpha, (s * s).max(1e-3), GRID_MU, GRID_PHI) as f32);
        }
    }
    t
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
            "src/render/sheen_albedo.in",
            "E(r, mu) of sheen.rs, written by its test the_stored_table_is_the_integral.",
        );
    }

    /// Entries against a grid four times finer each way, and the interpolation between
    /// entries against the integral at the cells' middles, as a white furnace feels them: the
    /// claims of the header.
    #[test]
    fn the_table_is_as_accurate_as_stated() {
        let mut worst_entry = 0.0f64;
        for (i, j) in [(1usize, 2usize), (3, 31), (8, 5), (15, 0), (15, 31), (5, 16)] {
            let q = i as f32 / (ROUGHNESS_STEPS - 1) as f32;
            let alpha = sheen_alpha(q * q);
            let s = j as f32 / (COS_STEPS - 1) as f32;
            let fine = integrate(alpha, (s * s).max(1e-3), 4 * GRID_MU, 4 * GRID_PHI);
            let e = table()[i * COS_STEPS + j] as f64;
            worst_entry = worst_entry.max((e - fine).abs() / e.max(1.0));
        }
        eprintln!("entries off by at most {worst_entry}");
        assert!(worst_entry < 1e-3, "entries off by {worst_entry}");
        let (mut worst_mid, mut worst_grazing) = (0.0f64, 0.0f64);
        for i in 0..ROUGHNESS_STEPS - 1 {
            for j in (0..COS_STEPS - 1).step_by(3) {
                let q = (i as f32 + 0.5) / (ROUGHNESS_STEPS - 1) as f32;
                let r = q * q;
                let s = (j as f32 + 0.5) / (COS_STEPS - 1) as f32;
                let exact = integrate(sheen_alpha(r), s * s, GRID_MU / 2, GRID_PHI / 2);
                // What the interpolation costs a white furnace: the layer reflects E·n and passes
                // 1 − Ê·n, n = 1/max(Ê, 1) (`layers`).
                let e = albedo(r, s * s) as f64;
                let err = (e - exact).abs() / e.max(1.0);
                if s * s >= 0.01 && r >= 0.05 {
                    worst_mid = worst_mid.max(err);
                } else {
                    worst_grazing = worst_grazing.max(err);
                }
            }
        }
        eprintln!("interpolation off by at most {worst_mid} (μ ≥ 0.01, r ≥ 0.05), {worst_grazing} elsewhere");
        assert!(worst_mid < 6e-3 && worst_grazing < 0.1, "interpolation off by {worst_mid}, {worst_grazing}");
    }

    /// The lobe is reciprocal (f(wo, wi) = f(wi, wo)), and its albedo is positive, and below
    /// 1 from roughness 0.3 up.
    #[test]
    fn the_lobe_is_reciprocal_and_bounded() {
        let mut rng = Sampler::new(3, 1, 4);
        let dir = |rng: &mut Sampler| {
            let z = rng.next_f32().max(1e-3);
            let phi = 2.0 * PI * rng.next_f32();
            let s = (1.0 - z * z).sqrt();
            V3::new(s * phi.cos(), s * phi.sin(), z)
        };
        for _ in 0..5000 {
            let alpha = sheen_alpha(rng.next_f32());
            let (wo, wi) = (dir(&mut rng), dir(&mut rng));
            let f = sheen_eval(alpha, wo, wi) / wi.z;
            let b = sheen_eval(alpha, wi, wo) / wo.z;
            assert!((f - b).abs() <= 1e-5 * f.max(1e-3), "α {alpha}: {f} vs {b}");
        }
        assert!(table().iter().all(|&e| e >= 0.0));
        // Rows from roughness 0.3 up (the axis is √r).
        let from = (0.3f32.sqrt() * (ROUGHNESS_STEPS - 1) as f32).ceil() as usize;
        assert!(table()[from * COS_STEPS..].iter().all(|&e| e < 1.0));
    }
}
