// The viewer's debug images (strahl view): one invocation per pixel of the dispatched tile,
// like whitted.wgsl, one primary ray per dispatch (sample frame.sample_base), written or added
// (FRAME_ACCUMULATE) to the same output buffer. shaders/present.wgsl turns the sums into colours.
// No CPU twin: the debug views exist only in the viewer (host: crates/viewer/src/gpu.rs).
//
// The mode is frame.flags >> VIEW_MODE_SHIFT (crates/viewer/src/gpu.rs: ViewMode):
//   normals: (front-face unit normal, 1) where the ray hits, 0 where it misses;
//   depth:   (t, 0, 0, 1) where it hits, 0 where it misses;
//   cost:    (BVH nodes visited, primitives tested, 0, 1) by the nearest-hit search.
// Composed with COUNT_VISITS (shaders/modules/traverse.wgsl counts its work) and the geometry flags only.
#import strahl::types::{FRAME_ACCUMULATE, F32_MAX}
#import strahl::bindings::frame
#import strahl::camera::{primary_ray, tile_pixel, output_index}
#import strahl::traverse::{nearest_hit, hit_normal, visited_nodes, tested_prims}

@group(1) @binding(0) var<storage, read_write> output: array<vec4<f32>>;

const VIEW_MODE_SHIFT: u32 = #{VIEW_MODE_SHIFT};
const VIEW_NORMALS: u32 = #{VIEW_NORMALS};
const VIEW_DEPTH: u32 = #{VIEW_DEPTH};
const VIEW_COST: u32 = #{VIEW_COST};

@compute @workgroup_size(#{TILE_WORKGROUP}, #{TILE_WORKGROUP}, 1)
fn view(@builtin(global_invocation_id) gid: vec3<u32>) {
    let px = tile_pixel(frame, gid);
    if px.z == 0u {
        return;
    }
    let ray = primary_ray(frame, px.x, px.y, frame.sample_base);
    visited_nodes = 0u;
    tested_prims = 0u;
    let hit = nearest_hit(ray.origin, ray.dir, 0.0, F32_MAX);
    let mode = frame.flags >> VIEW_MODE_SHIFT;
    var v = vec4<f32>(0.0);
    if mode == VIEW_COST {
        v = vec4<f32>(f32(visited_nodes), f32(tested_prims), 0.0, 1.0);
    } else if hit.found {
        if mode == VIEW_NORMALS {
            v = vec4<f32>(hit_normal(hit, ray.origin, ray.dir), 1.0);
        } else if mode == VIEW_DEPTH {
            v = vec4<f32>(hit.t, 0.0, 0.0, 1.0);
        }
    }
    let i = output_index(frame, px.x, px.y);
    if (frame.flags & FRAME_ACCUMULATE) != 0u {
        output[i] += v;
    } else {
        output[i] = v;
    }
}
