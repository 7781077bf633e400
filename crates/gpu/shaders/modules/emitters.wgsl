// Light sampling for next-event estimation: twin of crates/core/src/render/emitters.rs (in lanes crates/cpu/src/lanes/emitters.rs; area emitters chosen
// in proportion to power by inverting their cdf, points uniform on the chosen triangle or
// sphere; point and directional lights evaluated one by one at every vertex, not chosen).
#define_import_path strahl::emitters

#import strahl::types::{Emitter, Light, LIGHT_POINT, LIGHT_STAND_IN, spot_factor, KIND_TRIANGLE, INDEX_BITS, INDEX_MASK, MATERIAL_TWO_SIDED, F32_MAX}
#import strahl::bindings::{frame, load_emitter, load_light, load_material}
#ifdef TRIANGLES
#import strahl::traverse::scene_triangle
#endif
#ifdef SPHERES
#import strahl::bindings::{load_sphere, sphere_count}
#endif
#ifdef ENVIRONMENT
#import strahl::types::FRAME_ENVIRONMENT
#import strahl::bindings::load_environment
#import strahl::environment::env_sample
#endif
#import strahl::surface::emission

const TWO_PI: f32 = 6.28318530717959;

struct LightSample {
    dir: vec3<f32>,
    dist: f32,
    // Radiance (area) or normal irradiance (point, directional) divided by pdf.
    value: vec3<f32>,
    // 1 for a point or directional light.
    pdf: f32,
    valid: bool,
}

fn mean3(c: vec3<f32>) -> f32 {
    return (c.x + c.y + c.z) / 3.0;
}

fn select_emitter(u: f32) -> u32 {
    var lo = 0u;
    var hi = frame.num_emitters - 1u;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if u < load_emitter(mid).cdf {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

fn emitted_cos(material_flags: u32, c: f32) -> f32 {
    return select(c, abs(c), (material_flags & MATERIAL_TWO_SIDED) != 0u);
}

fn area_pdf(radiance: vec3<f32>, d2: f32, cos_l: f32) -> f32 {
    return mean3(radiance) * frame.emitter_norm * d2 / cos_l;
}

// Point or directional light l seen from p (render::emitters::delta_light): invalid for a
// Whitted stand-in and for a point light at p.
fn delta_light(l: Light, p: vec3<f32>) -> LightSample {
    let none = LightSample(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, false);
    if (l.flags & LIGHT_STAND_IN) != 0u {
        return none;
    }
    if l.kind == LIGHT_POINT {
        let to = l.vector - p;
        let d2 = dot(to, to);
        if !(d2 > 0.0) {
            return none;
        }
        let dist = sqrt(d2);
        let dir = to / dist;
        return LightSample(dir, dist, l.intensity / d2 * spot_factor(l, dir, dist), 1.0, true);
    }
    return LightSample(-l.vector, F32_MAX, l.intensity, 1.0, true);
}

// A light sample for p from three uniform numbers: the environment or an area light
// (render::emitters::sample).
fn sample_light(p: vec3<f32>, u: vec3<f32>) -> LightSample {
    let none = LightSample(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, false);
    var ux = u.x;
#ifdef ENVIRONMENT
    // The environment with probability select_prob, else an area emitter with u.x rescaled.
    if (frame.flags & FRAME_ENVIRONMENT) != 0u {
        let sel = load_environment().select_prob;
        if frame.num_emitters == 0u || ux < sel {
            let es = env_sample(u.y, u.z);
            return LightSample(es.dir, F32_MAX, es.value, es.pdf, es.valid);
        }
        ux = (ux - sel) / (1.0 - sel);
    }
#endif
    if frame.num_emitters == 0u {
        return none;
    }
    let e = load_emitter(select_emitter(ux));
    let kind = e.source >> INDEX_BITS;
    let i = e.source & INDEX_MASK;
    var q = vec3<f32>(0.0);
    var n = vec3<f32>(0.0, 0.0, 1.0);
    var material = 0u;
    var found = false;
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        let t = scene_triangle(i);
        let su = sqrt(u.y);
        let b0 = 1.0 - su;
        let b1 = u.z * su;
        q = t.va * b0 + t.vb * b1 + t.vc * (1.0 - b0 - b1);
        n = normalize(cross(t.vb - t.va, t.vc - t.va));
        material = t.material;
        found = true;
    }
#endif
#ifdef SPHERES
    if !found {
        let s = load_sphere(i);
        let z = 1.0 - 2.0 * u.y;
        let rad = sqrt(max(1.0 - z * z, 0.0));
        let phi = TWO_PI * u.z;
        n = vec3<f32>(rad * cos(phi), rad * sin(phi), z);
        q = s.center + n * s.radius;
        material = s.material;
        found = true;
    }
#endif
    if !found {
        return none;
    }
    let m = load_material(material);
    let to = q - p;
    let d2 = dot(to, to);
    let dist = sqrt(d2);
    let dir = to / dist;
    let cos_l = emitted_cos(m.flags, -dot(dir, n));
    if cos_l <= 0.0 || d2 <= 0.0 {
        return none;
    }
    let pdf = area_pdf(m.radiance, d2, cos_l);
    // The emission texture at the sampled point (its density is that of the untextured radiance).
    let radiance = emission(m, e.source, q);
    return LightSample(dir, dist, radiance / pdf, pdf, true);
}
