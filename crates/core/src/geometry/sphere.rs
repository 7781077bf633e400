//! Ray/sphere: |p0 + μd − p_s|² − r² = 0 (the lecture's first quadric).

use super::{Part, Roots, Shape, stable_quadratic, unit_or};
use crate::math::{Ray, Real, V3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere<R> {
    /// The centre p_s.
    pub center: V3<R>,
    pub radius: R,
}

impl<R: Real> Sphere<R> {
    pub fn cast<S: Real>(&self) -> Sphere<S> {
        Sphere { center: self.center.cast(), radius: S::from_f64(self.radius.to_f64()) }
    }
}

impl<R: Real> Shape<R> for Sphere<R> {
    /// With f = p0 − p_s, the lecture's quadratic is a μ² + 2βμ + c = 0, a = d·d, β = d·f,
    /// c = f·f − r². The textbook discriminant β² − ac cancels catastrophically for a small
    /// sphere far away (both terms ≈ |f|⁴); we use the equal form
    /// Δ = a (r² − |f − (β/a) d|²) (Hearn & Baker; Haines et al., Ray Tracing Gems ch. 7),
    /// whose only subtraction is between quantities of the size of r², and take the roots
    /// from [`stable_quadratic`]. Relative error of μ: O(γ(8)) away from tangency.
    #[inline]
    fn roots(&self, ray: &Ray<R>, tmin: R, tmax: R) -> Roots<R> {
        let f = ray.origin - self.center;
        let d = ray.dir;
        let a = d.dot(d);
        let beta = d.dot(f);
        let c = f.dot(f) - self.radius * self.radius;
        let l = f - d * (beta / a);
        let disc = a * (self.radius * self.radius - l.dot(l));
        let mut roots = Roots::empty();
        if let Some((t0, t1)) = stable_quadratic(a, beta, c, disc) {
            roots.push_in_range(t0, Part::Surface, tmin, tmax);
            // A tangent ray's double root is one point of contact, reported once.
            if t1 != t0 {
                roots.push_in_range(t1, Part::Surface, tmin, tmax);
            }
        }
        roots
    }

    /// Facing the ray where the hit point rounds onto the centre ([`unit_or`]).
    fn normal(&self, ray: &Ray<R>, t: R, _part: Part) -> V3<R> {
        unit_or((ray.origin - self.center) + ray.dir * t, -ray.dir)
    }

    fn bounds(&self) -> Option<(V3<R>, V3<R>)> {
        let r = V3::splat(self.radius);
        Some((self.center - r, self.center + r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::testutil::{TestRays, TestRng, ray_f32};

    /// The lecture's "Problem Time": p_v = (0,0,−10), the ray through p_i = (0,0,0).
    #[test]
    fn lecture_worked_example_is_exact() {
        let ray = Ray::new(V3::<f32>::new(0.0, 0.0, 0.0), V3::new(0.0, 0.0, 10.0).normalize());
        let a = Sphere { center: V3::new(0.0, 0.0, 8.0), radius: 5.0 };
        let b = Sphere { center: V3::new(0.0, 0.0, 9.0), radius: 3.0 };
        let c = Sphere { center: V3::new(0.0, -3.0, 8.0), radius: 2.0 };
        let ra = a.roots(&ray, 0.0, f32::INFINITY);
        assert_eq!((ra.len, ra.t[0], ra.t[1]), (2, 3.0, 13.0));
        let rb = b.roots(&ray, 0.0, f32::INFINITY);
        assert_eq!((rb.len, rb.t[0], rb.t[1]), (2, 6.0, 12.0));
        assert_eq!(c.roots(&ray, 0.0, f32::INFINITY).len, 0);
        assert_eq!(a.normal(&ray, 3.0, Part::Surface), V3::new(0.0, 0.0, -1.0));
    }

    #[test]
    fn tangent_ray_touches_once() {
        let s = Sphere { center: V3::<f64>::new(0.0, 1.0, 5.0), radius: 1.0 };
        let r = s.roots(&Ray::new(V3::zero(), V3::new(0.0, 0.0, 1.0)), 0.0, f64::INFINITY);
        assert_eq!((r.len, r.t[0]), (1, 5.0));
    }

    #[test]
    fn origin_inside_gives_only_the_exit() {
        let s = Sphere { center: V3::<f64>::zero(), radius: 2.0 };
        let r = s.roots(&Ray::new(V3::zero(), V3::new(1.0, 0.0, 0.0)), 0.0, f64::INFINITY);
        assert_eq!((r.len, r.t[0]), (1, 2.0));
    }

    /// f32 against the f64 oracle on random rays: hit/miss agree wherever the ray is not
    /// within a relative 1e-3 of tangency, and t agrees to a small relative error.
    #[test]
    fn f32_agrees_with_f64_oracle_on_random_rays() {
        let mut rng = TestRng(7);
        let mut max_rel = 0.0f64;
        let mut hits = 0;
        for _ in 0..20_000 {
            let center = rng.in_cube(50.0);
            let radius = rng.range(0.1, 10.0);
            let s64 = Sphere { center, radius };
            let s32 = s64.cast::<f32>();
            let ray64 = rng.ray_towards(100.0, center, 1.5 * radius);
            let ray32 = ray_f32(&ray64);
            // Judge the f32 problem exactly as posed: the oracle uses the f32 inputs in f64.
            let s_exact = s32.cast::<f64>();
            let r_exact = ray32.cast::<f64>();
            let oracle = s_exact.roots(&r_exact, 0.0, f64::INFINITY);
            let got = s32.roots(&ray32, 0.0, f32::INFINITY);
            // Distance of the line from the centre relative to r: near 1 means tangent.
            let f = r_exact.origin - s_exact.center;
            let miss_dist = (f - r_exact.dir * f.dot(r_exact.dir)).length() / s_exact.radius;
            if (miss_dist - 1.0).abs() < 1e-3 {
                continue;
            }
            assert_eq!(oracle.len, got.len, "hit/miss disagree, ray {ray64:?}, sphere {s64:?}");
            for i in 0..got.len {
                let (te, tg) = (oracle.t[i], got.t[i] as f64);
                max_rel = max_rel.max((te - tg).abs() / te.abs().max(radius));
                hits += 1;
            }
        }
        assert!(hits > 5_000, "too few hits to judge: {hits}");
        assert!(max_rel < 2e-5, "max relative error of t {max_rel}");
    }

    /// A sphere of radius 1 at distance 1e4: the textbook discriminant loses every bit here,
    /// the robust one keeps the hit.
    #[test]
    fn small_far_sphere_keeps_its_hits() {
        let s = Sphere { center: V3::<f32>::new(0.0, 0.0, 1.0e4), radius: 1.0 };
        for k in 0..20 {
            let y = -0.95 + 0.1 * k as f32;
            let target = V3::new(0.0, y, 1.0e4);
            let ray = Ray::new(V3::zero(), target.normalize());
            let r = s.roots(&ray, 0.0, f32::INFINITY);
            assert_eq!(r.len, 2, "ray at offset {y} missed");
            let exact = 1.0e4 - (1.0f64 - (y as f64).powi(2)).sqrt();
            assert!(((r.t[0] as f64) - exact).abs() < 5e-3, "{} vs {exact} (5 ulp at 1e4)", r.t[0]);
        }
    }
}
