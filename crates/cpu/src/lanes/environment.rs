//! The environment map in lanes: `background`, `pdf` and `sample` of
//! [`strahl_core::render::environment`] for a map sampled by importance, by their operations in their
//! order, so every lane computes what the scalar routines compute, bit for bit. The texels are
//! fetched lane after lane; the rest runs over the lanes: the distributions' searches (through
//! their guide tables, [`super::guide`], or by halving, a step of all lanes at a time) and the
//! angles' sines, cosines and arc tangents ([`strahl_core::math::sin_cos_turns`],
//! [`strahl_core::math::atan2`], [`strahl_core::math::acos`]). A constant sky, or a map sampled uniformly,
//! is left to the scalar routines.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::guide::Guides;
use super::surface::{sample_one, sample_rgba};
use super::texels::Texels;
use strahl_core::layout::{ENV_MAP, ENV_UNIFORM, FlatEnvironment, FlatScene, TEXTURE_NEAREST};
use strahl_core::math::lanes::{F, M, V};
use strahl_core::render::environment::cell_pdf;
const PI: f32 = std::f32::consts::PI;

/// The scene's environment where the lanes evaluate it: a map sampled by importance.
pub(super) fn map(g: &FlatScene) -> Option<&FlatEnvironment> {
    g.environment.first().filter(|e| {
        e.flags & ENV_MAP != 0
            && e.flags & ENV_UNIFORM == 0
            && g.textures[e.texture as usize].flags & TEXTURE_NEAREST == 0
    })
}

/// `environment::to_map`.
#[inline(always)]
fn to_map<const N: usize>(e: &FlatEnvironment, d: V<N>) -> V<N> {
    let (c, s) = (F::splat(e.rot_cos), F::splat(e.rot_sin));
    V::new(c * d.x - s * d.z, d.y, s * d.x + c * d.z)
}

/// `environment::from_map`.
#[inline(always)]
fn from_map<const N: usize>(e: &FlatEnvironment, d: V<N>) -> V<N> {
    let (c, s) = (F::splat(e.rot_cos), F::splat(e.rot_sin));
    V::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
}

/// `environment::map_uv`.
#[inline(always)]
fn map_uv<const N: usize>(e: &FlatEnvironment, d: V<N>) -> (F<N>, F<N>) {
    let m = to_map(e, d);
    (F::splat(0.5) + m.x.atan2(m.z) * F::splat(0.5 / PI), m.y.acos() * F::splat(1.0 / PI))
}

/// `environment::background` of map `e` along `d`, in the lanes `on`.
#[inline(always)]
pub(super) fn radiance<const N: usize>(
    g: &FlatScene,
    texels: &Texels,
    e: &FlatEnvironment,
    d: V<N>,
    on: [bool; N],
) -> V<N> {
    let (u, v) = map_uv(e, d);
    at_uv(g, texels, e, u, v, on)
}

/// The map's radiance at (u, v), in the lanes `on`.
#[inline(always)]
fn at_uv<const N: usize>(g: &FlatScene, texels: &Texels, e: &FlatEnvironment, u: F<N>, v: F<N>, on: [bool; N]) -> V<N> {
    let c = match texels.get(e.texture as usize) {
        Some(rgba) => sample_one(&g.textures[e.texture as usize], rgba, M::from_bools(&on), u, v),
        None => sample_rgba(g, texels, on.map(|o| o.then_some(e.texture)), u, v),
    };
    V::splat(e.radiance).mul_elem(V::new(c[0], c[1], c[2]))
}

/// The density over the sphere of cells of density `p` over (u, v) (`environment::cell_pdf`)
/// at sin θ = `sin_theta` (0 where that is not positive).
#[inline(always)]
fn density<const N: usize>(e: &FlatEnvironment, p: F<N>, sin_theta: F<N>) -> F<N> {
    let pdf = F::splat(e.select_prob) * p / (F::splat(2.0 * PI * PI) * sin_theta);
    sin_theta.le(F::splat(0.0)).select(F::splat(0.0), pdf)
}

/// `environment::background` and `environment::pdf` of map `e` along `d`, in the lanes `on`
/// (the map coordinates computed once).
#[inline(always)]
pub(super) fn radiance_and_pdf<const N: usize>(
    g: &FlatScene,
    texels: &Texels,
    guides: &Guides,
    e: &FlatEnvironment,
    d: V<N>,
    on: [bool; N],
) -> (V<N>, F<N>) {
    let (u, v) = map_uv(e, d);
    (at_uv(g, texels, e, u, v, on), pdf_at(g, e, guides, d, u, v, on))
}

