//! A χ² goodness-of-fit test of sampled directions against the density they claim to be
//! drawn with, on the whole sphere of directions: the test of Mitsuba's and pbrt's test
//! suites (Wenzel Jakob's `ChiSquareTest` in Mitsuba 0.5 and `mitsuba.chi2` in Mitsuba 3;
//! pbrt-v3's `src/tests/bsdfs.cpp`), as strahl's BSDF tests run it on the CPU and on the GPU.
//!
//! The sphere is cut into [`THETA_CELLS`] × [`PHI_CELLS`] cells in θ (from +z) and φ. A cell's
//! expected count is the density integrated over it by the midpoint rule on
//! [`SUB_THETA`] × [`SUB_PHI`] sub-cells, times the draws; its observed count the samples that
//! fall in it. Cells expecting fewer than [`MIN_EXPECTED`] are pooled into one (the χ²
//! approximation needs about five per cell), and the statistic Σ (o − e)² / e must stay below
//! the 99.9 % quantile of χ² with (cells − 1) degrees of freedom, by the Wilson–Hilferty
//! approximation. Before that, the density must integrate to the share of draws that gave a
//! direction, within 1 % of the draws: a density off by a constant factor passes no χ² test
//! either, but this says so plainly.
//!
//! The density is passed as its values at [`chi2_directions`] (in that order), so that a
//! caller can evaluate all of them at once, e.g. in one GPU dispatch; [`chi2_sphere_fn`]
//! takes a function instead.

use crate::math::V3;
use std::f64::consts::PI;

/// Cells in θ, from +z (θ = 0) to −z (θ = π).
pub const THETA_CELLS: usize = 20;
/// Cells in φ, from the +x axis counter-clockwise about +z.
pub const PHI_CELLS: usize = 40;
/// Sub-cells per cell in θ for the midpoint rule: many, so that a lobe's edge (a grazing
/// transmission's cut-off) does not fall within one midpoint's share.
pub const SUB_THETA: usize = 160;
/// Sub-cells per cell in φ.
pub const SUB_PHI: usize = 8;
/// Cells expecting fewer samples than this are pooled into one.
pub const MIN_EXPECTED: f64 = 5.0;
/// The standard normal quantile of the test's level, 99.9 %.
const Z_999: f64 = 3.09;

/// The figures of a test that passed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chi2 {
    /// Σ (observed − expected)² / expected over the cells (the pooled one included).
    pub statistic: f64,
    /// Degrees of freedom: the cells compared (after pooling) less one.
    pub dof: usize,
    /// The 99.9 % quantile of χ² with `dof` degrees of freedom (Wilson–Hilferty).
    pub limit: f64,
    /// ∫ density dω over the sphere.
    pub integral: f64,
    /// The share of draws that gave a direction.
    pub sampled: f64,
}

/// How many directions [`chi2_directions`] returns: 1,024,000.
pub const fn chi2_direction_count() -> usize {
    THETA_CELLS * SUB_THETA * PHI_CELLS * SUB_PHI
}

/// The midpoint of sub-cell (`i`, `j`) of the θ × φ grid of sub-cells, in f64, and its solid angle.
fn sub_cell(i: usize, j: usize) -> (V3<f64>, f64) {
    let rows = (THETA_CELLS * SUB_THETA) as f64;
    let columns = (PHI_CELLS * SUB_PHI) as f64;
    let (t0, t1) = (PI * i as f64 / rows, PI * (i + 1) as f64 / rows);
    let t = 0.5 * (t0 + t1);
    let p = 2.0 * PI * (j as f64 + 0.5) / columns;
    let area = (t0.cos() - t1.cos()) * 2.0 * PI / columns;
    (V3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()), area)
}

/// The directions at which [`chi2_sphere`] reads the density: the midpoint of every sub-cell,
/// rows of constant θ from +z down, each from φ = 0 round, rounded to f32.
pub fn chi2_directions() -> Vec<V3<f32>> {
    let columns = PHI_CELLS * SUB_PHI;
    (0..THETA_CELLS * SUB_THETA).flat_map(|i| (0..columns).map(move |j| sub_cell(i, j).0.cast::<f32>())).collect()
}

