// One vertex of a path-traced sample: twin of crates/cpu/src/path.rs (PathState, path_start,
// shade_vertex; in lanes crates/cpu/src/lanes/path.rs). Both GPU path tracers run it: the megakernel (megakernel.wgsl) traces the vertex's
// shadow ray at once, the wavefront one (wavefront.wgsl) queues it for a kernel of its own.
//
// Per vertex, in this order: the emission of what the segment hit (MIS-weighted against the
// light sample of the previous vertex), each point and directional light (shadow ray traced
// here), the area-light sample (returned as a NeeRay: a shadow ray and what it adds when
// unoccluded), the BSDF sample and Russian roulette. Random numbers are drawn in the same
// order on both backends: three for the area-light sample, three for the BSDF, one for Russian
// roulette when it applies.
#define_import_path strahl::path

#import strahl::types::{Material, MAT_EMISSIVE, MAT_PBR, MAT_DIELECTRIC, MATERIAL_UNLIT, KIND_TRIANGLE, KIND_SPHERE, INDEX_BITS, F32_MAX}
#import strahl::bindings::{frame, load_material}
#ifdef LIGHTS
#import strahl::bindings::load_light
#import strahl::emitters::delta_light
#import strahl::traverse::occluded
#endif
#import strahl::traverse::{Nearest, hit_normal, hit_material}
#import strahl::spawn::spawn_origin
#import strahl::camera::ray_through
#import strahl::sampler::{sampler_new, next_f32, uniform3, pixel_jitter}
#import strahl::bsdf::{BsdfEval, bsdf_sample, bsdf_eval, is_specular}
#import strahl::emitters::{sample_light, area_pdf, emitted_cos}
#import strahl::surface::{surface, shading_frame}
#ifdef ALPHA
#import strahl::types::{MATERIAL_ALPHA, MATERIAL_ALPHA_BLEND}
#import strahl::surface::coverage
#import strahl::traverse::nearest_hit
#endif
#ifdef ENVIRONMENT
#import strahl::environment::{env_background, env_pdf}
#endif

// Shadow rays stop this fraction short of the light point (render::path::SHADOW_REACH).
const SHADOW_REACH: f32 = #{SHADOW_REACH};
// Crossings a shadow ray towards a point or directional light may make (render::shade).
const SHADOW_PASSES: u32 = #{SHADOW_PASSES};

// A path between vertices (render::path::PathState); host-shareable, for the wavefront
// tracer's path buffer.
struct PathState {
    o: vec3<f32>,
    // The segment the next hit ends (1: the camera ray).
    seg: u32,
    d: vec3<f32>,
    rng: u32,
    beta: vec3<f32>,
    pdf_bsdf: f32,
    sum: vec3<f32>,
    // 1 while the last scattering was specular (or at the camera).
    specular: u32,
}

// The area-light sample of a vertex: the shadow ray (origin, dir, up to dist) and the radiance
// it adds to the path when nothing blocks it.
struct NeeRay {
    origin: vec3<f32>,
    dist: f32,
    dir: vec3<f32>,
    valid: u32,
    value: vec3<f32>,
    pad: u32,
}

fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b > 0.0 {
        return a / (a + b);
    }
    return 0.0;
}

fn max3(v: vec3<f32>) -> f32 {
    return max(v.x, max(v.y, v.z));
}

#ifdef LIGHTS
// What reaches the end of a shadow ray towards a delta light (render::path::transmittance).
fn delta_transmittance(o: vec3<f32>, d: vec3<f32>, tmax: f32) -> f32 {
#ifdef ALPHA
    var origin = o;
    var remaining = tmax;
    var tr = 1.0;
    for (var k = 0u; k < SHADOW_PASSES; k += 1u) {
        let hit = nearest_hit(origin, d, 0.0, remaining);
        if !hit.found {
            return tr;
        }
        let m = load_material(hit_material(hit));
        if (m.flags & MATERIAL_ALPHA) == 0u {
            return 0.0;
        }
        let hn = hit_normal(hit, origin, d);
        let sa = surface(m, hit.prim_ref, origin + d * hit.t, hn);
        tr = tr * (1.0 - coverage(m, sa.alpha));
        if tr <= 0.0 {
            return 0.0;
        }
        let side = select(-hn, hn, dot(d, hn) >= 0.0);
        origin = spawn_origin(origin, d, hit.t, side);
        remaining -= hit.t;
    }
    return 0.0;
#else
    return select(1.0, 0.0, occluded(o, d, 0.0, tmax));
#endif
}
#endif

// bsdf_eval about the shading normal for directions above the face only (render::path::eval_above).
fn eval_above(m: Material, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>, ng: vec3<f32>, front: bool) -> BsdfEval {
    if dot(wi, ng) <= 0.0 {
        return BsdfEval(vec3<f32>(0.0), 0.0);
    }
    return bsdf_eval(m, wo, wi, ns, front);
}

// The camera ray and random stream of sample s of pixel (x, y).
fn path_start(x: u32, y: u32, s: u32) -> PathState {
    let pixel = y * frame.width + x;
    let ray = ray_through(frame, x, y, pixel_jitter(pixel, s, frame.seed));
    return PathState(ray.origin, 1u, ray.dir, sampler_new(pixel, s, frame.seed), vec3<f32>(1.0), 0.0, vec3<f32>(0.0), 1u);
}

fn nee_none() -> NeeRay {
    return NeeRay(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u);
}

// Shades the vertex where segment p.seg of path p meets hit (or leaves the scene): adds to
// p.sum what reaches the camera from there except the area-light sample, which goes to nee;
// returns whether the path goes on (p then holds its next ray).
fn shade_vertex(p: ptr<function, PathState>, hit: Nearest, nee: ptr<function, NeeRay>) -> bool {
    // The stream in a variable of its own (samplers take a pointer to it).
    var rng = (*p).rng;
    let more = shade_with(p, hit, nee, &rng);
    (*p).rng = rng;
    return more;
}

