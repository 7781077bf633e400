//! Ray/triangle: the watertight test of Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1), 2013.
//!
//! The vertices are translated to the ray origin, sheared so that the ray becomes the +z
//! axis, and the three 2D edge functions U, V, W are evaluated there. An edge shared by two
//! triangles is evaluated from the same two sheared vertices in both, with opposite sign, so
//! a ray can never pass between them. A point exactly on the edge gives U = 0 for both; a
//! tie rule gives it to exactly one of them ([`edge_tie`]), so a ray crossing a shared edge or
//! vertex is one hit, on every backend. Polygons and meshes reach the tracer as these
//! triangles.

use super::{Part, Roots, Shape};
use crate::math::{Ray, Real, V3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle<R> {
    /// Counter-clockwise seen from the front: the front normal is (v1 − v0) × (v2 − v0).
    pub v: [V3<R>; 3],
}

/// The ray's shear, shared by all triangles a ray is tested against.
#[derive(Clone, Copy, Debug)]
pub struct Shear<R> {
    /// The permutation: kz is the dominant axis of d, kx and ky follow it.
    pub kx: usize,
    pub ky: usize,
    pub kz: usize,
    /// The shear: −d[kx]/d[kz] and −d[ky]/d[kz] enter as `x − sx·z`, and 1/d[kz].
    pub sx: R,
    pub sy: R,
    pub sz: R,
}

impl<R: Real> Shear<R> {
    /// kz is the axis of the largest |d|; kx, ky follow it cyclically and are swapped when
    /// d[kz] < 0 so the winding (and so the sign of the edge functions) is preserved.
    pub fn new(dir: V3<R>) -> Self {
        let kz = dir.max_abs_axis();
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if dir[kz] < R::ZERO {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = R::ONE / dir[kz];
        Self { kx, ky, kz, sx: dir[kx] * sz, sy: dir[ky] * sz, sz }
    }
}

/// The sign an edge function of exactly 0 counts with: that of the sheared edge vector's y,
/// or of −x when y is 0 too (the top-left rule of rasterisers). The vector of a shared edge is
/// exactly negated in its other triangle, so the point goes to exactly one of the two: the
/// one whose other edge functions share this sign. Where rounding makes an edge function 0
/// (lavapipe evaluates `fma` as a multiply and an add, so the GPU's edge functions are 0
/// more often than the CPU's exact-sign ones), the crossing is still one hit, never two.
#[inline]
pub fn edge_tie<R: Real>(e: R, ex: R, ey: R) -> R {
    if e != R::ZERO {
        e
    } else if ey != R::ZERO {
        ey
    } else {
        -ex
    }
}

impl<R: Real> Triangle<R> {
    pub fn cast<S: Real>(&self) -> Triangle<S> {
        Triangle { v: [self.v[0].cast(), self.v[1].cast(), self.v[2].cast()] }
    }

    /// The unnormalised front normal (v1 − v0) × (v2 − v0).
    pub fn face_normal(&self) -> V3<R> {
        (self.v[1] - self.v[0]).cross(self.v[2] - self.v[0])
    }

    /// The hit distance, if the ray meets the triangle within (tmin, tmax).
    #[inline]
    pub fn intersect(&self, ray: &Ray<R>, s: &Shear<R>, tmin: R, tmax: R) -> Option<R> {
        let a = self.v[0] - ray.origin;
        let b = self.v[1] - ray.origin;
        let c = self.v[2] - ray.origin;
        let ax = a[s.kx] - s.sx * a[s.kz];
        let ay = a[s.ky] - s.sy * a[s.kz];
        let bx = b[s.kx] - s.sx * b[s.kz];
        let by = b[s.ky] - s.sy * b[s.kz];
        let cx = c[s.kx] - s.sx * c[s.kz];
        let cy = c[s.ky] - s.sy * c[s.kz];
        // Edge functions with the exact sign (see Real::diff_of_products): a shared edge gives
        // opposite signs in its two triangles whatever the rounding, so no ray slips between.
        // A point exactly on an edge (value 0) belongs to one triangle by the tie rule.
        let u = R::diff_of_products(cx, by, cy, bx);
        let v = R::diff_of_products(ax, cy, ay, cx);
        let w = R::diff_of_products(bx, ay, by, ax);
        let (su, sv, sw) =
            (edge_tie(u, cx - bx, cy - by), edge_tie(v, ax - cx, ay - cy), edge_tie(w, bx - ax, by - ay));
        let zero = R::ZERO;
        if (su < zero || sv < zero || sw < zero) && (su > zero || sv > zero || sw > zero) {
            return None;
        }
        let det = u + v + w;
        if det == zero {
            return None; // degenerate in projection: the ray is in the triangle's plane
        }
        let az = s.sz * a[s.kz];
        let bz = s.sz * b[s.kz];
        let cz = s.sz * c[s.kz];
        let t = (u * az + v * bz + w * cz) / det;
        (t > tmin && t < tmax).then_some(t)
    }
}

impl<R: Real> Shape<R> for Triangle<R> {
    #[inline]
    fn roots(&self, ray: &Ray<R>, tmin: R, tmax: R) -> Roots<R> {
        let mut roots = Roots::empty();
        if let Some(t) = self.intersect(ray, &Shear::new(ray.dir), tmin, tmax) {
            roots.push_in_range(t, Part::Surface, tmin, tmax);
        }
        roots
    }

    fn normal(&self, _ray: &Ray<R>, _t: R, _part: Part) -> V3<R> {
        self.face_normal().normalize()
    }

    fn bounds(&self) -> Option<(V3<R>, V3<R>)> {
        Some((self.v[0].min_elem(self.v[1]).min_elem(self.v[2]), self.v[0].max_elem(self.v[1]).max_elem(self.v[2])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::testutil::{TestRays, TestRng, ray_f32};

    fn tri() -> Triangle<f64> {
        Triangle { v: [V3::new(0.0, 0.0, 5.0), V3::new(1.0, 0.0, 5.0), V3::new(0.0, 1.0, 5.0)] }
    }

    #[test]
    fn hits_inside_and_misses_outside() {
        let t = tri();
        let hit = Ray::new(V3::new(0.25, 0.25, 0.0), V3::new(0.0, 0.0, 1.0));
        assert_eq!(t.roots(&hit, 0.0, f64::INFINITY).t[0], 5.0);
        let miss = Ray::new(V3::new(0.75, 0.75, 0.0), V3::new(0.0, 0.0, 1.0));
        assert_eq!(t.roots(&miss, 0.0, f64::INFINITY).len, 0);
        // Back face is hit too (two-sided); the normal tells the side.
        let back = Ray::new(V3::new(0.25, 0.25, 9.0), V3::new(0.0, 0.0, -1.0));
        assert_eq!(t.roots(&back, 0.0, f64::INFINITY).t[0], 4.0);
        assert!(back.dir.dot(t.normal(&back, 4.0, Part::Surface)) < 0.0);
    }

    #[test]
    fn shared_edge_and_vertex_never_let_a_ray_through() {
        // A square fanned into four triangles around its centre m; rays aimed exactly at m
        // (shared by all four) and at points of the four interior edges.
        let m = V3::<f32>::new(0.5, 0.5, 3.0);
        let corners = [V3::new(0.0, 0.0, 3.0), V3::new(1.0, 0.0, 3.0), V3::new(1.0, 1.0, 3.0), V3::new(0.0, 1.0, 3.0)];
        let fan: Vec<Triangle<f32>> = (0..4).map(|i| Triangle { v: [corners[i], corners[(i + 1) % 4], m] }).collect();
        let mut rng = TestRng(3);
        for i in 0..4000 {
            let s = (i % 997) as f32 / 997.0;
            let target = if i % 50 == 0 { m } else { m + (corners[i % 4] - m) * s };
            let origin = rng.in_cube(5.0).cast::<f32>();
            let ray = Ray::new(origin, (target - origin).normalize());
            let hits: usize = fan.iter().map(|t| t.roots(&ray, 0.0, f32::INFINITY).len).sum();
            assert!(hits >= 1, "ray {ray:?} fell through at {target:?}");
        }
    }

    /// Rays exactly through points of a shared edge, and through the vertex a fan shares, hit
    /// exactly one triangle (both or all four reported a hit before the tie rule).
    #[test]
    fn a_shared_edge_or_vertex_is_hit_once() {
        let z = 3.0f32;
        let c = [V3::new(0.0, 0.0, z), V3::new(1.0, 0.0, z), V3::new(1.0, 1.0, z), V3::new(0.0, 1.0, z)];
        // The square split along its diagonal c0–c2, both halves wound alike.
        let halves = [Triangle { v: [c[0], c[1], c[2]] }, Triangle { v: [c[0], c[2], c[3]] }];
        let m = V3::new(0.5, 0.5, z);
        let fan: Vec<Triangle<f32>> = (0..4).map(|i| Triangle { v: [c[i], c[(i + 1) % 4], m] }).collect();
        for dz in [1.0f32, -1.0] {
            for k in 1..64 {
                let s = k as f32 / 64.0;
                let ray = Ray::new(V3::new(s, s, z - 5.0 * dz), V3::new(0.0, 0.0, dz));
                let n: usize = halves.iter().map(|t| t.roots(&ray, 0.0, f32::INFINITY).len).sum();
                assert_eq!(n, 1, "diagonal point {s}, direction {dz}");
                // The fan's edges from the corners to the centre.
                let on_spoke = Ray::new(V3::new(s * 0.5, s * 0.5, z - 5.0 * dz), V3::new(0.0, 0.0, dz));
                let n: usize = fan.iter().map(|t| t.roots(&on_spoke, 0.0, f32::INFINITY).len).sum();
                assert_eq!(n, 1, "spoke point {s}, direction {dz}");
            }
            let centre = Ray::new(V3::new(0.5, 0.5, z - 5.0 * dz), V3::new(0.0, 0.0, dz));
            let n: usize = fan.iter().map(|t| t.roots(&centre, 0.0, f32::INFINITY).len).sum();
            assert_eq!(n, 1, "the fan's centre, direction {dz}");
        }
    }

    #[test]
    fn degenerate_triangles_never_hit_and_never_give_nan() {
        let p = V3::<f32>::new(0.0, 0.0, 1.0);
        let q = V3::new(1.0, 1.0, 1.0);
        let degenerate = [Triangle { v: [p, p, p] }, Triangle { v: [p, q, (p + q) * 0.5] }, Triangle { v: [p, q, q] }];
        let mut rng = TestRng(5);
        for _ in 0..10_000 {
            let ray = ray_f32(&rng.ray_towards(3.0, V3::new(0.5, 0.5, 1.0), 0.6));
            for t in &degenerate {
                let r = t.roots(&ray, 0.0, f32::INFINITY);
                assert!(r.len == 0 || r.t[0].is_finite());
            }
        }
    }

    #[test]
    fn f32_agrees_with_f64_oracle_on_random_rays() {
        let mut rng = TestRng(9);
        let mut compared = 0;
        let mut max_rel = 0.0f64;
        for _ in 0..20_000 {
            let centre = rng.in_cube(20.0);
            let t64 = Triangle { v: [0, 1, 2].map(|_| centre + rng.in_cube(3.0)) };
            let t32 = t64.cast::<f32>();
            let exact = t32.cast::<f64>();
            let ray32 = ray_f32(&rng.ray_towards(40.0, centre, 2.0));
            let ray = ray32.cast::<f64>();
            let want = exact.roots(&ray, 0.0, f64::INFINITY);
            let got = t32.roots(&ray32, 0.0, f32::INFINITY);
            if edge_distance(&exact, &ray) < 1e-4 {
                continue;
            }
            assert_eq!(want.len, got.len, "hit/miss disagree: {ray:?} {exact:?}");
            if got.len == 1 {
                max_rel = max_rel.max((want.t[0] - got.t[0] as f64).abs() / want.t[0].max(1.0));
                compared += 1;
            }
        }
        assert!(compared > 2_000, "too few hits to judge: {compared}");
        assert!(max_rel < 1e-5, "max relative error of t {max_rel}");
    }

    /// Smallest barycentric coordinate magnitude of the ray's crossing with the triangle's
    /// plane, relative: near zero means the ray grazes an edge.
    fn edge_distance(t: &Triangle<f64>, ray: &Ray<f64>) -> f64 {
        let n = t.face_normal();
        let dn = ray.dir.dot(n);
        if dn.abs() < 1e-6 * n.length() {
            return 0.0;
        }
        let p = ray.at((t.v[0] - ray.origin).dot(n) / dn);
        let area = n.length_squared();
        let b0 = (t.v[1] - p).cross(t.v[2] - p).dot(n) / area;
        let b1 = (t.v[2] - p).cross(t.v[0] - p).dot(n) / area;
        let b2 = 1.0 - b0 - b1;
        b0.abs().min(b1.abs()).min(b2.abs())
    }
}
