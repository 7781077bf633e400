// Whitted shading: twin of crates/cpu/src/shade.rs (same stack order, same sums).
//
// Shader defs: LIGHTS (any light; with it POINT_LIGHTS / DIRECTIONAL_LIGHTS), MIRROR,
// DIELECTRIC, EMISSIVE (which material kinds exist; diffuse is always compiled), and
// SHADOW_CROSSING (DIELECTRIC, EMISSIVE or ALPHA: shadow rays may pass surfaces), ALPHA
// (materials let rays through by alpha).
#define_import_path strahl::shade

#import strahl::types::{Frame, Material, Light, MAT_MIRROR, MAT_DIELECTRIC, MAT_EMISSIVE, MAT_PBR, MATERIAL_ALPHA, LIGHT_POINT, F32_MAX, spot_factor}
#import strahl::bindings::{frame, load_material, load_light}
#import strahl::traverse::{nearest_hit, occluded, hit_normal, hit_material}
#import strahl::spawn::spawn_origin
#import strahl::camera::primary_ray
#import strahl::surface::{surface, shading_frame, coverage}
#ifdef PBR
#import strahl::pbr::pbr_lobes
#endif
#ifdef ENVIRONMENT
#import strahl::environment::{env_background, env_diffuse}
#endif

// Depth of the explicit ray stack (render::shade::WHITTED_STACK).
const WHITTED_STACK: u32 = #{WHITTED_STACK};
// Traversals a shadow ray may make: it crosses at most SHADOW_PASSES - 1 dielectric surfaces
// (render::shade::SHADOW_PASSES).
const SHADOW_PASSES: u32 = #{SHADOW_PASSES};
const INV_PI: f32 = 0.31830988618379067;

struct Pending {
    origin: vec3<f32>,
    dir: vec3<f32>,
    weight: vec3<f32>,
    depth: u32,
}

fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_parl * r_parl + r_perp * r_perp);
}

fn reflect_dir(d: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return d - n * (2.0 * dot(d, n));
}

fn refract_dir(d: vec3<f32>, n: vec3<f32>, cos_i: f32, eta_ratio: f32) -> vec3<f32> {
    let sin2_t = eta_ratio * eta_ratio * (1.0 - cos_i * cos_i);
    let cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    return normalize(d * eta_ratio + n * (eta_ratio * cos_i - cos_t));
}

