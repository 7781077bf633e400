//! Monte Carlo path tracing (`shaders/modules/path.wgsl` is the twin, `megakernel.wgsl` its entry): one path per pixel sample, next-event
//! estimation at every non-specular vertex, multiple importance sampling of light and BSDF
//! samples with the power heuristic (Veach 1997, ch. 9), Russian roulette once a path has
//! [`RR_DEPTH`] segments.
//!
//! `max_depth` counts path segments as Mitsuba's `max_depth` does: a light reached by the
//! k-th segment (by a BSDF sample or by a shadow ray) contributes while k ≤ max_depth, so 1
//! shows emitters only and 2 is direct lighting.
//!
//! Point and directional lights are evaluated at every non-specular vertex, each with a
//! shadow ray (see [`super::emitters`] for why they are not chosen by power); they use no
//! random numbers. Both backends consume the random stream in the same order: at every vertex
//! one number where the surface's material blends by alpha (whether the ray passes), three
//! for the area-light sample (drawn even where unused), three for the BSDF, and one for
//! Russian roulette when it applies; and add to a path's radiance in the same order:
//! emission, point and directional lights, the area-light sample.
//!
//! The stages are those of `shaders/modules/path.wgsl` ([`PathState`], [`shade_vertex`],
//! [`NeeRay`]), which the GPU's megakernel (`megakernel.wgsl`, like [`radiance`] here) and its
//! wavefront tracer (`wavefront.wgsl`) both run.

use crate::accel::wide_traverse;
use crate::shade::ShadeInputs;
use strahl_core::layout::{FlatMaterial, MATERIAL_ALPHA, MATERIAL_ALPHA_BLEND};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{Hit, PrimKind};
use strahl_core::render::bsdf::{self, is_specular};
use strahl_core::render::camera::ray_through;
use strahl_core::render::emitters::{self, area_pdf, emitted_cos, power_heuristic};
use strahl_core::render::environment;
use strahl_core::render::limits::{SHADOW_PASSES, SHADOW_REACH};
use strahl_core::render::sampler::{Sampler, pixel_jitter};
use strahl_core::render::spawn::spawn_origin;
use strahl_core::render::surface;
use strahl_core::scene::MaterialKind;

#[inline]
fn uniform3(rng: &mut Sampler) -> [f32; 3] {
    let a = rng.next_f32();
    let b = rng.next_f32();
    [a, b, rng.next_f32()]
}

/// The camera ray of sample `s` of pixel (x, y), jittered inside the pixel.
#[inline]
pub fn camera_ray(inp: &ShadeInputs, x: u32, y: u32, s: u32) -> Ray<f32> {
    let f = inp.frame;
    let (ox, oy) = pixel_jitter(y * f.width + x, s, f.seed);
    ray_through(f, x, y, ox, oy)
}

/// A path between vertices (`PathState` in `shaders/modules/path.wgsl`).
#[derive(Clone, Copy, Debug)]
pub struct PathState {
    pub ray: Ray<f32>,
    /// The segment the next hit ends (1: the camera ray).
    pub seg: u32,
    pub beta: V3<f32>,
    pub pdf_bsdf: f32,
    pub sum: V3<f32>,
    /// The last scattering was specular (or the path is at the camera).
    pub specular: bool,
}

impl PathState {
    pub fn new(ray: Ray<f32>) -> Self {
        Self { ray, seg: 1, beta: V3::splat(1.0), pdf_bsdf: 0.0, sum: V3::zero(), specular: true }
    }
}

/// A vertex's area-light sample (`NeeRay` in `shaders/modules/path.wgsl`): the shadow ray, up to
/// `dist`, and the radiance it adds to the path when nothing blocks it.
#[derive(Clone, Copy, Debug)]
pub struct NeeRay {
    pub ray: Ray<f32>,
    pub dist: f32,
    pub value: V3<f32>,
}

