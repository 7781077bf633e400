//! Area-light samples in lanes: [`emitters::sample`] for every lane at once, where the scene's
//! emitters have no emission texture (and no environment light competes): the emitter chosen
//! lane after lane, the point on it and the sample's value in lanes, by its operations.
//! Elsewhere each lane calls [`emitters::sample`] itself.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::environment;
use super::lane::{F, M, U, V};
use crate::layout::{FlatScene, FrameParams, MATERIAL_TWO_SIDED};
use crate::math::V3;
use crate::primitives::{PrimKind, PrimRef};
use crate::render::emitters;

/// The lanes' light samples (valid where `on`).
pub(super) struct Samples<const N: usize> {
    pub on: M<N>,
    pub dir: V<N>,
    pub dist: F<N>,
    pub value: V<N>,
    pub pdf: F<N>,
}

/// Whether [`sample`] computes the lanes' samples itself: no environment light, and no
/// emitter with an emission texture.
pub(super) fn in_lanes(g: &FlatScene) -> bool {
    g.environment.is_empty()
        && g.emitters.iter().all(|e| {
            let r = PrimRef(e.source);
            let material = match r.kind() {
                PrimKind::Triangle => g.triangles[r.index()].material,
                _ => g.spheres[r.index()].material,
            };
            g.materials[material as usize].radiance_texture == 0
        })
}

/// [`emitters::sample`] for shading points `x` with numbers `u`, in the lanes of `want`
/// (`lanes`: computed here, else lane by lane).
#[inline(always)]
pub(super) fn sample<const N: usize>(
    g: &FlatScene,
    f: &FrameParams,
    lanes: bool,
    x: V<N>,
    u: [F<N>; 3],
    want: [bool; N],
) -> Samples<N> {
    let mut out = Samples {
        on: M([0; N]),
        dir: V::splat([0.0; 3]),
        dist: F::splat(0.0),
        value: V::splat([0.0; 3]),
        pdf: F::splat(0.0),
    };
    if !lanes {
        // The environment's samples in lanes where it is a map sampled by importance (the
        // choice between it and the area emitters as emitters::sample makes it); the others
        // lane after lane.
        let env = environment::map(g);
        let mut to_env = [false; N];
        for l in 0..N {
            to_env[l] = want[l] && env.is_some_and(|e| f.num_emitters == 0 || u[0].0[l] < e.select_prob);
        }
        let (xr, mut dir, mut value) = (x.rows(), [[0.0f32; N]; 3], [[0.0f32; N]; 3]);
        let mut on = [false; N];
        for l in 0..N {
            if !want[l] || to_env[l] {
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
        if let Some(e) = env.filter(|_| to_env.contains(&true)) {
            let (env_on, dir, value, pdf) = environment::sample(g, e, u[1], u[2], to_env);
            out.on = out.on | env_on;
            out.dir = env_on.select_v(dir, out.dir);
            out.value = env_on.select_v(value, out.value);
            out.pdf = env_on.select(pdf, out.pdf);
            out.dist = env_on.select(F::splat(f32::MAX), out.dist);
        }
        return out;
    }
    if f.num_emitters == 0 {
        return out;
    }
    // Lane after lane: the emitter (emitters::select), its shape and its material.
    let table = &g.emitters[..f.num_emitters as usize];
    let mut corner = [[0.0f32; N]; 9];
    let mut sphere = [false; N];
    let mut flags = [0u32; N];
    let mut radiance = [[0.0f32; N]; 3];
    for l in 0..N {
        if !want[l] {
            continue;
        }
        let r = PrimRef(table[emitters::select(table, u[0].0[l])].source);
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
    let vertex = |j: usize| V::new(F(corner[3 * j]), F(corner[3 * j + 1]), F(corner[3 * j + 2]));
    // Uniform on a triangle (Turk 1990 / pbrt-v4 A.5.5).
    let (a, b, c) = (vertex(0), vertex(1), vertex(2));
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
    let dir = to.div(dist);
    let cos = -dir.dot(n);
    let one_sided = (U(flags) & U::splat(MATERIAL_TWO_SIDED)).eq(U::splat(0));
    let cos_l = one_sided.select(cos, cos.abs());
    let radiance = V::from_rows(&radiance);
    let mean = (radiance.x + radiance.y + radiance.z) / F::splat(3.0);
    let pdf = mean * F::splat(f.emitter_norm) * d2 / cos_l;
    out.on = M::from_bools(&want) & !(cos_l.le(zero) | d2.le(zero));
    out.dir = dir;
    out.dist = dist;
    out.value = radiance.div(pdf);
    out.pdf = pdf;
    out
}
