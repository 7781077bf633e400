// Environment lighting: twin of crates/core/src/render/environment.rs (in lanes crates/cpu/src/lanes/environment.rs; radiance along a direction, the
// piecewise-constant importance distribution over an equirectangular map and its density,
// uniform sphere sampling for a constant sky, Whitted's spherical-harmonic diffuse light).
//
// Shader defs: ENVIRONMENT (the scene has one; the frame flag FRAME_ENVIRONMENT says whether
// this scene does, for variants compiled with more features than the scene uses), ENV_MAP (a
// map rather than a constant).
#define_import_path strahl::environment

#ifdef ENVIRONMENT
#import strahl::types::{Environment, FRAME_ENVIRONMENT, ENV_FLAG_MAP, ENV_FLAG_UNIFORM}
#import strahl::bindings::{frame, load_environment}
#ifdef ENV_MAP
#import strahl::bindings::{env_distribution, load_texture}
#import strahl::texture::texture_sample
#endif

const PI: f32 = 3.14159265358979;

struct EnvSample {
    dir: vec3<f32>,
    // Radiance along dir over pdf.
    value: vec3<f32>,
    pdf: f32,
    valid: bool,
}

fn env_present() -> bool {
    return (frame.flags & FRAME_ENVIRONMENT) != 0u;
}

// d turned from the world into the map's frame, and back.
fn to_map(e: Environment, d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(e.rot_cos * d.x - e.rot_sin * d.z, d.y, e.rot_sin * d.x + e.rot_cos * d.z);
}

fn from_map(e: Environment, d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(e.rot_cos * d.x + e.rot_sin * d.z, d.y, -e.rot_sin * d.x + e.rot_cos * d.z);
}

#ifdef ENV_MAP
fn map_uv(e: Environment, d: vec3<f32>) -> vec2<f32> {
    let m = to_map(e, d);
    return vec2<f32>(0.5 + atan2(m.x, m.z) * (0.5 / PI), acos(clamp(m.y, -1.0, 1.0)) * (1.0 / PI));
}

// First cell k in 0..n with u < cdf[first + k + 1].
fn find_cell(first: u32, n: u32, u: f32) -> u32 {
    var lo = 0u;
    var hi = n - 1u;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if u < env_distribution(first + mid + 1u) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

fn cell_pdf(e: Environment, i: u32, j: u32) -> f32 {
    let row = e.height + 1u + j * (e.width + 1u);
    let pu = (env_distribution(row + i + 1u) - env_distribution(row + i)) * f32(e.width);
    return pu * ((env_distribution(j + 1u) - env_distribution(j)) * f32(e.height));
}
#endif

// Radiance seen by a ray leaving along d: the environment, else the frame's background.
fn env_background(d: vec3<f32>) -> vec3<f32> {
    if !env_present() {
        return frame.background;
    }
    let e = load_environment();
#ifdef ENV_MAP
    if (e.flags & ENV_FLAG_MAP) != 0u {
        return e.radiance * texture_sample(load_texture(e.texture), map_uv(e, d)).xyz;
    }
#endif
    return e.radiance;
}

// Solid-angle density of next-event estimation's choice of d (0 without an environment).
fn env_pdf(d: vec3<f32>) -> f32 {
    if !env_present() {
        return 0.0;
    }
    let e = load_environment();
    if (e.flags & ENV_FLAG_UNIFORM) != 0u {
        return e.select_prob * (0.25 / PI);
    }
#ifdef ENV_MAP
    let uv = map_uv(e, d);
    let i = min(u32(uv.x * f32(e.width)), e.width - 1u);
    let j = min(u32(uv.y * f32(e.height)), e.height - 1u);
    let m = to_map(e, d);
    let sin_theta = sqrt(m.x * m.x + m.z * m.z);
    if sin_theta <= 0.0 {
        return 0.0;
    }
    return e.select_prob * cell_pdf(e, i, j) / (2.0 * PI * PI * sin_theta);
#else
    return 0.0;
#endif
}

// A direction towards the environment from two uniform numbers (render::environment::sample).
fn env_sample(u1: f32, u2: f32) -> EnvSample {
    let none = EnvSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false);
    let e = load_environment();
    var d: vec3<f32>;
    var pdf: f32;
    if (e.flags & ENV_FLAG_UNIFORM) != 0u {
        let z = 1.0 - 2.0 * u1;
        let r = sqrt(max(1.0 - z * z, 0.0));
        let phi = 2.0 * PI * u2;
        d = vec3<f32>(r * cos(phi), r * sin(phi), z);
        pdf = e.select_prob * (0.25 / PI);
    } else {
#ifdef ENV_MAP
        let h = e.height;
        let j = find_cell(0u, h, u1);
        let dv = (u1 - env_distribution(j)) / (env_distribution(j + 1u) - env_distribution(j));
        let row = h + 1u + j * (e.width + 1u);
        let i = find_cell(row, e.width, u2);
        let du = (u2 - env_distribution(row + i)) / (env_distribution(row + i + 1u) - env_distribution(row + i));
        let u = (f32(i) + du) / f32(e.width);
        let v = (f32(j) + dv) / f32(h);
        let phi = 2.0 * PI * (u - 0.5);
        let theta = PI * v;
        let sin_theta = sin(theta);
        if sin_theta <= 0.0 {
            return none;
        }
        d = from_map(e, vec3<f32>(sin_theta * sin(phi), cos(theta), sin_theta * cos(phi)));
        pdf = e.select_prob * cell_pdf(e, i, j) / (2.0 * PI * PI * sin_theta);
#else
        return none;
#endif
    }
    if !(pdf > 0.0) {
        return none;
    }
    return EnvSample(d, env_background(d) / pdf, pdf, true);
}

// Whitted's unshadowed diffuse light from the environment about unit normal n.
fn env_diffuse(n: vec3<f32>) -> vec3<f32> {
    if !env_present() {
        return vec3<f32>(0.0);
    }
    let e = load_environment();
    let m = to_map(e, n);
    let x = m.x;
    let y = m.y;
    let z = m.z;
    var sum = e.sh[0].xyz * 0.282095;
    sum += e.sh[1].xyz * (0.488603 * y);
    sum += e.sh[2].xyz * (0.488603 * z);
    sum += e.sh[3].xyz * (0.488603 * x);
    sum += e.sh[4].xyz * (1.092548 * x * y);
    sum += e.sh[5].xyz * (1.092548 * y * z);
    sum += e.sh[6].xyz * (0.315392 * (3.0 * z * z - 1.0));
    sum += e.sh[7].xyz * (1.092548 * x * z);
    sum += e.sh[8].xyz * (0.546274 * (x * x - y * y));
    return max(sum, vec3<f32>(0.0));
}
#endif
