// Ray/sphere: twin of crates/core/src/geometry/sphere.rs (see there for the formulation and its error).
#define_import_path strahl::sphere

#import strahl::types::{Sphere, PART_SURFACE}
#import strahl::roots::{Roots, roots_empty, roots_push, stable_quadratic, unit_or}

// The stable roots (t_lo, t_hi, valid) of the ray's line with the sphere.
fn sphere_quadratic(s: Sphere, o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let f = o - s.center;
    let a = dot(d, d);
    let beta = dot(d, f);
    let r2 = s.radius * s.radius;
    let c = dot(f, f) - r2;
    let l = f - d * (beta / a);
    let disc = a * (r2 - dot(l, l));
    return stable_quadratic(a, beta, c, disc);
}

fn sphere_roots(s: Sphere, o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Roots {
    var roots = roots_empty();
    let q = sphere_quadratic(s, o, d);
    if q.z != 0.0 {
        roots_push(&roots, q.x, PART_SURFACE, tmin, tmax);
        // A tangent ray's double root is one point of contact, reported once.
        if q.y != q.x {
            roots_push(&roots, q.y, PART_SURFACE, tmin, tmax);
        }
    }
    return roots;
}

// Facing the ray where the hit point rounds onto the centre (unit_or).
fn sphere_normal(s: Sphere, o: vec3<f32>, d: vec3<f32>, t: f32) -> vec3<f32> {
    return unit_or((o - s.center) + d * t, -d);
}

// The first root in (tmin, tmax) as (t, part), or t = -1: the same root as
// sphere_roots(..).t[0], without building the list (nearest-hit traversal).
fn sphere_first(s: Sphere, o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> vec2<f32> {
    let q = sphere_quadratic(s, o, d);
    if q.z != 0.0 {
        if q.x > tmin && q.x < tmax {
            return vec2<f32>(q.x, 0.0);
        }
        if q.y > tmin && q.y < tmax {
            return vec2<f32>(q.y, 0.0);
        }
    }
    return vec2<f32>(-1.0, 0.0);
}
