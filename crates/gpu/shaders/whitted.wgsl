// Render entry point: one invocation per pixel of the dispatched tile; twin of
// crates/cpu/src/render.rs (render, one pixel per iteration over rayon's rows; its camera rays in lanes:
// crates/cpu/src/lanes/whitted.rs).
#import strahl::types::{FRAME_ACCUMULATE}
#import strahl::bindings::frame
#import strahl::shade::shade_pixel_sum
#import strahl::camera::{tile_pixel, output_index}

@group(1) @binding(0) var<storage, read_write> output: array<vec4<f32>>;

@compute @workgroup_size(#{TILE_WORKGROUP}, #{TILE_WORKGROUP}, 1)
fn render(@builtin(global_invocation_id) gid: vec3<u32>) {
    let px = tile_pixel(frame, gid);
    if px.z == 0u {
        return;
    }
    let sum = shade_pixel_sum(px.x, px.y);
    let i = output_index(frame, px.x, px.y);
    if (frame.flags & FRAME_ACCUMULATE) != 0u {
        output[i] += vec4<f32>(sum, 0.0);
    } else {
        output[i] = vec4<f32>(sum, 1.0);
    }
}
