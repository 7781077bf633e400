//! The textbook formulations the robust ones replace, kept only so that `strahl stiff` can
//! show what the robustness buys and costs. Nothing renders with these.

use strahl_core::geometry::{Cylinder, Sphere, Triangle};
use strahl_core::math::{Ray, V3};

/// The lecture's sphere formula as written: μ = −d·Δp ± √((d·Δp)² − |Δp|² + r²).
/// Both terms under the root are ≈ |Δp|⁴-sized for a small sphere far away, and cancel.
pub fn sphere_roots(s: &Sphere<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Vec<f32> {
    let dp = ray.origin - s.center;
    let b = ray.dir.dot(dp);
    let disc = b * b - dp.dot(dp) + s.radius * s.radius;
    if disc < 0.0 {
        return Vec::new();
    }
    let q = disc.sqrt();
    [-b - q, -b + q].into_iter().filter(|&t| t > tmin && t < tmax).collect()
}

/// The lecture's cylinder: q = p0 + μd − p1 − α Δp with α from the projection onto Δp,
/// expanded into A μ² + B μ + C = 0 by subtracting projections, roots by the schoolbook
/// formula; side roots kept for α ∈ [0, 1], caps as disks.
pub fn cylinder_roots(c: &Cylinder<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Vec<f32> {
    let dp = c.p2 - c.p1;
    let dd = dp.dot(dp);
    let o = ray.origin - c.p1;
    let d = ray.dir;
    let d_perp = d - dp * (d.dot(dp) / dd);
    let o_perp = o - dp * (o.dot(dp) / dd);
    let a = d_perp.dot(d_perp);
    let b = 2.0 * d_perp.dot(o_perp);
    let cc = o_perp.dot(o_perp) - c.radius * c.radius;
    let disc = b * b - 4.0 * a * cc;
    let mut out = Vec::new();
    if disc >= 0.0 && a != 0.0 {
        let s = disc.sqrt();
        for t in [(-b - s) / (2.0 * a), (-b + s) / (2.0 * a)] {
            let alpha = (o.dot(dp) + t * d.dot(dp)) / dd;
            if (0.0..=1.0).contains(&alpha) && t > tmin && t < tmax {
                out.push(t);
            }
        }
    }
    if c.caps {
        let n = dp / dd.sqrt();
        for centre in [c.p1, c.p2] {
            let dn = d.dot(n);
            if dn != 0.0 {
                let t = (centre - ray.origin).dot(n) / dn;
                let q = ray.at(t) - centre;
                if q.dot(q) <= c.radius * c.radius && t > tmin && t < tmax {
                    out.push(t);
                }
            }
        }
    }
    out.sort_by(f32::total_cmp);
    out
}

/// Möller & Trumbore (1997): not watertight — the barycentric tests of two triangles sharing
/// an edge are computed from different vertices and can both fail.
pub fn triangle_hit(t: &Triangle<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Option<f32> {
    let e1 = t.v[1] - t.v[0];
    let e2 = t.v[2] - t.v[0];
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = ray.origin - t.v[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = ray.dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let tt = e2.dot(q) * inv;
    (tt > tmin && tt < tmax).then_some(tt)
}

/// The lecture's ε remedy: move the hit point by a fixed ε along the normal.
pub const EPSILON: f32 = 1e-4;
pub fn offset_by_epsilon(p: V3<f32>, n: V3<f32>) -> V3<f32> {
    p + n * EPSILON
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textbook_forms_agree_with_the_lecture_example() {
        let ray = Ray::new(V3::zero(), V3::new(0.0, 0.0, 1.0));
        let a = Sphere { center: V3::new(0.0, 0.0, 8.0), radius: 5.0 };
        assert_eq!(sphere_roots(&a, &ray, 0.0, f32::INFINITY), vec![3.0, 13.0]);
        let tri = Triangle { v: [V3::new(-1.0, -1.0, 2.0), V3::new(1.0, -1.0, 2.0), V3::new(0.0, 1.0, 2.0)] };
        assert_eq!(triangle_hit(&tri, &ray, 0.0, f32::INFINITY), Some(2.0));
        let cyl = Cylinder { p1: V3::new(0.0, -1.0, 5.0), p2: V3::new(0.0, 1.0, 5.0), radius: 1.0, caps: true };
        assert_eq!(cylinder_roots(&cyl, &ray, 0.0, f32::INFINITY), vec![4.0, 6.0]);
    }
}
