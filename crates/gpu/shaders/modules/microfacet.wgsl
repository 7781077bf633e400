// GGX microfacet reflection and its directional albedo: twin of crates/core/src/render/microfacet.rs.
// GGX_ALBEDO holds E1 (F = 1) then E5 (F = (1 - cos)^5), each GGX_ROUGHNESS_STEPS rows of
// GGX_COS_STEPS values over perceptual roughness and cos(theta_o), computed by the host.
#define_import_path strahl::microfacet

const PI: f32 = 3.14159265358979;
const GGX_ROUGHNESS_STEPS: u32 = #{GGX_ROUGHNESS_STEPS};
const GGX_COS_STEPS: u32 = #{GGX_COS_STEPS};
const GGX_TABLE: u32 = GGX_ROUGHNESS_STEPS * GGX_COS_STEPS;
const GGX_ALBEDO = array<f32, #{GGX_ALBEDO_LEN}>(#{GGX_ALBEDO});

fn schlick(f0: vec3<f32>, cos_t: f32) -> vec3<f32> {
    let m = clamp(1.0 - cos_t, 0.0, 1.0);
    let m5 = m * m * m * m * m;
    return f0 + (vec3<f32>(1.0) - f0) * m5;
}

// f0 + (f90 - f0)(1 - cos)^5 (KHR_materials_specular's form).
fn schlick_grazing(f0: vec3<f32>, f90: f32, cos_t: f32) -> vec3<f32> {
    let m = clamp(1.0 - cos_t, 0.0, 1.0);
    let m5 = m * m * m * m * m;
    return f0 + (vec3<f32>(f90) - f0) * m5;
}

fn ggx_d(alpha: f32, cos_h: f32) -> f32 {
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let den = c2 * (a2 - 1.0) + 1.0;
    return a2 / (PI * den * den);
}

fn ggx_lambda(alpha: f32, cos_t: f32) -> f32 {
    let c2 = max(cos_t * cos_t, 1e-12);
    let a2_tan2 = alpha * alpha * max(1.0 - c2, 0.0) / c2;
    return 0.5 * (sqrt(1.0 + a2_tan2) - 1.0);
}

// Heitz, JCGT 2018, listing 1 (isotropic alpha), local frame z up.
fn ggx_sample_visible(alpha: f32, wo: vec3<f32>, u1: f32, u2: f32) -> vec3<f32> {
    let vh = normalize(vec3<f32>(alpha * wo.x, alpha * wo.y, wo.z));
    let lensq = vh.x * vh.x + vh.y * vh.y;
    var t1 = vec3<f32>(1.0, 0.0, 0.0);
    if lensq > 0.0 {
        t1 = vec3<f32>(-vh.y, vh.x, 0.0) / sqrt(lensq);
    }
    let t2 = cross(vh, t1);
    let r = sqrt(u1);
    let phi = 2.0 * PI * u2;
    let p1 = r * cos(phi);
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * (r * sin(phi));
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    return normalize(vec3<f32>(alpha * nh.x, alpha * nh.y, max(nh.z, 0.0)));
}

// (E1, E5) at perceptual roughness r and cos_o, bilinear in the table
// (render::microfacet::lookup).
fn ggx_albedo(r: f32, cos_o: f32) -> vec2<f32> {
    let x = clamp(r, 0.0, 1.0) * f32(GGX_ROUGHNESS_STEPS - 1u);
    let y = clamp(cos_o, 0.0, 1.0) * f32(GGX_COS_STEPS - 1u);
    let x0 = min(floor(x), f32(GGX_ROUGHNESS_STEPS - 2u));
    let y0 = min(floor(y), f32(GGX_COS_STEPS - 2u));
    let fx = x - x0;
    let fy = y - y0;
    let k = u32(x0) * GGX_COS_STEPS + u32(y0);
    var out = vec2<f32>(0.0);
    for (var i = 0u; i < 2u; i += 1u) {
        let base = i * GGX_TABLE + k;
        let top = GGX_ALBEDO[base] * (1.0 - fy) + GGX_ALBEDO[base + 1u] * fy;
        let bottom = GGX_ALBEDO[base + GGX_COS_STEPS] * (1.0 - fy) + GGX_ALBEDO[base + GGX_COS_STEPS + 1u] * fy;
        out[i] = top * (1.0 - fx) + bottom * fx;
    }
    return out;
}
