//! Ray/finite cylinder: the lecture's open surface between p1 and p2 (α ∈ [0, 1] along the
//! axis), plus optional end caps that make it a closed solid.

use super::{Part, Roots, Shape, stable_quadratic, unit_or};
use crate::math::{Ray, Real, V3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder<R> {
    pub p1: V3<R>,
    pub p2: V3<R>,
    pub radius: R,
    /// Closed by two disks (a solid) or open (a tube, two-sided surface).
    pub caps: bool,
}

impl<R: Real> Cylinder<R> {
    pub fn cast<S: Real>(&self) -> Cylinder<S> {
        Cylinder { p1: self.p1.cast(), p2: self.p2.cast(), radius: S::from_f64(self.radius.to_f64()), caps: self.caps }
    }

    /// Unit axis â = (p2 − p1)/|p2 − p1| and the length |p2 − p1|.
    #[inline]
    pub fn axis(&self) -> (V3<R>, R) {
        let dp = self.p2 - self.p1;
        let len = dp.length();
        (dp / len, len)
    }

    /// The root of a cap disk (centre `c`, unit normal `n`), if the hit lies within r of c.
    #[inline]
    fn cap_root(&self, ray: &Ray<R>, c: V3<R>, n: V3<R>) -> Option<R> {
        let dn = ray.dir.dot(n);
        if dn == R::ZERO {
            return None; // edge-on: the disk has no area along this ray
        }
        let t = (c - ray.origin).dot(n) / dn;
        let q = (ray.origin - c) + ray.dir * t;
        (q.dot(q) <= self.radius * self.radius).then_some(t)
    }
}

impl<R: Real> Shape<R> for Cylinder<R> {
    /// The side: with o' = p0 − p1 and the unit axis â, the lecture's q·q = r² becomes
    /// A μ² + 2βμ + C = 0 on the components perpendicular to the axis. We form those
    /// components with cross products rather than by subtracting projections
    /// (|d⊥|² = |d × â|² does not cancel for rays nearly parallel to the axis, where
    /// 1 − (d·â)² would): A = |d × â|², β = (o' × â)·(d × â), C = |o' × â|² − r², and the
    /// discriminant by Lagrange's identity Δ = β² − AC = A r² − ((o' × â)·d)², which has no
    /// term of size |o'|⁴ to cancel (the cylinder analogue of Hearn & Baker's sphere form).
    /// α = (o'·â + μ d·â)/|p2 − p1| keeps roots with α ∈ [0, 1]. Rays exactly parallel
    /// to the axis (A = 0) can only meet the caps.
    ///
    /// Error behaviour: relative error of μ within a few γ(n) away from tangency and rims, but
    /// the line's distance from the axis enters through (o' × â)·d, rounded to about u·|o'|,
    /// and is divided by |d × â| = sin θ: a thin cylinder seen nearly along its axis from far
    /// away (r = 1e-4, θ = 2.5e-3, |o'| = 20) is decided only to u·|o'|/sin θ ≈ 5e-4, five radii.
    #[inline]
    fn roots(&self, ray: &Ray<R>, tmin: R, tmax: R) -> Roots<R> {
        let (axis, len) = self.axis();
        let o = ray.origin - self.p1;
        let d = ray.dir;
        let oa = o.cross(axis);
        let da = d.cross(axis);
        let a = da.dot(da);
        let beta = oa.dot(da);
        let r2 = self.radius * self.radius;
        let c = oa.dot(oa) - r2;
        let e = oa.dot(d);
        let disc = a * r2 - e * e;
        let mut roots = Roots::empty();
        if let Some((t0, t1)) = stable_quadratic(a, beta, c, disc) {
            let o_axial = o.dot(axis);
            let d_axial = d.dot(axis);
            // A tangent ray's double root is one point of contact, reported once.
            let distinct = if t1 != t0 { 2 } else { 1 };
            for t in [t0, t1].into_iter().take(distinct) {
                let alpha = (o_axial + t * d_axial) / len;
                if alpha >= R::ZERO && alpha <= R::ONE {
                    roots.push_in_range(t, Part::Surface, tmin, tmax);
                }
            }
        }
        if self.caps {
            if let Some(t) = self.cap_root(ray, self.p1, -axis) {
                roots.push_in_range(t, Part::CapP1, tmin, tmax);
            }
            if let Some(t) = self.cap_root(ray, self.p2, axis) {
                roots.push_in_range(t, Part::CapP2, tmin, tmax);
            }
        }
        roots
    }

    fn normal(&self, ray: &Ray<R>, t: R, part: Part) -> V3<R> {
        let (axis, _) = self.axis();
        match part {
            Part::CapP1 => -axis,
            Part::CapP2 => axis,
            Part::Surface => {
                // Facing the ray where the hit point rounds onto the axis ([`unit_or`]).
                let q = (ray.origin - self.p1) + ray.dir * t;
                unit_or(q - axis * q.dot(axis), -ray.dir)
            }
        }
    }

    /// Bounds of the two end disks: each disk of normal â spans r·√(1 − â_i²) along axis i.
    fn bounds(&self) -> Option<(V3<R>, V3<R>)> {
        let (axis, _) = self.axis();
        let one = V3::splat(R::ONE);
        let e = one - axis.mul_elem(axis);
        let ext = V3::new(e.x.max(R::ZERO).sqrt(), e.y.max(R::ZERO).sqrt(), e.z.max(R::ZERO).sqrt()) * self.radius;
        let lo = self.p1.min_elem(self.p2) - ext;
        let hi = self.p1.max_elem(self.p2) + ext;
        Some((lo, hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::testutil::{TestRays, TestRng, ray_f32};

    fn unit_z(caps: bool) -> Cylinder<f64> {
        Cylinder { p1: V3::new(0.0, 0.0, 0.0), p2: V3::new(0.0, 0.0, 2.0), radius: 1.0, caps }
    }

    #[test]
    fn ray_across_the_side_from_outside_enters_and_leaves() {
        let cyl = unit_z(true);
        let ray = Ray::new(V3::new(-5.0, 0.0, 1.0), V3::new(1.0, 0.0, 0.0));
        let r = cyl.roots(&ray, 0.0, f64::INFINITY);
        assert_eq!((r.len, r.t[0], r.t[1]), (2, 4.0, 6.0));
        assert_eq!(cyl.normal(&ray, 4.0, r.part[0]), V3::new(-1.0, 0.0, 0.0));
        assert_eq!(cyl.normal(&ray, 6.0, r.part[1]), V3::new(1.0, 0.0, 0.0));
    }

    #[test]
    fn ray_along_the_axis_hits_only_the_caps() {
        let ray = Ray::new(V3::new(0.5, 0.0, -3.0), V3::new(0.0, 0.0, 1.0));
        let r = unit_z(true).roots(&ray, 0.0, f64::INFINITY);
        assert_eq!((r.len, r.t[0], r.t[1]), (2, 3.0, 5.0));
        assert_eq!((r.part[0], r.part[1]), (Part::CapP1, Part::CapP2));
        // Open tube: a ray along the axis inside it meets nothing.
        assert_eq!(unit_z(false).roots(&ray, 0.0, f64::INFINITY).len, 0);
        // Outside the radius, the caps are missed too.
        let outside = Ray::new(V3::new(1.5, 0.0, -3.0), V3::new(0.0, 0.0, 1.0));
        assert_eq!(unit_z(true).roots(&outside, 0.0, f64::INFINITY).len, 0);
    }

    #[test]
    fn ray_from_inside_leaves_through_side_or_cap() {
        let cyl = unit_z(true);
        let inside = V3::new(0.0, 0.0, 1.0);
        let side = cyl.roots(&Ray::new(inside, V3::new(0.0, 1.0, 0.0)), 0.0, f64::INFINITY);
        assert_eq!((side.len, side.t[0], side.part[0]), (1, 1.0, Part::Surface));
        let up = cyl.roots(&Ray::new(inside, V3::new(0.0, 0.0, 1.0)), 0.0, f64::INFINITY);
        assert_eq!((up.len, up.t[0], up.part[0]), (1, 1.0, Part::CapP2));
        // The lecture's open tube: the far wall is the inside surface (α₂ ∈ [0, 1]).
        let tube = unit_z(false);
        let ray = Ray::new(V3::new(-5.0, 0.0, 1.0), V3::new(1.0, 0.0, 0.0));
        let r = tube.roots(&ray, 0.0, f64::INFINITY);
        assert_eq!(r.len, 2);
        assert!(ray.dir.dot(tube.normal(&ray, r.t[1], r.part[1])) > 0.0, "inside surface faces away");
    }

    #[test]
    fn side_roots_outside_the_alpha_range_are_dropped() {
        // Enters through the side at α = 0.85, leaves through the top cap; its second side
        // root lies above the top (α > 1) and is dropped.
        let ray = Ray::new(V3::new(-5.0, 0.0, 0.5), V3::new(1.0, 0.0, 0.3).normalize());
        let r = unit_z(true).roots(&ray, 0.0, f64::INFINITY);
        for (t, part) in r.iter() {
            let p = ray.at(t);
            match part {
                Part::Surface => assert!((0.0..=2.0).contains(&p.z)),
                _ => assert!((p.x * p.x + p.y * p.y) <= 1.0 + 1e-12),
            }
        }
        assert_eq!(r.len, 2);
        assert_eq!(r.part[1], Part::CapP2);
    }

    #[test]
    fn f32_agrees_with_f64_oracle_on_random_rays() {
        let mut rng = TestRng(11);
        let mut compared = 0;
        let mut max_rel = 0.0f64;
        for _ in 0..20_000 {
            let p1 = rng.in_cube(20.0);
            let p2 = p1 + rng.unit_vector() * rng.range(0.5, 10.0);
            let cyl = Cylinder { p1, p2, radius: rng.range(0.1, 3.0), caps: rng.next_u64().is_multiple_of(2) };
            let c32 = cyl.cast::<f32>();
            let exact = c32.cast::<f64>();
            let ray32 = ray_f32(&rng.ray_towards(50.0, (p1 + p2) * 0.5, 4.0));
            let ray = ray32.cast::<f64>();
            let want = exact.roots(&ray, 0.0, f64::INFINITY);
            let got = c32.roots(&ray32, 0.0, f32::INFINITY);
            if !well_conditioned(&exact, &ray, &want) {
                continue;
            }
            assert_eq!(want.len, got.len, "hit/miss disagree: {ray:?} {exact:?}");
            for i in 0..got.len {
                assert_eq!(want.part[i], got.part[i]);
                let scale = want.t[i].abs().max(1.0);
                max_rel = max_rel.max((want.t[i] - got.t[i] as f64).abs() / scale);
                compared += 1;
            }
        }
        assert!(compared > 5_000, "too few hits to judge: {compared}");
        assert!(max_rel < 5e-5, "max relative error of t {max_rel}");
    }

    /// Away from tangency and from the rims (where f32 rounding legitimately decides between
    /// side and cap, or hit and miss).
    fn well_conditioned(c: &Cylinder<f64>, ray: &Ray<f64>, roots: &Roots<f64>) -> bool {
        let (axis, len) = c.axis();
        let o = ray.origin - c.p1;
        let oa = o.cross(axis);
        let da = ray.dir.cross(axis);
        if da.length() < 1e-3 || ray.dir.dot(axis).abs() < 1e-3 {
            return false;
        }
        let line_dist = oa.dot(ray.dir).abs() / da.length();
        if (line_dist / c.radius - 1.0).abs() < 1e-3 {
            return false;
        }
        // Crossings of the infinite side must sit clear of the rims (α ≠ 0, 1) ...
        let infinite = Cylinder { caps: false, p1: c.p1 - axis * 1e4, p2: c.p2 + axis * 1e4, ..*c };
        let side_clear = infinite.roots(ray, -1e9, 1e9).iter().all(|(t, _)| {
            let alpha = (ray.at(t) - c.p1).dot(axis) / len;
            alpha.abs() > 1e-3 && (alpha - 1.0).abs() > 1e-3
        });
        // ... and crossings of the cap planes clear of the rim circles.
        let cap_clear = [c.p1, c.p2].iter().all(|&centre| {
            let t = (centre - ray.origin).dot(axis) / ray.dir.dot(axis);
            let radial = (ray.at(t) - centre).length() / c.radius;
            (radial - 1.0).abs() > 1e-3
        });
        side_clear && cap_clear && roots.iter().all(|(t, _)| t > 1e-6)
    }
}
