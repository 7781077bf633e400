// Render entry point: one invocation per pixel of the dispatched tile.
#import strahl::types::{FRAME_ACCUMULATE}
#import strahl::bindings::frame
#import strahl::shade::shade_pixel_sum

@group(1) @binding(0) var<storage, read_write> output: array<vec4<f32>>;

@compute @workgroup_size(8, 8, 1)
fn render(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= frame.tile_size.x || gid.y >= frame.tile_size.y {
        return;
    }
    let x = frame.tile_origin.x + gid.x;
    let y = frame.tile_origin.y + gid.y;
    if x >= frame.width || y >= frame.height {
        return;
    }
    let sum = shade_pixel_sum(x, y);
    let i = (y - frame.out_first_row) * frame.out_pitch + x;
    if (frame.flags & FRAME_ACCUMULATE) != 0u {
        output[i] += vec4<f32>(sum, 0.0);
    } else {
        output[i] = vec4<f32>(sum, 1.0);
    }
}