/// `environment::pdf` of map `e` along `d`, at its map coordinates (u, v), in the lanes `on`.
#[inline(always)]
fn pdf_at<const N: usize>(
    g: &FlatScene,
    e: &FlatEnvironment,
    guides: &Guides,
    d: V<N>,
    u: F<N>,
    v: F<N>,
    on: [bool; N],
) -> F<N> {
    let mut p = [0.0f32; N];
    let table = &guides.env_pdf;
    for l in 0..N {
        if !on[l] {
            continue;
        }
        let i = ((u.0[l] * e.width as f32) as usize).min(e.width as usize - 1);
        let j = ((v.0[l] * e.height as f32) as usize).min(e.height as usize - 1);
        p[l] = if table.is_empty() { cell_pdf(g, e, i, j) } else { table[j * e.width as usize + i] };
    }
    let m = to_map(e, d);
    let sin_theta = (m.x * m.x + m.z * m.z).sqrt();
    density(e, F(p), sin_theta)
}

/// `environment::find_cell` in every lane, in the distribution of `len` edges at
/// `table[base[l]..]` for lane l: its halving steps, each taken by all lanes together.
#[inline(always)]
fn find_cells<const N: usize>(table: &[f32], base: [usize; N], len: usize, u: F<N>) -> [usize; N] {
    let (mut lo, mut n) = ([0usize; N], len - 1);
    while n > 1 {
        let half = n / 2;
        for l in 0..N {
            let m = lo[l] + half;
            lo[l] = if u.0[l] < table[base[l] + m] { lo[l] } else { m };
        }
        n -= half;
    }
    lo
}