/// The cell of direction `d` (row-major, θ then φ).
fn cell(d: V3<f32>) -> usize {
    let theta = (d.z as f64).clamp(-1.0, 1.0).acos();
    let phi = (d.y as f64).atan2(d.x as f64).rem_euclid(2.0 * PI);
    let i = ((theta / PI * THETA_CELLS as f64) as usize).min(THETA_CELLS - 1);
    let j = ((phi / (2.0 * PI) * PHI_CELLS as f64) as usize).min(PHI_CELLS - 1);
    i * PHI_CELLS + j
}

/// The χ² test of `samples`, the directions that `drawn` draws gave (a draw may give none: an
/// absorbed path), against the density they were drawn with, given as its values `density` at
/// [`chi2_directions`], in order. Ok with the figures where the density integrates to the
/// share of draws that gave a direction (within 1 % of the draws) and the statistic stays
/// below its 99.9 % limit; else Err saying which failed and by how much. Samples that are not
/// finite unit vectors, and densities that are negative or not finite, are errors too.
pub fn chi2_sphere(samples: impl IntoIterator<Item = V3<f32>>, drawn: usize, density: &[f32]) -> Result<Chi2, String> {
    if density.len() != chi2_direction_count() {
        return Err(format!("{} density values for {} directions", density.len(), chi2_direction_count()));
    }
    if drawn == 0 {
        return Err("no draws".into());
    }
    let mut observed = vec![0f64; THETA_CELLS * PHI_CELLS];
    let mut sampled = 0usize;
    for d in samples {
        let unit = (d.length() - 1.0).abs() < 1e-3;
        if !(d.x.is_finite() && d.y.is_finite() && d.z.is_finite() && unit) {
            return Err(format!("sample {sampled} is no unit vector: {d:?}"));
        }
        observed[cell(d)] += 1.0;
        sampled += 1;
    }
    let n = drawn as f64;
    let mut expected = vec![0f64; THETA_CELLS * PHI_CELLS];
    let columns = PHI_CELLS * SUB_PHI;
    for i in 0..THETA_CELLS * SUB_THETA {
        let area = sub_cell(i, 0).1;
        for j in 0..columns {
            let pdf = density[i * columns + j];
            if !(pdf >= 0.0 && pdf.is_finite()) {
                return Err(format!("density {pdf} at {:?}", sub_cell(i, j).0));
            }
            expected[(i / SUB_THETA) * PHI_CELLS + j / SUB_PHI] += pdf as f64 * area * n;
        }
    }
    // The density integrates to the share of draws that gave a direction.
    let total: f64 = expected.iter().sum();
    let (integral, share) = (total / n, sampled as f64 / n);
    if (total - sampled as f64).abs() >= 0.01 * n {
        return Err(format!("∫pdf {integral} vs sampled {share}"));
    }
    let (mut statistic, mut cells, mut pool_o, mut pool_e) = (0.0f64, 0usize, 0.0f64, 0.0f64);
    for (o, e) in observed.iter().zip(&expected) {
        if *e < MIN_EXPECTED {
            pool_o += o;
            pool_e += e;
        } else {
            statistic += (o - e) * (o - e) / e;
            cells += 1;
        }
    }
    // (Samples in cells whose density integrates to 0 count there too.)
    if pool_e > 0.0 || pool_o > 0.0 {
        statistic += (pool_o - pool_e) * (pool_o - pool_e) / pool_e.max(MIN_EXPECTED);
        cells += 1;
    }
    if cells < 2 {
        return Err(format!("only {cells} cells expect {MIN_EXPECTED} samples or more: draw more"));
    }
    let dof = cells - 1;
    let limit = wilson_hilferty(dof as f64, Z_999);
    let figures = Chi2 { statistic, dof, limit, integral, sampled: share };
    if !(statistic < limit) {
        return Err(format!("χ² {statistic:.1} over {dof} degrees of freedom (limit {limit:.1})"));
    }
    Ok(figures)
}

