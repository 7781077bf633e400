//! A bundle's vertices shaded lane by lane: [`crate::path::shade_vertex`] over SIMD lanes.
//!
//! The common vertices (a diffuse, emissive, smooth or rough mirror, glass or
//! metallic-roughness surface, with colour and metallic-roughness textures read bilinearly
//! and vertex normals, or the background or environment map, in a scene without point and
//! directional lights) are shaded by loops over the lanes, which the compiler turns into
//! vector instructions; each loop calls the one-path tracer's own routines ([`spawn_origin`],
//! [`power_heuristic`], [`surface::shading_frame`], ...) or performs its operations in the
//! same order ([`pbr`], `lanes::surface`, [`lane_env`]), so every lane computes what
//! [`crate::path::shade_vertex`] computes, bit for bit. Steps that do not vectorise (choosing a
//! light, fetching texels) run lane after lane between the loops. Every other vertex is
//! shaded by [`crate::path::shade_vertex`] itself.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::emitters as lights;
use super::environment as lane_env;
use super::facts::{Facts, Kind};
use super::paths::Paths;
use super::pbr;
use super::vertex::{self, Bundle, Gathered, Out, Vertex};
use crate::accel::wide::prefetch_all;
use crate::path::NeeRay;
use crate::shade::ShadeInputs;
use strahl_core::layout::FrameParams;
use strahl_core::math::lanes::{F, M, U, V};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{Nearest, PrimKind};
use strahl_core::render::bsdf::basis_lanes as basis;
use strahl_core::render::bsdf::{
    fresnel_dielectric_lanes as fresnel_dielectric, reflect_lanes as reflect, refract_lanes as refract,
};
use strahl_core::render::emitters::{emitted_cos_lanes as emitted_cos, power_heuristic_lanes as power_heuristic};
use strahl_core::render::limits::SHADOW_REACH;
use strahl_core::render::microfacet::schlick_lanes as schlick;
use strahl_core::render::pbr::{PbrLobesLanes, pbr_lobes_lanes};
use strahl_core::render::sampler::next_f32_lanes as draw;
use strahl_core::render::spawn::spawn_origin_lanes as spawn_origin;
use strahl_core::render::{environment, surface};

const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

/// Asks for what [`shade`] reads of the primitives `hits` met (their tags and shapes, and a
/// triangle's corners and attributes), ahead of it: in a large mesh each is a cache miss,
/// and the shading's loop over the lanes would wait for them one after the other.
#[inline(always)]
pub(super) fn prefetch(inp: &ShadeInputs, hits: &[Nearest<f32>]) {
    let (g, prims) = (inp.flat, inp.prims);
    for h in hits.iter().filter(|h| h.found) {
        let i = h.prim_ref.index();
        match h.prim_ref.kind() {
            PrimKind::Triangle => {
                prefetch_all(&prims.triangles[i]);
                if let (Some(t), Some(a)) = (g.triangles.get(i), g.triangle_attrs.get(i)) {
                    prefetch_all(t);
                    prefetch_all(a);
                }
            }
            PrimKind::Sphere => prefetch_all(&prims.spheres[i]),
            _ => {}
        }
    }
}

