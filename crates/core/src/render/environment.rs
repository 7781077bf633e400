//! Environment lighting (`environment.wgsl` is the twin): the radiance arriving from
//! infinitely far away along a direction (a constant, or an equirectangular map read with
//! [`super::texture::sample`]), next-event estimation's samples of it, their density for
//! multiple importance sampling, and Whitted's unshadowed diffuse light from it.
//!
//! **The map.** Equirectangular, +y up: texel column u ∈ [0, 1) is the azimuth
//! φ = 2π(u − ½) measured from +z towards +x, row v ∈ [0, 1] the polar angle θ = πv from +y.
//! The map's centre is seen looking along +z, its right half towards +x (on the right of
//! strahl's screen), so it is not mirrored. `rotation` turns it about +y (90: the centre
//! along +x).
//!
//! **Sampling.** The map's texels define a piecewise-constant density over (u, v), each texel
//! weighted by the mean luminance the bilinear lookups give over its cell (its neighbours blend
//! into it, so no direction whose radiance is non-zero gets density 0) times sin θ of its row
//! (the area of its patch of sphere). A row is chosen by inverting the marginal
//! cumulative distribution, then a column by inverting the row's (pbrt-v4's
//! `PiecewiseConstant2D`); the density of a direction is p(u, v) / (2π² sin θ). A constant sky,
//! or [`crate::scene::EnvSampling::Uniform`], is sampled uniformly over the sphere (1/4π).
//!
//! **Whitted** has no Monte Carlo: a diffuse surface gets the environment's irradiance about
//! its normal without shadows, from its projection onto the first 9 spherical harmonics
//! (Ramamoorthi & Hanrahan, "An Efficient Representation for Irradiance Environment Maps",
//! SIGGRAPH 2001): exact for a constant sky, within a few per cent for smooth maps, and ringing
//! (clamped at 0) around a small bright sun.

use super::texture;
use crate::layout::{ENV_MAP, ENV_UNIFORM, FlatEnvironment, FlatScene, FrameParams};
use crate::math::{Real, V3};
use crate::scene::{EnvSampling, Environment, texture::Texels};

const PI: f32 = std::f32::consts::PI;

/// Probability that next-event estimation samples the environment when the scene also has
/// area emitters.
pub const SELECT_WITH_EMITTERS: f32 = 0.5;

/// Real spherical harmonics up to l = 2 at unit direction d (the constants of Ramamoorthi &
/// Hanrahan, eq. 3): in f64 for the projection, in f32 for the lookup the GPU twins.
fn sh9<R: Real>(d: [R; 3]) -> [R; 9] {
    let [x, y, z] = d;
    let k = R::from_f64;
    [
        k(0.282095),
        k(0.488603) * y,
        k(0.488603) * z,
        k(0.488603) * x,
        k(1.092548) * x * y,
        k(1.092548) * y * z,
        k(0.315392) * (k(3.0) * z * z - R::ONE),
        k(1.092548) * x * z,
        k(0.546274) * (x * x - y * y),
    ]
}

/// The map's direction (map frame) of texel-space point (u, v).
fn map_direction(u: f64, v: f64) -> [f64; 3] {
    let (phi, theta) = (2.0 * std::f64::consts::PI * (u - 0.5), std::f64::consts::PI * v);
    [theta.sin() * phi.sin(), theta.cos(), theta.sin() * phi.cos()]
}

