//! The CPU's walk of the 8-wide tree ([`super::wide`]): nearest hit and occlusion.
//!
//! Per ray, the inverse direction, the near planes and the watertight test's shear are
//! computed once ([`RayPre`]). Each node tests its eight boxes at once; the children entered
//! are visited nearest first, the others stacked with their entry distance and dropped when
//! the search interval has shrunk below it. Leaves test four triangles at once. The occlusion
//! walk stops at the first hit. The lane tests ([`super::simd`]) compute what the scalar
//! routines compute, bit for bit, so [`nearest`] returns exactly [`Primitives::nearest_brute`]'s
//! hit: same `t`, same primitive, ties broken by the smaller [`PrimRef`].

use super::simd::{self, Kernels, RayPre, Scalar, widen};
use super::wide::{EMPTY_PRIM, LANES, LEAF_BIT, LeafBlock, MAX_DEPTH, WIDTH, WideBvh};
use crate::geometry::Part;
use crate::geometry::{Shape, Triangle};
use crate::math::Ray;
use crate::math::V3;
use crate::primitives::{Hit, Nearest, PrimRef, Primitives};
use std::mem::MaybeUninit;

/// Room for the children a walk defers: at most seven per level.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// The nearest hit in (tmin, tmax), identical to [`Primitives::nearest_brute`].
pub fn nearest(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Option<Hit<f32>> {
    #[cfg(target_arch = "x86_64")]
    if simd::has_avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { nearest_avx2(w, prims, ray, tmin, tmax) };
    }
    nearest_scalar(w, prims, ray, tmin, tmax)
}

/// Whether anything is hit in (tmin, tmax): the same answer as `nearest(..).is_some()`,
/// found by stopping at the first hit.
pub fn occluded(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> bool {
    #[cfg(target_arch = "x86_64")]
    if simd::has_avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { occluded_avx2(w, prims, ray, tmin, tmax) };
    }
    if tmin >= 0.0 {
        occluded_with::<Scalar, false>(w, prims, ray, tmin, tmax)
    } else {
        occluded_with::<Scalar, true>(w, prims, ray, tmin, tmax)
    }
}

