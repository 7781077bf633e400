//! The point on each primitive's surface nearest a query point, and whether a point lies inside
//! a solid: the point queries' counterpart of the ray/primitive roots, written once over
//! [`Real`] (f32, the mirror of the GPU's; f64, the oracle).
//!
//! Each routine returns a [`Foot`]: the nearest point, its squared distance and the part of the
//! surface it lies on. The squared distance is computed from the query point's own offsets
//! where a closed form exists (spheres, cylinders, planes), not as |p − foot|², so that its
//! error is relative to the distance and not to the coordinates.

use super::{Cylinder, Part, Plane, Sphere, Triangle, unit_or};
use crate::math::{Real, V3};

/// The nearest point of one primitive's surface to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Foot<R> {
    pub point: V3<R>,
    /// Squared distance from the query point to `point`.
    pub dist2: R,
    /// Barycentric (u, v) of a triangle's foot, point = (1 − u − v)·v0 + u·v1 + v·v2
    /// (Embree's and Open3D's convention); 0 for other primitives.
    pub uv: [R; 2],
    pub part: Part,
}

/// A unit vector perpendicular to unit `a`, for a query point on an axis (where every
/// direction away from it is as near).
#[inline]
fn perpendicular<R: Real>(a: V3<R>) -> V3<R> {
    let other = if a.x.abs() < R::from_f64(0.9) {
        V3::new(R::ONE, R::ZERO, R::ZERO)
    } else {
        V3::new(R::ZERO, R::ONE, R::ZERO)
    };
    a.cross(other).normalize()
}

/// The nearest point of the segment a–b to p, as the parameter along it in [0, 1].
#[inline]
fn segment_param<R: Real>(a: V3<R>, b: V3<R>, p: V3<R>) -> R {
    let ab = b - a;
    let l2 = ab.dot(ab);
    if !(l2 > R::ZERO) {
        return R::ZERO;
    }
    ((p - a).dot(ab) / l2).max(R::ZERO).min(R::ONE)
}

impl<R: Real> Triangle<R> {
    /// The nearest point of the triangle (its interior, edges and vertices) to `p`, by the
    /// Voronoi regions of its vertices, edges and face (Ericson, "Real-Time Collision
    /// Detection", 2005, §5.1.5: `ClosestPtPointTriangle`), with one change for thin
    /// triangles: Ericson's three region determinants (va, vb, vc, differences of products
    /// of dot products, Gram determinants) are taken in the equal triple-product form that
    /// Lagrange's identity gives, vc = n·(ap × bp) with n = ab × ac, and so on. The Gram form
    /// loses their sign on slivers: its relative error grows as ε/sin²θ with θ the
    /// triangle's smallest angle (1 % in f64 at θ = 10⁻⁷, where a test found a foot 0.018
    /// off), the triple products' as ε/sinθ. A foot inside the face is at the distance
    /// |ap·n|/|n| from the plane.
    ///
    /// Error: the distance is within a few γ(8)·(|p − v0| + |e1| + |e2|) of the exact one,
    /// absolutely, plus for a triangle thinner than that, up to its width (its vertices'
    /// own rounding makes it that uncertain). A triangle whose sine of its angle at v0 is
    /// below γ(16) (n within its own rounding of 0: collinear or coincident vertices, or a
    /// sliver thinner than its coordinates' rounding) is taken as its three edges, which
    /// moves the foot by at most the triangle's width.
    pub fn closest(&self, p: V3<R>) -> Foot<R> {
        let [a, b, c] = self.v;
        let at = |point: V3<R>, u: R, v: R| {
            let d = p - point;
            Foot { point, dist2: d.dot(d), uv: [u, v], part: Part::Surface }
        };
        let (ab, ac, ap) = (b - a, c - a, p - a);
        let (d1, d2) = (ab.dot(ap), ac.dot(ap));
        if d1 <= R::ZERO && d2 <= R::ZERO {
            return at(a, R::ZERO, R::ZERO);
        }
        let bp = p - b;
        let (d3, d4) = (ab.dot(bp), ac.dot(bp));
        if d3 >= R::ZERO && d4 <= d3 {
            return at(b, R::ONE, R::ZERO);
        }
        let n = ab.cross(ac);
        let n2 = n.dot(n);
        let g = R::gamma_bound(16);
        if !(n2 > g * g * ab.dot(ab) * ac.dot(ac)) || !n2.is_finite() {
            return self.nearest_edge(p);
        }
        let cp = p - c;
        let vc = n.dot(ap.cross(bp));
        if vc <= R::ZERO && d1 >= R::ZERO && d3 <= R::ZERO && d1 - d3 > R::ZERO {
            let v = d1 / (d1 - d3);
            return at(a + ab * v, v, R::ZERO);
        }
        let (d5, d6) = (ab.dot(cp), ac.dot(cp));
        if d6 >= R::ZERO && d5 <= d6 {
            return at(c, R::ZERO, R::ONE);
        }
        let vb = n.dot(cp.cross(ap));
        if vb <= R::ZERO && d2 >= R::ZERO && d6 <= R::ZERO && d2 - d6 > R::ZERO {
            let w = d2 / (d2 - d6);
            return at(a + ac * w, R::ZERO, w);
        }
        let va = n.dot(bp.cross(cp));
        let (e43, e56) = (d4 - d3, d5 - d6);
        if va <= R::ZERO && e43 >= R::ZERO && e56 >= R::ZERO && e43 + e56 > R::ZERO {
            let w = e43 / (e43 + e56);
            return at(b + (c - b) * w, R::ONE - w, w);
        }
        let sum = va + vb + vc;
        if sum > R::ZERO {
            let inv = R::ONE / sum;
            let (v, w) = (vb * inv, vc * inv);
            let h = ap.dot(n);
            return Foot { point: a + ab * v + ac * w, dist2: h * h / n2, uv: [v, w], part: Part::Surface };
        }
        self.nearest_edge(p)
    }

