// The viewer's present pass (strahl view): turns the accumulation buffer of the render or
// view program (sums of samples) into the rgba8unorm texture egui shows, with no trip through
// the CPU. Standalone: it imports nothing; only the shared values (#{NAME}) are substituted
// (host: crates/viewer/src/gpu.rs; no CPU twin, the CPU renders have no present pass).
//
// A pixel holds `samples` samples, plus one when its tile (tile × tile pixels, row-major, as
// render::Band orders them) is among the first `next_tile` tiles of the pass in progress.
// A pixel with no sample yet keeps what the texture showed.

struct Present {
    width: u32,
    height: u32,
    samples: u32,
    next_tile: u32,
    tiles_x: u32,
    tile: u32,
    // The view mode (ViewMode in crates/viewer/src/gpu.rs): the image modes (Whitted, path) show the
    // mean colour; VIEW_NORMALS, VIEW_DEPTH and VIEW_COST are the debug views.
    mode: u32,
    pad0: u32,
    // Depth mode: distances shown white (near) to dark (far), by inverse distance.
    near: f32,
    far: f32,
    // Cost mode: the cost shown at the hot end of the colour map.
    heat_max: f32,
    pad1: f32,
}

const VIEW_NORMALS: u32 = #{VIEW_NORMALS};
const VIEW_DEPTH: u32 = #{VIEW_DEPTH};
const VIEW_COST: u32 = #{VIEW_COST};

// Storage, not uniform, for the reason in bindings.wgsl (one present pass per UI frame).
@group(0) @binding(0) var<storage, read> p: Present;
@group(0) @binding(1) var<storage, read> accum: array<vec4<f32>>;
@group(0) @binding(2) var image: texture_storage_2d<rgba8unorm, write>;

// The sRGB transfer function on [0, 1] (crates/core/src/image.rs: linear_to_srgb).
fn linear_to_srgb(v: vec3<f32>) -> vec3<f32> {
    let c = clamp(v, vec3<f32>(0.0), vec3<f32>(1.0));
    let lo = 12.92 * c;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

// Google's Turbo colour map, polynomial fit (Mikhailov 2019), t in [0, 1]; sRGB-encoded.
fn turbo(t: f32) -> vec3<f32> {
    let x = clamp(t, 0.0, 1.0);
    let r = vec4<f32>(0.13572138, 4.61539260, -42.66032258, 132.13108234);
    let g = vec4<f32>(0.09140261, 2.19418839, 4.84296658, -14.18503333);
    let b = vec4<f32>(0.10667330, 12.64194608, -60.58204836, 110.36276771);
    let r2 = vec2<f32>(-152.94239396, 59.28637943);
    let g2 = vec2<f32>(4.27729857, 2.82956604);
    let b2 = vec2<f32>(-89.90310912, 27.34824973);
    let v4 = vec4<f32>(1.0, x, x * x, x * x * x);
    let v2 = v4.zw * v4.z;
    return clamp(
        vec3<f32>(dot(v4, r) + dot(v2, r2), dot(v4, g) + dot(v2, g2), dot(v4, b) + dot(v2, b2)),
        vec3<f32>(0.0),
        vec3<f32>(1.0),
    );
}

@compute @workgroup_size(8, 8, 1)
fn present(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = gid.x;
    let y = gid.y;
    if x >= p.width || y >= p.height {
        return;
    }
    let tile_index = (y / p.tile) * p.tiles_x + x / p.tile;
    let n = p.samples + select(0u, 1u, tile_index < p.next_tile);
    if n == 0u {
        return;
    }
    let a = accum[y * p.width + x];
    let inv = 1.0 / f32(n);
    // Fraction of the pixel's samples that hit something (debug modes).
    let coverage = a.w * inv;
    var rgb: vec3<f32>;
    switch p.mode {
        case VIEW_NORMALS: {
            let nrm = a.xyz / max(a.w, 1.0);
            rgb = (nrm * 0.5 + 0.5) * coverage;
        }
        case VIEW_DEPTH: {
            // Inverse distance between near and far: more contrast close to the eye.
            let t = max(a.x / max(a.w, 1.0), 1e-20);
            let near = max(p.near, 0.02 * p.far);
            let v = clamp((1.0 / t - 1.0 / p.far) / max(1.0 / near - 1.0 / p.far, 1e-20), 0.0, 1.0);
            rgb = vec3<f32>(0.1 + 0.9 * v) * coverage;
        }
        case VIEW_COST: {
            rgb = turbo((a.x + a.y) * inv / p.heat_max);
        }
        default: {
            rgb = linear_to_srgb(a.xyz / f32(n));
        }
    }
    textureStore(image, vec2<i32>(i32(x), i32(y)), vec4<f32>(rgb, 1.0));
}
