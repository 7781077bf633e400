// Path tracing entry point, one sample per pixel per dispatch (the megakernel): twin of
// crates/cpu/src/path.rs (radiance). Each vertex is shaded by strahl::path (next-event estimation
// with MIS by the power heuristic, Russian roulette from rr_depth segments on; max_depth counts
// segments as Mitsuba does), and its area-light shadow ray is traced at once.
#import strahl::types::{FRAME_ACCUMULATE, F32_MAX}
#import strahl::bindings::frame
#import strahl::traverse::{nearest_hit, occluded}
#import strahl::camera::{tile_pixel, output_index}
#import strahl::path::{PathState, NeeRay, path_start, shade_vertex, finite_or_black}

@group(1) @binding(0) var<storage, read_write> output: array<vec4<f32>>;

@compute @workgroup_size(#{TILE_WORKGROUP}, #{TILE_WORKGROUP}, 1)
fn render_path(@builtin(global_invocation_id) gid: vec3<u32>) {
    let px = tile_pixel(frame, gid);
    if px.z == 0u {
        return;
    }
    var p = path_start(px.x, px.y, frame.sample_base);
    var nee: NeeRay;
    loop {
        let hit = nearest_hit(p.o, p.d, 0.0, F32_MAX);
        let more = shade_vertex(&p, hit, &nee);
        if nee.valid != 0u && !occluded(nee.origin, nee.dir, 0.0, nee.dist) {
            p.sum += nee.value;
        }
        if !more {
            break;
        }
    }
    let c = finite_or_black(p.sum);
    let i = output_index(frame, px.x, px.y);
    if (frame.flags & FRAME_ACCUMULATE) != 0u {
        output[i] += vec4<f32>(c, 0.0);
    } else {
        output[i] = vec4<f32>(c, 1.0);
    }
}