    /// The nearest point of the three edges: the foot on a triangle too thin to have a
    /// face in this precision.
    fn nearest_edge(&self, p: V3<R>) -> Foot<R> {
        let [a, b, c] = self.v;
        let at = |point: V3<R>, u: R, v: R| {
            let d = p - point;
            Foot { point, dist2: d.dot(d), uv: [u, v], part: Part::Surface }
        };
        let edge = |from: V3<R>, to: V3<R>, uv: &dyn Fn(R) -> (R, R)| {
            let s = segment_param(from, to, p);
            let (u, v) = uv(s);
            at(from + (to - from) * s, u, v)
        };
        let feet = [edge(a, b, &|s| (s, R::ZERO)), edge(a, c, &|s| (R::ZERO, s)), edge(b, c, &|s| (R::ONE - s, s))];
        let mut best = feet[0];
        for f in &feet[1..] {
            if f.dist2 < best.dist2 {
                best = *f;
            }
        }
        best
    }

    /// The unit face normal (v1 − v0) × (v2 − v0), or 0 for a zero-area triangle.
    pub fn unit_normal(&self) -> V3<R> {
        unit_or(self.face_normal(), V3::zero())
    }

    /// The signed solid angle the triangle subtends at `p`, divided by 4π: its share of the
    /// generalized winding number (Jacobson, Kavan & Sorkine-Hornung, "Robust Inside-Outside
    /// Segmentation using Generalized Winding Numbers", SIGGRAPH 2013), positive where `p`
    /// lies behind the front face. The solid angle is Van Oosterom & Strackee's
    /// (IEEE Trans. Biomed. Eng. 30(2), 1983): tan(Ω/2) = a·(b × c) / (|a||b||c| + (a·b)|c| +
    /// (b·c)|a| + (c·a)|b|) with a, b, c the vertices relative to p, taken through atan2, so
    /// that Ω is right in all four quadrants. Its error is a few γ(12) relative to the terms'
    /// magnitudes: absolute, about 1e-6 in f32 for a point not on the triangle. A point on the
    /// triangle's plane outside it gives 0 exactly (a zero determinant).
    pub fn winding(&self, p: V3<R>) -> R {
        let (a, b, c) = (self.v[0] - p, self.v[1] - p, self.v[2] - p);
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let det = a.dot(b.cross(c));
        let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        R::from_f64(atan2_real(det, den).to_f64() / (2.0 * std::f64::consts::PI))
    }
}

/// atan2 in the precision of `R` (std's, through f64 for f64 and f32 for f32).
#[inline]
fn atan2_real<R: Real>(y: R, x: R) -> R {
    if std::mem::size_of::<R>() == 4 {
        R::from_f64((y.to_f64() as f32).atan2(x.to_f64() as f32) as f64)
    } else {
        R::from_f64(y.to_f64().atan2(x.to_f64()))
    }
}