/// Shades the vertices of one bundle's paths (`b`), as [`crate::path::shade_vertex`] does (`RICH`:
/// [`Facts::rich`], else that code is left out): updates the paths, sets `out.more[i]` for each
/// path that goes on, and pushes each area-light shadow ray with its path's index onto
/// `out.nee`. The steps: [`vertex::gather`] and [`vertex::vertex`] (the hits, their materials
/// and surfaces), [`emission`] (what a miss or an emitter adds), [`scattering`] (the shading
/// frame and the pbr lobes), [`light_sample`] (next-event estimation), [`bsdf_sample`] and
/// [`advance`] (Russian roulette, the next rays, the shadow rays).
#[inline(always)]
pub(super) fn shade<const N: usize, const RICH: bool>(
    inp: &ShadeInputs,
    facts: &Facts,
    p: &mut Paths,
    b: &Bundle,
    out: &mut Out,
) {
    debug_assert!(b.n <= N && b.k + N <= p.capacity());
    let s = vertex::gather::<N, RICH>(inp, facts, p, b, out);
    let mut v = vertex::vertex::<N, RICH>(inp, facts, p, b.k, &s);
    v.sum = emission::<N, RICH>(inp, facts, &v, &s, b.n);
    if !s.is_hit.contains(&true) {
        // No lane shaded here met a surface (misses only; the one-path code has shaded the
        // others): none scatters, so each ends with its sum, its random stream untouched;
        // what follows would change nothing.
        for (a, sum) in [v.sum.x, v.sum.y, v.sum.z].into_iter().enumerate() {
            put(&mut p.sum[a], b.k, sum, v.on);
        }
        for l in 0..b.n {
            if s.on[l] {
                out.more[b.k + l] = false;
            }
        }
        return;
    }
    // The six numbers of the light and BSDF samples.
    let f = inp.frame;
    let cont = v.seg.le(U::splat(f.max_depth)) & v.hit & !v.seg.eq(U::splat(f.max_depth));
    let mut u = [F::splat(0.0); 6];
    for x in &mut u {
        *x = draw(&mut v.rng, cont);
    }
    let sc = scattering::<N, RICH>(&v, &s, cont, b.n);
    let at = At { v: &v, s: &s, sc: &sc, cont };
    let samples = VertexSamples {
        light: light_sample(inp, facts, &at, [u[0], u[1], u[2]]),
        bsdf: bsdf_sample(&at, [u[3], u[4], u[5]]),
    };
    advance(f, p, b, &mut v, &sc, &samples, out);
}

/// The background of a miss (weighed against next-event estimation's samples of the
/// environment, lane after lane, where there is one) and the emission of an emissive hit
/// (weighed against the light samples), added to the lanes' sums: the new sums.
#[inline(always)]
fn emission<const N: usize, const RICH: bool>(
    inp: &ShadeInputs,
    facts: &Facts,
    v: &Vertex<N>,
    s: &Gathered<N>,
    n_lanes: usize,
) -> V<N> {
    let (f, g) = (inp.frame, inp.flat);
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let bg = V::splat(f.background);
    let alive = v.seg.le(U::splat(f.max_depth));
    // (Loops rather than array::from_fn, whose closures the compiler leaves uninlined in a
    // function this size.)
    let mut miss = [false; N];
    for l in 0..N {
        miss[l] = s.on[l] && !s.is_hit[l] && alive.lane(l);
    }
    let (bg, w) = if !RICH || g.environment.is_empty() {
        (bg, one)
    } else if let Some(e) = lane_env::map(g) {
        if miss.contains(&true) {
            let (c, p_env) = lane_env::radiance_and_pdf(g, &facts.texels, &facts.guides, e, v.d, miss);
            let p_env = v.specular.select(zero, p_env);
            (c, p_env.gt(zero).select(power_heuristic(v.pdf_b, p_env), one))
        } else {
            (bg, one)
        }
    } else {
        let (mut c, mut w) = ([[0.0f32; N]; 3], [1.0f32; N]);
        let dr = v.d.rows();
        for l in 0..n_lanes {
            if !miss[l] {
                continue;
            }
            let dir = v3(&dr, l);
            let pdf_env = if v.specular.lane(l) { 0.0 } else { environment::pdf(g, dir) };
            if pdf_env > 0.0 {
                w[l] = strahl_core::render::emitters::power_heuristic(v.pdf_b.0[l], pdf_env);
            }
            let b = environment::background(g, f, dir);
            (c[0][l], c[1][l], c[2][l]) = (b.x, b.y, b.z);
        }
        (V::from_rows(&c), F(w))
    };
    let s_miss = v.sum + v.beta.mul_elem(bg).scale(w);
    let cos_l = emitted_cos(U(s.flags), -v.d.dot(v.n));
    let r = v.radiance;
    let mean = (r.x + r.y + r.z) / F::splat(3.0);
    let light_pdf = mean * F::splat(f.emitter_norm) * (v.t * v.t) / cos_l;
    let w_e = (v.specular | !M::from_bools(&s.sampled)).select(one, power_heuristic(v.pdf_b, light_pdf));
    let s_emit = v.sum + v.beta.mul_elem(r).scale(w_e);
    let emit = M::from_bools(&s.emits) & cos_l.gt(zero);
    let s_hit = emit.select_v(s_emit, v.sum);
    (alive & v.hit).select_v(s_hit, (alive & !v.hit).select_v(s_miss, v.sum))
}

