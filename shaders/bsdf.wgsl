// Scattering for the path tracer: twin of src/render/bsdf.rs (Lambert, smooth and GGX-rough
// conductors with Schlick's Fresnel, smooth dielectrics). wo points away from the surface, ns
// is the normal on wo's side; "weight" is f |cos| / pdf.
#define_import_path strahl::bsdf

#import strahl::types::{Material, MAT_MIRROR, MAT_DIELECTRIC}
#import strahl::shade::{fresnel_dielectric, reflect_dir, refract_dir}

const PI: f32 = 3.14159265358979;
const INV_PI: f32 = 0.31830988618379067;
const MIN_ROUGHNESS: f32 = #{MIN_ROUGHNESS};

struct BsdfSample {
    dir: vec3<f32>,
    weight: vec3<f32>,
    pdf: f32,
    specular: bool,
    // false: the path ends here.
    valid: bool,
}

struct BsdfEval {
    f_cos: vec3<f32>,
    pdf: f32,
}

fn is_specular(m: Material) -> bool {
    return m.kind == MAT_DIELECTRIC || (m.kind == MAT_MIRROR && m.roughness < MIN_ROUGHNESS);
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

fn schlick(f0: vec3<f32>, cos_t: f32) -> vec3<f32> {
    let m = clamp(1.0 - cos_t, 0.0, 1.0);
    let m5 = m * m * m * m * m;
    return f0 + (vec3<f32>(1.0) - f0) * m5;
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

fn bsdf_eval(m: Material, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>) -> BsdfEval {
    let cos_i = dot(wi, ns);
    if cos_i <= 0.0 {
        return BsdfEval(vec3<f32>(0.0), 0.0);
    }
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
    let none = BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false, false);
#ifdef DIELECTRIC
    if m.kind == MAT_DIELECTRIC {
        let cos_i = dot(wo, ns);
        let eta = select(1.0 / m.ior, m.ior, front);
        let f = fresnel_dielectric(cos_i, eta);
        if u.x < f {
            return BsdfSample(reflect_dir(-wo, ns), vec3<f32>(1.0), 0.0, true, true);
        }
        return BsdfSample(refract_dir(-wo, ns, cos_i, 1.0 / eta), m.color / (eta * eta), 0.0, true, true);
    }
#endif
#ifdef MIRROR
    if m.kind == MAT_MIRROR {
        let cos_o = dot(wo, ns);
        if m.roughness < MIN_ROUGHNESS {
            return BsdfSample(reflect_dir(-wo, ns), schlick(m.color, cos_o), 0.0, true, true);
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
        return BsdfSample(dir, weight, pdf, false, true);
    }
#endif
    if max(m.color.x, max(m.color.y, m.color.z)) <= 0.0 {
        return none;
    }
    let local = cosine_hemisphere(u.y, u.z);
    return BsdfSample(normalize(to_world(local, ns)), m.color, local.z * INV_PI, false, true);
}
