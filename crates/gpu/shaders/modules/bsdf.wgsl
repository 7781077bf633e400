// Scattering for the path tracer: twin of crates/core/src/render/bsdf.rs (Lambert, smooth and GGX-rough
// conductors with Schlick's Fresnel, smooth and (ROUGH_GLASS) rough dielectrics, glTF's metallic-roughness
// material, mixed with a rough dielectric by its transmission, under (LAYERS) a clear coat and sheen).
// wo points away from the surface, ns
// is the normal on wo's side; "weight" is f |cos| / pdf.
#define_import_path strahl::bsdf

#import strahl::types::{Material, MAT_MIRROR, MAT_DIELECTRIC, MAT_PBR, MATERIAL_SINGLE_SCATTERING}
#import strahl::shade::{fresnel_dielectric, reflect_dir, refract_dir}
#import strahl::microfacet::{schlick, ggx_d, ggx_lambda, ggx_sample_visible}
#ifdef PBR
#import strahl::pbr::{pbr_lobes, pbr_fresnel}
#endif
#ifdef ROUGH_GLASS
#import strahl::dielectric::{rough_eval, rough_sample}
#endif
#ifdef PBR
#ifdef LAYERS
#import strahl::layers::{Layers, layers, coat_eval, layer_sheen_eval}
#endif
#endif

const PI: f32 = 3.14159265358979;
const INV_PI: f32 = 0.31830988618379067;
const MIN_ROUGHNESS: f32 = #{MIN_ROUGHNESS};
const MIN_PBR_ALPHA: f32 = #{MIN_PBR_ALPHA};

struct BsdfSample {
    dir: vec3<f32>,
    weight: vec3<f32>,
    pdf: f32,
    specular: bool,
    // Refracted through the surface.
    through: bool,
    // false: the path ends here.
    valid: bool,
}

struct BsdfEval {
    f_cos: vec3<f32>,
    pdf: f32,
}

fn is_specular(m: Material) -> bool {
    return (m.kind == MAT_DIELECTRIC || m.kind == MAT_MIRROR) && m.roughness < MIN_ROUGHNESS;
}

// Orthonormal basis around n (Duff et al., JCGT 2017): columns t, b.
fn basis_t(n: vec3<f32>) -> vec3<f32> {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    return vec3<f32>(1.0 + sign * n.x * n.x * a, sign * n.x * n.y * a, -sign * n.x);
}

fn basis_b(n: vec3<f32>) -> vec3<f32> {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    return vec3<f32>(n.x * n.y * a, sign + n.y * n.y * a, -n.y);
}

fn to_world(v: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return basis_t(n) * v.x + basis_b(n) * v.y + n * v.z;
}

fn to_local(v: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, basis_t(n)), dot(v, basis_b(n)), dot(v, n));
}

fn cosine_hemisphere(u1: f32, u2: f32) -> vec3<f32> {
    let r = sqrt(u1);
    let phi = 2.0 * PI * u2;
    return vec3<f32>(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u1, 0.0)));
}

#ifdef PBR
fn pbr_eval(m: Material, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>) -> BsdfEval {
    let cos_o = dot(wo, ns);
    let cos_i = dot(wi, ns);
    if cos_o <= 0.0 || cos_i <= 0.0 {
        return BsdfEval(vec3<f32>(0.0), 0.0);
    }
    let l = pbr_lobes(m, cos_o);
    // No lobe (render::bsdf::pbr_eval): pbr_sample never samples it.
    if l.p_spec <= 0.0 && max(l.diffuse.x, max(l.diffuse.y, l.diffuse.z)) <= 0.0 {
        return BsdfEval(vec3<f32>(0.0), 0.0);
    }
    var f_cos = l.diffuse * (cos_i * INV_PI);
    var pdf = (1.0 - l.p_spec) * cos_i * INV_PI;
    let h = normalize(wo + wi);
    let cos_h = dot(h, ns);
    if cos_h > 0.0 {
        let d = ggx_d(l.alpha, cos_h);
        let lo = ggx_lambda(l.alpha, cos_o);
        let li = ggx_lambda(l.alpha, cos_i);
        let k = d / (4.0 * cos_o);
        let f = pbr_fresnel(l, dot(wo, h));
        f_cos += f * (k / (1.0 + lo + li));
        pdf += l.p_spec * k / (1.0 + lo);
    }
    return BsdfEval(f_cos, pdf);
}

