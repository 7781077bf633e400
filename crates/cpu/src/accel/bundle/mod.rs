//! A bundle of rays of any directions walked through the 8-wide tree ([`super::wide`])
//! together, one ray per SIMD lane: 16 lanes with AVX-512, 8 with AVX2, 4 portable ones
//! elsewhere. It is the traversal of the lane path tracer ([`crate::lanes`]), whose
//! secondary rays share no octant, so the packet walk of batch queries ([`super::packet`],
//! which needs one) does not serve them.
//!
//! Each lane keeps its own ray, its own near and far planes (chosen by the signs of its own
//! direction), its own watertight permutation and its own best hit. A node's child boxes are
//! tested one after the other against every lane at once; the children some lane enters are
//! visited nearest first (by the distance of the lowest such lane), the others deferred with
//! the lanes that enter them and their entry distances, and revisited only for the lanes they
//! still may serve. A leaf's triangles, spheres and cylinders are each tested against every
//! lane at once. Where a subtree is entered by at most [`HYBRID`] lanes, those lanes finish it
//! with the one-ray walk ([`super::wide_traverse`]), as Embree's hybrid traversal does (Benthin,
//! Wald, Woop, Ernst & Mark, "Combining Single and Packet-Ray Tracing for Arbitrary Ray
//! Distributions on the Intel MIC Architecture", 2012).
//!
//! Lane for lane the box tests compute [`super::simd::Scalar`]'s values and the primitive
//! tests the IEEE operations of [`strahl_core::geometry`]'s f32 routines in the same order (the
//! loops below are written per lane, and the compiler turns them into vector instructions,
//! which round as the scalar ones do); hits are kept by [`Nearest::offer`]'s total order. So
//! every lane gets exactly the answer of [`super::wide_traverse::nearest`] (and of brute
//! force): the same `t`, the same primitive, the same tie rule. Only tmin = 0 is served.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

mod kernels;

use super::simd::{Kernels, RayPre, is_triangle, widen};
use super::wide::{EMPTY_CHILD, EMPTY_PRIM, LANES, LEAF_BIT, MAX_DEPTH, WIDTH, WideBvh};
use super::wide_traverse;
use kernels::{Lanes, mask_of, word};
use std::mem::MaybeUninit;
use strahl_core::geometry::Part;
use strahl_core::math::Ray;
use strahl_core::primitives::{Nearest, PrimKind, PrimRef, Primitives};

/// The most lanes a bundle has (AVX-512).
pub const MAX_WIDTH: usize = 16;

/// A subtree entered by at most this many lanes is finished by each of them alone (measured
/// in the book's performance chapter).
const HYBRID: u32 = 1;

/// Which lanes this processor runs: the bundle width and the instructions of its walk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// 16 lanes, AVX-512 (F, VL, BW, DQ) with FMA.
    Avx512,
    /// 8 lanes, AVX2 with FMA.
    Avx2,
    /// 4 lanes in whatever vector instructions the target has by default.
    Portable,
}

impl Isa {
    /// The widest this processor has (detected at run time).
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512vl")
                && std::is_x86_feature_detected!("avx512bw")
                && std::is_x86_feature_detected!("avx512dq")
                && super::simd::has_avx2()
            {
                return Isa::Avx512;
            }
            if super::simd::has_avx2() {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }

    /// Lanes per bundle.
    pub fn width(self) -> usize {
        match self {
            Isa::Avx512 => 16,
            Isa::Avx2 => 8,
            Isa::Portable => 4,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Avx512 => "avx512",
            Isa::Avx2 => "avx2",
            Isa::Portable => "portable",
        }
    }

    /// Every lane set this processor can run, widest first (for tests).
    pub fn available() -> Vec<Isa> {
        [Isa::Avx512, Isa::Avx2, Isa::Portable].into_iter().filter(|&i| i.runs_here()).collect()
    }