/// Where and how the lanes' vertices scatter: the side of the surface the ray meets, the
/// normal facing it, the shading normal, and the pbr lobes seen from `wo`.
struct Scattering<const N: usize> {
    front: M<N>,
    ng: V<N>,
    ns: V<N>,
    wo: V<N>,
    /// The lanes of Lambertian, pbr and rough mirror vertices: those that sample a light.
    nee_kind: M<N>,
    is_pbr: M<N>,
    is_rough: M<N>,
    any_rough: bool,
    lobes: Option<PbrLobesLanes<N>>,
}

#[inline(always)]
fn scattering<const N: usize, const RICH: bool>(
    v: &Vertex<N>,
    s: &Gathered<N>,
    cont: M<N>,
    n_lanes: usize,
) -> Scattering<N> {
    let zero = F::splat(0.0);
    let is_pbr = if RICH { v.is(Kind::Pbr) } else { M([0; N]) };
    let any_pbr = RICH && (0..n_lanes).any(|l| s.on[l] && s.kind[l] == Kind::Pbr as u32);
    let is_rough = v.is(Kind::Rough);
    let front = v.d.dot(v.n).lt(zero);
    let wo = -v.d;
    let smooth = M::from_bools(&s.smooth) & v.on & cont;
    let ns = shading_normal(v.kind, front, v.n, v.shading, wo, smooth);
    Scattering {
        front,
        ng: front.select_v(v.n, -v.n),
        ns,
        wo,
        nee_kind: v.is(Kind::Lambert) | is_pbr | is_rough,
        is_pbr,
        is_rough,
        any_rough: (0..n_lanes).any(|l| s.on[l] && s.kind[l] == Kind::Rough as u32),
        lobes: any_pbr.then(|| pbr_lobes_lanes(v.color, v.metallic, v.roughness, wo.dot(ns))),
    }
}

/// The lanes' vertices where they sample: what they are, what they read, how they scatter,
/// and the lanes that go on past them.
#[derive(Clone, Copy)]
struct At<'a, const N: usize> {
    v: &'a Vertex<N>,
    s: &'a Gathered<N>,
    sc: &'a Scattering<N>,
    cont: M<N>,
}

/// The light sample of each Lambertian, pbr and rough mirror vertex, its value and its
/// shadow ray.
struct LightSample<const N: usize> {
    ls: lights::Samples<N>,
    value: V<N>,
    /// The lanes whose sample counts: a shadow ray is traced for each.
    on: M<N>,
    origin: V<N>,
}

/// The light sample (from `u`) of each vertex that takes one, its value (`bsdf::eval` behind
/// `path::eval_above`'s face test, weighed by MIS) and its shadow ray's origin.
#[inline(always)]
fn light_sample<const N: usize>(inp: &ShadeInputs, facts: &Facts, at: &At<N>, u: [F<N>; 3]) -> LightSample<N> {
    let At { v, s, sc, cont } = *at;
    let (f, g) = (inp.frame, inp.flat);
    let zero = F::splat(0.0);
    let mut want = [false; N];
    for l in 0..N {
        want[l] = s.on[l] && cont.lane(l) && sc.nee_kind.lane(l);
    }
    let x = v.o + v.d.scale(v.t);
    let scene =
        lights::LightScene { g, f, in_lanes: facts.lights_in_lanes, guides: &facts.guides, texels: &facts.texels };
    let ls = lights::sample(&scene, x, u, want);
    let (wi, ns, ng, wo) = (ls.dir, sc.ns, sc.ng, sc.wo);
    let cos_i = wi.dot(ns);
    let above = wi.dot(ng).gt(zero) & cos_i.gt(zero);
    let mut fc = above.select_v(v.color.scale(cos_i * F::splat(INV_PI)), V::splat([0.0; 3]));
    let mut pdf_l = above.select(cos_i * F::splat(INV_PI), zero);
    if let Some(lobes) = &sc.lobes {
        // path::eval_above's face test, bsdf::eval's, then the material's own.
        let (pf, pp) = pbr::eval(lobes, wo, wi, ns);
        let face = !wi.dot(ng).le(zero) & !cos_i.le(zero);
        fc = (sc.is_pbr & face).select_v(pf, (sc.is_pbr & !face).select_v(V::splat([0.0; 3]), fc));
        pdf_l = (sc.is_pbr & face).select(pp, (sc.is_pbr & !face).select(zero, pdf_l));
    }
    if sc.any_rough {
        let (rf, rp) = pbr::conductor_eval(v.roughness, v.color, wo, wi, ns);
        let face = !wi.dot(ng).le(zero);
        fc = (sc.is_rough & face).select_v(rf, (sc.is_rough & !face).select_v(V::splat([0.0; 3]), fc));
        pdf_l = (sc.is_rough & face).select(rp, (sc.is_rough & !face).select(zero, pdf_l));
    }
    let value = v.beta.mul_elem(fc).mul_elem(ls.value).scale(power_heuristic(ls.pdf, pdf_l));
    let on = cont & sc.nee_kind & ls.on & fc.max_component().gt(zero);
    LightSample { ls, value, on, origin: spawn_origin(v.o, v.d, v.t, ng) }
}

