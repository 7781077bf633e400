//! Light samples in lanes: [`emitters::sample`] for every lane at once. The choice between
//! the environment and the area emitters is made in lanes; the environment map's samples are
//! drawn in lanes ([`environment::sample`]); where the scene's emitters have no emission
//! texture, the emitter is chosen through its guide table ([`super::guide`]; without one, by
//! halving steps all lanes take together, [`select`]), its shape and material are read lane
//! after lane, and the point on it and the sample's value are computed in lanes, by its
//! operations. Elsewhere each lane calls [`emitters::sample`] itself.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::environment;
use super::guide::Guides;
use super::texels::Texels;
use strahl_core::layout::{FlatEmitter, FlatScene, FrameParams, MATERIAL_TWO_SIDED};
use strahl_core::math::V3;
use strahl_core::math::lanes::{F, M, U, V};
use strahl_core::primitives::{PrimKind, PrimRef};
use strahl_core::render::emitters;

/// The lanes' light samples (valid where `on`).
pub(super) struct Samples<const N: usize> {
    pub on: M<N>,
    pub dir: V<N>,
    pub dist: F<N>,
    pub value: V<N>,
    pub pdf: F<N>,
}

impl<const N: usize> Samples<N> {
    /// No sample in any lane.
    #[inline(always)]
    fn none() -> Self {
        Self {
            on: M([0; N]),
            dir: V::splat([0.0; 3]),
            dist: F::splat(0.0),
            value: V::splat([0.0; 3]),
            pdf: F::splat(0.0),
        }
    }
}

/// Whether [`sample`] computes the area lights' samples itself: no emitter has an emission
/// texture.
pub(super) fn in_lanes(g: &FlatScene) -> bool {
    g.emitters.iter().all(|e| {
        let r = PrimRef(e.source);
        let material = match r.kind() {
            PrimKind::Triangle => g.triangles[r.index()].material,
            _ => g.spheres[r.index()].material,
        };
        g.materials[material as usize].radiance_texture == 0
    })
}

/// What light samples read: the scene and frame, whether its area emitters are sampled in
/// lanes ([`in_lanes`]), and the tables and decoded textures of the searches.
pub(super) struct LightScene<'a> {
    pub g: &'a FlatScene,
    pub f: &'a FrameParams,
    pub in_lanes: bool,
    pub guides: &'a Guides,
    pub texels: &'a Texels,
}

/// [`emitters::sample`] for shading points `x` with numbers `u`, in the lanes of `want`:
/// the choice between the environment and the area emitters as it makes it; the
/// environment's samples in lanes where it is a map sampled by importance; the area
/// emitters' in lanes where `scene.in_lanes`. The others lane after lane.
#[inline(always)]
pub(super) fn sample<const N: usize>(scene: &LightScene, x: V<N>, u: [F<N>; 3], want: [bool; N]) -> Samples<N> {
    let LightScene { g, f, in_lanes: lanes, guides, texels } = *scene;
    let mut out = Samples::none();
    // The lanes that sample the environment, and u[0] rescaled for the others.
    let mut to_env = [false; N];
    let mut u0 = u[0];
    if let Some(e) = g.environment.first() {
        for l in 0..N {
            to_env[l] = want[l] && (f.num_emitters == 0 || u[0].0[l] < e.select_prob);
        }
        u0 = (u[0] - F::splat(e.select_prob)) / F::splat(1.0 - e.select_prob);
    }
    let map = environment::map(g);
    // Lane after lane: the lanes left to the scalar routine (it makes the same choice).
    let (xr, mut dir, mut value) = (x.rows(), [[0.0f32; N]; 3], [[0.0f32; N]; 3]);
    let mut on = [false; N];
    let mut to_area = [false; N];
    for l in 0..N {
        if !want[l] || (to_env[l] && map.is_some()) {
            continue;
        }
        if lanes && !to_env[l] {
            to_area[l] = f.num_emitters > 0;
            continue;
        }
        let p = V3::new(xr[0][l], xr[1][l], xr[2][l]);
        if let Some(ls) = emitters::sample(g, f, p, [u[0].0[l], u[1].0[l], u[2].0[l]]) {
            on[l] = true;
            for a in 0..3 {
                dir[a][l] = ls.dir[a];
                value[a][l] = ls.value[a];
            }
            out.dist.0[l] = ls.dist;
            out.pdf.0[l] = ls.pdf;
        }
    }
    (out.on, out.dir, out.value) = (M::from_bools(&on), V::from_rows(&dir), V::from_rows(&value));
    if let Some(e) = map.filter(|_| to_env.contains(&true)) {
        let (env_on, dir, value, pdf) = environment::sample(g, texels, e, guides, u[1], u[2], to_env);
        out.on = out.on | env_on;
        out.dir = env_on.select_v(dir, out.dir);
        out.value = env_on.select_v(value, out.value);
        out.pdf = env_on.select(pdf, out.pdf);
        out.dist = env_on.select(F::splat(f32::MAX), out.dist);
    }
    if to_area.contains(&true) {
        let area = area(g, f, guides, x, [u0, u[1], u[2]], to_area);
        out.on = out.on | area.on;
        out.dir = area.on.select_v(area.dir, out.dir);
        out.value = area.on.select_v(area.value, out.value);
        out.pdf = area.on.select(area.pdf, out.pdf);
        out.dist = area.on.select(area.dist, out.dist);
    }
    out
}

