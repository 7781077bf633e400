// The sheen of cloth (KHR_materials_sheen): twin of crates/core/src/render/sheen.rs. The Charlie
// distribution with Estevez and Kulla's visibility fit, and its white albedo E(r, cos_o) from the
// host's table SHEEN_ALBEDO (SHEEN_ROUGHNESS_STEPS rows of SHEEN_COS_STEPS values).
#define_import_path strahl::sheen

const SHEEN_PI: f32 = 3.14159265358979;
const SHEEN_ROUGHNESS_STEPS: u32 = #{SHEEN_ROUGHNESS_STEPS};
const SHEEN_COS_STEPS: u32 = #{SHEEN_COS_STEPS};
const SHEEN_MIN_ALPHA: f32 = #{SHEEN_MIN_ALPHA};
const SHEEN_ALBEDO = array<f32, #{SHEEN_ALBEDO_LEN}>(#{SHEEN_ALBEDO});

fn sheen_alpha(r: f32) -> f32 {
    let c = clamp(r, 0.0, 1.0);
    return max(c * c, SHEEN_MIN_ALPHA);
}

fn charlie_d(alpha: f32, cos_h: f32) -> f32 {
    let inv = 1.0 / alpha;
    let sin2 = max(1.0 - cos_h * cos_h, 0.0);
    return (2.0 + inv) * pow(sin2, 0.5 * inv) / (2.0 * SHEEN_PI);
}

fn sheen_fit_l(alpha: f32, x: f32) -> f32 {
    let t = (1.0 - alpha) * (1.0 - alpha);
    let a = mix(21.5473, 25.3245, t);
    let b = mix(3.82987, 3.32435, t);
    let c = mix(0.19823, 0.16801, t);
    let d = mix(-1.97760, -1.27393, t);
    let e = mix(-4.32054, -4.85967, t);
    return a / (1.0 + b * pow(x, c)) + d * x + e;
}

fn sheen_lambda(alpha: f32, mu_in: f32) -> f32 {
    let mu = clamp(mu_in, 0.0, 1.0);
    if mu < 0.5 {
        return exp(sheen_fit_l(alpha, mu));
    }
    return exp(2.0 * sheen_fit_l(alpha, 0.5) - sheen_fit_l(alpha, 1.0 - mu));
}

// f cos(theta_i) of the white lobe for local directions (z up).
fn sheen_eval(alpha: f32, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = normalize(wo + wi);
    let g2 = 1.0 / (1.0 + sheen_lambda(alpha, wo.z) + sheen_lambda(alpha, wi.z));
    return charlie_d(alpha, h.z) * g2 / (4.0 * wo.z);
}

// The white lobe's albedo, bilinear in the table (render::sheen::albedo).
fn sheen_albedo(r: f32, cos_o: f32) -> f32 {
    let x = sqrt(clamp(r, 0.0, 1.0)) * f32(SHEEN_ROUGHNESS_STEPS - 1u);
    let y = sqrt(clamp(cos_o, 0.0, 1.0)) * f32(SHEEN_COS_STEPS - 1u);
    let x0 = min(floor(x), f32(SHEEN_ROUGHNESS_STEPS - 2u));
    let y0 = min(floor(y), f32(SHEEN_COS_STEPS - 2u));
    let fx = x - x0;
    let fy = y - y0;
    let k = u32(x0) * SHEEN_COS_STEPS + u32(y0);
    let top = SHEEN_ALBEDO[k] * (1.0 - fy) + SHEEN_ALBEDO[k + 1u] * fy;
    let bottom = SHEEN_ALBEDO[k + SHEEN_COS_STEPS] * (1.0 - fy) + SHEEN_ALBEDO[k + SHEEN_COS_STEPS + 1u] * fy;
    return top * (1.0 - fx) + bottom * fx;
}
