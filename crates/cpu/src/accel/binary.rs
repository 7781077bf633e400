//! BVH traversal of the binary tree, as the CPU renderer runs it; the GPU walks the collapsed
//! tree of [`strahl_core::accel::gpu_bvh`] (whose walk is the twin of `shaders/modules/traverse.wgsl`). Both return
//! exactly what brute force returns.

use strahl_core::accel::bvh::{Bvh, MAX_DEPTH};
use strahl_core::accel::slab::{safe_inverse, slab};
use strahl_core::math::{Ray, Real};
use strahl_core::primitives::{Hit, Nearest, Primitives, sort_hits};

/// Stack entries: a node to visit and the distance at which the ray enters its box.
const STACK: usize = MAX_DEPTH as usize + 1;

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
    best.found.then(|| prims.hit(best.prim_ref, ray, best.t, best.part))
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
    use strahl_core::accel::BvhNode;
    use strahl_core::geometry::testutil::{TestRays, TestRng, ray_f32};
    use strahl_core::math::V3;
    use strahl_core::primitives::testutil::mixed_scene;

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

    /// A ray parallel to two axes from 1e38 away enters a box at t ≈ 1e38: the parallel axes
    /// must not bound it (a stand-in inverse of 1e30 cut it off at 1e30·gap and the BVH missed
    /// what brute force hit), and the box on its max face is entered too.
    #[test]
    fn parallel_axes_bound_nothing_at_any_distance() {
        let node = BvhNode { bmin: [-5.0, -5.0, 3.0], left_or_first: 0, bmax: [5.0, 5.0, 13.0], count: 1 };
        let far = Ray::new(V3::<f32>::new(1e38, 0.0, 8.0), V3::new(-1.0, 0.0, 0.0));
        assert_eq!(slab(&node, &far, safe_inverse(far.dir), 0.0, f32::INFINITY), Some(1e38));
        let on_max_face = Ray::new(V3::<f32>::new(-20.0, 5.0, 13.0), V3::new(1.0, 0.0, 0.0));
        assert_eq!(slab(&node, &on_max_face, safe_inverse(on_max_face.dir), 0.0, f32::INFINITY), Some(15.0));
        let beside = Ray::new(V3::<f32>::new(-20.0, 5.0 + 1e-6, 8.0), V3::new(1.0, 0.0, 0.0));
        assert_eq!(slab(&node, &beside, safe_inverse(beside.dir), 0.0, f32::INFINITY), None);
        // The lecture's spheres, through the BVH and by brute force.
        let mut prims = Primitives::<f32>::default();
        for (i, (c, r)) in
            [([0.0, 0.0, 8.0], 5.0), ([0.0, 0.0, 9.0], 3.0), ([0.0, -3.0, 8.0], 2.0)].into_iter().enumerate()
        {
            let shape = strahl_core::geometry::Sphere { center: V3::from_array(c), radius: r };
            prims.spheres.push(strahl_core::primitives::Tagged {
                shape,
                tag: strahl_core::primitives::Tag { object: i as u32, ..Default::default() },
            });
        }
        let bvh = Bvh::build(&prims);
        let hits = all(&bvh, &prims, &far, 0.0, f32::INFINITY);
        assert_eq!(hits, prims.all_brute(&far, 0.0, f32::INFINITY));
        assert_eq!(hits.len(), 2, "{hits:?}");
        assert!(hits.iter().all(|h| h.t == 1e38 && h.normal.is_finite()), "{hits:?}");
    }
}