fn pbr_sample(m: Material, wo: vec3<f32>, ns: vec3<f32>, u: vec3<f32>) -> BsdfSample {
    let none = BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false, false, false);
    let cos_o = dot(wo, ns);
    if cos_o <= 0.0 {
        return none;
    }
    let l = pbr_lobes(m, cos_o);
    if l.p_spec <= 0.0 && max(l.diffuse.x, max(l.diffuse.y, l.diffuse.z)) <= 0.0 {
        return none;
    }
    var dir: vec3<f32>;
    if u.x < l.p_spec {
        let h = to_world(ggx_sample_visible(l.alpha, to_local(wo, ns), u.y, u.z), ns);
        dir = reflect_dir(-wo, h);
    } else {
        dir = normalize(to_world(cosine_hemisphere(u.y, u.z), ns));
    }
    let ev = pbr_eval(m, wo, dir, ns);
    if !(ev.pdf > 0.0) {
        return none;
    }
    return BsdfSample(dir, ev.f_cos / ev.pdf, ev.pdf, false, false, true);
}
#endif

#ifdef ROUGH_GLASS
// The glass share of a pbr material (render::bsdf::glass_share).
fn glass_share(m: Material) -> f32 {
    return (1.0 - clamp(m.metallic, 0.0, 1.0)) * clamp(m.transmission, 0.0, 1.0);
}

fn glass_alpha(m: Material) -> f32 {
    if m.kind == MAT_PBR {
        let r = clamp(m.roughness, 0.0, 1.0);
        return max(r * r, MIN_PBR_ALPHA);
    }
    return m.roughness;
}

fn glass_eta(m: Material, front: bool) -> f32 {
    return select(1.0 / m.ior, m.ior, front);
}

// The reflection of the rough dielectric lobe (render::bsdf::glass_eval).
fn glass_eval(m: Material, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>, front: bool) -> vec2<f32> {
    if dot(wi, ns) <= 0.0 {
        return vec2<f32>(0.0);
    }
    let compensate = (m.flags & MATERIAL_SINGLE_SCATTERING) == 0u;
    return rough_eval(glass_alpha(m), glass_eta(m, front), to_local(wo, ns), to_local(wi, ns), compensate);
}

fn glass_sample(m: Material, wo: vec3<f32>, ns: vec3<f32>, front: bool, u: vec3<f32>) -> BsdfSample {
    let compensate = (m.flags & MATERIAL_SINGLE_SCATTERING) == 0u;
    let s = rough_sample(glass_alpha(m), glass_eta(m, front), to_local(wo, ns), u, compensate);
    if !s.valid {
        return BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false, false, false);
    }
    let dir = normalize(to_world(s.wi, ns));
    var weight = vec3<f32>(s.weight);
    if s.through {
        if m.kind == MAT_PBR {
            // glTF's glass: no 1/eta^2, sqrt(colour) a crossing (render::bsdf::glass_sample).
            let eta = glass_eta(m, front);
            weight = sqrt(m.color) * (s.weight * (eta * eta));
        } else {
            weight = m.color * s.weight;
        }
    }
    return BsdfSample(dir, weight, s.pdf, s.through, s.through, true);
}

#ifdef PBR
fn opaque_part(m: Material, t: f32) -> Material {
    var o = m;
    o.metallic = clamp(m.metallic, 0.0, 1.0) / (1.0 - t);
    o.transmission = 0.0;
    return o;
}

// render::bsdf::pbr_glass_eval.
fn pbr_glass_eval(m: Material, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>, front: bool) -> BsdfEval {
    let t = glass_share(m);
    let g = glass_eval(m, wo, wi, ns, front);
    if t >= 1.0 {
        return BsdfEval(vec3<f32>(g.x), g.y);
    }
    let p = pbr_eval(opaque_part(m, t), wo, wi, ns);
    return BsdfEval(p.f_cos * (1.0 - t) + vec3<f32>(g.x * t), p.pdf * (1.0 - t) + g.y * t);
}