impl<R: Real> Sphere<R> {
    /// c + r·(p − c)/|p − c|, at distance ||p − c| − r| (one subtraction of two rounded
    /// lengths: error within γ(5)·max(|p − c|, r)); a query point at the centre gets the
    /// point on +x (every point is as near).
    pub fn closest(&self, p: V3<R>) -> Foot<R> {
        let d = p - self.center;
        let l = d.length();
        let dir = if l > R::ZERO && l.is_finite() { d / l } else { V3::new(R::ONE, R::ZERO, R::ZERO) };
        let gap = (l - self.radius).abs();
        Foot { point: self.center + dir * self.radius, dist2: gap * gap, uv: [R::ZERO; 2], part: Part::Surface }
    }

    /// Whether `p` lies strictly inside the ball.
    pub fn contains(&self, p: V3<R>) -> bool {
        let d = p - self.center;
        d.dot(d) < self.radius * self.radius
    }

    /// The outward normal at a foot.
    pub fn foot_normal(&self, foot: &Foot<R>) -> V3<R> {
        unit_or(foot.point - self.center, V3::new(R::ONE, R::ZERO, R::ZERO))
    }
}

impl<R: Real> Cylinder<R> {
    /// The query point in the cylinder's frame: (s, ρ, ê) with s the distance along the unit
    /// axis from p1, ρ the distance from the axis and ê the unit direction away from it.
    #[inline]
    fn frame(&self, p: V3<R>) -> (V3<R>, R, R, R, V3<R>) {
        let (axis, len) = self.axis();
        let d = p - self.p1;
        let s = d.dot(axis);
        let q = d - axis * s;
        let rho = q.length();
        let e = if rho > R::ZERO && rho.is_finite() { q / rho } else { perpendicular(axis) };
        (axis, len, s, rho, e)
    }

    /// The nearest point of the side (the axis clamped to [0, len], at radius r from it) and,
    /// for a closed cylinder, of each cap disk (the point's projection onto the cap's plane,
    /// pulled in to radius r): the surface is their union, so the nearest of the three is
    /// the answer. Each squared distance is the sum of the two squared offsets in the
    /// cylinder's frame (along the axis, away from it), so its error is relative to the
    /// distance plus that of the frame (γ(6)·|p − p1| for s and ρ). A foot on the rim, where
    /// side and cap meet, is the side's.
    pub fn closest(&self, p: V3<R>) -> Foot<R> {
        let (axis, len, s, rho, e) = self.frame(p);
        let sc = s.max(R::ZERO).min(len);
        let (ds, dr) = (s - sc, rho - self.radius);
        let mut best = Foot {
            point: self.p1 + axis * sc + e * self.radius,
            dist2: ds * ds + dr * dr,
            uv: [R::ZERO; 2],
            part: Part::Surface,
        };
        if self.caps {
            let out = (rho - self.radius).max(R::ZERO);
            let radial = e * rho.min(self.radius);
            for (at, part) in [(R::ZERO, Part::CapP1), (len, Part::CapP2)] {
                let da = s - at;
                let d2 = da * da + out * out;
                if d2 < best.dist2 {
                    best = Foot { point: self.p1 + axis * at + radial, dist2: d2, uv: [R::ZERO; 2], part };
                }
            }
        }
        best
    }

    /// Whether `p` lies strictly inside the closed cylinder; an open one (a tube) encloses
    /// nothing.
    pub fn contains(&self, p: V3<R>) -> bool {
        if !self.caps {
            return false;
        }
        let (_, len, s, rho, _) = self.frame(p);
        s > R::ZERO && s < len && rho < self.radius
    }

    /// The outward normal at a foot: away from the axis on the side, ∓â on the caps.
    pub fn foot_normal(&self, foot: &Foot<R>) -> V3<R> {
        let (axis, _) = self.axis();
        match foot.part {
            Part::CapP1 => -axis,
            Part::CapP2 => axis,
            Part::Surface => {
                let d = foot.point - self.p1;
                unit_or(d - axis * d.dot(axis), perpendicular(axis))
            }
        }
    }
}

