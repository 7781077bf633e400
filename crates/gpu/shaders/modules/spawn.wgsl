// Secondary-ray origins: twin of crates/core/src/render/spawn.rs (Wachter & Binder, Ray Tracing Gems ch. 6,
// with the ULP measured at |p0_i| + |t|, the magnitude that bounds the error of p_i, 32 steps,
// and no fixed step near the origin, so the offset is relative at every scale: see there for
// why and for the measurements).
#define_import_path strahl::spawn

// One ULP of the positive finite float m, exactly (integer arithmetic on its bits).
fn ulp_of(m: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(m) + 1u) - m;
}

// The smallest ULP used: that of the smallest normal f32, 2^-126 (render::spawn::MIN_ULP).
const MIN_ULP: f32 = #{MIN_ULP};

fn offset_component(p: f32, o: f32, t: f32, n: f32) -> f32 {
    let m = max(max(abs(o) + abs(t), abs(p)), MIN_ULP);
    return p + 32.0 * n * max(ulp_of(m), MIN_ULP);
}

// The origin of a ray leaving the hit point o + t d on the side of the unit normal n.
fn spawn_origin(o: vec3<f32>, d: vec3<f32>, t: f32, n: vec3<f32>) -> vec3<f32> {
    let p = o + d * t;
    return vec3<f32>(offset_component(p.x, o.x, t, n.x), offset_component(p.y, o.y, t, n.y), offset_component(p.z, o.z, t, n.z));
}
