// The layers over a pbr material's base: twin of crates/core/src/render/layers.rs. A clear coat
// (KHR_materials_clearcoat: GGX, F0 0.04, compensated) over a sheen (KHR_materials_sheen) over the
// base, each passing on what its directional albedo at cos_o leaves.
#define_import_path strahl::layers

#import strahl::types::Material
#import strahl::microfacet::{ggx_albedo, ggx_d, ggx_lambda, schlick}
#import strahl::sheen::{sheen_alpha, sheen_albedo, sheen_eval}

const PBR_F0: f32 = #{PBR_F0};
const LAYER_MIN_ALPHA: f32 = #{MIN_PBR_ALPHA};
const LAYER_INV_PI: f32 = 0.31830988618379067;

struct Layers {
    coat: f32,
    coat_alpha: f32,
    // (Not `sheen_alpha`: naga_oil would read it as the imported function.)
    alpha_sheen: f32,
    base: f32,
    p_coat: f32,
    p_sheen: f32,
    sheen: vec3<f32>,
}

// render::layers::layers.
fn layers(m: Material, cos_o: f32) -> Layers {
    let cc = clamp(m.clearcoat, 0.0, 1.0);
    let r = clamp(m.clearcoat_roughness, 0.0, 1.0);
    let g = ggx_albedo(r, cos_o);
    let e1 = max(g.x, 1e-3);
    let coat = cc * (1.0 + PBR_F0 * (1.0 - e1) / e1);
    let coat_albedo = min(coat * (PBR_F0 * e1 + (1.0 - PBR_F0) * g.y), 1.0);
    let color = clamp(m.sheen_color, vec3<f32>(0.0), vec3<f32>(1.0));
    let e = sheen_albedo(m.sheen_roughness, cos_o);
    let norm = select(1.0, 1.0 / e, e > 1.0);
    let sheen_a = max(color.x, max(color.y, color.z)) * e * norm;
    let passed = 1.0 - coat_albedo;
    return Layers(
        coat, max(r * r, LAYER_MIN_ALPHA), sheen_alpha(m.sheen_roughness),
        passed * (1.0 - sheen_a), coat_albedo, passed * sheen_a, color * (passed * norm),
    );
}

// f cos(theta_i) and density of the coat lobe, local directions (render::layers::coat_eval).
fn coat_eval(l: Layers, wo: vec3<f32>, wi: vec3<f32>) -> vec2<f32> {
    if wo.z <= 0.0 || wi.z <= 0.0 || l.coat <= 0.0 {
        return vec2<f32>(0.0);
    }
    let h = normalize(wo + wi);
    if h.z <= 0.0 {
        return vec2<f32>(0.0);
    }
    let d = ggx_d(l.coat_alpha, h.z);
    let lo = ggx_lambda(l.coat_alpha, wo.z);
    let li = ggx_lambda(l.coat_alpha, wi.z);
    let k = d / (4.0 * wo.z);
    let f = schlick(vec3<f32>(PBR_F0), dot(wo, h)).x;
    return vec2<f32>(l.coat * f * k / (1.0 + lo + li), k / (1.0 + lo));
}

// f cos(theta_i) (w: the cosine density) of the sheen lobe (render::layers::sheen_eval).
fn layer_sheen_eval(l: Layers, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(l.sheen * sheen_eval(l.alpha_sheen, wo, wi), wi.z * LAYER_INV_PI);
}
