// Path tracing entry point, one sample per pixel per dispatch: twin of src/render/path.rs
// (next-event estimation with MIS by the power heuristic, Russian roulette from rr_depth
// segments on; max_depth counts segments as Mitsuba does; point and directional lights evaluated
// at every vertex). Random numbers are drawn in the same order as there: three for the area-light
// sample at every vertex, three for the BSDF, one for Russian roulette when it applies.
#import strahl::types::{FRAME_ACCUMULATE, MAT_EMISSIVE, KIND_TRIANGLE, KIND_SPHERE, INDEX_BITS, F32_MAX}
#import strahl::bindings::{frame, materials}
#ifdef LIGHTS
#import strahl::bindings::lights
#endif
#import strahl::traverse::{nearest_hit, occluded, hit_normal, hit_material}
#import strahl::spawn::spawn_origin
#import strahl::raygen::{tile_pixel, output_index, ray_through}
#import strahl::sampler::{sampler_new, next_f32, uniform3, pixel_jitter}
#import strahl::bsdf::{bsdf_sample, bsdf_eval, is_specular}
#import strahl::emitters::{sample_light, area_pdf, emitted_cos}
#ifdef LIGHTS
#import strahl::emitters::delta_light
#endif
#ifdef TEXTURES
#import strahl::texture::textured
#endif
#ifdef ENVIRONMENT
#import strahl::environment::{env_background, env_pdf}
#endif

@group(1) @binding(0) var<storage, read_write> output: array<vec4<f32>>;

// Shadow rays stop this fraction short of the light point (render::path::SHADOW_REACH).
const SHADOW_REACH: f32 = 0.999755859375;

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

fn path_radiance(origin: vec3<f32>, dir: vec3<f32>, rng: ptr<function, u32>) -> vec3<f32> {
    var o = origin;
    var d = dir;
    var beta = vec3<f32>(1.0);
    var sum = vec3<f32>(0.0);
    var specular = true;
    var pdf_bsdf = 0.0;
    for (var seg = 1u; seg <= frame.max_depth; seg += 1u) {
        let hit = nearest_hit(o, d, 0.0, F32_MAX);
        if !hit.found {
#ifdef ENVIRONMENT
            // Weighted against next-event estimation's samples of the environment.
            var w = 1.0;
            if !specular {
                w = power_heuristic(pdf_bsdf, env_pdf(d));
            }
            sum += beta * env_background(d) * w;
#else
            sum += beta * frame.background;
#endif
            break;
        }
#ifdef TEXTURES
        let m = textured(materials[hit_material(hit)], hit.prim, o + d * hit.t);
#else
        let m = materials[hit_material(hit)];
#endif
        let n = hit_normal(hit, o, d);
        let front = dot(d, n) < 0.0;
        let ns = select(-n, n, front);
#ifdef EMISSIVE
        if m.kind == MAT_EMISSIVE {
            let cos_l = emitted_cos(m.flags, -dot(d, n));
            if cos_l > 0.0 {
                let kind = hit.prim >> INDEX_BITS;
                let sampled = kind == KIND_TRIANGLE || kind == KIND_SPHERE;
                var w = 1.0;
                if !specular && sampled {
                    w = power_heuristic(pdf_bsdf, area_pdf(m.radiance, hit.t * hit.t, cos_l));
                }
                sum += beta * m.radiance * w;
            }
        }
#endif
        if seg == frame.max_depth {
            break;
        }
        let wo = -d;
        let u_light = uniform3(rng);
        if !is_specular(m) {
            let ls = sample_light(o + d * hit.t, u_light);
            if ls.valid {
                let ev = bsdf_eval(m, wo, ls.dir, ns);
                if max3(ev.f_cos) > 0.0 {
                    let so = spawn_origin(o, d, hit.t, ns);
                    if !occluded(so, ls.dir, 0.0, ls.dist * SHADOW_REACH) {
                        sum += beta * ev.f_cos * ls.value * power_heuristic(ls.pdf, ev.pdf);
                    }
                }
            }
        }
#ifdef LIGHTS
        // Point and directional lights, each at every vertex (render::path: chosen by power
        // with the area lights, one could be starved).
        if !is_specular(m) {
            let p = o + d * hit.t;
            for (var i = 0u; i < frame.num_lights; i += 1u) {
                let dl = delta_light(lights[i], p);
                if dl.valid {
                    let ev = bsdf_eval(m, wo, dl.dir, ns);
                    if max3(ev.f_cos) > 0.0 {
                        let so = spawn_origin(o, d, hit.t, ns);
                        if !occluded(so, dl.dir, 0.0, dl.dist * SHADOW_REACH) {
                            sum += beta * ev.f_cos * dl.value;
                        }
                    }
                }
            }
        }
#endif
        let bs = bsdf_sample(m, wo, ns, front, uniform3(rng));
        if !bs.valid {
            break;
        }
        beta = beta * bs.weight;
        specular = bs.specular;
        pdf_bsdf = bs.pdf;
        if seg >= frame.rr_depth {
            let q = min(max3(beta), 0.95);
            if next_f32(rng) >= q {
                break;
            }
            beta = beta / q;
        }
        let side = select(-n, n, dot(bs.dir, n) >= 0.0);
        o = spawn_origin(o, d, hit.t, side);
        d = bs.dir;
    }
    return sum;
}

@compute @workgroup_size(8, 8, 1)
fn render_path(@builtin(global_invocation_id) gid: vec3<u32>) {
    let px = tile_pixel(frame, gid);
    if px.z == 0u {
        return;
    }
    let s = frame.sample_base;
    let pixel = px.y * frame.width + px.x;
    var rng = sampler_new(pixel, s, frame.seed);
    let ray = ray_through(frame, px.x, px.y, pixel_jitter(pixel, s, frame.seed));
    var c = path_radiance(ray.origin, ray.dir, &rng);
    // A non-finite sample (never on a valid scene) counts as black.
    if !all(abs(c) <= vec3<f32>(F32_MAX)) {
        c = vec3<f32>(0.0);
    }
    let i = output_index(frame, px.x, px.y);
    if (frame.flags & FRAME_ACCUMULATE) != 0u {
        output[i] += vec4<f32>(c, 0.0);
    } else {
        output[i] = vec4<f32>(c, 1.0);
    }
}