// render::bsdf::pbr_glass_sample.
fn pbr_glass_sample(m: Material, wo: vec3<f32>, ns: vec3<f32>, front: bool, u: vec3<f32>) -> BsdfSample {
    let t = glass_share(m);
    var s: BsdfSample;
    if u.x < t {
        s = glass_sample(m, wo, ns, front, vec3<f32>(u.x / t, u.y, u.z));
    } else {
        s = pbr_sample(opaque_part(m, t), wo, ns, vec3<f32>((u.x - t) / (1.0 - t), u.y, u.z));
    }
    if !s.valid || s.through {
        return s;
    }
    let ev = pbr_glass_eval(m, wo, s.dir, ns, front);
    if !(ev.pdf > 0.0) {
        return BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false, false, false);
    }
    return BsdfSample(s.dir, ev.f_cos / ev.pdf, ev.pdf, s.specular, false, true);
}
#endif
#endif

#ifdef PBR
// render::bsdf::base_eval: the pbr material without its layers.
fn base_eval(m: Material, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>, front: bool) -> BsdfEval {
#ifdef ROUGH_GLASS
    if m.transmission > 0.0 {
        return pbr_glass_eval(m, wo, wi, ns, front);
    }
#endif
    return pbr_eval(m, wo, wi, ns);
}

// render::bsdf::base_sample.
fn base_sample(m: Material, wo: vec3<f32>, ns: vec3<f32>, front: bool, u: vec3<f32>) -> BsdfSample {
#ifdef ROUGH_GLASS
    if m.transmission > 0.0 {
        return pbr_glass_sample(m, wo, ns, front, u);
    }
#endif
    return pbr_sample(m, wo, ns, u);
}
#endif

#ifdef PBR
#ifdef LAYERS
// render::bsdf::has_layers.
fn has_layers(m: Material, front: bool) -> bool {
    return (m.clearcoat > 0.0 || any(m.sheen_color > vec3<f32>(0.0))) && (front || m.transmission <= 0.0);
}

// render::bsdf::layered_eval.
fn layered_eval(m: Material, l: Layers, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>, front: bool) -> BsdfEval {
    let b = base_eval(m, wo, wi, ns, front);
    let lo = to_local(wo, ns);
    let li = to_local(wi, ns);
    let c = coat_eval(l, lo, li);
    let s = layer_sheen_eval(l, lo, li);
    return BsdfEval(b.f_cos * l.base + vec3<f32>(c.x) + s.xyz, b.pdf * l.base + c.y * l.p_coat + s.w * l.p_sheen);
}

// render::bsdf::layered_sample.
fn layered_sample(m: Material, wo: vec3<f32>, ns: vec3<f32>, front: bool, u: vec3<f32>) -> BsdfSample {
    let none = BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false, false, false);
    let l = layers(m, dot(wo, ns));
    var dir: vec3<f32>;
    if u.x < l.p_coat {
        let h = to_world(ggx_sample_visible(l.coat_alpha, to_local(wo, ns), u.y, u.z), ns);
        dir = reflect_dir(-wo, h);
    } else if u.x < l.p_coat + l.p_sheen {
        dir = normalize(to_world(cosine_hemisphere(u.y, u.z), ns));
    } else {
        let v = min((u.x - l.p_coat - l.p_sheen) / l.base, 0.99999994);
        let s = base_sample(m, wo, ns, front, vec3<f32>(v, u.y, u.z));
        if !s.valid {
            return none;
        }
        if s.through {
            return s;
        }
        dir = s.dir;
    }
    let ev = layered_eval(m, l, wo, dir, ns, front);
    if !(ev.pdf > 0.0) {
        return none;
    }
    return BsdfSample(dir, ev.f_cos / ev.pdf, ev.pdf, false, false, true);
}
#endif
#endif