impl<R: Real> Plane<R> {
    /// p − ((p − point)·n)·n, at distance |(p − point)·n| (error γ(4)·|p − point|).
    pub fn closest(&self, p: V3<R>) -> Foot<R> {
        let s = (p - self.point).dot(self.normal);
        Foot { point: p - self.normal * s, dist2: s * s, uv: [R::ZERO; 2], part: Part::Surface }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::testutil::{TestRays, TestRng};

    /// The nearest point of a triangle by brute force in f64: a fine barycentric grid refined
    /// around its best cell, good to ~1e-9 of the triangle's size.
    fn triangle_brute(t: &Triangle<f64>, p: V3<f64>) -> f64 {
        let mut best = f64::INFINITY;
        let (mut u0, mut v0, mut h) = (0.5, 0.5, 1.0);
        for _ in 0..30 {
            let n = 16;
            let (mut bu, mut bv) = (u0, v0);
            for i in 0..=n {
                for j in 0..=n {
                    let u = (u0 + h * (i as f64 / n as f64 - 0.5)).clamp(0.0, 1.0);
                    let v = (v0 + h * (j as f64 / n as f64 - 0.5)).clamp(0.0, 1.0 - u);
                    let q = t.v[0] * (1.0 - u - v) + t.v[1] * u + t.v[2] * v;
                    let d = (q - p).length_squared();
                    if d < best {
                        (best, bu, bv) = (d, u, v);
                    }
                }
            }
            (u0, v0, h) = (bu, bv, h * 0.25);
        }
        best.sqrt()
    }

    #[test]
    fn triangle_feet_match_a_brute_force_search() {
        let mut rng = TestRng(11);
        for k in 0..400 {
            let t = Triangle { v: [0, 1, 2].map(|_| rng.in_cube(1.0)) };
            let p = rng.in_cube(2.0);
            let f = t.closest(p);
            let want = triangle_brute(&t, p);
            assert!((f.dist2.sqrt() - want).abs() < 1e-7, "case {k}: {} vs {want}", f.dist2.sqrt());
            // The foot is the point its barycentrics name, and lies on the triangle.
            let [u, v] = f.uv;
            assert!(u >= 0.0 && v >= 0.0 && u + v <= 1.0 + 1e-12, "case {k}: uv {u}, {v}");
            let q = t.v[0] * (1.0 - u - v) + t.v[1] * u + t.v[2] * v;
            assert!((q - f.point).length() < 1e-12, "case {k}");
        }
    }

    #[test]
    fn degenerate_triangles_are_their_edges() {
        let p = V3::new(0.5, 1.0, 0.0);
        let line = Triangle { v: [V3::new(0.0, 0.0, 0.0), V3::new(1.0, 0.0, 0.0), V3::new(2.0, 0.0, 0.0)] };
        let f = line.closest(p);
        assert_eq!(f.dist2, 1.0);
        assert_eq!(f.point, V3::new(0.5, 0.0, 0.0));
        let dot = Triangle { v: [V3::new(3.0, 0.0, 0.0); 3] };
        assert_eq!(dot.closest(V3::new(3.0, 4.0, 0.0)).dist2, 16.0);
        assert!(dot.closest(p).dist2.is_finite());
    }

    #[test]
    fn sphere_and_plane_feet_are_exact() {
        let s = Sphere { center: V3::new(1.0, 2.0, 3.0), radius: 2.0 };
        let f = s.closest(V3::new(1.0, 2.0, 8.0));
        assert_eq!((f.point, f.dist2), (V3::new(1.0, 2.0, 5.0), 9.0));
        assert_eq!(s.closest(V3::new(1.0, 2.0, 3.5)).dist2, 2.25);
        assert_eq!(s.closest(s.center).dist2, 4.0);
        assert!(s.contains(V3::new(1.0, 2.0, 4.9)) && !s.contains(V3::new(1.0, 2.0, 5.1)));
        let pl = Plane { point: V3::new(0.0, 1.0, 0.0), normal: V3::new(0.0, 1.0, 0.0) };
        let f = pl.closest(V3::new(3.0, -2.0, 4.0));
        assert_eq!((f.point, f.dist2), (V3::new(3.0, 1.0, 4.0), 9.0));
    }

    #[test]
    fn cylinder_feet_are_on_side_caps_and_rims() {
        let c = Cylinder { p1: V3::new(0.0, 0.0, 0.0), p2: V3::new(0.0, 0.0, 4.0), radius: 1.0, caps: true };
        // Beside the side.
        let f = c.closest(V3::new(3.0, 0.0, 2.0));
        assert_eq!((f.point, f.dist2, f.part), (V3::new(1.0, 0.0, 2.0), 4.0, Part::Surface));
        // Above a cap, within its radius: straight down onto it.
        let f = c.closest(V3::new(0.5, 0.0, 6.0));
        assert_eq!((f.point, f.dist2, f.part), (V3::new(0.5, 0.0, 4.0), 4.0, Part::CapP2));
        // Beyond the rim, outside both: the rim.
        let f = c.closest(V3::new(4.0, 0.0, -4.0));
        assert_eq!((f.point, f.dist2), (V3::new(1.0, 0.0, 0.0), 25.0));
        // Inside, nearer a cap than the side.
        let f = c.closest(V3::new(0.0, 0.0, 0.25));
        assert_eq!((f.dist2, f.part), (0.0625, Part::CapP1));
        assert_eq!(c.foot_normal(&f), V3::new(0.0, 0.0, -1.0));
        assert!(c.contains(V3::new(0.0, 0.5, 0.25)) && !c.contains(V3::new(0.0, 1.5, 0.25)));
        // An open tube: the inside point's foot is on the side, and it encloses nothing.
        let tube = Cylinder { caps: false, ..c };
        assert_eq!(tube.closest(V3::new(0.0, 0.0, 0.25)).part, Part::Surface);
        assert!(!tube.contains(V3::new(0.0, 0.5, 0.25)));
        // On the axis: any direction, at distance r.
        assert_eq!(c.closest(V3::new(0.0, 0.0, 2.0)).dist2, 1.0);
    }

    #[test]
    fn cylinder_feet_match_sampling_of_its_surface() {
        let mut rng = TestRng(5);
        for k in 0..200 {
            let p1 = rng.in_cube(1.0);
            let c = Cylinder {
                p1,
                p2: p1 + rng.unit_vector() * rng.range(0.5, 2.0),
                radius: rng.range(0.2, 1.0),
                caps: true,
            };
            let p = rng.in_cube(3.0);
            let got = c.closest(p).dist2.sqrt();
            // Sampled side and caps: no sample is nearer than the foot, and the nearest is close.
            let (axis, len) = c.axis();
            let (u, w) = (perpendicular(axis), axis.cross(perpendicular(axis)));
            let mut best = f64::INFINITY;
            for i in 0..200 {
                let phi = i as f64 / 200.0 * std::f64::consts::TAU;
                let e = u * phi.cos() + w * phi.sin();
                for j in 0..=100 {
                    let f = j as f64 / 100.0;
                    best = best.min((c.p1 + axis * (len * f) + e * c.radius - p).length());
                    best = best.min((c.p1 + e * (c.radius * f) - p).length());
                    best = best.min((c.p1 + axis * len + e * (c.radius * f) - p).length());
                }
            }
            assert!(got <= best + 1e-12, "case {k}: the foot at {got} is farther than a sample at {best}");
            assert!(best - got < 0.05, "case {k}: {got} vs sampled {best}");
        }
    }

    #[test]
    fn winding_numbers_of_a_closed_tetrahedron() {
        let v = [V3::new(0.0, 0.0, 0.0), V3::new(1.0, 0.0, 0.0), V3::new(0.0, 1.0, 0.0), V3::new(0.0, 0.0, 1.0)];
        // Outward faces: counter-clockwise seen from outside.
        let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let w = |p: V3<f64>| faces.iter().map(|f| Triangle { v: f.map(|i| v[i]) }.winding(p)).sum::<f64>();
        assert!((w(V3::new(0.1, 0.1, 0.1)) - 1.0).abs() < 1e-12);
        assert!(w(V3::new(2.0, 0.3, 0.1)).abs() < 1e-12);
        assert!(w(V3::new(-0.1, -0.2, -0.3)).abs() < 1e-12);
        // Half a ball's worth just behind the middle of one face.
        let face = Triangle { v: faces[3].map(|i| v[i]) };
        let centroid = (v[1] + v[2] + v[3]) / 3.0;
        let p = centroid - face.unit_normal() * 1e-9;
        assert!((face.winding(p) - 0.5).abs() < 1e-6);
    }
}