/// The BSDF sample of each vertex: its direction, weight (f·cos/pdf) and density, and the
/// lanes that have one.
struct BsdfSample<const N: usize> {
    dir: V<N>,
    weight: V<N>,
    pdf: F<N>,
    has: M<N>,
}

/// The BSDF sample from `u`: glass reflects or refracts by the Fresnel term, a smooth mirror
/// reflects, a Lambertian surface takes a cosine-weighted direction about the shading normal,
/// a pbr surface `bsdf::pbr_sample`'s, a rough mirror `bsdf::sample`'s.
#[inline(always)]
fn bsdf_sample<const N: usize>(at: &At<N>, u: [F<N>; 3]) -> BsdfSample<N> {
    let At { v, s, sc, cont } = *at;
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let (wo, ns) = (sc.wo, sc.ns);
    let (lambert, glass) = (v.is(Kind::Lambert), v.is(Kind::Glass));
    let color = v.color;
    let cos_g = wo.dot(ns);
    let eta = sc.front.select(F(s.ior), one / F(s.ior));
    let fres = fresnel_dielectric(cos_g, eta);
    let reflects = u[0].lt(fres);
    let inv_eta = one / eta;
    let glass_dir = reflects.select_v(reflect(-wo, ns), refract(-wo, ns, cos_g, inv_eta));
    let glass_w = reflects.select_v(V::splat([1.0; 3]), color / (eta * eta));
    let mirror_dir = reflect(-wo, ns);
    let mirror_w = schlick(color, cos_g);
    // Lambertian: its angle's sine and cosine lane after lane.
    let mut has = cont & (!lambert | color.max_component().gt(zero));
    let (sin_phi, cos_phi) = u[2].sin_cos_turns();
    let r = u[1].sqrt();
    let local = V::new(r * cos_phi, r * sin_phi, (one - u[1]).max(zero).sqrt());
    let (tb, bb) = basis(ns);
    let world = (tb.scale(local.x) + bb.scale(local.y) + ns.scale(local.z)).normalize();
    let mut dir = lambert.select_v(world, glass.select_v(glass_dir, mirror_dir));
    let mut weight = lambert.select_v(color, glass.select_v(glass_w, mirror_w));
    let mut pdf = lambert.select(local.z * F::splat(INV_PI), zero);
    if let Some(lobes) = &sc.lobes {
        // bsdf::pbr_sample: the lobe by u[0], its direction by u[1], u[2] (the diffuse base's
        // is the Lambertian one above), weighed by bsdf::pbr_eval.
        let pd = pbr::sample_dir(lobes, wo, ns, u, world);
        let (pf, pp) = pbr::eval(lobes, wo, pd, ns);
        let ok = pbr::samples(lobes, wo.dot(ns)) & pp.gt(zero);
        has = (sc.is_pbr & cont & ok) | (!sc.is_pbr & has);
        dir = sc.is_pbr.select_v(pd, dir);
        weight = sc.is_pbr.select_v(pf / pp, weight);
        pdf = sc.is_pbr.select(pp, pdf);
    }
    if sc.any_rough {
        // bsdf::sample's rough mirror, by u[1], u[2].
        let (ok, rd, rw, rp) = pbr::conductor_sample(v.roughness, color, wo, ns, u[1], u[2]);
        has = (sc.is_rough & cont & ok) | (!sc.is_rough & has);
        dir = sc.is_rough.select_v(rd, dir);
        weight = sc.is_rough.select_v(rw, weight);
        pdf = sc.is_rough.select(rp, pdf);
    }
    BsdfSample { dir, weight, pdf, has }
}

/// A vertex's two samples.
struct VertexSamples<const N: usize> {
    light: LightSample<N>,
    bsdf: BsdfSample<N>,
}