#ifdef LIGHTS
// Transmittance towards a light dist away: 0 behind an opaque surface, the product of the
// dielectric colours crossed otherwise.
fn shadow_transmittance(o: vec3<f32>, d: vec3<f32>, t: f32, n: vec3<f32>, l: vec3<f32>, dist: f32) -> vec3<f32> {
    var origin = spawn_origin(o, d, t, n);
#ifndef SHADOW_CROSSING
    // Every surface is opaque: any hit blocks the light.
    return select(vec3<f32>(1.0), vec3<f32>(0.0), occluded(origin, l, 0.0, dist));
#else
    var remaining = dist;
    var tr = vec3<f32>(1.0);
    for (var pass_ = 0u; pass_ < SHADOW_PASSES; pass_ += 1u) {
        let hit = nearest_hit(origin, l, 0.0, remaining);
        if !hit.found {
            return tr;
        }
        // Dielectrics tint the shadow ray; emissive surfaces (lights) let it through.
        let m = load_material(hit_material(hit));
        let hn = hit_normal(hit, origin, l);
#ifdef ALPHA
        if (m.flags & MATERIAL_ALPHA) != 0u {
            let sa = surface(m, hit.prim_ref, origin + l * hit.t, hn);
            tr = tr * (1.0 - coverage(m, sa.alpha));
            if max(tr.x, max(tr.y, tr.z)) <= 0.0 {
                return vec3<f32>(0.0);
            }
        } else if m.kind == MAT_DIELECTRIC {
#else
        if m.kind == MAT_DIELECTRIC {
#endif
            tr = tr * m.color;
        } else if m.kind != MAT_EMISSIVE {
            return vec3<f32>(0.0);
        }
        let side = select(hn, -hn, dot(l, hn) < 0.0);
        origin = spawn_origin(origin, l, hit.t, side);
        remaining -= hit.t;
    }
    return vec3<f32>(0.0);
#endif
}
#endif

fn direct_light(o: vec3<f32>, d: vec3<f32>, t: f32, ng: vec3<f32>, ns: vec3<f32>, albedo: vec3<f32>) -> vec3<f32> {
    let p = o + d * t;
    var sum = frame.ambient;
#ifdef ENVIRONMENT
    // The environment's unshadowed diffuse light joins the ambient term.
    sum += env_diffuse(ns);
#endif
#ifdef LIGHTS
    for (var i = 0u; i < frame.num_lights; i += 1u) {
        let light = load_light(i);
        var l: vec3<f32>;
        var dist: f32;
        var e: vec3<f32>;
#ifdef POINT_LIGHTS
#ifdef DIRECTIONAL_LIGHTS
        let is_point = light.kind == LIGHT_POINT;
#else
        let is_point = true;
#endif
#else
        let is_point = false;
#endif
        if is_point {
            let to = light.vector - p;
            let d2 = dot(to, to);
            dist = sqrt(d2);
            l = to / dist;
            e = light.intensity / d2 * spot_factor(light, l, dist);
        } else {
            l = -light.vector;
            dist = F32_MAX;
            e = light.intensity;
        }
        let cos = dot(ns, l);
        if cos <= 0.0 || dot(ng, l) <= 0.0 {
            continue;
        }
        let tr = shadow_transmittance(o, d, t, ng, l, dist);
        sum += e * tr * (cos * INV_PI);
    }
#endif
    return albedo * sum;
}

// The rays still to trace, in the order of render::shade's stack: the most recent one held in
// `top`, the ones below it in the array `below`. A private array indexed per lane costs a
// driver that runs invocations as SIMD lanes (lavapipe) a scalar load or store per lane and
// per word, so the ray that is pushed and popped next (the camera ray, a mirror's reflection,
// a dielectric's refraction) never goes through it.
struct RayStack {
    below: array<Pending, WHITTED_STACK>,
    stored: u32,
    top: Pending,
    top_held: bool,
}

fn ray_stack_size(s: ptr<function, RayStack>) -> u32 {
    return (*s).stored + select(0u, 1u, (*s).top_held);
}

fn ray_stack_push(s: ptr<function, RayStack>, r: Pending) {
    if (*s).top_held {
        (*s).below[(*s).stored] = (*s).top;
        (*s).stored += 1u;
    }
    (*s).top = r;
    (*s).top_held = true;
}

fn ray_stack_pop(s: ptr<function, RayStack>) -> Pending {
    if (*s).top_held {
        (*s).top_held = false;
        return (*s).top;
    }
    (*s).stored -= 1u;
    return (*s).below[(*s).stored];
}

// Radiance along a primary ray.
fn radiance(origin: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    var rs: RayStack;
    rs.top = Pending(origin, dir, vec3<f32>(1.0), 0u);
    rs.top_held = true;
    rs.stored = 0u;
    var color = vec3<f32>(0.0);
    let max_depth = frame.max_depth;
    while ray_stack_size(&rs) > 0u {
        let cur = ray_stack_pop(&rs);
        let hit = nearest_hit(cur.origin, cur.dir, 0.0, F32_MAX);
        if !hit.found {
#ifdef ENVIRONMENT
            color += cur.weight * env_background(cur.dir);
#else
            color += cur.weight * frame.background;
#endif
            continue;
        }
        let n = hit_normal(hit, cur.origin, cur.dir);
        let s = surface(load_material(hit_material(hit)), hit.prim_ref, cur.origin + cur.dir * hit.t, n);
        let m = s.m;
        var weight = cur.weight;
#ifdef ALPHA
        if (m.flags & MATERIAL_ALPHA) != 0u {
            // What the surface lets through goes on as a ray of its own (render::shade).
            let c = coverage(m, s.alpha);
            if c < 1.0 && ray_stack_size(&rs) < WHITTED_STACK {
                let side = select(-n, n, dot(cur.dir, n) >= 0.0);
                ray_stack_push(&rs, Pending(spawn_origin(cur.origin, cur.dir, hit.t, side), cur.dir, weight * (1.0 - c), cur.depth));
            }
            if c <= 0.0 {
                continue;
            }
            weight = weight * c;
        }
#endif
        let front = dot(cur.dir, n) < 0.0;
        let fr = shading_frame(m, front, n, s.normal, -cur.dir);
        let ng = fr.ng;
        let ns = fr.ns;
        // A mirror direction about the shading normal that falls below the face is taken about
        // the face's normal instead.
        var mirrored = reflect_dir(cur.dir, ns);
        if dot(mirrored, ng) <= 0.0 {
            mirrored = reflect_dir(cur.dir, ng);
        }
        var handled = false;
#ifdef EMISSIVE
        if m.kind == MAT_EMISSIVE {
            color += weight * m.radiance;
            handled = true;
        }
#endif
#ifdef MIRROR
        if m.kind == MAT_MIRROR {
            if cur.depth < max_depth && ray_stack_size(&rs) < WHITTED_STACK {
                ray_stack_push(&rs, Pending(spawn_origin(cur.origin, cur.dir, hit.t, ng), mirrored, weight * m.color, cur.depth + 1u));
            }
            handled = true;
        }
#endif
#ifdef PBR
        if m.kind == MAT_PBR {
            // Whitted follows one mirror ray for the lobe's sharp part (render::shade).
            let l = pbr_lobes(m, dot(-cur.dir, ns));
            let rough = 1.0 - clamp(m.roughness, 0.0, 1.0);
            let sharp = rough * rough;
            let diffuse = l.diffuse + l.spec_albedo * (1.0 - sharp);
            color += weight * m.radiance;
            color += weight * direct_light(cur.origin, cur.dir, hit.t, ng, ns, diffuse);
            if cur.depth < max_depth && ray_stack_size(&rs) < WHITTED_STACK && sharp > 0.0 {
                ray_stack_push(&rs, Pending(spawn_origin(cur.origin, cur.dir, hit.t, ng), mirrored, weight * (l.spec_albedo * sharp), cur.depth + 1u));
            }
            handled = true;
        }
#endif
#ifdef DIELECTRIC
        if m.kind == MAT_DIELECTRIC {
            if cur.depth < max_depth {
                let cos_i = -dot(cur.dir, ns);
                let eta = select(1.0 / m.ior, m.ior, front);
                let f = fresnel_dielectric(cos_i, eta);
                if ray_stack_size(&rs) < WHITTED_STACK {
                    ray_stack_push(&rs, Pending(spawn_origin(cur.origin, cur.dir, hit.t, ns), reflect_dir(cur.dir, ns), weight * f, cur.depth + 1u));
                }
                if f < 1.0 && ray_stack_size(&rs) < WHITTED_STACK {
                    let t = refract_dir(cur.dir, ns, cos_i, 1.0 / eta);
                    ray_stack_push(&rs, Pending(spawn_origin(cur.origin, cur.dir, hit.t, -ns), t, weight * m.color * (1.0 - f), cur.depth + 1u));
                }
            }
            handled = true;
        }
#endif
        if !handled {
            color += weight * direct_light(cur.origin, cur.dir, hit.t, ng, ns, m.color);
        }
    }
    return color;
}

// Sum (not mean) of samples sample_base .. sample_base + spp of pixel (x, y); the host
// divides by the total sample count, as render::shade::shade_pixel does.
fn shade_pixel_sum(x: u32, y: u32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    for (var s = 0u; s < frame.spp; s += 1u) {
        let ray = primary_ray(frame, x, y, frame.sample_base + s);
        let c = radiance(ray.origin, ray.dir);
        // A non-finite sample (never on a valid scene) counts as black.
        let finite = all(abs(c) <= vec3<f32>(F32_MAX));
        if finite {
            sum += c;
        }
    }
    return sum;
}