/// [`chi2_sphere`] with the density a function of the direction.
pub fn chi2_sphere_fn(
    samples: impl IntoIterator<Item = V3<f32>>,
    drawn: usize,
    density: impl Fn(V3<f32>) -> f32,
) -> Result<Chi2, String> {
    let values: Vec<f32> = chi2_directions().into_iter().map(density).collect();
    chi2_sphere(samples, drawn, &values)
}

/// The quantile of χ² with `k` degrees of freedom at the standard normal quantile `z`
/// (Wilson & Hilferty 1931: (χ²/k)^(1/3) is nearly normal with mean 1 − 2/(9k) and variance
/// 2/(9k)).
fn wilson_hilferty(k: f64, z: f64) -> f64 {
    let v = 2.0 / (9.0 * k);
    k * (1.0 - v + z * v.sqrt()).powi(3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// Uniform directions over the sphere, `n` draws.
    fn uniform(n: usize, seed: u64) -> Vec<V3<f32>> {
        let mut rng = SplitMix64(seed);
        (0..n).map(|_| rng.direction().cast::<f32>()).collect()
    }

    #[test]
    fn the_grid_covers_the_sphere_once() {
        let dirs = chi2_directions();
        assert_eq!(dirs.len(), chi2_direction_count());
        // The sub-cells' solid angles add up to the sphere's.
        let cols = PHI_CELLS * SUB_PHI;
        let total: f64 = (0..THETA_CELLS * SUB_THETA).map(|i| sub_cell(i, 0).1 * cols as f64).sum();
        assert!((total - 4.0 * PI).abs() < 1e-9, "{total}");
        // Each sub-cell's midpoint lies in the cell it is counted in.
        for (k, d) in dirs.iter().enumerate().step_by(997) {
            let (i, j) = (k / cols, k % cols);
            assert_eq!(cell(*d), (i / SUB_THETA) * PHI_CELLS + j / SUB_PHI, "sub-cell ({i}, {j})");
        }
    }

    #[test]
    fn uniform_samples_pass_against_the_uniform_density() {
        let c = chi2_sphere_fn(uniform(200_000, 5), 200_000, |_| 0.25 / PI as f32).unwrap();
        assert!(c.statistic < c.limit && (c.integral - 1.0).abs() < 1e-6, "{c:?}");
        // With 800 cells, none pooled: 799 degrees of freedom, limit about 925.
        assert_eq!(c.dof, 799);
        assert!((c.limit - 925.0).abs() < 5.0, "{}", c.limit);
    }

    /// The test fails a density that is wrong in shape, in scale, or where samples are missing.
    #[test]
    fn wrong_densities_fail() {
        let samples = uniform(200_000, 6);
        // Cosine-weighted over the upper half, but the samples are uniform over the sphere:
        // the integral is 1 but the shape is wrong.
        let e = chi2_sphere_fn(samples.iter().copied(), 200_000, |d| d.z.max(0.0) / PI as f32).unwrap_err();
        assert!(e.contains("χ²"), "{e}");
        // Half the density.
        let e = chi2_sphere_fn(samples.iter().copied(), 200_000, |_| 0.125 / PI as f32).unwrap_err();
        assert!(e.contains("∫pdf"), "{e}");
        // A tenth of the samples drawn but lost (an absorbed share the density does not know).
        let e = chi2_sphere_fn(samples.iter().copied().take(180_000), 200_000, |_| 0.25 / PI as f32).unwrap_err();
        assert!(e.contains("∫pdf"), "{e}");
        // A bias the integral check cannot see: a tenth of the lower half's directions lost,
        // and the draws counted without them.
        let mut rng = SplitMix64(9);
        let biased: Vec<V3<f32>> = samples.iter().copied().filter(|d| d.z > 0.0 || rng.unit() > 0.1).collect();
        let e = chi2_sphere_fn(biased.iter().copied(), biased.len(), |_| 0.25 / PI as f32).unwrap_err();
        assert!(e.contains("χ²"), "{e}");
        assert!(chi2_sphere([V3::new(f32::NAN, 0.0, 1.0)], 1, &vec![0.0; chi2_direction_count()]).is_err());
    }
}