/// The face test, the path weight, Russian roulette and the next ray, written back to the
/// paths shaded here (the one-path code wrote the others'); then, lane after lane, which paths
/// go on and the shadow rays.
#[inline(always)]
fn advance<const N: usize>(
    f: &FrameParams,
    p: &mut Paths,
    b: &Bundle,
    v: &mut Vertex<N>,
    sc: &Scattering<N>,
    samples: &VertexSamples<N>,
    out: &mut Out,
) {
    let (light, bs) = (&samples.light, &samples.bsdf);
    let zero = F::splat(0.0);
    let k = b.k;
    let leaks = !v.is(Kind::Glass) & bs.dir.dot(sc.ng).le(zero);
    let beta = v.beta.mul_elem(bs.weight);
    let roulette = U::splat(f.rr_depth).le(v.seg);
    let q = beta.max_component().min(F::splat(0.95));
    let plays = bs.has & !leaks & roulette;
    let survives = draw(&mut v.rng, plays).lt(q) | !plays;
    let beta = roulette.select_v(beta / q, beta);
    let go = v.on & bs.has & !leaks & survives;
    let side = bs.dir.dot(v.n).ge(zero).select_v(v.n, -v.n);
    let origin = spawn_origin(v.o, v.d, v.t, side);
    for (a, (no, nd)) in [(origin.x, bs.dir.x), (origin.y, bs.dir.y), (origin.z, bs.dir.z)].into_iter().enumerate() {
        put(&mut p.o[a], k, no, go);
        put(&mut p.d[a], k, nd, go);
    }
    for (a, (nb, ns)) in [(beta.x, v.sum.x), (beta.y, v.sum.y), (beta.z, v.sum.z)].into_iter().enumerate() {
        put(&mut p.beta[a], k, nb, go);
        put(&mut p.sum[a], k, ns, v.on);
    }
    put(&mut p.pdf, k, bs.pdf, go);
    put_u(&mut p.specular, k, (!sc.nee_kind).select_u(U::splat(1), U::splat(0)), go);
    put_u(&mut p.seg, k, v.seg.wrapping_add(U::splat(1)), go);
    put_u(&mut p.rng, k, v.rng, v.on);
    let (no, wv, lsd) = (light.origin.rows(), light.value.rows(), light.ls.dir.rows());
    for l in 0..b.n {
        if !v.on.lane(l) {
            continue;
        }
        out.more[k + l] = go.lane(l);
        if light.on.lane(l) {
            let ray = Ray::new(v3(&no, l), v3(&lsd, l));
            let nee = NeeRay { ray, dist: light.ls.dist.0[l] * SHADOW_REACH, value: v3(&wv, l) };
            out.nee.push(((k + l) as u32, nee));
        }
    }
}

/// Lane `l` of rows `a` as a vector.
#[inline(always)]
fn v3<const N: usize>(a: &[[f32; N]; 3], l: usize) -> V3<f32> {
    V3::new(a[0][l], a[1][l], a[2][l])
}

/// `new` written over lanes `k .. k + N` of `v` where `m`.
#[inline(always)]
fn put<const N: usize>(v: &mut [f32], k: usize, new: F<N>, m: M<N>) {
    let old = F::<N>::load(v, k);
    v[k..k + N].copy_from_slice(&m.select(new, old).0);
}

#[inline(always)]
fn put_u<const N: usize>(v: &mut [u32], k: usize, new: U<N>, m: M<N>) {
    let old = U::<N>::load(v, k);
    v[k..k + N].copy_from_slice(&m.select_u(new, old).0);
}

