//! Point queries: the nearest point of a scene's surfaces to a query point
//! ([`closest`], a walk of the BVH that prunes boxes farther than the best foot so far), and
//! whether a point lies inside the scene ([`winding`]: the generalized winding number of its
//! meshes, summed through the same tree with far-field approximations, after [`orient`] has
//! turned faces flipped against their neighbours back; the solids' own inside tests).
//!
//! Written once over [`Real`]: f32, the mirror of what the GPU computes, and f64, the oracle.
//! The per-primitive formulas are in [`crate::geometry::closest`].

pub mod orient;
pub mod winding;

use crate::accel::bvh::{Bvh, BvhNode, MAX_DEPTH};
use crate::geometry::closest::Foot;
use crate::math::{Real, V3};
use crate::primitives::{PrimKind, PrimRef, Primitives};

/// The nearest surface point of a scene: which primitive, and its foot there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closest<R> {
    pub prim_ref: PrimRef,
    pub foot: Foot<R>,
}

impl<R: Real> Closest<R> {
    /// Keeps the nearer foot; at equal squared distance the smaller [`PrimRef`], the tie rule
    /// of the ray queries, so that the walk and brute force name the same primitive.
    #[inline]
    pub fn offer(best: &mut Option<Closest<R>>, prim_ref: PrimRef, foot: Foot<R>) {
        let better = match best {
            None => !foot.dist2.to_f64().is_nan(),
            Some(b) => foot.dist2 < b.foot.dist2 || (foot.dist2 == b.foot.dist2 && prim_ref < b.prim_ref),
        };
        if better {
            *best = Some(Closest { prim_ref, foot });
        }
    }

    pub fn distance(&self) -> R {
        self.foot.dist2.sqrt()
    }
}

impl<R: Real> Primitives<R> {
    /// The foot of `p` on primitive `r`.
    #[inline]
    pub fn closest_of(&self, r: PrimRef, p: V3<R>) -> Foot<R> {
        let i = r.index();
        match r.kind() {
            PrimKind::Sphere => self.spheres[i].shape.closest(p),
            PrimKind::Cylinder => self.cylinders[i].shape.closest(p),
            PrimKind::Triangle => self.triangles[i].shape.closest(p),
            PrimKind::Plane => self.planes[i].shape.closest(p),
        }
    }

    /// The unit normal at a foot: a triangle's face normal (v1 − v0) × (v2 − v0), as the ray
    /// queries report it; outward for spheres and cylinders; a plane's own.
    pub fn foot_normal(&self, r: PrimRef, foot: &Foot<R>) -> V3<R> {
        let i = r.index();
        match r.kind() {
            PrimKind::Sphere => self.spheres[i].shape.foot_normal(foot),
            PrimKind::Cylinder => self.cylinders[i].shape.foot_normal(foot),
            PrimKind::Triangle => self.triangles[i].shape.unit_normal(),
            PrimKind::Plane => self.planes[i].shape.normal,
        }
    }

    /// Whether `p` lies inside the solid `r` (a sphere, or a cylinder with caps); surfaces
    /// enclose nothing on their own.
    #[inline]
    pub fn solid_contains(&self, r: PrimRef, p: V3<R>) -> bool {
        let i = r.index();
        match r.kind() {
            PrimKind::Sphere => self.spheres[i].shape.contains(p),
            PrimKind::Cylinder => self.cylinders[i].shape.contains(p),
            PrimKind::Triangle | PrimKind::Plane => false,
        }
    }
}

/// The nearest surface point by testing every primitive: the reference the walk must match.
pub fn closest_brute<R: Real>(prims: &Primitives<R>, p: V3<R>) -> Option<Closest<R>> {
    let mut best = None;
    for r in prims.bounded_refs().chain(prims.plane_refs()) {
        Closest::offer(&mut best, r, prims.closest_of(r, p));
    }
    best
}

/// Squared distance from `p` to a node's box (0 inside it), from its f32 bounds.
#[inline]
pub fn box_dist2<R: Real>(node: &BvhNode, p: V3<R>) -> R {
    let mut d2 = R::ZERO;
    for a in 0..3 {
        let lo = R::from_f64(node.bmin[a] as f64);
        let hi = R::from_f64(node.bmax[a] as f64);
        let d = (lo - p[a]).max(p[a] - hi).max(R::ZERO);
        d2 += d * d;
    }
    d2
}

/// Stack entries of the walks: the tree's depth bounds them.
const STACK: usize = MAX_DEPTH as usize + 1;

