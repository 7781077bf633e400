//! Ray/primitive intersection, written once over [`Real`] (f32 mirror of the WGSL code,
//! f64 oracle).
//!
//! Each primitive reports its *roots*: every parameter μ (`t`) in (tmin, tmax) at which the
//! ray p = p0 + μd crosses its surface, in ascending order, each with the part of the surface
//! it lies on. The normal is computed afterwards, once, for the hit that is kept: nearest-hit
//! traversal only needs the `t`s.

pub mod closest;
pub mod cylinder;
pub mod plane;
pub mod sphere;
pub mod triangle;

pub use cylinder::Cylinder;
pub use plane::Plane;
pub use sphere::Sphere;
pub use triangle::Triangle;

use crate::math::{Ray, Real, V3};

/// Which part of a primitive's surface a root lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum Part {
    /// The curved side of a sphere or cylinder, or the single face of a flat primitive.
    #[default]
    Surface = 0,
    /// The cylinder's end cap at p1 (outward normal −â).
    CapP1 = 1,
    /// The cylinder's end cap at p2 (outward normal +â).
    CapP2 = 2,
}

/// Up to four roots of one primitive, ascending in `t`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Roots<R> {
    pub t: [R; 4],
    pub part: [Part; 4],
    pub len: usize,
}

impl<R: Real> Roots<R> {
    pub fn empty() -> Self {
        Self { t: [R::ZERO; 4], part: [Part::Surface; 4], len: 0 }
    }
    /// Adds a root if it lies strictly inside (tmin, tmax); keeps the list sorted.
    #[inline]
    pub fn push_in_range(&mut self, t: R, part: Part, tmin: R, tmax: R) {
        if !(t > tmin && t < tmax) {
            return; // also rejects NaN
        }
        let mut i = self.len;
        while i > 0 && self.t[i - 1] > t {
            self.t[i] = self.t[i - 1];
            self.part[i] = self.part[i - 1];
            i -= 1;
        }
        self.t[i] = t;
        self.part[i] = part;
        self.len += 1;
    }
    pub fn first(&self) -> Option<(R, Part)> {
        (self.len > 0).then(|| (self.t[0], self.part[0]))
    }
    pub fn iter(&self) -> impl Iterator<Item = (R, Part)> + '_ {
        (0..self.len).map(|i| (self.t[i], self.part[i]))
    }
}

/// What every primitive offers the traversal and the shading code.
pub trait Shape<R: Real> {
    /// Every root in (tmin, tmax), ascending.
    fn roots(&self, ray: &Ray<R>, tmin: R, tmax: R) -> Roots<R>;
    /// Unit outward (front-face) normal at the root `t` on `part`.
    fn normal(&self, ray: &Ray<R>, t: R, part: Part) -> V3<R>;
    /// Axis-aligned bounds, or `None` for unbounded shapes (planes).
    fn bounds(&self) -> Option<(V3<R>, V3<R>)>;
}

/// `n` normalised, or `fallback` where `n` is zero or its squared length overflows: a normal
/// from a hit point that rounding put on a sphere's centre or a cylinder's axis (a ray from
/// 1e38 away, where f32 cannot tell the surface from the centre). No NaN leaves a normal.
#[inline]
pub fn unit_or<R: Real>(n: V3<R>, fallback: V3<R>) -> V3<R> {
    let l2 = n.dot(n);
    if l2 > R::ZERO && l2.is_finite() { n.normalize() } else { fallback }
}

/// Solves a t² + 2βt + c = 0 for its real roots in the form that does not cancel
/// (Press et al., Numerical Recipes §5.6; Haines et al., Ray Tracing Gems ch. 7):
/// q = −(β + sign(β)·√Δ), t₁ = q/a, t₂ = c/q, with the discriminant Δ = β² − ac supplied by
/// the caller in a form of its own that avoids cancellation. Both roots then carry a
/// relative error of a few γ(n) unless Δ itself is near zero (tangent rays).
/// Returns the roots in ascending order, or `None` for Δ < 0.
#[inline]
pub fn stable_quadratic<R: Real>(a: R, beta: R, c: R, disc: R) -> Option<(R, R)> {
    if !(disc >= R::ZERO) || a == R::ZERO {
        return None;
    }
    let q = -(beta + beta.signum_nonzero() * disc.sqrt());
    if q == R::ZERO {
        // β = 0 and Δ = 0: a double root at the origin.
        return Some((R::ZERO, R::ZERO));
    }
    let t1 = q / a;
    let t2 = c / q;
    Some(if t1 <= t2 { (t1, t2) } else { (t2, t1) })
}

#[doc(hidden)]
pub mod testutil {
    use crate::math::{Ray, V3};

    pub use crate::rng::SplitMix64 as TestRng;

    /// Test-ray helpers on top of the shared generator.
    pub trait TestRays {
        fn in_cube(&mut self, h: f64) -> V3<f64>;
        fn unit_vector(&mut self) -> V3<f64>;
        fn ray_towards(&mut self, h: f64, target: V3<f64>, target_h: f64) -> Ray<f64>;
    }

    impl TestRays for TestRng {
        fn in_cube(&mut self, h: f64) -> V3<f64> {
            self.cube(h)
        }
        fn unit_vector(&mut self) -> V3<f64> {
            self.direction()
        }
        /// A ray from a random point in a cube of half-size `h` aimed at a random point in a
        /// cube of half-size `target_h` around `target`.
        fn ray_towards(&mut self, h: f64, target: V3<f64>, target_h: f64) -> Ray<f64> {
            let o = self.in_cube(h);
            let p = target + self.in_cube(target_h);
            Ray::new(o, (p - o).normalize())
        }
    }

    /// The f32 image of an f64 ray, with the direction renormalised in f32 as strahl does.
    pub fn ray_f32(r: &Ray<f64>) -> Ray<f32> {
        Ray::new(r.origin.cast(), r.dir.cast::<f32>().normalize())
    }
}