    /// Whether this processor runs `self`.
    pub fn runs_here(self) -> bool {
        match (self, Isa::detect()) {
            (Isa::Portable, _) => true,
            (Isa::Avx2, Isa::Avx512 | Isa::Avx2) => true,
            (a, b) => a == b,
        }
    }
}

/// Up to [`MAX_WIDTH`] rays field by field: origins `o[axis][lane]`, unit directions `d`.
/// Lanes past those in use hold any finite ray (their answers are not read).
#[derive(Clone, Copy, Debug)]
pub struct BundleRays<const N: usize> {
    pub o: [[f32; N]; 3],
    pub d: [[f32; N]; 3],
}

impl BundleRays<MAX_WIDTH> {
    /// `rays` (at most [`MAX_WIDTH`]), the last repeated in the lanes past them.
    pub fn from_rays(rays: &[Ray<f32>]) -> Self {
        let ray = |l: usize| rays[l.min(rays.len().saturating_sub(1))];
        let field = |f: &dyn Fn(&Ray<f32>) -> [f32; 3]| -> [[f32; MAX_WIDTH]; 3] {
            std::array::from_fn(|a| std::array::from_fn(|l| if rays.is_empty() { 0.0 } else { f(&ray(l))[a] }))
        };
        Self { o: field(&|r| r.origin.to_array()), d: field(&|r| r.dir.to_array()) }
    }

    /// The first `N` lanes.
    #[inline(always)]
    fn first<const N: usize>(&self) -> BundleRays<N> {
        BundleRays {
            o: std::array::from_fn(|a| std::array::from_fn(|l| self.o[a][l])),
            d: std::array::from_fn(|a| std::array::from_fn(|l| self.d[a][l])),
        }
    }
}

/// The nearest hit in (0, ∞) of each of `rays` (at most `isa.width()`), into `out`: exactly
/// what [`wide_traverse::nearest`] finds (its record is [`Primitives::hit`] of it).
///
/// # Panics
/// If `isa` does not run here, or `rays` is longer than its width or than `out`.
pub fn nearest(isa: Isa, w: &WideBvh, prims: &Primitives<f32>, rays: &[Ray<f32>], out: &mut [Nearest<f32>]) {
    assert!(rays.len() <= MAX_WIDTH);
    nearest_lanes(isa, w, prims, &BundleRays::from_rays(rays), rays.len(), out)
}

