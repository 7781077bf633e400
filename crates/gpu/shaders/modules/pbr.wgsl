// glTF's metallic-roughness material: twin of crates/core/src/render/pbr.rs (its lobes in lanes there too; eval and sample in lanes crates/cpu/src/lanes/pbr.rs: the two lobes seen from
// cos(theta_o): a GGX lobe with Schlick's F0 = mix(F0d, base, metallic), compensated for
// multiple scattering, over a Lambertian base weighted by what the coat lets through; the
// dielectric's F0d and F90 are the material's spec_at_normal, spec_at_grazing).
#define_import_path strahl::pbr

#import strahl::types::Material
#import strahl::microfacet::{ggx_albedo, schlick, schlick_grazing}

const MIN_PBR_ALPHA: f32 = #{MIN_PBR_ALPHA};

struct PbrLobes {
    alpha: f32,
    p_spec: f32,
    coat_grazing: f32,
    coat_weight: vec3<f32>,
    coat_reflect: vec3<f32>,
    reflectance: vec3<f32>,
    metal_weight: vec3<f32>,
    diffuse: vec3<f32>,
    spec_albedo: vec3<f32>,
}

fn luminance(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

fn pbr_lobes(m: Material, cos_o: f32) -> PbrLobes {
    let base = m.color;
    let metal = clamp(m.metallic, 0.0, 1.0);
    let r = clamp(m.roughness, 0.0, 1.0);
    let alpha = max(r * r, MIN_PBR_ALPHA);
    let e = ggx_albedo(r, cos_o);
    let e1 = max(e.x, 1e-3);
    let e5 = e.y;
    let lost = (1.0 - e1) / e1;
    let metal_weight = (vec3<f32>(1.0) + base * lost) * metal;
    let f0 = m.spec_at_normal;
    let f90 = m.spec_at_grazing;
    let coat_comp = vec3<f32>(1.0) + f0 * lost;
    let coat_weight = coat_comp * (1.0 - metal);
    let coat = coat_comp * (f0 * e1 + (vec3<f32>(f90) - f0) * e5);
    let kept = 1.0 - max(coat.x, max(coat.y, coat.z));
    let diffuse = base * ((1.0 - metal) * max(kept, 0.0));
    let metal_albedo = (base * e1 + (vec3<f32>(1.0) - base) * e5) * metal_weight;
    let spec_albedo = metal_albedo + coat * (1.0 - metal);
    let ls = luminance(spec_albedo);
    let ld = luminance(diffuse);
    var p_spec = 0.0;
    if ls + ld > 0.0 {
        p_spec = ls / (ls + ld);
    }
    return PbrLobes(alpha, p_spec, f90, coat_weight, f0, base, metal_weight, diffuse, spec_albedo);
}

// The lobe's Fresnel term (render::pbr::pbr_fresnel).
fn pbr_fresnel(l: PbrLobes, cos_t: f32) -> vec3<f32> {
    return schlick(l.reflectance, cos_t) * l.metal_weight + schlick_grazing(l.coat_reflect, l.coat_grazing, cos_t) * l.coat_weight;
}
