//! BVH traversal; `shaders/traverse.wgsl` is its line-by-line twin.

use super::bvh::{Bvh, BvhNode, MAX_DEPTH};
use crate::math::{Ray, Real, V3};
use crate::primitives::{Hit, Nearest, Primitives, sort_hits};

/// Stack entries: a node to visit and the distance at which the ray enters its box.
const STACK: usize = MAX_DEPTH as usize + 1;

/// 1/d per axis, with zero (and tiny) components replaced by ±1e-30 first, so the slab test
/// never forms 0·∞ = NaN for axis-parallel rays: the replaced axis gives slab distances of
/// ±1e30·(gap), which are beyond every real hit, or exactly 0 on the slab plane.
#[inline]
pub fn safe_inverse<R: Real>(d: V3<R>) -> V3<R> {
    let tiny = R::from_f64(1e-30);
    let fix = |v: R| if v.abs() < tiny { if v < R::ZERO { -tiny } else { tiny } } else { v };
    V3::new(R::ONE / fix(d.x), R::ONE / fix(d.y), R::ONE / fix(d.z))
}

/// Ray/box slab test over [tmin, tmax]; returns the entry distance or `None`. The far
/// distance is scaled by 1 + 2γ(3) (pbrt-v3 §3.9.2), which covers the rounding of the three
/// operations behind each slab distance, so a box is never missed where its contents are hit.
#[inline]
pub fn slab<R: Real>(node: &BvhNode, ray: &Ray<R>, inv: V3<R>, tmin: R, tmax: R) -> Option<R> {
    let grow = R::ONE + R::from_f64(2.0) * R::gamma_bound(3);
    let mut tnear = tmin;
    let mut tfar = tmax;
    for a in 0..3 {
        let lo = R::from_f64(node.bmin[a] as f64);
        let hi = R::from_f64(node.bmax[a] as f64);
        let t0 = (lo - ray.origin[a]) * inv[a];
        let t1 = (hi - ray.origin[a]) * inv[a];
        let (t0, t1) = if t0 > t1 { (t1, t0) } else { (t0, t1) };
        tnear = if t0 > tnear { t0 } else { tnear };
        let t1 = t1 * grow;
        tfar = if t1 < tfar { t1 } else { tfar };
    }
    (tnear <= tfar).then_some(tnear)
}

/// Calls `leaf(first, count)` for every leaf whose box the ray enters within [tmin, bound()],
/// nearer child first; `bound` is re-read as the search narrows.
#[inline]
fn walk<R: Real>(bvh: &Bvh, ray: &Ray<R>, tmin: R, bound: &mut dyn FnMut() -> R, leaf: &mut dyn FnMut(usize, usize)) {
    if bvh.nodes.is_empty() {
        return;
    }
    let inv = safe_inverse(ray.dir);
    let mut stack_node = [0u32; STACK];
    let mut stack_t = [R::ZERO; STACK];
    let mut sp = 0usize;
    if slab(&bvh.nodes[0], ray, inv, tmin, bound()).is_none() {
        return;
    }
    let mut node = 0usize;
    loop {
        let n = &bvh.nodes[node];
        let mut next = None;
        if n.is_leaf() {
            leaf(n.left_or_first as usize, n.count as usize);
        } else {
            let (l, r) = (node + 1, n.left_or_first as usize);
            let tb = bound();
            let hl = slab(&bvh.nodes[l], ray, inv, tmin, tb);
            let hr = slab(&bvh.nodes[r], ray, inv, tmin, tb);
            match (hl, hr) {
                (Some(a), Some(b)) => {
                    let (near, far, tfar) = if b < a { (r, l, a) } else { (l, r, b) };
                    stack_node[sp] = far as u32;
                    stack_t[sp] = tfar;
                    sp += 1;
                    next = Some(near);
                }
                (Some(_), None) => next = Some(l),
                (None, Some(_)) => next = Some(r),
                (None, None) => {}
            }
        }
        node = match next {
            Some(n) => n,
            None => loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                if stack_t[sp] <= bound() {
                    break stack_node[sp] as usize;
                }
            },
        };
    }
}

