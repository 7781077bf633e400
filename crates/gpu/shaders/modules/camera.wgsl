// Primary rays: twin of crates/core/src/render/camera.rs (in lanes, a batch's: crates/cpu/src/lanes/camera.rs).
#define_import_path strahl::camera

#import strahl::types::Frame

// R2 sub-pixel offset of sample s (the first one is the pixel centre).
fn sample_offset(s: u32) -> vec2<f32> {
    let sf = f32(s);
    return fract(vec2<f32>(0.5 + sf * 0.7548777, 0.5 + sf * 0.5698403));
}

struct RayPair {
    origin: vec3<f32>,
    dir: vec3<f32>,
}

// The image pixel (x, y) that invocation gid of a tile dispatch covers; z = 0 where the
// invocation lies outside the tile or the image (dispatches round up to whole workgroups).
fn tile_pixel(f: Frame, gid: vec3<u32>) -> vec3<u32> {
    let x = f.tile_origin.x + gid.x;
    let y = f.tile_origin.y + gid.y;
    let inside = gid.x < f.tile_size.x && gid.y < f.tile_size.y && x < f.width && y < f.height;
    return vec3<u32>(x, y, select(0u, 1u, inside));
}

// Index of image pixel (x, y) in the output buffer, which holds rows from out_first_row on.
fn output_index(f: Frame, x: u32, y: u32) -> u32 {
    return (y - f.out_first_row) * f.out_pitch + x;
}

fn primary_ray(f: Frame, x: u32, y: u32, s: u32) -> RayPair {
    return ray_through(f, x, y, sample_offset(s));
}

// The ray through sub-pixel position off in [0, 1)^2 of pixel (x, y).
fn ray_through(f: Frame, x: u32, y: u32, off: vec2<f32>) -> RayPair {
    let u = 2.0 * (f32(x) + off.x) / f32(f.width) - 1.0;
    let v = 1.0 - 2.0 * (f32(y) + off.y) / f32(f.height);
    let dir = f.forward + f.right * u + f.up * v;
    return RayPair(f.eye, normalize(dir));
}
