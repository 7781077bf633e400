// Ray/infinite plane: twin of crates/core/src/geometry/plane.rs.
#define_import_path strahl::plane

#import strahl::types::{Plane, PART_SURFACE}
#import strahl::roots::{Roots, roots_empty, roots_push}

fn plane_roots(p: Plane, o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Roots {
    var roots = roots_empty();
    let dn = dot(d, p.normal);
    if dn != 0.0 {
        roots_push(&roots, dot(p.point - o, p.normal) / dn, PART_SURFACE, tmin, tmax);
    }
    return roots;
}

// The root in (tmin, tmax) as (t, part), or t = -1.
fn plane_first(p: Plane, o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> vec2<f32> {
    let dn = dot(d, p.normal);
    if dn != 0.0 {
        let t = dot(p.point - o, p.normal) / dn;
        if t > tmin && t < tmax {
            return vec2<f32>(t, 0.0);
        }
    }
    return vec2<f32>(-1.0, 0.0);
}
