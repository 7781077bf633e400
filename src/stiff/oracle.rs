//! The oracle for the stiff cases: the f32 inputs taken exactly and solved in double-double
//! arithmetic (≈ 106-bit significands, `twofloat`), where f64 alone cannot judge f32 (a
//! sphere of radius 1e-4 a million units away needs t to 1e-10 relative).

use strahl_core::geometry::{Cylinder, Sphere, Triangle};
use strahl_core::math::{Ray, V3};
use twofloat::TwoFloat;

type Dd = TwoFloat;

/// f32's unit roundoff.
const U32: f64 = f32::EPSILON as f64 * 0.5;

/// The smallest relative margin a decision needs to count as clear: 1e-6, or the positional
/// uncertainty f32 itself has at distance `reach` (about u·reach), relative to `size`, with a
/// factor 32 for the few roundings of any f32 formulation. Inside that margin no f32
/// computation can decide, and the case is reported as ambiguous rather than counted.
fn margin(reach: f64, size: f64) -> f64 {
    (32.0 * U32 * reach / size).max(1e-6)
}

fn dd(v: f32) -> Dd {
    Dd::from(v as f64)
}

fn dot(a: [Dd; 3], b: [Dd; 3]) -> Dd {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [Dd; 3], b: [Dd; 3]) -> [Dd; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [Dd; 3], b: [Dd; 3]) -> [Dd; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn v(p: V3<f32>) -> [Dd; 3] {
    [dd(p.x), dd(p.y), dd(p.z)]
}

/// Exact-ish roots of a μ² + 2βμ + c = 0 and how clear the decision hit/miss is: the
/// discriminant relative to `scale`, its value for a ray through the centre (near 0: tangent).
fn quadratic(a: Dd, beta: Dd, c: Dd, scale: Dd) -> (Option<(f64, f64)>, f64) {
    let disc = beta * beta - a * c;
    let clarity = disc.hi() / scale.hi().abs().max(f64::MIN_POSITIVE);
    if disc.hi() < 0.0 {
        return (None, clarity);
    }
    let s = disc.sqrt();
    let t0 = (-beta - s) / a;
    let t1 = (-beta + s) / a;
    (Some((t0.hi() + t0.lo(), t1.hi() + t1.lo())), clarity)
}

/// Both crossings of the ray's line with the sphere (unbounded in t), and the clarity: the
/// smaller of how far the line is from tangency (Δ relative to a·r²) and how far the origin
/// is from the surface (c = |f|² − r² relative to 8u(|f|² + r²), u = 2⁻²⁴: closer than a few
/// ULPs of its coordinates, no f32 computation can tell on which side the origin is).
pub fn sphere(s: &Sphere<f32>, ray: &Ray<f32>) -> (Option<(f64, f64)>, f64) {
    let f = sub(v(ray.origin), v(s.center));
    let d = v(ray.dir);
    let r = dd(s.radius);
    let a = dot(d, d);
    let (ff, rr) = (dot(f, f), r * r);
    let (roots, tangency) = quadratic(a, dot(d, f), ff - rr, a * rr);
    // The line's distance from the centre is known to about u·|f|: scale the tangency margin.
    let tangency = tangency.abs() / margin(ff.hi().sqrt() + s.radius as f64, s.radius as f64) * 1e-6;
    (roots, tangency.min(origin_clarity(ff, rr)))
}

/// |c| relative to the rounding of c in f32, scaled so that 1e-6 marks "a few ULPs".
fn origin_clarity(ff: Dd, rr: Dd) -> f64 {
    let c = (ff - rr).hi().abs();
    c / (8.0 * f32::EPSILON as f64 * 0.5 * (ff.hi() + rr.hi())) * 1e-6
}

/// Crossings of the ray's line with the infinite cylinder through p1, p2 (the axis not
/// normalised, so no rounding enters), with their α along the axis, and the clarity.
pub fn cylinder_side(c: &Cylinder<f32>, ray: &Ray<f32>) -> (Option<[(f64, f64); 2]>, f64) {
    let axis = sub(v(c.p2), v(c.p1));
    let aa = dot(axis, axis);
    let o = sub(v(ray.origin), v(c.p1));
    let d = v(ray.dir);
    // |x × axis|² / |axis|² is the squared distance of x from the axis line.
    let oa = cross(o, axis);
    let da = cross(d, axis);
    let r = dd(c.radius);
    let a = dot(da, da);
    let (oo, rr) = (dot(oa, oa), r * r * aa);
    let (roots, tangency) = quadratic(a, dot(oa, da), oo - rr, a * rr);
    // The f32 side test knows the line's distance from the axis to about u·|o|/sin θ (θ between
    // ray and axis; see geometry::cylinder), so nearly axial rays get a wider margin.
    let sin_theta = (a.hi() / (dot(d, d).hi() * aa.hi())).sqrt().max(1e-12);
    let reach = (dot(o, o).hi().sqrt() + c.radius as f64) / sin_theta;
    let clarity = (tangency.abs() / margin(reach, c.radius as f64) * 1e-6).min(origin_clarity(oo, rr));
    let alpha = |t: f64| {
        let p = [o[0] + d[0] * Dd::from(t), o[1] + d[1] * Dd::from(t), o[2] + d[2] * Dd::from(t)];
        (dot(p, axis) / aa).hi()
    };
    (roots.map(|(t0, t1)| [(t0, alpha(t0)), (t1, alpha(t1))]), clarity)
}

/// Whether the ray's line crosses the triangle, by the signs of exact-ish edge volumes, and
/// the smallest |barycentric coordinate| (near 0: on an edge, ambiguous); `None` for a line
/// parallel to the triangle's plane (or a degenerate triangle).
pub fn triangle(t: &Triangle<f32>, ray: &Ray<f32>) -> Option<(f64, f64, bool)> {
    let (o, d) = (v(ray.origin), v(ray.dir));
    let p = [v(t.v[0]), v(t.v[1]), v(t.v[2])];
    // Signed volumes of (d, p_i − o, p_j − o): the edge functions of the ray.
    let e = |i: usize, j: usize| dot(d, cross(sub(p[i], o), sub(p[j], o)));
    let (u, w, x) = (e(1, 2), e(2, 0), e(0, 1));
    let det = u + w + x;
    if det.hi() == 0.0 {
        return None;
    }
    let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let dn = dot(d, n);
    if dn.hi() == 0.0 {
        return None;
    }
    let tt = dot(sub(p[0], o), n) / dn;
    let bary = [u / det, w / det, x / det].map(|b| b.hi());
    let inside = bary.iter().all(|&b| b >= 0.0);
    let margin = bary.iter().map(|b| b.abs()).fold(f64::INFINITY, f64::min);
    Some((tt.hi() + tt.lo(), margin, inside))
}

/// The exact point ray.origin + t·ray.dir, in f64 (rounded once).
pub fn point(ray: &Ray<f32>, t: f64) -> V3<f64> {
    let (o, d) = (v(ray.origin), v(ray.dir));
    let t = Dd::from(t);
    let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
    V3::new(p[0].hi(), p[1].hi(), p[2].hi())
}

/// Every crossing of the ray (t > 0) with a finite, optionally capped cylinder, ascending, and
/// whether the answer is clear: no crossing within a relative 1e-6 of tangency, of a rim, or
/// of the origin.
pub fn cylinder(c: &Cylinder<f32>, ray: &Ray<f32>) -> (Vec<f64>, bool) {
    let mut roots = Vec::new();
    let mut clear = true;
    let (side, clarity) = cylinder_side(c, ray);
    let len = ((c.p2 - c.p1).to_f64()).length();
    let reach = |t: f64| ray.origin.to_f64().length() + t.abs();
    // The side's tangency matters only where the line passes the finite part (α of its
    // closest approach to the axis within reach of [0, 1]); axial rays meet only the caps.
    if closest_alpha(c, ray).is_some_and(|alpha| (-0.5..=1.5).contains(&alpha)) {
        clear &= clarity.abs() > 1e-6;
    }
    if let Some(pair) = side {
        for (t, alpha) in pair {
            let m = margin(reach(t), len);
            clear &= alpha.abs() > m && (alpha - 1.0).abs() > m;
            if (0.0..=1.0).contains(&alpha) && t > 0.0 {
                roots.push(t);
            }
        }
    }
    if c.caps {
        let axis = sub(v(c.p2), v(c.p1));
        let (o, d) = (v(ray.origin), v(ray.dir));
        let dn = dot(d, axis);
        if dn.hi() != 0.0 {
            for centre in [v(c.p1), v(c.p2)] {
                let t = dot(sub(centre, o), axis) / dn;
                let q = [o[0] + d[0] * t - centre[0], o[1] + d[1] * t - centre[1], o[2] + d[2] * t - centre[2]];
                let r2 = dd(c.radius) * dd(c.radius);
                let rel = ((dot(q, q) - r2) / r2).hi();
                clear &= rel.abs() > 2.0 * margin(reach(t.hi()), c.radius as f64);
                if rel <= 0.0 && t.hi() > 0.0 {
                    roots.push(t.hi() + t.lo());
                }
            }
        }
    }
    roots.sort_by(f64::total_cmp);
    clear &= roots.first().is_none_or(|&t| t > 1e-6);
    (roots, clear)
}

/// α along the axis of the ray's closest approach to the axis line (None if parallel).
fn closest_alpha(c: &Cylinder<f32>, ray: &Ray<f32>) -> Option<f64> {
    let (o, d) = (ray.origin.to_f64() - c.p1.to_f64(), ray.dir.to_f64());
    let axis = c.p2.to_f64() - c.p1.to_f64();
    let da = d.cross(axis);
    let a = da.length_squared();
    if a == 0.0 {
        return None;
    }
    let t = -o.cross(axis).dot(da) / a;
    Some((o + d * t).dot(axis) / axis.length_squared())
}

/// The sphere's crossings with t > 0, ascending, and whether the answer is clear.
pub fn sphere_roots(s: &Sphere<f32>, ray: &Ray<f32>) -> (Vec<f64>, bool) {
    let (roots, clarity) = sphere(s, ray);
    let mut out: Vec<f64> =
        roots.map(|(a, b)| vec![a, b]).unwrap_or_default().into_iter().filter(|&t| t > 0.0).collect();
    out.dedup();
    (out.clone(), clarity.abs() > 1e-6 && out.first().is_none_or(|&t| t > 1e-6 * s.radius as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oracle_solves_the_lecture_example_exactly() {
        let ray = Ray::new(V3::zero(), V3::new(0.0, 0.0, 1.0));
        let (roots, clarity) = sphere(&Sphere { center: V3::new(0.0, 0.0, 8.0), radius: 5.0 }, &ray);
        assert_eq!(roots, Some((3.0, 13.0)));
        assert!(clarity > 0.1);
    }

    #[test]
    fn oracle_resolves_a_tiny_far_sphere_beyond_f64_naive() {
        // r = 1e-4 at 1e6: the naive f64 discriminant b² − c (≈1e24 − 1e24) has no digits left.
        let s = Sphere { center: V3::new(0.0, 0.0, 1.0e6), radius: 1.0e-4 };
        let ray = Ray::new(V3::zero(), V3::new(0.0, 0.0, 1.0));
        let (roots, _) = sphere(&s, &ray);
        let (t0, t1) = roots.expect("hit");
        // Within 2 f64 ULPs at 1e6 (2.3e-10); the naive form would return 1e6 twice, 1e-4 off.
        let r = 1.0e-4f32 as f64;
        assert!((t0 - (1.0e6 - r)).abs() < 2.5e-10, "{t0}");
        assert!((t1 - (1.0e6 + r)).abs() < 2.5e-10, "{t1}");
    }
}
