// Random numbers of the path tracer: twin of crates/core/src/render/sampler.rs (PCG-RXS-M-XS 32 started
// from pcg_hash of the counters; Jarzynski & Olano, JCGT 2020). u32 arithmetic only, so both
// backends draw identical numbers for the same pixel, sample and seed.
#define_import_path strahl::sampler

#import strahl::camera::sample_offset

const PCG_MULT: u32 = #{PCG_MULT};
const PCG_INC: u32 = #{PCG_INC};

fn pcg_permute(state: u32) -> u32 {
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn pcg_hash(v: u32) -> u32 {
    return pcg_permute(v * PCG_MULT + PCG_INC);
}

// The stream of sample `s` of pixel `pixel` under `seed`.
fn sampler_new(pixel: u32, s: u32, seed: u32) -> u32 {
    return pcg_hash(pixel ^ pcg_hash(s + pcg_hash(seed)));
}

fn next_u32(state: ptr<function, u32>) -> u32 {
    let old = *state;
    *state = old * PCG_MULT + PCG_INC;
    return pcg_permute(old);
}

// Uniform in [0, 1) from the top 24 bits (exact conversion).
fn next_f32(state: ptr<function, u32>) -> f32 {
    return f32(next_u32(state) >> 8u) * (1.0 / 16777216.0);
}

fn uniform3(state: ptr<function, u32>) -> vec3<f32> {
    let a = next_f32(state);
    let b = next_f32(state);
    return vec3<f32>(a, b, next_f32(state));
}

// R2 sub-pixel position of sample s, rotated by a per-pixel random offset.
fn pixel_jitter(pixel: u32, s: u32, seed: u32) -> vec2<f32> {
    let h = pcg_hash(pixel ^ pcg_hash(seed ^ 0x5bd1e995u));
    let rx = f32(h >> 8u) * (1.0 / 16777216.0);
    let ry = f32(pcg_hash(h) >> 8u) * (1.0 / 16777216.0);
    let o = sample_offset(s);
    let v = o + vec2<f32>(rx, ry);
    return v - floor(v);
}
