// The nearest point of one primitive's surface to a query point: twin of
// crates/core/src/geometry/closest.rs (Triangle::closest, Sphere::closest, Cylinder::closest,
// Plane::closest; see there for where each formula comes from and its error bound). Each
// function performs the f32 operations of its twin in the same order, with the same
// fallbacks, so that GPU and CPU feet agree to the device's rounding of those operations.
//
// Shader defs: SPHERES, CYLINDERS, PLANES (which of their routines exist; the triangle's takes
// bare vertices, as leaf triangles and scene triangles both give them).
#define_import_path strahl::closest

#import strahl::types::{F32_MAX, PART_SURFACE}
#ifdef SPHERES
#import strahl::types::Sphere
#endif
#ifdef CYLINDERS
#import strahl::types::{Cylinder, PART_CAP_P1, PART_CAP_P2}
#endif
#ifdef PLANES
#import strahl::types::Plane
#endif

// The square of the sine below which a triangle is taken as its three edges: g * g for
// g = gamma(16), rounded in f32 as the twin rounds it (geometry::closest, Triangle::closest).
const CLOSEST_SLIVER_SQ: f32 = #{CLOSEST_SLIVER_SQ};

// The nearest point of one primitive (geometry::closest::Foot): the point, its squared
// distance from the query point, a triangle's barycentric (u, v) (0 for other kinds) and the
// part of the surface it lies on (PART_*). dist_sq is the twin's dist2 (naga renames members
// that end in a digit).
struct Foot {
    point: vec3<f32>,
    dist_sq: f32,
    uv: vec2<f32>,
    part: u32,
}

// One query's answer as the host reads it (GpuClosestPoint in strahl-gpu's closest module):
// the nearest primitive's PrimRef and its foot.
struct ClosestPoint {
    point: vec3<f32>,
    dist_sq: f32,
    uv: vec2<f32>,
    prim_ref: u32,
    part: u32,
}

// The foot at `point` of query point p, at the squared distance |p - point|^2 (the `at` closure
// of Triangle::closest and nearest_edge).
fn foot_at(p: vec3<f32>, point: vec3<f32>, u: f32, v: f32) -> Foot {
    let d = p - point;
    return Foot(point, dot(d, d), vec2<f32>(u, v), PART_SURFACE);
}

// A unit vector perpendicular to unit a, for a query point on an axis (geometry::closest::
// perpendicular): normalize as V3::normalize, v * (1 / |v|).
fn perpendicular(a: vec3<f32>) -> vec3<f32> {
    let other = select(vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(1.0, 0.0, 0.0), abs(a.x) < 0.9);
    let c = cross(a, other);
    return c * (1.0 / sqrt(dot(c, c)));
}

// The nearest point of the segment a-b to p as the parameter along it in [0, 1]
// (geometry::closest::segment_param).
fn segment_param(a: vec3<f32>, b: vec3<f32>, p: vec3<f32>) -> f32 {
    let ab = b - a;
    let l2 = dot(ab, ab);
    if !(l2 > 0.0) {
        return 0.0;
    }
    return min(max(dot(p - a, ab) / l2, 0.0), 1.0);
}

// The foot on the edge e0-e1, with (u, v) of the parameter s along it: (s, 0) on v0-v1,
// (0, s) on v0-v2, (1 - s, s) on v1-v2 (which: 0, 1, 2).
fn edge_foot(e0: vec3<f32>, e1: vec3<f32>, p: vec3<f32>, which: u32) -> Foot {
    let s = segment_param(e0, e1, p);
    var uv = vec2<f32>(s, 0.0);
    if which == 1u {
        uv = vec2<f32>(0.0, s);
    } else if which == 2u {
        uv = vec2<f32>(1.0 - s, s);
    }
    return foot_at(p, e0 + (e1 - e0) * s, uv.x, uv.y);
}

// The nearest point of the three edges, the first of equally near ones (Triangle::nearest_edge):
// the foot on a triangle too thin to have a face in this precision.
fn nearest_edge(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, p: vec3<f32>) -> Foot {
    var best = edge_foot(a, b, p, 0u);
    let f1 = edge_foot(a, c, p, 1u);
    if f1.dist_sq < best.dist_sq {
        best = f1;
    }
    let f2 = edge_foot(b, c, p, 2u);
    if f2.dist_sq < best.dist_sq {
        best = f2;
    }
    return best;
}

