// Rough dielectric interfaces, GGX reflection and transmission (Walter et al. 2007) through
// the visible normals, divided by their albedo table: twin of crates/core/src/render/dielectric.rs.
// Local frame, z up on wo's side; eta: the other side's index over wo's.
// The albedo table (load_glass_table, in the objects buffer) holds E(alpha, mu, eta) in
// DIELECTRIC_ETA_STEPS blocks (+-sqrt(|ln eta| / ln 3)) of DIELECTRIC_ROUGH_STEPS rows
// (sqrt alpha) of DIELECTRIC_COS_STEPS values, computed by the host.
#define_import_path strahl::dielectric

#import strahl::shade::{fresnel_dielectric, reflect_dir, refract_dir}
#import strahl::microfacet::{ggx_d, ggx_lambda, ggx_sample_visible}
#import strahl::bindings::load_glass_table

const DIELECTRIC_ROUGH_STEPS: u32 = #{DIELECTRIC_ROUGH_STEPS};
const DIELECTRIC_COS_STEPS: u32 = #{DIELECTRIC_COS_STEPS};
const DIELECTRIC_ETA_STEPS: u32 = #{DIELECTRIC_ETA_STEPS};
const DIELECTRIC_LN_ETA_MAX: f32 = #{DIELECTRIC_LN_ETA_MAX};

struct RoughSample {
    wi: vec3<f32>,
    // f |cos| / pdf, compensated; transmission includes 1 / eta^2.
    weight: f32,
    pdf: f32,
    through: bool,
    valid: bool,
}

// E(alpha, cos_o, eta), trilinear in the table (render::dielectric::albedo).
fn dielectric_albedo(alpha: f32, cos_o: f32, eta: f32) -> f32 {
    let x = min(sqrt(max(alpha, 0.0)), 1.0) * f32(DIELECTRIC_ROUGH_STEPS - 1u);
    let y = clamp(cos_o, 0.0, 1.0) * f32(DIELECTRIC_COS_STEPS - 1u);
    let l = log(eta) / DIELECTRIC_LN_ETA_MAX;
    let z = clamp(0.5 + 0.5 * sign(l) * sqrt(abs(l)), 0.0, 1.0) * f32(DIELECTRIC_ETA_STEPS - 1u);
    let x0 = min(floor(x), f32(DIELECTRIC_ROUGH_STEPS - 2u));
    let y0 = min(floor(y), f32(DIELECTRIC_COS_STEPS - 2u));
    let z0 = min(floor(z), f32(DIELECTRIC_ETA_STEPS - 2u));
    let fx = x - x0;
    let fy = y - y0;
    let fz = z - z0;
    let base = (u32(z0) * DIELECTRIC_ROUGH_STEPS + u32(x0)) * DIELECTRIC_COS_STEPS + u32(y0);
    var e = vec2<f32>(0.0);
    for (var k = 0u; k < 2u; k += 1u) {
        let plane = base + k * DIELECTRIC_ROUGH_STEPS * DIELECTRIC_COS_STEPS;
        let top = load_glass_table(plane) * (1.0 - fy) + load_glass_table(plane + 1u) * fy;
        let bottom = load_glass_table(plane + DIELECTRIC_COS_STEPS) * (1.0 - fy)
            + load_glass_table(plane + DIELECTRIC_COS_STEPS + 1u) * fy;
        e[k] = top * (1.0 - fx) + bottom * fx;
    }
    return max(e[0] * (1.0 - fz) + e[1] * fz, 1e-3);
}

// What the lobe is divided by: its albedo where compensating, else 1
// (render::dielectric::compensation).
fn compensation(alpha: f32, cos_o: f32, eta: f32, compensate: bool) -> f32 {
    if compensate {
        return dielectric_albedo(alpha, cos_o, eta);
    }
    return 1.0;
}

// f |cos theta_i| and the density rough_sample chooses wi with (render::dielectric::rough_eval).
fn rough_eval(alpha: f32, eta: f32, wo: vec3<f32>, wi: vec3<f32>, compensate: bool) -> vec2<f32> {
    let cos_o = wo.z;
    if cos_o <= 0.0 || wi.z == 0.0 {
        return vec2<f32>(0.0);
    }
    let e = compensation(alpha, cos_o, eta, compensate);
    let lo = ggx_lambda(alpha, cos_o);
    let li = ggx_lambda(alpha, wi.z);
    if wi.z > 0.0 {
        let h = normalize(wo + wi);
        let f = fresnel_dielectric(dot(wo, h), eta);
        let k = f * ggx_d(alpha, h.z) / (4.0 * cos_o);
        return vec2<f32>(k / (1.0 + lo + li) / e, k / (1.0 + lo));
    }
    var h = normalize(wo + wi * eta);
    if h.z < 0.0 {
        h = -h;
    }
    let cos_oh = dot(wo, h);
    let cos_ih = dot(wi, h);
    if !(cos_oh > 0.0 && cos_ih < 0.0) {
        return vec2<f32>(0.0);
    }
    let f = fresnel_dielectric(cos_oh, eta);
    let s = cos_ih + cos_oh / eta;
    let k = (1.0 - f) * ggx_d(alpha, h.z) * cos_oh * -cos_ih / (cos_o * s * s);
    return vec2<f32>(k / ((1.0 + lo + li) * eta * eta) / e, k / (1.0 + lo));
}

// A direction from the rough interface (render::dielectric::rough_sample).
fn rough_sample(alpha: f32, eta: f32, wo: vec3<f32>, u: vec3<f32>, compensate: bool) -> RoughSample {
    let none = RoughSample(vec3<f32>(0.0), 0.0, 0.0, false, false);
    let cos_o = wo.z;
    if cos_o <= 0.0 {
        return none;
    }
    let h = ggx_sample_visible(alpha, wo, u.y, u.z);
    let cos_oh = dot(wo, h);
    let f = fresnel_dielectric(cos_oh, eta);
    let lo = ggx_lambda(alpha, cos_o);
    let d = ggx_d(alpha, h.z);
    let e = compensation(alpha, cos_o, eta, compensate);
    if u.x < f {
        let wi = reflect_dir(-wo, h);
        if wi.z <= 0.0 {
            return none;
        }
        let li = ggx_lambda(alpha, wi.z);
        let weight = (1.0 + lo) / (1.0 + lo + li);
        let pdf = f * d / ((1.0 + lo) * 4.0 * cos_o);
        return RoughSample(wi, weight / e, pdf, false, true);
    }
    let wi = refract_dir(-wo, h, cos_oh, 1.0 / eta);
    let cos_ih = dot(wi, h);
    if wi.z >= 0.0 || cos_ih >= 0.0 {
        return none;
    }
    let li = ggx_lambda(alpha, wi.z);
    let weight = (1.0 + lo) / ((1.0 + lo + li) * eta * eta);
    let s = cos_ih + cos_oh / eta;
    let pdf = (1.0 - f) * d * cos_oh * -cos_ih / ((1.0 + lo) * cos_o * s * s);
    return RoughSample(wi, weight / e, pdf, true, true);
}