/// Shades the vertex where segment `p.seg` of path `p` meets `hit` (`None`: the ray leaves the
/// scene), as `shade_vertex` in `shaders/modules/path.wgsl`: adds the emission there and each
/// point and directional light to `p.sum`, returns the area-light sample in `nee` (for the
/// caller to trace), samples the BSDF and plays Russian roulette. Returns whether the path goes
/// on (`p` then holds its next ray).
pub fn shade_vertex(
    inp: &ShadeInputs,
    p: &mut PathState,
    hit: Option<&Hit<f32>>,
    rng: &mut Sampler,
    nee: &mut Option<NeeRay>,
) -> bool {
    let (f, g) = (inp.frame, inp.flat);
    *nee = None;
    let ray = p.ray;
    if p.seg > f.max_depth {
        return false;
    }
    let Some(hit) = hit else {
        // The environment (or the background), weighted against next-event estimation's
        // samples of it.
        let pdf_env = if p.specular { 0.0 } else { environment::pdf(g, ray.dir) };
        let w = if pdf_env > 0.0 { power_heuristic(p.pdf_bsdf, pdf_env) } else { 1.0 };
        p.sum += p.beta.mul_elem(environment::background(g, f, ray.dir)) * w;
        return false;
    };
    let untextured = &g.materials[hit.tag.material as usize];
    let wo = -ray.dir;
    let s = surface::surface(g, untextured, hit.prim_ref, ray.at(hit.t), hit.normal);
    let m = &s.m;
    if m.flags & MATERIAL_ALPHA != 0 {
        // A BLEND surface stops the ray with probability alpha (one random number, drawn only
        // here); a MASK one where alpha reaches the cut-off.
        let stop = if m.flags & MATERIAL_ALPHA_BLEND != 0 { rng.next_f32() } else { 0.5 };
        let c = surface::coverage(m, s.alpha);
        if !(stop < c) {
            // On through the surface, the same segment. Next-event estimation's shadow rays
            // towards area lights and the sky stop at such surfaces, so light through them is
            // found by this path alone: it counts in full where it arrives (as after a
            // specular bounce), which keeps the estimate unbiased.
            let side = if ray.dir.dot(hit.normal) >= 0.0 { hit.normal } else { -hit.normal };
            p.ray = Ray::new(spawn_origin(&ray, hit.t, side), ray.dir);
            p.specular = true;
            return true;
        }
    }
    let front = ray.dir.dot(hit.normal) < 0.0;
    if !front && m.absorption != [0.0; 3] {
        // The segment ran inside the material (it ends on a back face): Beer–Lambert.
        p.beta = p.beta.mul_elem(absorbed(m, hit.t));
    }
    let (ng, ns) = surface::shading_frame(m, front, hit.normal, s.normal, wo);
    if m.kind() == MaterialKind::Emissive || m.kind() == MaterialKind::Pbr {
        let cos_l = emitted_cos(m.flags, -ray.dir.dot(hit.normal));
        if cos_l > 0.0 {
            let sampled = m.is_light() && matches!(hit.prim_ref.kind(), PrimKind::Triangle | PrimKind::Sphere);
            let w = if p.specular || !sampled {
                1.0
            } else {
                // Emitters are sampled by their untextured radiance (emitters::sample).
                power_heuristic(p.pdf_bsdf, area_pdf(f, untextured.radiance, hit.t * hit.t, cos_l))
            };
            p.sum += p.beta.mul_elem(V3::from_array(m.radiance)) * w;
        }
    }
    if p.seg == f.max_depth {
        return false;
    }
    let u_light = uniform3(rng);
    if !is_specular(m) {
        let x = ray.at(hit.t);
        let origin = spawn_origin(&ray, hit.t, ng);
        for l in &g.lights[..f.num_lights as usize] {
            let Some(ls) = emitters::delta_light(l, x) else { continue };
            let (fc, _) = eval_above(m, wo, ls.dir, ns, ng, front);
            if fc.max_component() > 0.0 {
                let tr = transmittance(inp, &Ray::new(origin, ls.dir), ls.dist * SHADOW_REACH);
                if tr > 0.0 {
                    p.sum += p.beta.mul_elem(fc).mul_elem(ls.value) * tr;
                }
            }
        }
        if let Some(ls) = emitters::sample(g, f, x, u_light) {
            let (fc, pdf) = eval_above(m, wo, ls.dir, ns, ng, front);
            if fc.max_component() > 0.0 {
                let value = p.beta.mul_elem(fc).mul_elem(ls.value) * power_heuristic(ls.pdf, pdf);
                *nee = Some(NeeRay { ray: Ray::new(origin, ls.dir), dist: ls.dist * SHADOW_REACH, value });
            }
        }
    }
    let Some(bs) = bsdf::sample(m, wo, ns, front, uniform3(rng)) else {
        return false;
    };
    // A reflection the shading normal allows but the surface does not (below its face) ends
    // the path: continuing it would leak light through the surface; so does a refraction
    // that stays above it. (The smooth dielectric turns about the face's normal.)
    if !is_smooth_glass(m) && (bs.dir.dot(ng) <= 0.0) != bs.through {
        return false;
    }
    p.beta = p.beta.mul_elem(bs.weight);
    p.specular = bs.specular;
    p.pdf_bsdf = bs.pdf;
    if p.seg >= f.rr_depth {
        let q = p.beta.max_component().min(0.95);
        if rng.next_f32() >= q {
            return false;
        }
        p.beta = p.beta / q;
    }
    let side = if bs.dir.dot(hit.normal) >= 0.0 { hit.normal } else { -hit.normal };
    p.ray = Ray::new(spawn_origin(&ray, hit.t, side), bs.dir);
    p.seg += 1;
    true
}