/// `environment::sample` of map `e` from numbers `u1`, `u2` in the lanes of `want`: the lanes
/// with a sample, its direction, its radiance over its density, and its density.
#[inline(always)]
pub(super) fn sample<const N: usize>(
    g: &FlatScene,
    texels: &Texels,
    e: &FlatEnvironment,
    guides: &Guides,
    u1: F<N>,
    u2: F<N>,
    want: [bool; N],
) -> (M<N>, V<N>, V<N>, F<N>) {
    let (w, h) = (e.width as usize, e.height as usize);
    let marginal = &g.env_distribution[..h + 1];
    // The row, then the column, by their guides or the distributions' halving, every lane at
    // once (each lane's search in range whatever its number).
    let (js, is, base);
    match &guides.env {
        Some((rows, columns)) if rows.len() + 1 == h && columns.len() + 1 == w => {
            js = rows.count([0; N], u1);
            is = columns.count(js, u2);
            base = js.map(|j| h + 1 + j * (w + 1));
        }
        _ => {
            js = find_cells(&g.env_distribution, [0; N], h + 1, u1);
            base = js.map(|j| h + 1 + j * (w + 1));
            is = find_cells(&g.env_distribution, base, w + 1, u2);
        }
    }
    let (mut ij, mut lo, mut width) = ([[0.0f32; N]; 2], [[0.0f32; N]; 2], [[1.0f32; N]; 2]);
    let mut p = [0.0f32; N];
    for l in 0..N {
        if !want[l] {
            continue;
        }
        let (i, j) = (is[l], js[l]);
        let row = &g.env_distribution[base[l]..base[l] + w + 1];
        (ij[0][l], ij[1][l]) = (i as f32, j as f32);
        (lo[0][l], lo[1][l]) = (row[i], marginal[j]);
        (width[0][l], width[1][l]) = (row[i + 1] - row[i], marginal[j + 1] - marginal[j]);
        p[l] = if guides.env_pdf.is_empty() { cell_pdf(g, e, i, j) } else { guides.env_pdf[j * w + i] };
    }
    let dv = (u1 - F(lo[1])) / F(width[1]);
    let du = (u2 - F(lo[0])) / F(width[0]);
    let u = (F(ij[0]) + du) / F::splat(w as f32);
    let v = (F(ij[1]) + dv) / F::splat(h as f32);
    let (sin_theta, cos_theta) = (F::splat(0.5) * v).sin_cos_turns();
    let (sin_u, cos_u) = u.sin_cos_turns();
    let m = V::new(sin_theta * -sin_u, cos_theta, sin_theta * -cos_u);
    let dir = from_map(e, m);
    let pdf = density(e, F(p), sin_theta);
    let on = M::from_bools(&want) & !sin_theta.le(F::splat(0.0)) & pdf.gt(F::splat(0.0));
    let value = radiance(g, texels, e, dir, want) / pdf;
    (on, dir, value, pdf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::layout::FrameParams;
    use strahl_core::math::V3;
    use strahl_core::render::sampler::Sampler;
    use strahl_core::render::{environment, texture};
    use strahl_core::scene::texture::{Texels as Image, Texture, Wrap};
    use strahl_core::scene::{EnvSampling, Environment};

    const N: usize = 16;

    fn lane(x: V<N>, l: usize) -> [u32; 3] {
        [x.x.0[l].to_bits(), x.y.0[l].to_bits(), x.z.0[l].to_bits()]
    }

    /// Samples, densities and radiance in lanes equal the scalar routines' bit for bit, for a
    /// rotated map with a bright patch, at random numbers and random directions (poles
    /// included).
    #[test]
    fn lanes_equal_the_scalar_environment() {
        let (w, h) = (32u32, 16u32);
        let texels = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| if (x == 20 || x == 21) && y == 5 { [500.0, 400.0, 300.0] } else { [0.5, 0.6, 0.9] })
            .collect();
        let t = Texture { wrap: [Wrap::Repeat, Wrap::Clamp], ..Texture::new("m", w, h, Image::Linear(texels)) };
        let env = Environment {
            map: Some(t),
            rotation_deg: 30.0,
            sampling: EnvSampling::Importance,
            ..Environment::constant([1.0; 3])
        };
        let mut g = FlatScene::default();
        (g.textures, g.texels) = texture::pack(std::iter::once(env.map.as_ref().unwrap()));
        let (e, d) = environment::build(&env, 0, true);
        g.environment = vec![e];
        g.env_distribution = d;
        let e = map(&g).expect("a map sampled by importance");
        // Every other round by the guides and the cells' densities computed ahead, the others
        // by the halving searches and the densities computed where needed; one round in three
        // reads the map's packed texels, the others its decoded copy.
        let (guided, unguided) = (Guides::new(&g, Some(e)), Guides::default());
        let (decoded, packed) =
            (Texels::new(&g, [e.texture as usize], super::super::texels::BUDGET), Texels::default());
        assert!(decoded.get(e.texture as usize).is_some());
        assert!(guided.env.is_some());
        assert_eq!(guided.env_pdf.len(), (w * h) as usize);
        let f = FrameParams::default();
        let mut rng = Sampler::new(1, 2, 3);
        let mut sampled = 0;
        for round in 0..500 {
            let u1 = F(std::array::from_fn(|_| rng.next_f32()));
            let u2 = F(std::array::from_fn(|_| rng.next_f32()));
            let want: [bool; N] = std::array::from_fn(|l| (l + round) % 5 != 0);
            let guides = if round % 2 == 0 { &guided } else { &unguided };
            let tx = if round % 3 == 0 { &packed } else { &decoded };
            let (on, dir, value, p) = sample(&g, tx, e, guides, u1, u2, want);
            for l in 0..N {
                let s = environment::sample(&g, &f, u1.0[l], u2.0[l]).filter(|_| want[l]);
                let got = on.lane(l).then(|| (lane(dir, l), lane(value, l), p.0[l].to_bits()));
                let want =
                    s.map(|(d, v, p)| (d.to_array().map(f32::to_bits), v.to_array().map(f32::to_bits), p.to_bits()));
                assert_eq!(got, want, "lane {l}: sample");
                sampled += got.is_some() as usize;
            }
            let d: [V3<f32>; N] = std::array::from_fn(|l| match (round, l) {
                (0, 0) => V3::new(0.0, 1.0, 0.0),
                (0, 1) => V3::new(0.0, -1.0, 0.0),
                _ => {
                    let z = 1.0 - 2.0 * rng.next_f32();
                    let phi = 2.0 * PI * rng.next_f32();
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    V3::new(r * phi.cos(), z, r * phi.sin())
                }
            });
            let vd = V::new(F(d.map(|v| v.x)), F(d.map(|v| v.y)), F(d.map(|v| v.z)));
            let (r, p) = radiance_and_pdf(&g, tx, guides, e, vd, [true; N]);
            assert_eq!(
                radiance(&g, tx, e, vd, [true; N]).rows().map(|a| a.map(f32::to_bits)),
                r.rows().map(|a| a.map(f32::to_bits))
            );
            for l in 0..N {
                assert_eq!(
                    lane(r, l),
                    environment::background(&g, &f, d[l]).to_array().map(f32::to_bits),
                    "{:?}",
                    d[l]
                );
                assert_eq!(p.0[l].to_bits(), environment::pdf(&g, d[l]).to_bits(), "{:?}", d[l]);
            }
        }
        assert!(sampled > 500 * N * 3 / 4, "{sampled} samples");
    }
}