/// The nearest surface point of the scene to `p` (`None` only for an empty scene), equal to
/// [`closest_brute`]'s: a depth-first walk of the binary tree, nearer child first, that skips
/// a box whose distance exceeds the best foot's. The box distance is computed from the
/// outward-rounded f32 bounds in `R`; its rounding (γ(4) relative) is covered by comparing it
/// with the best squared distance grown by 2γ(4), so no box that holds an equally near foot is
/// skipped.
pub fn closest<R: Real>(bvh: &Bvh, prims: &Primitives<R>, p: V3<R>) -> Option<Closest<R>> {
    let mut best = None;
    for r in prims.plane_refs() {
        Closest::offer(&mut best, r, prims.closest_of(r, p));
    }
    if bvh.nodes.is_empty() {
        return best;
    }
    let grow = R::ONE + R::from_f64(2.0) * R::gamma_bound(4);
    let bound = |best: &Option<Closest<R>>| best.map_or(R::INFINITY, |b| b.foot.dist2 * grow);
    let mut stack = [(0u32, R::ZERO); STACK];
    let mut sp = 0usize;
    let mut node = 0usize;
    let mut d_node = box_dist2(&bvh.nodes[0], p);
    loop {
        if d_node <= bound(&best) {
            let n = &bvh.nodes[node];
            if n.is_leaf() {
                let first = n.left_or_first as usize;
                for &r in &bvh.prim_refs[first..first + n.count as usize] {
                    Closest::offer(&mut best, r, prims.closest_of(r, p));
                }
            } else {
                let (l, r) = (node + 1, n.left_or_first as usize);
                let (dl, dr) = (box_dist2(&bvh.nodes[l], p), box_dist2(&bvh.nodes[r], p));
                let ((near, dn), (far, df)) = if dr < dl { ((r, dr), (l, dl)) } else { ((l, dl), (r, dr)) };
                stack[sp] = (far as u32, df);
                sp += 1;
                (node, d_node) = (near, dn);
                continue;
            }
        }
        if sp == 0 {
            return best;
        }
        sp -= 1;
        (node, d_node) = (stack[sp].0 as usize, stack[sp].1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Triangle;
    use crate::geometry::testutil::{TestRays, TestRng};
    use crate::primitives::Tagged;
    use crate::primitives::testutil::mixed_scene;

    #[test]
    fn the_walk_finds_what_brute_force_finds() {
        let p32 = mixed_scene(3);
        let p64: Primitives<f64> = p32.cast();
        let (b32, b64) = (Bvh::build(&p32), Bvh::build(&p64));
        let mut rng = TestRng(9);
        for k in 0..3000 {
            // Near the scene, inside it, and far outside it.
            let h = [10.0, 60.0, 500.0][k % 3];
            let p = rng.in_cube(h);
            let want = closest_brute(&p64, p).unwrap();
            let got = closest(&b64, &p64, p).unwrap();
            assert_eq!(got, want, "f64, point {k}");
            let p = p.cast::<f32>();
            let want = closest_brute(&p32, p).unwrap();
            let got = closest(&b32, &p32, p).unwrap();
            assert_eq!(got, want, "f32, point {k}");
        }
    }

    /// The bound on the f32 distance's error the docs state: 4ε (ε = 2⁻²³) times the query
    /// point's largest coordinate plus the scene's extent (the feet are sums of products of
    /// coordinates of that size).
    fn f32_bound(p: V3<f64>, scale: f64) -> f64 {
        4.0 * f32::EPSILON as f64 * (p.abs().max_component() + scale)
    }

    #[test]
    fn f32_distances_are_within_their_bound_of_the_f64_oracle() {
        // The mixed scene, with sliver and degenerate triangles added; points on, near and
        // far from its surfaces.
        let mut p64: Primitives<f64> = mixed_scene(7).cast();
        let mut rng = TestRng(21);
        let tag = p64.triangles[0].tag;
        for k in 0..200 {
            let a = rng.in_cube(40.0);
            let d = rng.unit_vector();
            let v = match k % 4 {
                0 => [a, a + d * 5.0, a + d * 10.0 + rng.unit_vector() * 1e-6], // sliver
                1 => [a, a + d * 5.0, a + d * 2.5],                             // collinear
                2 => [a, a, a],                                                 // a point
                _ => [a, a, a + d * 3.0],                                       // a segment
            };
            p64.triangles.push(Tagged { shape: Triangle { v }, tag });
        }
        let p32: Primitives<f32> = p64.cast();
        let p64: Primitives<f64> = p32.cast(); // the same geometry, exactly
        let b32 = Bvh::build(&p32);
        let scale = 60.0;
        let mut worst = 0.0f64;
        for k in 0..4000 {
            let p = match k % 4 {
                // On a surface: a foot of a random point.
                0 => closest_brute(&p64, rng.in_cube(55.0)).unwrap().foot.point,
                // Near one.
                1 => closest_brute(&p64, rng.in_cube(55.0)).unwrap().foot.point + rng.unit_vector() * 1e-3,
                2 => rng.in_cube(55.0),
                _ => rng.in_cube(5000.0),
            };
            let p = p.cast::<f32>().cast::<f64>();
            let want = closest_brute(&p64, p).unwrap().distance();
            let c32 = closest(&b32, &p32, p.cast()).unwrap();
            let got = c32.distance() as f64;
            let err = (got - want).abs();
            worst = worst.max(err / f32_bound(p, scale));
            assert!(err <= f32_bound(p, scale), "point {k} at {p:?}: f32 {got}, f64 {want}");
        }
        eprintln!("largest f32 error: {worst:.3} of the bound");
    }

    #[test]
    fn an_empty_scene_has_no_closest_point() {
        let p = Primitives::<f32>::default();
        let bvh = Bvh::build(&p);
        assert!(closest(&bvh, &p, V3::new(1.0, 2.0, 3.0)).is_none());
        assert!(closest_brute(&p, V3::new(1.0, 2.0, 3.0)).is_none());
    }
}