// The nearest point of the triangle (a, b, c) to p by the Voronoi regions of its vertices, edges
// and face (Ericson, "Real-Time Collision Detection", 2005, 5.1.5, ClosestPtPointTriangle), the
// face's region determinants taken as triple products n.(ap x bp) (equal to Ericson's Gram
// determinants by Lagrange's identity, and keeping their sign on slivers). A triangle whose
// sine at a is below gamma(16) (n within its own rounding of 0), or whose n overflows, is taken
// as its three edges (nearest_edge).
//
// Error (Triangle::closest): the distance is within a few gamma(8) (|p - v0| + |e1| + |e2|) of
// the exact one, absolutely, plus for a triangle thinner than that, up to its width.
fn triangle_closest(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, p: vec3<f32>) -> Foot {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return foot_at(p, a, 0.0, 0.0);
    }
    let bp = p - b;
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return foot_at(p, b, 1.0, 0.0);
    }
    let n = cross(ab, ac);
    let n2 = dot(n, n);
    // !(n2 <= F32_MAX): the twin's !n2.is_finite() (n2 is not NaN past the first test).
    if !(n2 > CLOSEST_SLIVER_SQ * dot(ab, ab) * dot(ac, ac)) || !(n2 <= F32_MAX) {
        return nearest_edge(a, b, c, p);
    }
    let cp = p - c;
    let vc = dot(n, cross(ap, bp));
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 && d1 - d3 > 0.0 {
        let v = d1 / (d1 - d3);
        return foot_at(p, a + ab * v, v, 0.0);
    }
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return foot_at(p, c, 0.0, 1.0);
    }
    let vb = dot(n, cross(cp, ap));
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 && d2 - d6 > 0.0 {
        let w = d2 / (d2 - d6);
        return foot_at(p, a + ac * w, 0.0, w);
    }
    let va = dot(n, cross(bp, cp));
    let e43 = d4 - d3;
    let e56 = d5 - d6;
    if va <= 0.0 && e43 >= 0.0 && e56 >= 0.0 && e43 + e56 > 0.0 {
        let w = e43 / (e43 + e56);
        return foot_at(p, b + (c - b) * w, 1.0 - w, w);
    }
    let sum = va + vb + vc;
    if sum > 0.0 {
        let inv = 1.0 / sum;
        let v = vb * inv;
        let w = vc * inv;
        // A foot inside the face is at the distance |ap.n| / |n| from the plane.
        let h = dot(ap, n);
        return Foot(a + ab * v + ac * w, h * h / n2, vec2<f32>(v, w), PART_SURFACE);
    }
    return nearest_edge(a, b, c, p);
}

#ifdef SPHERES
// c + r (p - c) / |p - c|, at distance ||p - c| - r| (Sphere::closest: error within
// gamma(5) max(|p - c|, r)); a query point at the centre gets the point on +x.
fn sphere_closest(s: Sphere, p: vec3<f32>) -> Foot {
    let d = p - s.center;
    let l = sqrt(dot(d, d));
    var dir = vec3<f32>(1.0, 0.0, 0.0);
    if l > 0.0 && l <= F32_MAX {
        dir = d / l;
    }
    let gap = abs(l - s.radius);
    return Foot(s.center + dir * s.radius, gap * gap, vec2<f32>(0.0), PART_SURFACE);
}
#endif

#ifdef CYLINDERS
// The nearest point of the side (the axis clamped to [0, len], at radius r from it) and, with
// caps, of each cap disk (the point's projection onto the cap's plane pulled in to radius r):
// the nearest of the three, a foot on the rim the side's (Cylinder::closest). Each squared
// distance is the sum of the two squared offsets in the cylinder's frame (s along the unit
// axis from p1, rho from the axis: Cylinder::frame), so its error is relative to the distance
// plus that of the frame (gamma(6) |p - p1| for s and rho).
fn cylinder_closest(cy: Cylinder, p: vec3<f32>) -> Foot {
    let dp = cy.pb - cy.pa;
    let len = sqrt(dot(dp, dp));
    let axis = dp / len;
    let d = p - cy.pa;
    let s = dot(d, axis);
    let q = d - axis * s;
    let rho = sqrt(dot(q, q));
    var e: vec3<f32>;
    if rho > 0.0 && rho <= F32_MAX {
        e = q / rho;
    } else {
        e = perpendicular(axis);
    }
    let sc = min(max(s, 0.0), len);
    let ds = s - sc;
    let dr = rho - cy.radius;
    var best = Foot(cy.pa + axis * sc + e * cy.radius, ds * ds + dr * dr, vec2<f32>(0.0), PART_SURFACE);
    if cy.caps != 0u {
        let out = max(rho - cy.radius, 0.0);
        let radial = e * min(rho, cy.radius);
        // The cap at p1 (axis offset 0), then the one at p2 (len).
        let da1 = s - 0.0;
        let d1 = da1 * da1 + out * out;
        if d1 < best.dist_sq {
            best = Foot(cy.pa + axis * 0.0 + radial, d1, vec2<f32>(0.0), PART_CAP_P1);
        }
        let da2 = s - len;
        let d2 = da2 * da2 + out * out;
        if d2 < best.dist_sq {
            best = Foot(cy.pa + axis * len + radial, d2, vec2<f32>(0.0), PART_CAP_P2);
        }
    }
    return best;
}
#endif

#ifdef PLANES
// p - ((p - point).n) n, at distance |(p - point).n| (Plane::closest: error gamma(4) |p - point|).
fn plane_closest(pl: Plane, p: vec3<f32>) -> Foot {
    let s = dot(p - pl.point, pl.normal);
    return Foot(p - pl.normal * s, s * s, vec2<f32>(0.0), PART_SURFACE);
}
#endif
