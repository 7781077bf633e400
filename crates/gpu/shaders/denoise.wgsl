// The denoiser: twin of crates/core/src/denoise.rs (prepare, atrous, finish), by the same
// operations; the method, its sources and its parameters are described there. Standalone: it
// imports nothing; only the shared values are substituted (host:
// crates/gpu/src/denoise.rs). One invocation per pixel; the host runs prepare, atrous once per
// step (1, 2, 4, ...) between two work buffers, then finish.

struct Params {
    width: u32,
    height: u32,
    // Tap spacing in pixels (atrous).
    step: u32,
    pad: u32,
}

const DENOISE_SIGMA_L: f32 = #{DENOISE_SIGMA_L};
const DENOISE_SIGMA_N2: f32 = #{DENOISE_SIGMA_N2};
const DENOISE_SIGMA_A2: f32 = #{DENOISE_SIGMA_A2};
const DENOISE_ALBEDO_EPS: f32 = #{DENOISE_ALBEDO_EPS};
const DENOISE_VARIANCE_EPS: f32 = #{DENOISE_VARIANCE_EPS};

// Storage, not uniform, for the reason in bindings.wgsl.
@group(0) @binding(0) var<storage, read> p: Params;
// The render's mean radiance (rgb).
@group(0) @binding(1) var<storage, read> color: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> albedo: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> normal: array<vec4<f32>>;
// Work pixels: demodulated radiance (rgb) and luminance variance (w).
@group(0) @binding(4) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> dst: array<vec4<f32>>;

fn luminance(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

fn dist2(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let d = a - b;
    return d.x * d.x + d.y * d.y + d.z * d.z;
}

fn demodulated(i: u32) -> vec3<f32> {
    let c = color[i].xyz;
    let a = albedo[i].xyz;
    return vec3<f32>(c.x / (a.x + DENOISE_ALBEDO_EPS), c.y / (a.y + DENOISE_ALBEDO_EPS), c.z / (a.z + DENOISE_ALBEDO_EPS));
}

@compute @workgroup_size(#{DENOISE_WORKGROUP}, #{DENOISE_WORKGROUP}, 1)
fn prepare(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= p.width || gid.y >= p.height {
        return;
    }
    let x = i32(gid.x);
    let y = i32(gid.y);
    var s1 = 0.0;
    var s2 = 0.0;
    var n = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let qx = x + dx;
            let qy = y + dy;
            if qx < 0 || qy < 0 || qx >= i32(p.width) || qy >= i32(p.height) {
                continue;
            }
            let l = luminance(demodulated(u32(qy) * p.width + u32(qx)));
            s1 += l;
            s2 += l * l;
            n += 1.0;
        }
    }
    let mean = s1 / n;
    let i = gid.y * p.width + gid.x;
    dst[i] = vec4<f32>(demodulated(i), max(s2 / n - mean * mean, 0.0));
}

@compute @workgroup_size(#{DENOISE_WORKGROUP}, #{DENOISE_WORKGROUP}, 1)
fn atrous(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= p.width || gid.y >= p.height {
        return;
    }
    let kernel = array<f32, 3>(0.25, 0.5, 0.25);
    let x = i32(gid.x);
    let y = i32(gid.y);
    let step = i32(p.step);
    let i = gid.y * p.width + gid.x;
    let c = src[i];
    let lp = luminance(c.xyz);
    let np = normal[i].xyz;
    let ap = albedo[i].xyz;
    let scale = 1.0 / (DENOISE_SIGMA_L * sqrt(c.w) + DENOISE_VARIANCE_EPS);
    var sum = vec3<f32>(0.0);
    var sum_w = 0.0;
    var sum_var = 0.0;
    for (var j = 0; j < 3; j++) {
        for (var k = 0; k < 3; k++) {
            let qx = x + (k - 1) * step;
            let qy = y + (j - 1) * step;
            if qx < 0 || qy < 0 || qx >= i32(p.width) || qy >= i32(p.height) {
                continue;
            }
            let q = u32(qy) * p.width + u32(qx);
            let d = src[q];
            let dl = abs(luminance(d.xyz) - lp) * scale;
            let e = dl + dist2(normal[q].xyz, np) / DENOISE_SIGMA_N2 + dist2(albedo[q].xyz, ap) / DENOISE_SIGMA_A2;
            let w = kernel[k] * kernel[j] * exp(-e);
            sum.x += w * d.x;
            sum.y += w * d.y;
            sum.z += w * d.z;
            sum_w += w;
            sum_var += w * w * d.w;
        }
    }
    dst[i] = vec4<f32>(sum.x / sum_w, sum.y / sum_w, sum.z / sum_w, sum_var / (sum_w * sum_w));
}

@compute @workgroup_size(#{DENOISE_WORKGROUP}, #{DENOISE_WORKGROUP}, 1)
fn finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= p.width || gid.y >= p.height {
        return;
    }
    let i = gid.y * p.width + gid.x;
    let d = src[i];
    let a = albedo[i].xyz;
    dst[i] = vec4<f32>(d.x * (a.x + DENOISE_ALBEDO_EPS), d.y * (a.y + DENOISE_ALBEDO_EPS), d.z * (a.z + DENOISE_ALBEDO_EPS), 0.0);
}