/// The area emitters' samples of [`emitters::sample`] in the lanes of `want`, `u[0]` already
/// rescaled where an environment competes, for emitters without emission textures.
#[inline(always)]
fn area<const N: usize>(
    g: &FlatScene,
    f: &FrameParams,
    guides: &Guides,
    x: V<N>,
    u: [F<N>; 3],
    want: [bool; N],
) -> Samples<N> {
    let mut out = Samples::none();
    // The emitters (emitters::select, by its guide or every lane halving together); lane
    // after lane, their shapes and materials.
    let table = &g.emitters[..f.num_emitters as usize];
    let chosen = match &guides.emitters {
        Some(guide) if guide.len() + 1 == table.len() => guide.count([0; N], u[0]),
        _ => select(table, u[0]),
    };
    let mut corner = [[0.0f32; N]; 9];
    let mut sphere = [false; N];
    let mut flags = [0u32; N];
    let mut radiance = [[0.0f32; N]; 3];
    for l in 0..N {
        if !want[l] {
            continue;
        }
        let r = PrimRef(table[chosen[l]].source);
        let material = if r.kind() == PrimKind::Triangle {
            let t = &g.triangles[r.index()];
            for (j, c) in t.va.iter().chain(&t.vb).chain(&t.vc).enumerate() {
                corner[j][l] = *c;
            }
            t.material
        } else {
            let s = &g.spheres[r.index()];
            (corner[0][l], corner[1][l], corner[2][l], corner[3][l]) =
                (s.center[0], s.center[1], s.center[2], s.radius);
            sphere[l] = true;
            s.material
        };
        let m = &g.materials[material as usize];
        flags[l] = m.flags;
        for a in 0..3 {
            radiance[a][l] = m.radiance[a];
        }
    }
    let one = F::splat(1.0);
    let zero = F::splat(0.0);
    // Uniform on a triangle (Turk 1990 / pbrt-v4 A.5.5).
    let (a, b, c) = (V::nth(&corner, 0), V::nth(&corner, 1), V::nth(&corner, 2));
    let su = u[1].sqrt();
    let b0 = one - su;
    let (b1, b2) = (u[2] * su, one - b0 - u[2] * su);
    let q_tri = a.scale(b0) + b.scale(b1) + c.scale(b2);
    let (e1, e2) = (b - a, c - a);
    let n_tri = V::new(e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x).normalize();
    // Uniform on a sphere.
    let z = one - F::splat(2.0) * u[1];
    let rad = (one - z * z).max(zero).sqrt();
    let (sin_phi, cos_phi) = u[2].sin_cos_turns();
    let n_sph = V::new(rad * cos_phi, rad * sin_phi, z);
    let q_sph = a + n_sph.scale(F(corner[3]));
    let is_sphere = M::from_bools(&sphere);
    let (q, n) = (is_sphere.select_v(q_sph, q_tri), is_sphere.select_v(n_sph, n_tri));
    // The sample seen from x: direction, distance, the emitter's cosine and the density.
    let to = q - x;
    let d2 = to.dot(to);
    let dist = d2.sqrt();
    let dir = to / dist;
    let cos = -dir.dot(n);
    let one_sided = (U(flags) & U::splat(MATERIAL_TWO_SIDED)).eq(U::splat(0));
    let cos_l = one_sided.select(cos, cos.abs());
    let radiance = V::from_rows(&radiance);
    let mean = (radiance.x + radiance.y + radiance.z) / F::splat(3.0);
    let pdf = mean * F::splat(f.emitter_norm) * d2 / cos_l;
    out.on = M::from_bools(&want) & !(cos_l.le(zero) | d2.le(zero));
    out.dir = dir;
    out.dist = dist;
    out.value = radiance / pdf;
    out.pdf = pdf;
    out
}