fn bsdf_eval(m: Material, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>, front: bool) -> BsdfEval {
    let cos_i = dot(wi, ns);
    if cos_i <= 0.0 {
        return BsdfEval(vec3<f32>(0.0), 0.0);
    }
#ifdef PBR
    if m.kind == MAT_PBR {
#ifdef LAYERS
        if has_layers(m, front) {
            return layered_eval(m, layers(m, dot(wo, ns)), wo, wi, ns, front);
        }
#endif
        return base_eval(m, wo, wi, ns, front);
    }
#endif
#ifdef ROUGH_GLASS
    if m.kind == MAT_DIELECTRIC {
        let g = glass_eval(m, wo, wi, ns, front);
        return BsdfEval(vec3<f32>(g.x), g.y);
    }
#endif
#ifdef MIRROR
    if m.kind == MAT_MIRROR {
        let alpha = m.roughness;
        let cos_o = dot(wo, ns);
        let h = normalize(wo + wi);
        let cos_h = dot(h, ns);
        if cos_o <= 0.0 || cos_h <= 0.0 {
            return BsdfEval(vec3<f32>(0.0), 0.0);
        }
        let d = ggx_d(alpha, cos_h);
        let lo = ggx_lambda(alpha, cos_o);
        let li = ggx_lambda(alpha, cos_i);
        let g2 = 1.0 / (1.0 + lo + li);
        let g1 = 1.0 / (1.0 + lo);
        let f = schlick(m.color, dot(wo, h));
        let k = d / (4.0 * cos_o);
        return BsdfEval(f * (k * g2), k * g1);
    }
#endif
    return BsdfEval(m.color * (cos_i * INV_PI), cos_i * INV_PI);
}

fn bsdf_sample(m: Material, wo: vec3<f32>, ns: vec3<f32>, front: bool, u: vec3<f32>) -> BsdfSample {
    let none = BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false, false, false);
#ifdef PBR
    if m.kind == MAT_PBR {
#ifdef LAYERS
        if has_layers(m, front) {
            return layered_sample(m, wo, ns, front, u);
        }
#endif
        return base_sample(m, wo, ns, front, u);
    }
#endif
#ifdef ROUGH_GLASS
    if m.kind == MAT_DIELECTRIC && m.roughness >= MIN_ROUGHNESS {
        return glass_sample(m, wo, ns, front, u);
    }
#endif
#ifdef DIELECTRIC
    if m.kind == MAT_DIELECTRIC {
        let cos_i = dot(wo, ns);
        let eta = select(1.0 / m.ior, m.ior, front);
        let f = fresnel_dielectric(cos_i, eta);
        if u.x < f {
            return BsdfSample(reflect_dir(-wo, ns), vec3<f32>(1.0), 0.0, true, false, true);
        }
        return BsdfSample(refract_dir(-wo, ns, cos_i, 1.0 / eta), m.color / (eta * eta), 0.0, true, true, true);
    }
#endif
#ifdef MIRROR
    if m.kind == MAT_MIRROR {
        let cos_o = dot(wo, ns);
        if m.roughness < MIN_ROUGHNESS {
            return BsdfSample(reflect_dir(-wo, ns), schlick(m.color, cos_o), 0.0, true, false, true);
        }
        let alpha = m.roughness;
        let h = to_world(ggx_sample_visible(alpha, to_local(wo, ns), u.y, u.z), ns);
        let dir = reflect_dir(-wo, h);
        let cos_i = dot(dir, ns);
        if cos_i <= 0.0 || cos_o <= 0.0 {
            return none;
        }
        let lo = ggx_lambda(alpha, cos_o);
        let li = ggx_lambda(alpha, cos_i);
        let weight = schlick(m.color, dot(wo, h)) * ((1.0 + lo) / (1.0 + lo + li));
        let pdf = ggx_d(alpha, dot(h, ns)) / ((1.0 + lo) * 4.0 * cos_o);
        return BsdfSample(dir, weight, pdf, false, false, true);
    }
#endif
    if max(m.color.x, max(m.color.y, m.color.z)) <= 0.0 {
        return none;
    }
    let local = cosine_hemisphere(u.y, u.z);
    return BsdfSample(normalize(to_world(local, ns)), m.color, local.z * INV_PI, false, false, true);
}