/// [`nearest`] with the portable lanes, whatever the CPU (for tests and comparisons).
pub fn nearest_scalar(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Option<Hit<f32>> {
    if tmin >= 0.0 {
        nearest_with::<Scalar, false>(w, prims, ray, tmin, tmax)
    } else {
        nearest_with::<Scalar, true>(w, prims, ray, tmin, tmax)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn nearest_avx2(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Option<Hit<f32>> {
    if tmin >= 0.0 {
        nearest_with::<simd::Avx2, false>(w, prims, ray, tmin, tmax)
    } else {
        nearest_with::<simd::Avx2, true>(w, prims, ray, tmin, tmax)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn occluded_avx2(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> bool {
    if tmin >= 0.0 {
        occluded_with::<simd::Avx2, false>(w, prims, ray, tmin, tmax)
    } else {
        occluded_with::<simd::Avx2, true>(w, prims, ray, tmin, tmax)
    }
}

/// The deferred children: child words and their entry distances. Left uninitialised: it is
/// a few kilobytes, and most rays use a few entries of it.
struct Stack {
    entry: [MaybeUninit<(u32, f32)>; STACK],
    len: usize,
}

impl Stack {
    #[inline(always)]
    fn new() -> Self {
        Self { entry: [const { MaybeUninit::uninit() }; STACK], len: 0 }
    }
    #[inline(always)]
    fn push(&mut self, word: u32, t: f32) {
        // The tree's depth is at most MAX_DEPTH levels, each deferring at most WIDTH − 1.
        self.entry[self.len] = MaybeUninit::new((word, t));
        self.len += 1;
    }
    /// The most recently deferred child whose entry lies within `bound`.
    #[inline(always)]
    fn pop_within(&mut self, bound: f32) -> Option<u32> {
        while self.len > 0 {
            self.len -= 1;
            // SAFETY: entries below `len` were written by `push`.
            let (word, t) = unsafe { self.entry[self.len].assume_init() };
            if t <= bound {
                return Some(word);
            }
        }
        None
    }
}

/// Visits the children entered (`mask`, distances `tnear`) of `node`: returns the nearest,
/// after stacking the others farthest first.
#[inline(always)]
fn order_children(child: &[u32; WIDTH], mut mask: u32, tnear: &[f32; WIDTH], stack: &mut Stack) -> u32 {
    let first = mask.trailing_zeros() as usize;
    mask &= mask - 1;
    if mask == 0 {
        return child[first];
    }
    let second = mask.trailing_zeros() as usize;
    mask &= mask - 1;
    if mask == 0 {
        // Two children, the common case: no sort.
        let (near, far) = if tnear[second] < tnear[first] { (second, first) } else { (first, second) };
        stack.push(child[far], tnear[far]);
        return child[near];
    }
    // Three or more: insertion sort by distance, farthest first, on keys that hold the
    // distance's bits above the child word (distances here are ≥ 0, whose bits order as the
    // values do; a negative one only changes the visiting order).
    let key = |i: usize| (tnear[i].to_bits() as u64) << 32 | child[i] as u64;
    let mut list = [0u64; WIDTH];
    list[0] = key(first);
    list[1] = key(second);
    let mut n = 2;
    while mask != 0 {
        let i = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        list[n] = key(i);
        n += 1;
    }
    for i in 1..n {
        let x = list[i];
        let mut j = i;
        while j > 0 && list[j - 1] < x {
            list[j] = list[j - 1];
            j -= 1;
        }
        list[j] = x;
    }
    for &k in &list[..n - 1] {
        stack.push(k as u32, f32::from_bits((k >> 32) as u32));
    }
    list[n - 1] as u32
}

#[inline(always)]
fn nearest_with<K: Kernels, const NEG: bool>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    tmin: f32,
    tmax: f32,
) -> Option<Hit<f32>> {
    let mut best = Nearest::new(tmax);
    for r in prims.plane_refs() {
        prims.offer_nearest(r, ray, tmin, &mut best);
    }
    // The block of the best triangle hit so far, for its hit record.
    let mut from_block: Option<&LeafBlock> = None;
    if !w.is_empty() {
        let pre = RayPre::new(ray);
        let mut stack = Stack::new();
        let mut bound = best.search_bound();
        let mut cull = widen(bound);
        let mut word = 0u32; // the root node
        let mut tnear = [0.0f32; WIDTH];
        let mut t = [0.0f32; LANES];
        loop {
            let next = if word & LEAF_BIT == 0 {
                let node = w.node(word);
                // SAFETY: K's features are present (the caller dispatched on them).
                let mask = unsafe { K::boxes::<NEG>(node, &pre, tmin, cull, &mut tnear) };
                (mask != 0).then(|| order_children(&node.child, mask, &tnear, &mut stack))
            } else {
                let (blocks, other) = w.leaf(word);
                for block in blocks {
                    // SAFETY: as above.
                    let mut hits = unsafe { K::triangles(block, &pre, tmin, bound, &mut t) };
                    if hits != 0 {
                        let before = best.prim;
                        while hits != 0 {
                            let lane = hits.trailing_zeros() as usize;
                            hits &= hits - 1;
                            best.offer(t[lane], PrimRef(block.prim[lane]), Part::Surface);
                        }
                        if best.prim != before {
                            from_block = Some(block);
                            bound = best.search_bound();
                        }
                    }
                    if other {
                        for &p in &block.prim {
                            if p != EMPTY_PRIM && !simd::is_triangle(p) {
                                prims.offer_nearest(PrimRef(p), ray, tmin, &mut best);
                            }
                        }
                        bound = best.search_bound();
                    }
                }
                cull = widen(bound);
                None
            };
            word = match next {
                Some(n) => n,
                None => match stack.pop_within(cull) {
                    Some(n) => n,
                    None => break,
                },
            };
        }
    }
    if !best.found {
        return None;
    }
    // A sphere or cylinder found later may have won, even in the same block.
    let lane = from_block
        .filter(|_| simd::is_triangle(best.prim.0))
        .and_then(|b| b.prim.iter().position(|&p| p == best.prim.0).map(|lane| (b, lane)));
    Some(match lane {
        // The record prims.hit makes, from the copy of the triangle in the block.
        Some((block, lane)) => {
            let v = |k: usize| V3::new(block.v[k][0][lane], block.v[k][1][lane], block.v[k][2][lane]);
            let normal = Triangle { v: [v(0), v(1), v(2)] }.normal(ray, best.t, best.part);
            let tag = w.triangle_tag(best.prim.index());
            Hit { t: best.t, normal, prim: best.prim, part: best.part, tag, enter: ray.dir.dot(normal) < 0.0 }
        }
        _ => prims.hit(best.prim, ray, best.t, best.part),
    })
}

#[inline(always)]
fn occluded_with<K: Kernels, const NEG: bool>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    tmin: f32,
    tmax: f32,
) -> bool {
    if prims.plane_refs().any(|r| prims.roots(r, ray, tmin, tmax).len > 0) {
        return true;
    }
    if w.is_empty() {
        return false;
    }
    let pre = RayPre::new(ray);
    let mut stack = Stack::new();
    let cull = widen(tmax);
    let mut word = 0u32;
    let mut tnear = [0.0f32; WIDTH];
    let mut t = [0.0f32; LANES];
    loop {
        if word & LEAF_BIT == 0 {
            let node = w.node(word);
            // SAFETY: K's features are present (the caller dispatched on them).
            let mut mask = unsafe { K::boxes::<NEG>(node, &pre, tmin, cull, &mut tnear) };
            if mask != 0 {
                // Order does not matter for "any hit": take the children as they come.
                let first = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    stack.push(node.child[i], tnear[i]);
                }
                word = node.child[first];
                continue;
            }
        } else {
            let (blocks, other) = w.leaf(word);
            for block in blocks {
                // SAFETY: as above.
                if unsafe { K::triangles(block, &pre, tmin, tmax, &mut t) } != 0 {
                    return true;
                }
                if other
                    && block.prim.iter().any(|&p| {
                        p != EMPTY_PRIM && !simd::is_triangle(p) && prims.roots(PrimRef(p), ray, tmin, tmax).len > 0
                    })
                {
                    return true;
                }
            }
        }
        match stack.pop_within(cull) {
            Some(n) => word = n,
            None => return false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Bvh;
    use crate::geometry::testutil::{TestRays, TestRng, mixed_scene, ray_f32};
    use crate::math::V3;

    /// Runs `check` with each lane implementation this CPU has.
    fn each_kernel(check: impl Fn(&str, &dyn Fn(&WideBvh, &Primitives<f32>, &Ray<f32>) -> Option<Hit<f32>>)) {
        check("scalar", &|w, p, r| nearest_with::<Scalar, false>(w, p, r, 0.0, f32::INFINITY));
        #[cfg(target_arch = "x86_64")]
        if simd::has_avx2() {
            check("avx2", &|w, p, r| unsafe { nearest_avx2(w, p, r, 0.0, f32::INFINITY) });
        }
    }

    #[test]
    fn occlusion_agrees_with_nearest_within_the_interval() {
        let prims = mixed_scene(7);
        let bvh = Bvh::build(&prims);
        let w = WideBvh::new(&bvh, &prims);
        let mut rng = TestRng(17);
        let mut blocked = 0;
        for i in 0..20_000 {
            let ray = ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0));
            let tmax = [f32::INFINITY, 40.0, 80.0, 120.0][i % 4];
            let want = prims.nearest_brute(&ray, 0.0, tmax).is_some();
            assert_eq!(occluded(&w, &prims, &ray, 0.0, tmax), want, "ray {i}");
            assert_eq!(occluded_with::<Scalar, false>(&w, &prims, &ray, 0.0, tmax), want, "ray {i}");
            blocked += want as usize;
        }
        assert!(blocked > 5_000 && blocked < 19_000, "{blocked} blocked: the test would prove little");
    }

    /// Intervals that start behind the origin and end short of infinity: the far planes'
    /// correction for negative distances, and the search bound, must lose no hit.
    #[test]
    fn windows_reaching_behind_the_origin_find_the_brute_force_hit() {
        let prims = mixed_scene(11);
        let bvh = Bvh::build(&prims);
        let w = WideBvh::new(&bvh, &prims);
        let mut rng = TestRng(12);
        let mut found = 0;
        for i in 0..20_000 {
            let ray = ray_f32(&rng.ray_towards(40.0, V3::zero(), 50.0));
            let tmin = rng.range(-60.0, 10.0) as f32;
            let tmax = tmin + rng.range(0.5, 80.0) as f32;
            let want = prims.nearest_brute(&ray, tmin, tmax);
            assert_eq!(nearest(&w, &prims, &ray, tmin, tmax), want, "ray {i} in ({tmin}, {tmax})");
            assert_eq!(nearest_scalar(&w, &prims, &ray, tmin, tmax), want, "scalar, ray {i}");
            assert_eq!(occluded(&w, &prims, &ray, tmin, tmax), want.is_some(), "occlusion, ray {i}");
            found += want.is_some_and(|h| h.t < 0.0) as usize;
        }
        assert!(found > 1000, "only {found} hits behind the origin: the test would prove little");
    }

    #[test]
    fn both_kernels_find_the_brute_force_hit() {
        let prims = mixed_scene(3);
        let bvh = Bvh::build(&prims);
        let w = WideBvh::new(&bvh, &prims);
        each_kernel(|name, f| {
            let mut rng = TestRng(4);
            for i in 0..20_000 {
                let ray = ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0));
                assert_eq!(f(&w, &prims, &ray), prims.nearest_brute(&ray, 0.0, f32::INFINITY), "{name}: ray {i}");
            }
        });
    }
}
