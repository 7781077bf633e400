// The BSDF probe, a test and diagnostic stage that renders nothing: strahl::bsdf's bsdf_sample
// and bsdf_eval on a material of the scene, read by load_material as the path tracer reads it,
// for inputs the host chooses; twin of crates/core/src/render/bsdf.rs (sample, eval) (host:
// crates/gpu/src/bsdf_probe.rs).
//
// probe_sample: per input (material, wo, ns, front, three uniform numbers) what bsdf_sample
// chose (direction, weight, density, flags), bsdf_eval at that direction, and probe_density
// there. probe_eval: per input (material, wo, ns, front, wi) bsdf_eval at wi and probe_density
// at wi, so that a chi-square test integrates the device's own density over the sphere.
// Composed with the scene's key less the flags that select no BSDF code (bsdf_probe.rs,
// probe_key): the same material code as in a render, and of the scene's bindings only the
// frame and the objects.
#import strahl::bindings::load_material
#import strahl::bsdf::{bsdf_sample, bsdf_eval}
#ifdef ROUGH_GLASS
#import strahl::types::{Material, MAT_DIELECTRIC, MAT_PBR, MATERIAL_SINGLE_SCATTERING}
#import strahl::bsdf::{glass_alpha, glass_eta, glass_share, to_local}
#import strahl::dielectric::rough_eval
#else
#import strahl::types::Material
#endif
#ifdef PBR
#ifdef LAYERS
#import strahl::bsdf::has_layers
#import strahl::layers::layers
#endif
#endif

// One input (crates/gpu/src/bsdf_probe.rs, GpuProbeInput).
struct ProbeInput {
    wo: vec3<f32>,
    material: u32,
    ns: vec3<f32>,
    // 1: wo lies on the front face's side.
    front: u32,
    // probe_sample: the three uniform numbers; probe_eval: wi.
    v: vec3<f32>,
    pad: u32,
}

// One answer (GpuProbeOutput). Flags are 0 or 1.
struct ProbeOutput {
    dir: vec3<f32>,
    pdf: f32,
    weight: vec3<f32>,
    valid: u32,
    f_cos: vec3<f32>,
    eval_pdf: f32,
    density: f32,
    specular: u32,
    through: u32,
    pad: u32,
}

@group(1) @binding(0) var<storage, read> inputs: array<ProbeInput>;
@group(1) @binding(1) var<storage, read_write> outputs: array<ProbeOutput>;

const WORKGROUP: u32 = #{PROBE_WORKGROUP};
const PROBE_MIN_ROUGHNESS: f32 = #{MIN_ROUGHNESS};

// The density with which bsdf_sample chooses wi, on either side of the surface, where
// `above` is bsdf_eval's density of wi. Above the surface that. Below it the transmission of
// the rough dielectric lobe, which bsdf_eval leaves out (the path tracer samples lights above
// the surface only), weighed by the share of the material that is glass (and by what a pbr
// material's layers pass to it): the density of that lobe's rough_eval, the one rough_sample
// draws with. 0 below smooth materials, whose transmission has no density.
fn probe_density(m: Material, wo: vec3<f32>, wi: vec3<f32>, ns: vec3<f32>, front: bool, above: f32) -> f32 {
    if dot(wi, ns) > 0.0 {
        return above;
    }
#ifdef ROUGH_GLASS
    var share = 0.0;
    if m.kind == MAT_DIELECTRIC && m.roughness >= PROBE_MIN_ROUGHNESS {
        share = 1.0;
    } else if m.kind == MAT_PBR && m.transmission > 0.0 {
        share = glass_share(m);
#ifdef PBR
#ifdef LAYERS
        if has_layers(m, front) {
            share *= layers(m, dot(wo, ns)).base;
        }
#endif
#endif
    }
    if share > 0.0 {
        let compensate = (m.flags & MATERIAL_SINGLE_SCATTERING) == 0u;
        let g = rough_eval(glass_alpha(m), glass_eta(m, front), to_local(wo, ns), to_local(wi, ns), compensate);
        return share * g.y;
    }
#endif
    return 0.0;
}

fn flag(b: bool) -> u32 {
    return select(0u, 1u, b);
}

@compute @workgroup_size(WORKGROUP)
fn probe_sample(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&inputs) {
        return;
    }
    let q = inputs[i];
    let m = load_material(q.material);
    let front = q.front != 0u;
    let s = bsdf_sample(m, q.wo, q.ns, front, q.v);
    var out = ProbeOutput(s.dir, s.pdf, s.weight, flag(s.valid), vec3<f32>(0.0), 0.0, 0.0, flag(s.specular),
        flag(s.through), 0u);
    if s.valid {
        let e = bsdf_eval(m, q.wo, s.dir, q.ns, front);
        out.f_cos = e.f_cos;
        out.eval_pdf = e.pdf;
        out.density = probe_density(m, q.wo, s.dir, q.ns, front, e.pdf);
    }
    outputs[i] = out;
}

@compute @workgroup_size(WORKGROUP)
fn probe_eval(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&inputs) {
        return;
    }
    let q = inputs[i];
    let m = load_material(q.material);
    let front = q.front != 0u;
    let e = bsdf_eval(m, q.wo, q.v, q.ns, front);
    let density = probe_density(m, q.wo, q.v, q.ns, front, e.pdf);
    outputs[i] = ProbeOutput(q.v, 0.0, vec3<f32>(0.0), 0u, e.f_cos, e.pdf, density, 0u, 0u, 0u);
}
