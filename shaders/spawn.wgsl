// Secondary-ray origins: twin of src/render/spawn.rs (Wachter & Binder, Ray Tracing Gems
// ch. 6). The integer step on the float's bits cannot be fused or reassociated away.
#define_import_path strahl::spawn

fn offset_component(p: f32, n: f32) -> f32 {
    if abs(p) < 1.0 / 32.0 {
        return p + (1.0 / 65536.0) * n;
    }
    let ofs = i32(256.0 * n);
    return bitcast<f32>(bitcast<i32>(p) + select(ofs, -ofs, p < 0.0));
}

fn offset_ray_origin(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(offset_component(p.x, n.x), offset_component(p.y, n.y), offset_component(p.z, n.z));
}