/// [`bsdf::eval`] about the shading normal, for directions above the surface's face only: light
/// from below the face reaches no point of it, whatever the shading normal says.
#[inline]
pub fn eval_above(m: &FlatMaterial, wo: V3<f32>, wi: V3<f32>, ns: V3<f32>, ng: V3<f32>, front: bool) -> (V3<f32>, f32) {
    if wi.dot(ng) <= 0.0 {
        return (V3::zero(), 0.0);
    }
    bsdf::eval(m, wo, wi, ns, front)
}

/// A smooth dielectric: it reflects and refracts about the face's own normal.
#[inline]
fn is_smooth_glass(m: &FlatMaterial) -> bool {
    m.kind() == MaterialKind::Dielectric && is_specular(m)
}

/// What a segment of length `t` inside material `m` lets through: exp(−σ_a t) per channel
/// (rays' directions are unit vectors, so `t` is the length).
#[inline]
pub fn absorbed(m: &FlatMaterial, t: f32) -> V3<f32> {
    let a = m.absorption;
    V3::new((-a[0] * t).exp(), (-a[1] * t).exp(), (-a[2] * t).exp())
}

/// What reaches the end of a shadow ray towards a point or directional light, up to `tmax`:
/// 0 or 1 when no material has alpha (any surface blocks), else the product of what the alpha
/// surfaces crossed let through (1 − coverage), 0 at the first opaque surface or after
/// [`SHADOW_PASSES`] crossings. Only the delta lights need it: light from area
/// emitters and the sky through alpha surfaces is found by paths that pass them.
pub fn transmittance(inp: &ShadeInputs, ray: &Ray<f32>, tmax: f32) -> f32 {
    if !inp.flat.alpha {
        return if occluded(inp, ray, tmax) { 0.0 } else { 1.0 };
    }
    let mut origin = ray.origin;
    let mut remaining = tmax;
    let mut tr = 1.0f32;
    for _ in 0..SHADOW_PASSES {
        let r = Ray::new(origin, ray.dir);
        let Some(hit) = wide_traverse::nearest(inp.wide, inp.prims, &r, 0.0, remaining) else {
            return tr;
        };
        let m = &inp.flat.materials[hit.tag.material as usize];
        if m.flags & MATERIAL_ALPHA == 0 {
            return 0.0;
        }
        let s = surface::surface(inp.flat, m, hit.prim_ref, r.at(hit.t), hit.normal);
        tr *= 1.0 - surface::coverage(m, s.alpha);
        if tr <= 0.0 {
            return 0.0;
        }
        let side = if ray.dir.dot(hit.normal) >= 0.0 { hit.normal } else { -hit.normal };
        origin = spawn_origin(&r, hit.t, side);
        remaining -= hit.t;
    }
    0.0
}

/// Whether anything lies in (0, tmax) along the shadow ray.
fn occluded(inp: &ShadeInputs, ray: &Ray<f32>, tmax: f32) -> bool {
    wide_traverse::occluded(inp.wide, inp.prims, ray, 0.0, tmax)
}

/// Radiance arriving along `ray`, one path (the GPU's megakernel, `megakernel.wgsl`): each vertex
/// shaded, its area-light shadow ray traced at once.
pub fn radiance(inp: &ShadeInputs, ray: Ray<f32>, rng: &mut Sampler) -> V3<f32> {
    let mut p = PathState::new(ray);
    let mut nee = None;
    loop {
        let hit = wide_traverse::nearest(inp.wide, inp.prims, &p.ray, 0.0, f32::INFINITY);
        let more = shade_vertex(inp, &mut p, hit.as_ref(), rng, &mut nee);
        if let Some(n) = nee
            && !occluded(inp, &n.ray, n.dist)
        {
            p.sum += n.value;
        }
        if !more {
            return p.sum;
        }
    }
}

/// Radiance of sample `s` of pixel (x, y); a non-finite sample (which a valid scene never
/// produces) counts as black.
#[inline]
pub fn sample_pixel(inp: &ShadeInputs, x: u32, y: u32, s: u32) -> V3<f32> {
    let f = inp.frame;
    let mut rng = Sampler::new(y * f.width + x, s, f.seed);
    let c = radiance(inp, camera_ray(inp, x, y, s), &mut rng);
    if c.is_finite() { c } else { V3::zero() }
}

/// The mean of samples `sample_base .. sample_base + spp` of pixel (x, y), added in sample
/// order as the GPU's passes add them.
pub fn shade_pixel(inp: &ShadeInputs, x: u32, y: u32) -> [f32; 3] {
    let f = inp.frame;
    let mut sum = V3::zero();
    for s in 0..f.spp {
        sum += sample_pixel(inp, x, y, f.sample_base + s);
    }
    (sum / f.spp as f32).to_array()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_heuristic_weights_sum_to_one() {
        for (a, b) in [(1.0, 1.0), (0.3, 7.0), (5.0, 0.0)] {
            assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-6);
        }
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
    }
}