/// The shading normal of [`surface::shading_frame`] for materials of lane kinds `kind`, seen
/// from `wo` on the `front` side of face normal `n`, with interpolated normal `shading` where
/// `smooth`, else the face's (which is what shading_frame gives there for every material: its
/// mirrors' and pbr surfaces' reflecting_normal keeps a normal that is the face's). Where a
/// mirror's or pbr lane's normal fails [`surface::reflecting_normal`]'s first test, that
/// routine bends it, lane after lane.
#[inline(always)]
fn shading_normal<const N: usize>(kind: U<N>, front: M<N>, n: V<N>, shading: V<N>, wo: V<N>, smooth: M<N>) -> V<N> {
    let is = |k: Kind| kind.eq(U::splat(k as u32));
    let ng = front.select_v(n, -n);
    let turned = front.select_v(shading, -shading);
    let to_face = is(Kind::Glass) | turned.dot(wo).le(F::splat(0.0));
    let wz = wo.dot(ng);
    let keeps = (F::splat(2.0) * wo.dot(turned) * turned.dot(ng) - wz).ge((F::splat(0.9) * wz).min(F::splat(0.01)));
    let reflects = is(Kind::Mirror) | is(Kind::Rough) | is(Kind::Pbr);
    let ns = (smooth & !to_face).select_v(turned, ng);
    let bend = smooth & !to_face & reflects & !keeps;
    if !(0..N).any(|l| bend.lane(l)) {
        return ns;
    }
    let v3 = |a: &[[f32; N]; 3], l: usize| V3::new(a[0][l], a[1][l], a[2][l]);
    let (mut rows, t, g, w) = (ns.rows(), turned.rows(), ng.rows(), wo.rows());
    for l in 0..N {
        if bend.lane(l) {
            let b = surface::reflecting_normal(v3(&g, l), v3(&w, l), v3(&t, l));
            (rows[0][l], rows[1][l], rows[2][l]) = (b.x, b.y, b.z);
        }
    }
    V::from_rows(&rows)
}

#[cfg(test)]
mod tests {
    use super::super::unit_direction;
    use super::*;
    use strahl_core::layout::FlatMaterial;
    use strahl_core::render::sampler::Sampler;
    use strahl_core::scene::MaterialKind;

    const N: usize = 16;

    /// The lanes' shading normal is surface::shading_frame's bit for bit, for every lane kind,
    /// both sides, flat and interpolated normals, and interpolated normals tilted far enough
    /// that mirrors' and pbr surfaces' reflections bend them (counted: the test needs some).
    #[test]
    fn lanes_shading_normal_equals_shading_frame() {
        let mut rng = Sampler::new(4, 5, 6);
        let kinds = [Kind::Lambert, Kind::Mirror, Kind::Glass, Kind::Pbr, Kind::Rough];
        let material = |k: Kind| {
            let kind = match k {
                Kind::Lambert => MaterialKind::Diffuse,
                Kind::Mirror | Kind::Rough => MaterialKind::Mirror,
                Kind::Glass => MaterialKind::Dielectric,
                Kind::Pbr => MaterialKind::Pbr,
            };
            FlatMaterial { kind: kind as u32, ..Default::default() }
        };
        let (mut bent, mut checked) = (0, 0);
        for _ in 0..2000 {
            let mut lanes = [[[0.0f32; N]; 3]; 3];
            let (mut kind, mut front, mut smooth) = ([0u32; N], [false; N], [false; N]);
            let mut cases = Vec::new();
            for l in 0..N {
                let k = kinds[(rng.next_f32() * 5.0) as usize % 5];
                let n = unit_direction(&mut rng);
                // Interpolated normals within about 80 degrees of the face's.
                let shading = (n + unit_direction(&mut rng) * (1.5 * rng.next_f32())).normalize();
                let wo = unit_direction(&mut rng);
                let f = rng.next_f32() < 0.5;
                let s = rng.next_f32() < 0.8;
                (kind[l], front[l], smooth[l]) = (k as u32, f, s);
                for (j, v) in [n, shading, wo].into_iter().enumerate() {
                    (lanes[j][0][l], lanes[j][1][l], lanes[j][2][l]) = (v.x, v.y, v.z);
                }
                cases.push((k, f, s, n, shading, wo));
            }
            let [n, shading, wo] = lanes.map(|r| V::from_rows(&r));
            let got = shading_normal(U(kind), M::from_bools(&front), n, shading, wo, M::from_bools(&smooth)).rows();
            for (l, &(k, f, s, n, shading, wo)) in cases.iter().enumerate() {
                let (ng, frame) = surface::shading_frame(&material(k), f, n, shading, wo);
                let want = if s { frame } else { ng };
                let turned = if f { shading } else { -shading };
                bent += (s && want != turned && want != ng) as usize;
                checked += 1;
                assert_eq!(
                    [got[0][l], got[1][l], got[2][l]].map(f32::to_bits),
                    want.to_array().map(f32::to_bits),
                    "{k:?}"
                );
            }
        }
        assert!(bent > 100, "{bent} of {checked} normals bent");
    }
}
