//! Every hit of a ray on the 8-wide tree ([`super::wide`]), and the number of hits: the walk
//! that visits every leaf the ray meets, keeping each hit; with a stop at the first hit it is
//! the occlusion walk ([`super::wide_traverse::occluded`]).
//!
//! The lane tests ([`super::simd`]) compute what the scalar routines compute, bit for bit, and
//! the interval is the same open (tmin, tmax), so [`all`] returns exactly the hits of
//! [`super::traverse::all`] on the binary tree (and of [`Primitives::all_brute`]), in the same
//! order: the same `t`, the same primitives, each edge or vertex shared by triangles counted by
//! one of them (the watertight test's tie rule). What it saves is the binary walk's one box and
//! one triangle at a time: eight boxes and four triangles per step here. The walks of the wide
//! tree share its stack ([`Stack`]).

use super::record::hit_record;
use super::simd::{self, Kernels, RayPre, Scalar, widen};
use super::wide::{EMPTY_PRIM, LANES, LEAF_BIT, LeafBlock, MAX_DEPTH, WIDTH, WideBvh};
use std::mem::MaybeUninit;
use strahl_core::geometry::Part;
use strahl_core::math::Ray;
use strahl_core::primitives::{Hit, Nearest, PrimRef, Primitives, sort_hits};

/// Room for the children a walk defers: at most seven per level.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// The deferred children: child words and their entry distances. Left uninitialised: it is
/// a few kilobytes, and most rays use a few entries of it.
pub(super) struct Stack {
    entry: [MaybeUninit<(u32, f32)>; STACK],
    len: usize,
}

impl Stack {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Self { entry: [const { MaybeUninit::uninit() }; STACK], len: 0 }
    }
    /// Empties it, for the next ray.
    #[inline(always)]
    pub(super) fn clear(&mut self) {
        self.len = 0;
    }
    #[inline(always)]
    pub(super) fn push(&mut self, word: u32, t: f32) {
        // The tree's depth is at most MAX_DEPTH levels, each deferring at most WIDTH − 1.
        self.entry[self.len] = MaybeUninit::new((word, t));
        self.len += 1;
    }
    /// The most recently deferred child whose entry lies within `bound`.
    #[inline(always)]
    pub(super) fn pop_within(&mut self, bound: f32) -> Option<u32> {
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

/// Every hit in (tmin, tmax) into `hits` (emptied first), sorted as [`Primitives::all_brute`]
/// sorts them. `hits` keeps its room from ray to ray.
pub fn all(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32, hits: &mut Vec<Hit<f32>>) {
    hits.clear();
    let mut sink = Records { w, prims, ray, tmin, tmax, hits };
    walk(w, prims, ray, tmin, tmax, &mut sink);
    sort_hits(hits);
}

/// How many hits [`all`] returns, without making their records.
pub fn count(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> usize {
    let mut sink = Count { prims, ray, tmin, tmax, n: 0 };
    walk(w, prims, ray, tmin, tmax, &mut sink);
    sink.n
}

/// What the walk does with the hits it finds; true stops it.
pub(super) trait Sink {
    /// Lanes `mask` (not 0) of `block` are triangles hit at `t[lane]`.
    fn triangles(&mut self, block: &LeafBlock, mask: u32, t: &[f32; LANES]) -> bool;
    /// A plane, sphere or cylinder to intersect: all of its roots in (tmin, tmax).
    fn other(&mut self, r: PrimRef) -> bool;
}

struct Records<'a> {
    w: &'a WideBvh,
    prims: &'a Primitives<f32>,
    ray: &'a Ray<f32>,
    tmin: f32,
    tmax: f32,
    hits: &'a mut Vec<Hit<f32>>,
}

impl Sink for Records<'_> {
    #[inline(always)]
    fn triangles(&mut self, block: &LeafBlock, mut mask: u32, t: &[f32; LANES]) -> bool {
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            // The record the nearest-hit walk makes, from the block's copy of the triangle.
            let hit = Nearest { t: t[lane], prim_ref: PrimRef(block.prim_ref[lane]), part: Part::Surface, found: true };
            self.hits.extend(hit_record(self.w, self.prims, self.ray, &hit, Some(block)));
        }
        false
    }

    #[inline(always)]
    fn other(&mut self, r: PrimRef) -> bool {
        self.prims.collect_hits(r, self.ray, self.tmin, self.tmax, self.hits);
        false
    }
}

struct Count<'a> {
    prims: &'a Primitives<f32>,
    ray: &'a Ray<f32>,
    tmin: f32,
    tmax: f32,
    n: usize,
}

impl Sink for Count<'_> {
    #[inline(always)]
    fn triangles(&mut self, _: &LeafBlock, mask: u32, _: &[f32; LANES]) -> bool {
        self.n += mask.count_ones() as usize;
        false
    }

    #[inline(always)]
    fn other(&mut self, r: PrimRef) -> bool {
        self.n += self.prims.roots(r, self.ray, self.tmin, self.tmax).len;
        false
    }
}