/// [`nearest`] for the first `count` lanes of `rays`.
pub fn nearest_lanes(
    isa: Isa,
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &BundleRays<MAX_WIDTH>,
    count: usize,
    out: &mut [Nearest<f32>],
) {
    assert!(isa.runs_here() && count <= isa.width() && out.len() >= count);
    if count == 0 {
        return;
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the processor has AVX-512 and AVX2 (asserted above).
        Isa::Avx512 => unsafe { x86::nearest_avx512(w, prims, rays, count, out) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above, AVX2.
        Isa::Avx2 => unsafe { x86::nearest_avx2(w, prims, rays, count, out) },
        _ => nearest_n::<4, super::simd::Scalar>(w, prims, &rays.first(), count, out),
    }
}

/// Whether anything lies in (0, tmax[i]) along each of `rays` (at most `isa.width()`): bit i
/// set for ray i, exactly where [`wide_traverse::occluded`] says so.
///
/// # Panics
/// As [`nearest`], and if `tmax` is shorter than `rays`.
pub fn occluded(isa: Isa, w: &WideBvh, prims: &Primitives<f32>, rays: &[Ray<f32>], tmax: &[f32]) -> u32 {
    assert!(rays.len() <= MAX_WIDTH && tmax.len() >= rays.len());
    let mut t = [0.0f32; MAX_WIDTH];
    t[..rays.len()].copy_from_slice(&tmax[..rays.len()]);
    occluded_lanes(isa, w, prims, &BundleRays::from_rays(rays), &t, rays.len())
}

/// [`occluded`] for the first `count` lanes of `rays`, each up to `tmax[lane]`.
pub fn occluded_lanes(
    isa: Isa,
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &BundleRays<MAX_WIDTH>,
    tmax: &[f32; MAX_WIDTH],
    count: usize,
) -> u32 {
    assert!(isa.runs_here() && count <= isa.width());
    if count == 0 {
        return 0;
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `nearest_lanes`.
        Isa::Avx512 => unsafe { x86::occluded_avx512(w, prims, rays, tmax, count) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `nearest_lanes`.
        Isa::Avx2 => unsafe { x86::occluded_avx2(w, prims, rays, tmax, count) },
        _ => occluded_n::<4>(w, prims, &rays.first(), &std::array::from_fn(|l| tmax[l]), count),
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::*;
    use crate::accel::simd::Avx2;

    #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn nearest_avx512(
        w: &WideBvh,
        prims: &Primitives<f32>,
        rays: &BundleRays<MAX_WIDTH>,
        count: usize,
        out: &mut [Nearest<f32>],
    ) {
        nearest_n::<16, Avx2>(w, prims, &rays.first(), count, out)
    }

    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn nearest_avx2(
        w: &WideBvh,
        prims: &Primitives<f32>,
        rays: &BundleRays<MAX_WIDTH>,
        count: usize,
        out: &mut [Nearest<f32>],
    ) {
        nearest_n::<8, Avx2>(w, prims, &rays.first(), count, out)
    }

    #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn occluded_avx512(
        w: &WideBvh,
        prims: &Primitives<f32>,
        rays: &BundleRays<MAX_WIDTH>,
        tmax: &[f32; MAX_WIDTH],
        count: usize,
    ) -> u32 {
        occluded_n::<16>(w, prims, &rays.first(), &std::array::from_fn(|l| tmax[l]), count)
    }

    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn occluded_avx2(
        w: &WideBvh,
        prims: &Primitives<f32>,
        rays: &BundleRays<MAX_WIDTH>,
        tmax: &[f32; MAX_WIDTH],
        count: usize,
    ) -> u32 {
        occluded_n::<8>(w, prims, &rays.first(), &std::array::from_fn(|l| tmax[l]), count)
    }
}

/// A deferred child: its word, the lanes that enter it and their entry distances.
#[derive(Clone, Copy)]
struct Entry<const N: usize> {
    tn: [f32; N],
    word: u32,
    mask: u32,
}

/// Room for the children a walk defers: at most seven per level.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

struct Stack<const N: usize> {
    entry: [MaybeUninit<Entry<N>>; STACK],
    len: usize,
}

impl<const N: usize> Stack<N> {
    #[inline(always)]
    fn new() -> Self {
        Self { entry: [const { MaybeUninit::uninit() }; STACK], len: 0 }
    }
    #[inline(always)]
    fn push(&mut self, e: Entry<N>) {
        self.entry[self.len] = MaybeUninit::new(e);
        self.len += 1;
    }
    /// The most recently deferred child some of whose lanes still enter it within `cull`
    /// (and are in `live`), with those lanes.
    #[inline(always)]
    fn pop_within(&mut self, cull: &[f32; N], live: u32) -> Option<(u32, u32)> {
        while self.len > 0 {
            self.len -= 1;
            // SAFETY: entries below `len` were written by `push`.
            let e = unsafe { self.entry[self.len].assume_init_ref() };
            let mut within = [0i32; N];
            for l in 0..N {
                within[l] = word(e.tn[l] <= cull[l]);
            }
            let mask = e.mask & mask_of(&within) & live;
            if mask != 0 {
                return Some((e.word, mask));
            }
        }
        None
    }
}

/// The best hits of the lanes.
struct Best<const N: usize> {
    t: [f32; N],
    prim: [u32; N],
    part: [u8; N],
    found: [bool; N],
    /// [`Nearest::search_bound`] per lane, and its widening for box entry distances.
    bound: [f32; N],
    cull: [f32; N],
}

impl<const N: usize> Best<N> {
    #[inline(always)]
    fn lane(&self, l: usize) -> Nearest<f32> {
        let part = match self.part[l] {
            0 => Part::Surface,
            1 => Part::CapP1,
            _ => Part::CapP2,
        };
        Nearest { t: self.t[l], prim_ref: PrimRef(self.prim[l]), part, found: self.found[l] }
    }

    #[inline(always)]
    fn set_lane(&mut self, l: usize, n: &Nearest<f32>) {
        self.t[l] = n.t;
        self.prim[l] = n.prim_ref.0;
        self.part[l] = n.part as u8;
        self.found[l] = n.found;
        self.bound[l] = n.search_bound();
        self.cull[l] = widen(self.bound[l]);
    }

    /// [`Nearest::offer`] of primitive `prim` at `t[l]` (part `part[l]`) for lanes `hits`.
    #[inline(always)]
    fn offer(&mut self, hits: u32, prim: u32, t: &[f32; N], part: &[u8; N]) {
        for l in 0..N {
            let on = hits >> l & 1 != 0;
            let take = on && (t[l] < self.t[l] || (t[l] == self.t[l] && prim < self.prim[l]));
            self.t[l] = if take { t[l] } else { self.t[l] };
            self.prim[l] = if take { prim } else { self.prim[l] };
            self.part[l] = if take { part[l] } else { self.part[l] };
            self.found[l] |= take;
            // Nearest::search_bound: the next f32 above t (t > 0 and finite here).
            let bound = f32::from_bits(t[l].to_bits() + 1);
            self.bound[l] = if take { bound } else { self.bound[l] };
            self.cull[l] = if take { widen(bound) } else { self.cull[l] };
        }
    }
}

/// The nearest-hit walk of up to N rays; `K`: the one-ray walk's kernels for the lanes that
/// finish a subtree alone.
#[inline(always)]
fn nearest_n<const N: usize, K: Kernels>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &BundleRays<N>,
    count: usize,
    out: &mut [Nearest<f32>],
) {
    let lanes = Lanes::<N>::new(rays, count);
    let mut best = Best::<N> {
        t: [f32::INFINITY; N],
        prim: [u32::MAX; N],
        part: [0; N],
        found: [false; N],
        bound: [f32::INFINITY; N],
        cull: [f32::INFINITY; N],
    };
    if !prims.planes.is_empty() {
        for l in 0..count {
            let mut n = best.lane(l);
            for r in prims.plane_refs() {
                prims.offer_nearest(r, &lanes.ray(l), 0.0, &mut n);
            }
            best.set_lane(l, &n);
        }
    }
    if !w.is_empty() {
        walk_nearest::<N, K>(w, prims, &lanes, &mut best);
    }
    for (l, o) in out[..count].iter_mut().enumerate() {
        *o = best.lane(l);
    }
}