/// [`emitters::select`] in every lane: the number of the table's first `len − 1` entries
/// whose cdf u is not below (a prefix, the cdf never falling), which is the first entry whose
/// cdf exceeds u, or the last (for a NaN u, the last, as there). Its halving steps depend on
/// the table's length only, so all lanes take each together and their loads overlap, where one
/// search's would wait on each other. (The choice where the table has no guide.)
#[inline(always)]
fn select<const N: usize>(table: &[FlatEmitter], u: F<N>) -> [usize; N] {
    let mut base = [0usize; N];
    let mut n = table.len() - 1;
    if n == 0 {
        return base;
    }
    while n > 1 {
        let half = n / 2;
        for l in 0..N {
            let m = base[l] + half;
            base[l] = if u.0[l] < table[m].cdf { base[l] } else { m };
        }
        n -= half;
    }
    for l in 0..N {
        base[l] += !(u.0[l] < table[base[l]].cdf) as usize;
    }
    base
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::render::sampler::Sampler;

    /// The lanes' emitter choice, by halving and by the guide, is emitters::select's, for
    /// tables of every length up to 40 (ties of zero-power emitters among them) and numbers on
    /// and between the cdf's steps, below 0, at and above 1, and NaN.
    #[test]
    fn lanes_select_as_emitters_select() {
        let mut rng = Sampler::new(7, 8, 9);
        for len in 1..=40usize {
            let mut cdf = 0.0f32;
            let table: Vec<FlatEmitter> = (0..len)
                .map(|k| {
                    // Every fourth emitter has no power: its cdf repeats the one before.
                    if k % 4 != 3 {
                        cdf += 0.1 + rng.next_f32();
                    }
                    FlatEmitter { cdf, ..Default::default() }
                })
                .collect();
            let total = table[len - 1].cdf;
            let mut table = table;
            for e in &mut table {
                e.cdf /= total;
            }
            let mut us: Vec<f32> = table.iter().map(|e| e.cdf).collect();
            us.extend([0.0, 0.999_999_94, 1.0, -1.0, 1.5, f32::NAN]);
            us.extend((0..64).map(|_| rng.next_f32()));
            let g = FlatScene { emitters: table.clone(), ..FlatScene::default() };
            let guides = Guides::new(&g, None);
            let guide = guides.emitters.as_ref().expect("a guide");
            for chunk in us.chunks(8) {
                let mut u = [0.0f32; 8];
                u[..chunk.len()].copy_from_slice(chunk);
                let halved = select::<8>(&table, F(u));
                let guided = guide.count([0; 8], F(u));
                for l in 0..8 {
                    let want = emitters::select(&table, u[l]);
                    assert_eq!(halved[l], want, "len {len}, u {}", u[l]);
                    assert_eq!(guided[l], want, "len {len}, u {} (guided)", u[l]);
                }
            }
        }
    }
}