/// The walk with the CPU's best lanes.
#[inline(always)]
fn walk(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32, sink: &mut impl Sink) {
    #[cfg(target_arch = "x86_64")]
    if simd::has_avx2() {
        // SAFETY: the CPU has AVX2.
        unsafe { walk_avx2(w, prims, ray, tmin, tmax, sink) };
        return;
    }
    walk_scalar(w, prims, ray, tmin, tmax, sink);
}

fn walk_scalar(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    tmin: f32,
    tmax: f32,
    sink: &mut impl Sink,
) -> bool {
    walk_signed::<Scalar>(w, prims, ray, tmin, tmax, sink)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn walk_avx2(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32, sink: &mut impl Sink) -> bool {
    walk_signed::<simd::Avx2>(w, prims, ray, tmin, tmax, sink)
}

/// [`walk_with`] with the box test for tmin ≥ 0 or for a negative tmin.
#[inline(always)]
fn walk_signed<K: Kernels>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    tmin: f32,
    tmax: f32,
    sink: &mut impl Sink,
) -> bool {
    if tmin >= 0.0 {
        walk_with::<K, false>(w, prims, ray, tmin, tmax, sink)
    } else {
        walk_with::<K, true>(w, prims, ray, tmin, tmax, sink)
    }
}

/// Visits every leaf whose box the ray meets in [tmin, tmax] (the far side widened) and hands
/// its hits to `sink`, planes first, until the sink says stop: whether it did. The occlusion
/// walk ([`super::wide_traverse::occluded`]) is this walk with a sink that stops at a hit.
#[inline(always)]
pub(super) fn walk_with<K: Kernels, const NEG: bool>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    tmin: f32,
    tmax: f32,
    sink: &mut impl Sink,
) -> bool {
    for r in prims.plane_refs() {
        if sink.other(r) {
            return true;
        }
    }
    if w.is_empty() {
        return false;
    }
    let pre = RayPre::new(ray);
    let tmin = tmin + 0.0; // as in the nearest-hit walk
    let cull = widen(tmax);
    let mut stack = Stack::new();
    let mut word = 0u32;
    let mut tnear = [0.0f32; WIDTH];
    let mut t = [0.0f32; LANES];
    loop {
        if word & LEAF_BIT == 0 {
            // SAFETY: K's features are present (the caller dispatched on them).
            let mut mask = unsafe { K::boxes::<NEG>(w.node(word), &pre, tmin, cull, &mut tnear) };
            if mask != 0 {
                // Every child entered is visited: the order does not matter.
                let node = w.node(word);
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
                let mask = unsafe { K::triangles(block, &pre, tmin, tmax, &mut t) };
                if mask != 0 && sink.triangles(block, mask, &t) {
                    return true;
                }
                if other {
                    for &p in &block.prim_ref {
                        if p != EMPTY_PRIM && !simd::is_triangle(p) && sink.other(PrimRef(p)) {
                            return true;
                        }
                    }
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
    use crate::accel::binary as traverse;
    use strahl_core::accel::Bvh;
    use strahl_core::geometry::testutil::{TestRays, TestRng, ray_f32};
    use strahl_core::math::V3;
    use strahl_core::primitives::testutil::mixed_scene;

    /// On random rays through spheres, cylinders, planes and triangles, in (0, ∞) and in an
    /// interval that starts behind the origin and ends inside the scene: the same hits as the
    /// binary tree's walk, in the same order, with both lane implementations, and counts equal
    /// to their number.
    #[test]
    fn every_hit_equals_the_binary_walk() {
        let prims = mixed_scene(31);
        let bvh = Bvh::build(&prims);
        let w = WideBvh::new(&bvh, &prims);
        let mut rng = TestRng(32);
        let (mut rays, mut hits, mut many) = (0, 0, 0);
        let mut got = Vec::new();
        for i in 0..20_000 {
            let ray = ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0));
            let (tmin, tmax) = if i % 3 == 0 { (-20.0, 90.0) } else { (0.0, f32::INFINITY) };
            let expected = traverse::all(&bvh, &prims, &ray, tmin, tmax);
            all(&w, &prims, &ray, tmin, tmax, &mut got);
            assert_eq!(got, expected, "ray {i} in ({tmin}, {tmax})");
            assert_eq!(count(&w, &prims, &ray, tmin, tmax), expected.len(), "ray {i}");
            let mut scalar = Records { w: &w, prims: &prims, ray: &ray, tmin, tmax, hits: &mut Vec::new() };
            assert!(!walk_scalar(&w, &prims, &ray, tmin, tmax, &mut scalar));
            sort_hits(scalar.hits);
            assert_eq!(*scalar.hits, expected, "ray {i}, portable lanes");
            rays += 1;
            hits += expected.len();
            many += (expected.len() > 2) as usize;
        }
        assert!(hits > rays && many > 1_000, "{hits} hits on {rays} rays, {many} with more than two");
        let empty = WideBvh::new(&Bvh::default(), &Primitives::default());
        all(&empty, &Primitives::default(), &ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0)), 0.0, 1.0, &mut got);
        assert!(got.is_empty());
    }
}