#[inline(always)]
fn walk_nearest<const N: usize, K: Kernels>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    lanes: &Lanes<N>,
    best: &mut Best<N>,
) {
    let mut stack = Stack::<N>::new();
    let (mut word, mut mask) = (0u32, lanes.on);
    let mut t = [0.0f32; N];
    // Per node: each child's entry distances, and the children entered.
    let mut tn = [[0.0f32; N]; WIDTH];
    let mut entered = [(0u32, 0.0f32, 0usize); WIDTH];
    let mut part = [0u8; N];
    loop {
        if mask.count_ones() <= HYBRID {
            // Few lanes left in this subtree: each finishes it alone.
            let mut m = mask;
            while m != 0 {
                let l = m.trailing_zeros() as usize;
                m &= m - 1;
                let mut n = best.lane(l);
                wide_traverse::nearest_from::<K>(w, prims, &RayPre::new(&lanes.ray(l)), word, &mut n);
                best.set_lane(l, &n);
            }
        } else if word & LEAF_BIT == 0 {
            let node = w.node(word);
            let mut n_in = 0;
            for c in 0..WIDTH {
                if node.child[c] == EMPTY_CHILD {
                    continue;
                }
                let m = lanes.child_box(node, c, &best.cull, &mut tn[c]) & mask;
                if m != 0 {
                    entered[n_in] = (m, tn[c][m.trailing_zeros() as usize], c);
                    n_in += 1;
                }
            }
            if n_in > 0 {
                // Farthest first onto the stack; visit the nearest now.
                let list = &mut entered[..n_in];
                list.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
                for &(m, _, c) in &list[..n_in - 1] {
                    stack.push(Entry { tn: tn[c], word: node.child[c], mask: m });
                }
                let (m, _, c) = list[n_in - 1];
                (word, mask) = (node.child[c], m);
                continue;
            }
        } else {
            leaf_nearest(w, prims, lanes, (word, mask), best, (&mut t, &mut part));
        }
        match stack.pop_within(&best.cull, lanes.on) {
            Some((wd, m)) => (word, mask) = (wd, m),
            None => return,
        }
    }
}

