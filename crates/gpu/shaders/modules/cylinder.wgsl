// Ray/finite cylinder with optional caps: twin of crates/core/src/geometry/cylinder.rs (see there for
// the cross-product formulation that survives rays parallel to the axis).
#define_import_path strahl::cylinder

#import strahl::types::{Cylinder, PART_SURFACE, PART_CAP_P1, PART_CAP_P2}
#import strahl::roots::{Roots, roots_empty, roots_push, stable_quadratic, unit_or}

// Root of the cap disk (centre c, unit normal n), or -1 with .y = 0 when missed.
fn cap_root(radius: f32, o: vec3<f32>, d: vec3<f32>, c: vec3<f32>, n: vec3<f32>) -> vec2<f32> {
    let dn = dot(d, n);
    if dn == 0.0 {
        return vec2<f32>(0.0, 0.0);
    }
    let t = dot(c - o, n) / dn;
    let q = (o - c) + d * t;
    return vec2<f32>(t, select(0.0, 1.0, dot(q, q) <= radius * radius));
}

// The open side's crossings: the stable roots (t_lo, t_hi, valid) of the infinite cylinder,
// their alphas along the axis, and the unit axis.
struct CylinderSide {
    q: vec3<f32>,
    alpha: vec2<f32>,
    axis: vec3<f32>,
}

fn cylinder_side(cy: Cylinder, ro: vec3<f32>, d: vec3<f32>) -> CylinderSide {
    let dp = cy.pb - cy.pa;
    let len = length(dp);
    let axis = dp / len;
    let o = ro - cy.pa;
    let oa = cross(o, axis);
    let da = cross(d, axis);
    let a = dot(da, da);
    let beta = dot(oa, da);
    let r2 = cy.radius * cy.radius;
    let c = dot(oa, oa) - r2;
    let e = dot(oa, d);
    let disc = a * r2 - e * e;
    let q = stable_quadratic(a, beta, c, disc);
    let o_axial = dot(o, axis);
    let d_axial = dot(d, axis);
    let alpha = vec2<f32>((o_axial + q.x * d_axial) / len, (o_axial + q.y * d_axial) / len);
    return CylinderSide(q, alpha, axis);
}

fn cylinder_roots(cy: Cylinder, ro: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Roots {
    let side = cylinder_side(cy, ro, d);
    let q = side.q;
    var roots = roots_empty();
    if q.z != 0.0 {
        if side.alpha.x >= 0.0 && side.alpha.x <= 1.0 {
            roots_push(&roots, q.x, PART_SURFACE, tmin, tmax);
        }
        // A tangent ray's double root is one point of contact, reported once.
        if q.y != q.x && side.alpha.y >= 0.0 && side.alpha.y <= 1.0 {
            roots_push(&roots, q.y, PART_SURFACE, tmin, tmax);
        }
    }
    if cy.caps != 0u {
        let c1 = cap_root(cy.radius, ro, d, cy.pa, -side.axis);
        if c1.y != 0.0 {
            roots_push(&roots, c1.x, PART_CAP_P1, tmin, tmax);
        }
        let c2 = cap_root(cy.radius, ro, d, cy.pb, side.axis);
        if c2.y != 0.0 {
            roots_push(&roots, c2.x, PART_CAP_P2, tmin, tmax);
        }
    }
    return roots;
}

fn cylinder_normal(cy: Cylinder, o: vec3<f32>, d: vec3<f32>, t: f32, part: u32) -> vec3<f32> {
    let dp = cy.pb - cy.pa;
    let axis = dp / length(dp);
    if part == PART_CAP_P1 {
        return -axis;
    }
    if part == PART_CAP_P2 {
        return axis;
    }
    // Facing the ray where the hit point rounds onto the axis (unit_or).
    let q = (o - cy.pa) + d * t;
    return unit_or(q - axis * dot(q, axis), -d);
}

// Keeps (t, part) as the best candidate if it lies in (tmin, tmax) and below the best so far;
// at equal t the earlier candidate stays, as in roots_push.
fn keep_first(best: vec2<f32>, t: f32, part: u32, tmin: f32, tmax: f32) -> vec2<f32> {
    if t > tmin && t < tmax && (best.x < 0.0 || t < best.x) {
        return vec2<f32>(t, f32(part));
    }
    return best;
}

// The first root in (tmin, tmax) as (t, part), or t = -1: cylinder_roots(..).t[0] without
// the list. Candidates in the order cylinder_roots pushes them.
fn cylinder_first(cy: Cylinder, ro: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> vec2<f32> {
    let side = cylinder_side(cy, ro, d);
    let q = side.q;
    var best = vec2<f32>(-1.0, 0.0);
    if q.z != 0.0 {
        if side.alpha.x >= 0.0 && side.alpha.x <= 1.0 {
            best = keep_first(best, q.x, PART_SURFACE, tmin, tmax);
        }
        if side.alpha.y >= 0.0 && side.alpha.y <= 1.0 {
            best = keep_first(best, q.y, PART_SURFACE, tmin, tmax);
        }
    }
    if cy.caps != 0u {
        let c1 = cap_root(cy.radius, ro, d, cy.pa, -side.axis);
        if c1.y != 0.0 {
            best = keep_first(best, c1.x, PART_CAP_P1, tmin, tmax);
        }
        let c2 = cap_root(cy.radius, ro, d, cy.pb, side.axis);
        if c2.y != 0.0 {
            best = keep_first(best, c2.x, PART_CAP_P2, tmin, tmax);
        }
    }
    return best;
}