fn shade_with(p: ptr<function, PathState>, hit: Nearest, nee: ptr<function, NeeRay>, rng: ptr<function, u32>) -> bool {
    *nee = nee_none();
    let o = (*p).o;
    let d = (*p).d;
    let seg = (*p).seg;
    if seg > frame.max_depth {
        // max_depth 0: not even the camera ray counts.
        return false;
    }
    if !hit.found {
#ifdef ENVIRONMENT
        // The environment, weighted against next-event estimation's samples of it.
        var pdf_env = 0.0;
        if (*p).specular == 0u {
            pdf_env = env_pdf(d);
        }
        var w = 1.0;
        if pdf_env > 0.0 {
            w = power_heuristic((*p).pdf_bsdf, pdf_env);
        }
        (*p).sum += (*p).beta * env_background(d) * w;
#else
        (*p).sum += (*p).beta * frame.background;
#endif
        return false;
    }
    let untextured = load_material(hit_material(hit));
    let n = hit_normal(hit, o, d);
    let wo = -d;
    let sf = surface(untextured, hit.prim_ref, o + d * hit.t, n);
    let m = sf.m;
#ifdef ALPHA
    if (m.flags & MATERIAL_ALPHA) != 0u {
        // Through the surface where it lets the ray pass (render::path::shade_vertex).
        var stop = 0.5;
        if (m.flags & MATERIAL_ALPHA_BLEND) != 0u {
            stop = next_f32(rng);
        }
        if !(stop < coverage(m, sf.alpha)) {
            let side = select(-n, n, dot(d, n) >= 0.0);
            (*p).o = spawn_origin(o, d, hit.t, side);
            (*p).specular = 1u;
            return true;
        }
    }
#endif
    let front = dot(d, n) < 0.0;
#ifdef ABSORPTION
    if !front && any(m.absorption != vec3<f32>(0.0)) {
        // The segment ran inside the material: Beer-Lambert (render::path::absorbed).
        (*p).beta = (*p).beta * exp(-m.absorption * hit.t);
    }
#endif
    let fr = shading_frame(m, front, n, sf.normal, wo);
    let ng = fr.ng;
    let ns = fr.ns;
#ifdef EMISSIVE
    if m.kind == MAT_EMISSIVE || m.kind == MAT_PBR {
        let cos_l = emitted_cos(m.flags, -dot(d, n));
        if cos_l > 0.0 {
            let kind = hit.prim_ref >> INDEX_BITS;
            let sampled = (m.flags & MATERIAL_UNLIT) == 0u && (kind == KIND_TRIANGLE || kind == KIND_SPHERE);
            var w = 1.0;
            if (*p).specular == 0u && sampled {
                // Emitters are sampled by their untextured radiance (emitters::sample_light).
                w = power_heuristic((*p).pdf_bsdf, area_pdf(untextured.radiance, hit.t * hit.t, cos_l));
            }
            (*p).sum += (*p).beta * m.radiance * w;
        }
    }
#endif
    if seg == frame.max_depth {
        return false;
    }
    let u_light = uniform3(rng);
    if !is_specular(m) {
        let x = o + d * hit.t;
        let so = spawn_origin(o, d, hit.t, ng);
#ifdef LIGHTS
        // Point and directional lights, each at every vertex (render::path: chosen by power
        // with the area lights, one could be starved).
        for (var i = 0u; i < frame.num_lights; i += 1u) {
            let dl = delta_light(load_light(i), x);
            if dl.valid {
                let ev = eval_above(m, wo, dl.dir, ns, ng, front);
                if max3(ev.f_cos) > 0.0 {
                    let tr = delta_transmittance(so, dl.dir, dl.dist * SHADOW_REACH);
                    if tr > 0.0 {
                        (*p).sum += (*p).beta * ev.f_cos * dl.value * tr;
                    }
                }
            }
        }
#endif
        let ls = sample_light(x, u_light);
        if ls.valid {
            let ev = eval_above(m, wo, ls.dir, ns, ng, front);
            if max3(ev.f_cos) > 0.0 {
                let value = (*p).beta * ev.f_cos * ls.value * power_heuristic(ls.pdf, ev.pdf);
                *nee = NeeRay(so, ls.dist * SHADOW_REACH, ls.dir, 1u, value, 0u);
            }
        }
    }
    let bs = bsdf_sample(m, wo, ns, front, uniform3(rng));
    if !bs.valid {
        return false;
    }
    // A reflection below the surface's face, or a refraction above it, ends the path
    // (render::path: no leaks); the smooth dielectric turns about the face's normal.
    let smooth_glass = m.kind == MAT_DIELECTRIC && is_specular(m);
    if !smooth_glass && (dot(bs.dir, ng) <= 0.0) != bs.through {
        return false;
    }
    (*p).beta = (*p).beta * bs.weight;
    (*p).specular = select(0u, 1u, bs.specular);
    (*p).pdf_bsdf = bs.pdf;
    if seg >= frame.rr_depth {
        let q = min(max3((*p).beta), 0.95);
        if next_f32(rng) >= q {
            return false;
        }
        (*p).beta = (*p).beta / q;
    }
    let side = select(-n, n, dot(bs.dir, n) >= 0.0);
    (*p).o = spawn_origin(o, d, hit.t, side);
    (*p).d = bs.dir;
    (*p).seg = seg + 1u;
    return true;
}

// A finished sample's radiance; a non-finite one (never on a valid scene) counts as black.
fn finite_or_black(c: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(0.0), c, all(abs(c) <= vec3<f32>(F32_MAX)));
}