/// Offers to `best` the hits of the lanes of `mask` on the primitives of leaf `word` (`t` and
/// `part`: scratch for the distances and parts each test finds).
#[inline(always)]
fn leaf_nearest<const N: usize>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    lanes: &Lanes<N>,
    (word, mask): (u32, u32),
    best: &mut Best<N>,
    (t, part): (&mut [f32; N], &mut [u8; N]),
) {
    let (blocks, _) = w.leaf(word);
    let surface = [Part::Surface as u8; N];
    for block in blocks {
        for j in 0..LANES {
            let p = block.prim_ref[j];
            if p == EMPTY_PRIM {
                continue;
            }
            let hits = if is_triangle(p) {
                lanes.triangle(block, j, &best.bound, t) & mask
            } else {
                let r = PrimRef(p);
                match r.kind() {
                    PrimKind::Sphere => lanes.sphere(&prims.spheres[r.index()].shape, &best.bound, t) & mask,
                    PrimKind::Cylinder => {
                        let h = lanes.cylinder(&prims.cylinders[r.index()].shape, &best.bound, t, part) & mask;
                        if h != 0 {
                            best.offer(h, p, t, part);
                        }
                        continue;
                    }
                    _ => 0,
                }
            };
            if hits != 0 {
                best.offer(hits, p, t, &surface);
            }
        }
    }
}

