// Output variables besides radiance (strahl render --aov, the denoiser's guides): twin of
// crates/core/src/render/aov.rs (value; driven by crates/cpu/src/aov.rs there, by
// crates/gpu/src/aov.rs here). One invocation per pixel of the dispatched tile, one camera ray
// per dispatch (sample frame.sample_base, the R2 offsets of camera.wgsl), written or added
// (FRAME_ACCUMULATE) to the output buffer, as the render programs do. The pass is
// frame.flags >> AOV_PASS_SHIFT:
//   albedo:    (albedo of the first non-specular surface, 0)
//   normal:    (its shading normal, 0)
//   first hit: (depth, object index, material index, 0) of the first surface the ray stops at
//   position:  (that surface's point, 0)
// Composed with the geometry, material and asset flags (FeatureKey::for_program): no lights.
#import strahl::types::{Material, F32_MAX, FRAME_ACCUMULATE, MAT_EMISSIVE}
#import strahl::bindings::{frame, load_material}
#import strahl::camera::{primary_ray, tile_pixel, output_index}
#import strahl::traverse::{nearest_hit, hit_normal, hit_material, prim_tag}
#import strahl::spawn::spawn_origin
#import strahl::surface::{Surface, surface, shading_frame}
#import strahl::bsdf::{bsdf_sample, is_specular}
#ifdef ALPHA
#import strahl::types::MATERIAL_ALPHA
#import strahl::surface::coverage
#endif
#ifdef ENVIRONMENT
#import strahl::environment::env_background
#endif

@group(1) @binding(0) var<storage, read_write> output: array<vec4<f32>>;

const AOV_CHAIN: u32 = #{AOV_CHAIN};
const AOV_PASS_SHIFT: u32 = #{AOV_PASS_SHIFT};
const AOV_PASS_ALBEDO: u32 = #{AOV_PASS_ALBEDO};
const AOV_PASS_FIRST_HIT: u32 = #{AOV_PASS_FIRST_HIT};
const AOV_PASS_POSITION: u32 = #{AOV_PASS_POSITION};

// render::aov::albedo.
fn guide_albedo(m: Material) -> vec3<f32> {
    var c = m.color;
    if m.kind == MAT_EMISSIVE {
        c = m.radiance;
    }
    return clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
}

// render::aov::passes_through.
fn passes_through(s: Surface) -> bool {
#ifdef ALPHA
    return (s.m.flags & MATERIAL_ALPHA) != 0u && coverage(s.m, s.alpha) < 0.5;
#else
    return false;
#endif
}

fn background(d: vec3<f32>) -> vec3<f32> {
#ifdef ENVIRONMENT
    return env_background(d);
#else
    return frame.background;
#endif
}

// render::aov::guides (the albedo and normal passes) and render::aov::first_hit (the others).
fn aov_value(pass_id: u32, origin: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    var miss = vec3<f32>(0.0);
    if pass_id == AOV_PASS_FIRST_HIT {
        miss = vec3<f32>(0.0, -1.0, -1.0);
    }
    var o = origin;
    var d = dir;
    var travelled = 0.0;
    var tint = vec3<f32>(1.0);
    for (var k = 0u; k < AOV_CHAIN; k++) {
        let hit = nearest_hit(o, d, 0.0, F32_MAX);
        if !hit.found {
            if pass_id == AOV_PASS_ALBEDO {
                return tint * clamp(background(d), vec3<f32>(0.0), vec3<f32>(1.0));
            }
            return miss;
        }
        let n = hit_normal(hit, o, d);
        let material = hit_material(hit);
        let s = surface(load_material(material), hit.prim_ref, o + d * hit.t, n);
        if passes_through(s) {
            travelled += hit.t;
            o = spawn_origin(o, d, hit.t, select(-n, n, dot(d, n) >= 0.0));
            continue;
        }
        if pass_id == AOV_PASS_FIRST_HIT {
            return vec3<f32>(travelled + hit.t, f32(prim_tag(hit.prim_ref).x), f32(material));
        }
        if pass_id == AOV_PASS_POSITION {
            return o + d * hit.t;
        }
        let m = s.m;
        let wo = -d;
        let front = dot(d, n) < 0.0;
        let ns = shading_frame(m, front, n, s.normal, wo).ns;
        if !is_specular(m) {
            if pass_id == AOV_PASS_ALBEDO {
                return tint * guide_albedo(m);
            }
            return ns;
        }
        let b = bsdf_sample(m, wo, ns, front, vec3<f32>(0.5));
        if !b.valid {
            return miss;
        }
        tint *= b.weight;
        o = spawn_origin(o, d, hit.t, select(-n, n, dot(b.dir, n) >= 0.0));
        d = b.dir;
    }
    return miss;
}

@compute @workgroup_size(#{TILE_WORKGROUP}, #{TILE_WORKGROUP}, 1)
fn aov(@builtin(global_invocation_id) gid: vec3<u32>) {
    let px = tile_pixel(frame, gid);
    if px.z == 0u {
        return;
    }
    let ray = primary_ray(frame, px.x, px.y, frame.sample_base);
    let v = vec4<f32>(aov_value(frame.flags >> AOV_PASS_SHIFT, ray.origin, ray.dir), 0.0);
    let i = output_index(frame, px.x, px.y);
    if (frame.flags & FRAME_ACCUMULATE) != 0u {
        output[i] += v;
    } else {
        output[i] = v;
    }
}