/// The nearest hit in (tmin, tmax), identical to [`Primitives::nearest_brute`].
pub fn nearest<R: Real>(bvh: &Bvh, prims: &Primitives<R>, ray: &Ray<R>, tmin: R, tmax: R) -> Option<Hit<R>> {
    let mut best = Nearest::new(tmax);
    for r in prims.plane_refs() {
        prims.offer_nearest(r, ray, tmin, &mut best);
    }
    let best_cell = std::cell::Cell::new(best);
    walk(bvh, ray, tmin, &mut || best_cell.get().search_bound(), &mut |first, count| {
        let mut b = best_cell.get();
        for &r in &bvh.prim_refs[first..first + count] {
            prims.offer_nearest(r, ray, tmin, &mut b);
        }
        best_cell.set(b);
    });
    best = best_cell.get();
    best.found.then(|| prims.hit(best.prim, ray, best.t, best.part))
}

/// Every hit in (tmin, tmax), sorted as [`Primitives::all_brute`] sorts them.
pub fn all<R: Real>(bvh: &Bvh, prims: &Primitives<R>, ray: &Ray<R>, tmin: R, tmax: R) -> Vec<Hit<R>> {
    let mut hits = Vec::new();
    for r in prims.plane_refs() {
        prims.collect_hits(r, ray, tmin, tmax, &mut hits);
    }
    walk(bvh, ray, tmin, &mut || tmax, &mut |first, count| {
        for &r in &bvh.prim_refs[first..first + count] {
            prims.collect_hits(r, ray, tmin, tmax, &mut hits);
        }
    });
    sort_hits(&mut hits);
    hits
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{WideBvh, wide_traverse};
    use crate::geometry::testutil::{TestRays, TestRng, mixed_scene, ray_f32};

    /// The acceptance test of the BVH: on 100k random rays the binary walk (the GPU's
    /// mirror) and the CPU's wide walk, with each lane implementation this CPU has, return
    /// exactly the hit the brute-force loop returns (same t bit for bit, same primitive, same
    /// normal).
    #[test]
    fn bvh_nearest_equals_brute_force_on_100k_rays() {
        let prims = mixed_scene(21);
        let bvh = Bvh::build(&prims);
        let wide = WideBvh::new(&bvh, &prims);
        let mut rng = TestRng(99);
        let mut hits = 0;
        for i in 0..100_000 {
            let ray = if i % 10 == 0 {
                // Axis-parallel rays exercise the slab test's zero components.
                let mut d = V3::<f64>::zero();
                let axis = (i / 10) % 3;
                if axis == 0 {
                    d.x = 1.0
                } else if axis == 1 {
                    d.y = -1.0
                } else {
                    d.z = 1.0
                };
                ray_f32(&Ray::new(rng.in_cube(60.0), d))
            } else {
                ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0))
            };
            let want = prims.nearest_brute(&ray, 0.0, f32::INFINITY);
            let got = nearest(&bvh, &prims, &ray, 0.0, f32::INFINITY);
            assert_eq!(want, got, "ray {i}: {ray:?}");
            assert_eq!(want, wide_traverse::nearest(&wide, &prims, &ray, 0.0, f32::INFINITY), "wide, ray {i}: {ray:?}");
            assert_eq!(
                want,
                wide_traverse::nearest_scalar(&wide, &prims, &ray, 0.0, f32::INFINITY),
                "wide scalar, ray {i}"
            );
            hits += want.is_some() as usize;
        }
        assert!(hits > 30_000, "only {hits} hits: the test would prove little");
    }

    #[test]
    fn bvh_all_hits_equal_brute_force() {
        let prims = mixed_scene(5);
        let bvh = Bvh::build(&prims);
        let mut rng = TestRng(8);
        for _ in 0..5_000 {
            let ray = ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0));
            assert_eq!(prims.all_brute(&ray, 0.0, f32::INFINITY), all(&bvh, &prims, &ray, 0.0, f32::INFINITY));
        }
    }

    #[test]
    fn slab_test_has_no_nan_for_rays_on_box_faces() {
        let node = BvhNode { bmin: [0.0; 3], left_or_first: 0, bmax: [1.0; 3], count: 1 };
        // A ray lying in the box's x = 0 face, parallel to it.
        let ray = Ray::new(V3::<f32>::new(0.0, 0.5, -1.0), V3::new(0.0, 0.0, 1.0));
        assert_eq!(slab(&node, &ray, safe_inverse(ray.dir), 0.0, f32::INFINITY), Some(1.0));
        let outside = Ray::new(V3::<f32>::new(-0.1, 0.5, -1.0), V3::new(0.0, 0.0, 1.0));
        assert_eq!(slab(&node, &outside, safe_inverse(outside.dir), 0.0, f32::INFINITY), None);
    }
}