/// The occlusion walk of up to N rays: every leaf a live lane's box test enters, until each
/// lane has a hit.
#[inline(always)]
fn occluded_n<const N: usize>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &BundleRays<N>,
    bound: &[f32; N],
    count: usize,
) -> u32 {
    let lanes = Lanes::<N>::new(rays, count);
    let bound = *bound;
    let cull: [f32; N] = std::array::from_fn(|l| widen(bound[l]));
    let mut done = 0u32;
    if !prims.planes.is_empty() {
        for l in 0..count {
            if prims.plane_refs().any(|r| prims.roots(r, &lanes.ray(l), 0.0, bound[l]).len > 0) {
                done |= 1 << l;
            }
        }
    }
    if w.is_empty() || done == lanes.on {
        return done;
    }
    let mut stack = Stack::<N>::new();
    let (mut word, mut mask) = (0u32, lanes.on & !done);
    let mut t = [0.0f32; N];
    let mut part = [0u8; N];
    loop {
        if word & LEAF_BIT == 0 {
            let node = w.node(word);
            let mut tn = [0.0f32; N];
            let mut first: Option<(u32, u32)> = None;
            for c in 0..WIDTH {
                if node.child[c] == EMPTY_CHILD {
                    continue;
                }
                let m = lanes.child_box(node, c, &cull, &mut tn) & mask;
                if m != 0 {
                    // Every child entered is visited: the order does not matter.
                    match first {
                        None => first = Some((node.child[c], m)),
                        Some(_) => stack.push(Entry { tn, word: node.child[c], mask: m }),
                    }
                }
            }
            if let Some((wd, m)) = first {
                (word, mask) = (wd, m);
                continue;
            }
        } else {
            let (blocks, _) = w.leaf(word);
            'blocks: for block in blocks {
                for j in 0..LANES {
                    let p = block.prim_ref[j];
                    if p == EMPTY_PRIM {
                        continue;
                    }
                    let hits = if is_triangle(p) {
                        lanes.triangle(block, j, &bound, &mut t)
                    } else {
                        let r = PrimRef(p);
                        match r.kind() {
                            PrimKind::Sphere => lanes.sphere(&prims.spheres[r.index()].shape, &bound, &mut t),
                            PrimKind::Cylinder => {
                                lanes.cylinder(&prims.cylinders[r.index()].shape, &bound, &mut t, &mut part)
                            }
                            _ => 0,
                        }
                    };
                    done |= hits & mask;
                    mask &= !hits;
                    if mask == 0 {
                        break 'blocks;
                    }
                }
            }
            if done == lanes.on {
                return done;
            }
        }
        match stack.pop_within(&cull, lanes.on & !done) {
            Some((wd, m)) => (word, mask) = (wd, m),
            None => return done,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::accel::Bvh;
    use strahl_core::geometry::testutil::{TestRays, TestRng, ray_f32};
    use strahl_core::math::V3;
    use strahl_core::primitives::Hit;
    use strahl_core::primitives::testutil::mixed_scene;

    /// Random rays (any octant, bundled in arrival order) through spheres, cylinders (capped
    /// and open), triangles and a plane: each lane's nearest hit equals the one-ray walk's,
    /// field for field, and its occlusion answer too, with every lane set this CPU runs and
    /// bundles of every length.
    #[test]
    fn bundles_answer_as_the_one_ray_walk() {
        let prims = mixed_scene(41);
        let w = WideBvh::new(&Bvh::build(&prims), &prims);
        let mut rng = TestRng(42);
        let rays: Vec<Ray<f32>> = (0..6_000).map(|_| ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0))).collect();
        // Inside-out rays too: origins inside the scene's cluster.
        let inner: Vec<Ray<f32>> = (0..2_000).map(|_| ray_f32(&rng.ray_towards(10.0, V3::zero(), 50.0))).collect();
        let rays: Vec<Ray<f32>> = rays.into_iter().chain(inner).collect();
        let want: Vec<Option<Hit<f32>>> =
            rays.iter().map(|r| wide_traverse::nearest(&w, &prims, r, 0.0, f32::INFINITY)).collect();
        let tmax: Vec<f32> = rays.iter().enumerate().map(|(i, _)| [f32::INFINITY, 30.0, 60.0, 90.0][i % 4]).collect();
        let blocked: Vec<bool> =
            rays.iter().zip(&tmax).map(|(r, &t)| wide_traverse::occluded(&w, &prims, r, 0.0, t)).collect();
        let (hits, blocks) = (want.iter().flatten().count(), blocked.iter().filter(|&&b| b).count());
        assert!(hits > 4_000 && hits < 7_900, "{hits} hits: the test would prove little");
        assert!(blocks > 3_000 && blocks < 7_900, "{blocks} blocked");
        let mut caps = 0;
        for isa in Isa::available() {
            let width = isa.width();
            let mut start = 0;
            let mut len = 1;
            while start < rays.len() {
                let end = (start + len).min(rays.len());
                let mut out = vec![Nearest::<f32>::new(0.0); end - start];
                nearest(isa, &w, &prims, &rays[start..end], &mut out);
                for (i, b) in out.iter().enumerate() {
                    let got = b.found.then(|| prims.hit(b.prim_ref, &rays[start + i], b.t, b.part));
                    assert_eq!(got, want[start + i], "{isa:?}: ray {}", start + i);
                    caps += got.is_some_and(|h| h.part != Part::Surface) as usize;
                }
                let m = occluded(isa, &w, &prims, &rays[start..end], &tmax[start..end]);
                for i in 0..end - start {
                    assert_eq!(m >> i & 1 != 0, blocked[start + i], "{isa:?}: shadow ray {}", start + i);
                }
                start = end;
                len = len % width + 1;
            }
        }
        assert!(caps > 10, "{caps} cap hits: the caps went untested");
    }
}