fn luminance(c: [f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Appends the running sums `sums` (n + 1 of them, from 0 to the total) divided by their total,
/// the last exactly 1; a table that sums to nothing as the uniform one, k/n.
fn push_cdf(distribution: &mut Vec<f32>, sums: &[f64]) {
    let n = sums.len() - 1;
    let total = sums[n];
    for (k, &m) in sums.iter().enumerate() {
        distribution.push(if total > 0.0 {
            if k == n { 1.0 } else { (m / total) as f32 }
        } else {
            k as f32 / n as f32
        });
    }
}

/// The GPU's record of `env` (its map, if any, being texture `texture`) and the map's sampling
/// distribution: the marginal cumulative distribution over rows (height + 1 values), then
/// each row's over columns (width + 1 values each). `emitters`: the scene also has area
/// emitters, which next-event estimation then chooses with probability 1 − `select`.
pub fn build(env: &Environment, texture: u32, emitters: bool) -> (FlatEnvironment, Vec<f32>) {
    let s = env.strength;
    let (sin, cos) = env.rotation_deg.to_radians().sin_cos();
    let mut g = FlatEnvironment {
        radiance: env.radiance.map(|c| (c * s) as f32),
        flags: 0,
        rot_cos: cos as f32,
        rot_sin: sin as f32,
        texture,
        select_prob: if emitters { SELECT_WITH_EMITTERS } else { 1.0 },
        ..Default::default()
    };
    // Projection onto the spherical harmonics, in the map's frame.
    let mut coeff = [[0.0f64; 3]; 9];
    let mut distribution = Vec::new();
    match &env.map {
        None => {
            g.flags |= ENV_UNIFORM;
            // ∫ L Y₀₀ dω = L √(4π); the other coefficients vanish.
            for (c, l) in coeff[0].iter_mut().zip(env.radiance) {
                *c = l * s * (4.0 * std::f64::consts::PI).sqrt();
            }
        }
        Some(map) => {
            g.flags |= ENV_MAP;
            if env.sampling == EnvSampling::Uniform {
                g.flags |= ENV_UNIFORM;
            }
            let (w, h) = (map.width as usize, map.height as usize);
            (g.width, g.height) = (map.width, map.height);
            let texels = match &*map.texels {
                Texels::Linear(t) => t,
                Texels::Rgba8(_) => unreachable!("environment maps are decoded as linear radiance"),
            };
            let d_omega = |j: usize| {
                let theta = std::f64::consts::PI * (j as f64 + 0.5) / h as f64;
                (2.0 * std::f64::consts::PI / w as f64) * (std::f64::consts::PI / h as f64) * theta.sin()
            };
            for j in 0..h {
                for i in 0..w {
                    let d = map_direction((i as f64 + 0.5) / w as f64, (j as f64 + 0.5) / h as f64);
                    let y = sh9(d);
                    let l = texels[j * w + i];
                    for k in 0..9 {
                        for c in 0..3 {
                            coeff[k][c] += l[c] as f64 * s * y[k] * d_omega(j);
                        }
                    }
                }
            }
            // Weights: the mean over each texel's cell of the bilinear reconstruction of the
            // luminance, which is the luminance filtered by [1/8, 3/4, 1/8] along each axis
            // (columns wrap, rows clamp as the lookups do), times the row's sin θ. A cell the
            // reconstruction lights at all gets a weight > 0.
            let lum: Vec<f64> = texels.iter().map(|&t| luminance(t)).collect();
            let filter = [(-1i64, 0.125), (0, 0.75), (1, 0.125)];
            let mut across = vec![0.0f64; w * h];
            for j in 0..h {
                for i in 0..w {
                    across[j * w + i] = filter
                        .iter()
                        .map(|&(d, k)| k * lum[j * w + (i as i64 + d).rem_euclid(w as i64) as usize])
                        .sum();
                }
            }
            let mut marginal = vec![0.0f64; h + 1];
            let mut rows = vec![0.0f64; h * (w + 1)];
            for j in 0..h {
                let sin_theta = (std::f64::consts::PI * (j as f64 + 0.5) / h as f64).sin();
                let row = &mut rows[j * (w + 1)..(j + 1) * (w + 1)];
                for i in 0..w {
                    let m: f64 = filter
                        .iter()
                        .map(|&(d, k)| k * across[(j as i64 + d).clamp(0, h as i64 - 1) as usize * w + i])
                        .sum();
                    row[i + 1] = row[i] + m * sin_theta;
                }
                marginal[j + 1] = marginal[j] + row[w];
            }
            distribution = Vec::with_capacity(h + 1 + h * (w + 1));
            let total = marginal[h];
            push_cdf(&mut distribution, &marginal);
            for j in 0..h {
                push_cdf(&mut distribution, &rows[j * (w + 1)..(j + 1) * (w + 1)]);
            }
            if total <= 0.0 {
                // A black map: nothing to sample by importance.
                g.flags |= ENV_UNIFORM;
            }
        }
    }
    // Diffuse radiance = albedo · E(n)/π with E = Σ Âₗ Lₗₘ Yₗₘ(n), Â = (π, 2π/3, π/4).
    let a_hat = [1.0, 2.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0, 0.25, 0.25, 0.25, 0.25, 0.25];
    for k in 0..9 {
        g.sh[k] = [coeff[k][0] * a_hat[k], coeff[k][1] * a_hat[k], coeff[k][2] * a_hat[k], 0.0].map(|c| c as f32);
    }
    (g, distribution)
}

/// `d` turned from the world into the map's frame (the inverse of `rotation`).
#[inline]
fn to_map(e: &FlatEnvironment, d: V3<f32>) -> V3<f32> {
    V3::new(e.rot_cos * d.x - e.rot_sin * d.z, d.y, e.rot_sin * d.x + e.rot_cos * d.z)
}

/// `d` turned from the map's frame into the world.
#[inline]
fn from_map(e: &FlatEnvironment, d: V3<f32>) -> V3<f32> {
    V3::new(e.rot_cos * d.x + e.rot_sin * d.z, d.y, -e.rot_sin * d.x + e.rot_cos * d.z)
}

/// Map coordinates (u, v) of the world direction `d` (unit).
#[inline]
fn map_uv(e: &FlatEnvironment, d: V3<f32>) -> (f32, f32) {
    let m = to_map(e, d);
    (0.5 + crate::math::atan2(m.x, m.z) * (0.5 / PI), crate::math::acos(m.y) * (1.0 / PI))
}

/// Radiance arriving along `-d` from the environment, i.e. seen by a ray leaving in direction
/// `d`; without an environment the frame's constant background.
pub fn background(g: &FlatScene, f: &FrameParams, d: V3<f32>) -> V3<f32> {
    let Some(e) = g.environment.first() else {
        return V3::from_array(f.background);
    };
    let l = V3::from_array(e.radiance);
    if e.flags & ENV_MAP == 0 {
        return l;
    }
    let (u, v) = map_uv(e, d);
    l.mul_elem(texture::sample(&g.texels, &g.textures[e.texture as usize], u, v))
}

/// First index k in 0..n with u < cdf[k + 1] (cdf[0] ≤ u < cdf[n] = 1): the cell `u` selects.
#[inline]
fn find_cell(cdf: &[f32], u: f32) -> usize {
    // Halving without branches on u (the lane tracer steps all its lanes at once the same
    // way): the cells lo .. lo + n hold the answer; the upper half does where u reaches its
    // lower edge cdf[lo + half].
    let (mut lo, mut n) = (0usize, cdf.len() - 1);
    while n > 1 {
        let half = n / 2;
        lo = if u < cdf[lo + half] { lo } else { lo + half };
        n -= half;
    }
    lo
}

/// Density of the map's distribution at cell (i, j), over (u, v) ∈ [0, 1]².
#[inline(always)]
pub fn cell_pdf(g: &FlatScene, e: &FlatEnvironment, i: usize, j: usize) -> f32 {
    let (w, h) = (e.width as usize, e.height as usize);
    let marginal = &g.env_distribution[..h + 1];
    let row = &g.env_distribution[h + 1 + j * (w + 1)..h + 1 + (j + 1) * (w + 1)];
    (row[i + 1] - row[i]) * w as f32 * ((marginal[j + 1] - marginal[j]) * h as f32)
}

/// Solid-angle density with which next-event estimation picks direction `d` towards the
/// environment (the choice between it and the area emitters included); 0 without one.
pub fn pdf(g: &FlatScene, d: V3<f32>) -> f32 {
    let Some(e) = g.environment.first() else {
        return 0.0;
    };
    if e.flags & ENV_UNIFORM != 0 {
        return e.select_prob * (0.25 / PI);
    }
    let (u, v) = map_uv(e, d);
    let i = ((u * e.width as f32) as usize).min(e.width as usize - 1);
    let j = ((v * e.height as f32) as usize).min(e.height as usize - 1);
    // sin θ as the length of the direction's horizontal part: exact near the poles, where
    // √(1 − y²) loses its digits.
    let m = to_map(e, d);
    let sin_theta = (m.x * m.x + m.z * m.z).sqrt();
    if sin_theta <= 0.0 {
        return 0.0;
    }
    e.select_prob * cell_pdf(g, e, i, j) / (2.0 * PI * PI * sin_theta)
}

/// A direction towards the environment from two uniform numbers, with the radiance along it
/// divided by its density, and that density ([`pdf`]); None where the density is 0.
pub fn sample(g: &FlatScene, f: &FrameParams, u1: f32, u2: f32) -> Option<(V3<f32>, V3<f32>, f32)> {
    let e = g.environment.first()?;
    let (d, pdf) = if e.flags & ENV_UNIFORM != 0 {
        let z = 1.0 - 2.0 * u1;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * PI * u2;
        (V3::new(r * phi.cos(), r * phi.sin(), z), e.select_prob * (0.25 / PI))
    } else {
        let (w, h) = (e.width as usize, e.height as usize);
        let marginal = &g.env_distribution[..h + 1];
        let j = find_cell(marginal, u1);
        let dv = (u1 - marginal[j]) / (marginal[j + 1] - marginal[j]);
        let row = &g.env_distribution[h + 1 + j * (w + 1)..h + 1 + (j + 1) * (w + 1)];
        let i = find_cell(row, u2);
        let du = (u2 - row[i]) / (row[i + 1] - row[i]);
        let u = (i as f32 + du) / w as f32;
        let v = (j as f32 + dv) / h as f32;
        // θ = πv and φ = 2π(u − 1/2): sin φ = −sin 2πu, cos φ = −cos 2πu.
        let (sin_theta, cos_theta) = crate::math::sin_cos_turns(0.5 * v);
        let (sin_u, cos_u) = crate::math::sin_cos_turns(u);
        if sin_theta <= 0.0 {
            return None;
        }
        let m = V3::new(sin_theta * -sin_u, cos_theta, sin_theta * -cos_u);
        (from_map(e, m), e.select_prob * cell_pdf(g, e, i, j) / (2.0 * PI * PI * sin_theta))
    };
    if !(pdf > 0.0) {
        return None;
    }
    Some((d, background(g, f, d) / pdf, pdf))
}

/// Whitted's diffuse light from the environment at a surface of normal `n` (unit): its
/// irradiance about n over π, from the spherical-harmonic projection, not shadowed; 0 without
/// an environment.
pub fn diffuse(g: &FlatScene, n: V3<f32>) -> V3<f32> {
    let Some(e) = g.environment.first() else {
        return V3::zero();
    };
    let m = to_map(e, n);
    let basis = sh9([m.x, m.y, m.z]);
    let mut sum = V3::zero();
    for (c, b) in e.sh.iter().zip(basis) {
        sum += V3::new(c[0], c[1], c[2]) * b;
    }
    V3::new(sum.x.max(0.0), sum.y.max(0.0), sum.z.max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;
    use crate::scene::texture::{Texture, Wrap};

    fn scene_with(env: Environment) -> FlatScene {
        let mut g = FlatScene::default();
        let map = env.map.as_ref();
        if let Some(m) = map {
            (g.textures, g.texels) = texture::pack(std::iter::once(m));
        }
        let (e, d) = build(&env, 0, false);
        g.environment = vec![e];
        g.env_distribution = d;
        g
    }

    fn map(w: u32, h: u32, f: impl Fn(u32, u32) -> f32) -> Environment {
        let texels = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| [f(x, y); 3]).collect();
        let t = Texture { wrap: [Wrap::Repeat, Wrap::Clamp], ..Texture::new("m", w, h, Texels::Linear(texels)) };
        Environment { map: Some(t), ..Environment::constant([1.0; 3]) }
    }

    /// A constant sky's irradiance over π is its radiance, whatever the normal.
    #[test]
    fn constant_sky_diffuse_light_is_its_radiance() {
        let g = scene_with(Environment::constant([0.5, 1.0, 2.0]));
        for n in [V3::new(0.0, 1.0, 0.0f32), V3::new(0.6, 0.0, -0.8), V3::new(0.0, 0.0, -1.0)] {
            let d = diffuse(&g, n);
            assert!((d - V3::new(0.5, 1.0, 2.0)).length() < 1e-5, "{n:?}: {d:?}");
        }
        // A uniform map of radiance 1 projects to the same (up to the quadrature).
        let g = scene_with(map(64, 32, |_, _| 1.0));
        let d = diffuse(&g, V3::new(0.0, 1.0, 0.0));
        assert!((d.x - 1.0).abs() < 1e-3, "{d:?}");
    }

    /// The map is not mirrored: its right half (u > ½) is seen towards +x, its top row up.
    #[test]
    fn map_orientation() {
        // 8 × 8 texels: the top two rows 10, the others their column number.
        let texels = |x: u32, y: u32| if y < 2 { 10.0 } else { x as f32 };
        let g = scene_with(map(8, 8, texels));
        let f = FrameParams::default();
        assert_eq!(background(&g, &f, V3::new(0.0, 1.0, 0.0)).x, 10.0);
        // Along +x: u = 0.75, between the centres of columns 5 and 6; along −x: u = 0.25,
        // between 1 and 2; along +z, the middle.
        let at = |g: &FlatScene, d: V3<f32>| background(g, &f, d.normalize()).x;
        assert!((at(&g, V3::new(1.0, -0.1, 0.0)) - 5.5).abs() < 1e-4);
        assert!((at(&g, V3::new(-1.0, -0.1, 0.0)) - 1.5).abs() < 1e-4);
        assert!((at(&g, V3::new(0.0, -0.1, 1.0)) - 3.5).abs() < 1e-4);
        // Rotated by 90°, the map's middle lies along +x.
        let mut env = map(8, 8, texels);
        env.rotation_deg = 90.0;
        let g = scene_with(env);
        assert!((at(&g, V3::new(1.0, -0.1, 0.0)) - 3.5).abs() < 1e-4);
    }

    /// Sampled directions have the density pdf() reports, and radiance / pdf averages to the
    /// integral of the radiance over the sphere.
    #[test]
    fn sampling_density_matches_pdf_and_integrates_the_map() {
        // A dim sky with a bright 2 × 1 patch.
        let env = map(32, 16, |x, y| if (x == 20 || x == 21) && y == 5 { 500.0 } else { 0.5 });
        let g = scene_with(env.clone());
        let f = FrameParams::default();
        let mut rng = Sampler::new(3, 4, 5);
        let n = 200_000;
        let mut sum = 0.0f64;
        let mut differ = 0;
        for _ in 0..n {
            let (d, value, p) = sample(&g, &f, rng.next_f32(), rng.next_f32()).unwrap();
            // A direction on a cell boundary may be looked up in the neighbouring cell.
            differ += ((p - pdf(&g, d)).abs() > 1e-3 * p) as usize;
            sum += value.x as f64;
        }
        assert!(differ <= n / 10_000, "{differ} of {n} samples have another density than pdf() gives");
        // The integral by quadrature over a fine grid of directions, with bilinear lookups.
        let mut exact = 0.0f64;
        let (gw, gh) = (512, 256);
        for j in 0..gh {
            let theta = std::f64::consts::PI * (j as f64 + 0.5) / gh as f64;
            for i in 0..gw {
                let d = map_direction((i as f64 + 0.5) / gw as f64, (j as f64 + 0.5) / gh as f64);
                let l = background(&g, &f, V3::new(d[0] as f32, d[1] as f32, d[2] as f32)).x as f64;
                exact +=
                    l * theta.sin() * (2.0 * std::f64::consts::PI / gw as f64) * (std::f64::consts::PI / gh as f64);
            }
        }
        let est = sum / n as f64;
        assert!((est - exact).abs() < 0.01 * exact, "importance-sampled integral {est} vs {exact}");
    }
}
