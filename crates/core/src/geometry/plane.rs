//! Ray/infinite plane: (p0 + μd − point)·n = 0.

use super::{Part, Roots, Shape};
use crate::math::{Ray, Real, V3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane<R> {
    pub point: V3<R>,
    /// Unit normal; its side is the front face.
    pub normal: V3<R>,
}

impl<R: Real> Plane<R> {
    pub fn cast<S: Real>(&self) -> Plane<S> {
        Plane { point: self.point.cast(), normal: self.normal.cast() }
    }
}

impl<R: Real> Shape<R> for Plane<R> {
    /// μ = ((point − p0)·n) / (d·n); a ray parallel to the plane (d·n = 0) misses it, also
    /// when it lies in it. One division: relative error of μ within γ(7).
    #[inline]
    fn roots(&self, ray: &Ray<R>, tmin: R, tmax: R) -> Roots<R> {
        let mut roots = Roots::empty();
        let dn = ray.dir.dot(self.normal);
        if dn != R::ZERO {
            let t = (self.point - ray.origin).dot(self.normal) / dn;
            roots.push_in_range(t, Part::Surface, tmin, tmax);
        }
        roots
    }

    fn normal(&self, _ray: &Ray<R>, _t: R, _part: Part) -> V3<R> {
        self.normal
    }

    fn bounds(&self) -> Option<(V3<R>, V3<R>)> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_from_both_sides_and_misses_parallel_rays() {
        let p = Plane { point: V3::<f64>::new(0.0, -5.0, 0.0), normal: V3::new(0.0, 1.0, 0.0) };
        let down = Ray::new(V3::new(1.0, 0.0, 2.0), V3::new(0.0, -1.0, 0.0));
        assert_eq!(p.roots(&down, 0.0, f64::INFINITY).t[0], 5.0);
        let up = Ray::new(V3::new(1.0, -7.0, 2.0), V3::new(0.0, 1.0, 0.0));
        assert_eq!(p.roots(&up, 0.0, f64::INFINITY).t[0], 2.0);
        let parallel = Ray::new(V3::new(0.0, -5.0, 0.0), V3::new(1.0, 0.0, 0.0));
        assert_eq!(p.roots(&parallel, 0.0, f64::INFINITY).len, 0);
        assert_eq!(p.roots(&down, 0.0, 4.0).len, 0, "tmax excludes the hit");
    }
}
