// Watertight ray/triangle (Woop, Benthin & Wald, JCGT 2013): twin of
// crates/core/src/geometry/triangle.rs (see there for why shared edges never leak, and for the tie rule
// that gives a point on a shared edge to one triangle).
#define_import_path strahl::triangle

#import strahl::types::{Triangle, PART_SURFACE}
#import strahl::roots::{Roots, roots_empty, roots_push}

// The ray's shear: permutation (kx, ky, kz) and (sx, sy, sz).
struct Shear {
    k: vec3<u32>,
    s: vec3<f32>,
}

fn shear_new(d: vec3<f32>) -> Shear {
    let ad = abs(d);
    var kz = 2u;
    if ad.x >= ad.y && ad.x >= ad.z {
        kz = 0u;
    } else if ad.y >= ad.z {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    if d[kz] < 0.0 {
        let tmp = kx;
        kx = ky;
        ky = tmp;
    }
    let sz = 1.0 / d[kz];
    return Shear(vec3<u32>(kx, ky, kz), vec3<f32>(d[kx] * sz, d[ky] * sz, sz));
}

// a*b - c*d by Kahan's algorithm: with a fused fma its sign is exact (relative error <= 2u,
// Jeannerod, Louvet & Muller 2013); where a driver splits fma into a multiply and an add
// (Vulkan allows it), it is the plain rounded difference, which is exactly antisymmetric. Either
// way swapping (a, b) with (c, d) flips the sign, which is what watertightness needs; a bare
// `a * b - c * d` could be contracted into an fma on one product only and lose that.
fn difference_of_products(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let cd = c * d;
    let err = fma(-c, d, cd);
    let dop = fma(a, b, -cd);
    return dop + err;
}

// The sign an edge function of exactly 0 counts with (geometry::triangle::edge_tie): the sheared
// edge vector's y, or -x where y is 0.
fn edge_tie(e: f32, ex: f32, ey: f32) -> f32 {
    return select(e, select(-ex, ey, ey != 0.0), e == 0.0);
}

// Hit distance in (tmin, tmax), or -1 when missed.
fn triangle_intersect(tri: Triangle, o: vec3<f32>, sh: Shear, tmin: f32, tmax: f32) -> f32 {
    return vertices_intersect(tri.va, tri.vb, tri.vc, o, sh, tmin, tmax);
}

// The same for the triangle (va, vb, vc).
fn vertices_intersect(va: vec3<f32>, vb: vec3<f32>, vc: vec3<f32>, o: vec3<f32>, sh: Shear, tmin: f32, tmax: f32) -> f32 {
    let a = va - o;
    let b = vb - o;
    let c = vc - o;
    let kx = sh.k.x;
    let ky = sh.k.y;
    let kz = sh.k.z;
    let ax = a[kx] - sh.s.x * a[kz];
    let ay = a[ky] - sh.s.y * a[kz];
    let bx = b[kx] - sh.s.x * b[kz];
    let by = b[ky] - sh.s.y * b[kz];
    let cx = c[kx] - sh.s.x * c[kz];
    let cy = c[ky] - sh.s.y * c[kz];
    // Edge functions antisymmetric whatever the compiler fuses (see difference_of_products): a
    // shared edge gives opposite signs in its two triangles, so no ray slips between them. A
    // point exactly on an edge (0) goes to one triangle by the tie rule.
    let u = difference_of_products(cx, by, cy, bx);
    let v = difference_of_products(ax, cy, ay, cx);
    let w = difference_of_products(bx, ay, by, ax);
    let su = edge_tie(u, cx - bx, cy - by);
    let sv = edge_tie(v, ax - cx, ay - cy);
    let sw = edge_tie(w, bx - ax, by - ay);
    if (su < 0.0 || sv < 0.0 || sw < 0.0) && (su > 0.0 || sv > 0.0 || sw > 0.0) {
        return -1.0;
    }
    let det = u + v + w;
    if det == 0.0 {
        return -1.0;
    }
    let az = sh.s.z * a[kz];
    let bz = sh.s.z * b[kz];
    let cz = sh.s.z * c[kz];
    let t = (u * az + v * bz + w * cz) / det;
    if t > tmin && t < tmax {
        return t;
    }
    return -1.0;
}

fn triangle_roots(tri: Triangle, o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Roots {
    var roots = roots_empty();
    let t = triangle_intersect(tri, o, shear_new(d), tmin, tmax);
    if t >= 0.0 {
        roots_push(&roots, t, PART_SURFACE, tmin, tmax);
    }
    return roots;
}

fn triangle_normal(tri: Triangle) -> vec3<f32> {
    return normalize(cross(tri.vb - tri.va, tri.vc - tri.va));
}
