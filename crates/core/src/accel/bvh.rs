//! Binned SAH BVH build (Wald, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies", 2007), parallel over subtrees with rayon, flattened depth-first into 32-byte
//! nodes.
//!
//! The build works on one array of 32-byte primitive records, partitioned in place. A node
//! bins its primitives' centroids on all three axes in one pass, sweeps the bins for the
//! cheapest split, and partitions the records in a second pass that also gathers both
//! children's bounds, so no pass is spent on bounds alone and nothing is allocated per node.
//! Boxes and bin positions are computed four lanes at a time (`F4`). Nodes of up to
//! 12 primitives are split exactly, all three axes sorted at once by a sorting network;
//! nodes of up to 4 try every split in two. Subtrees below `PARALLEL_THRESHOLD` primitives
//! are built by one thread each, appended to that thread's node arena; the arenas are copied
//! into the depth-first array once at the end, both halves of each split at once.

use crate::math::{Real, V3};
use crate::primitives::{PrimKind, PrimRef, Primitives};
use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;
use std::mem::MaybeUninit;
use std::sync::{Mutex, MutexGuard};

/// One node of the binary tree, 32 bytes: the tree the CPU walks ([`super::traverse`]) and
/// [`super::gpu_bvh`] collapses into the nodes the GPU walks.
///
/// Interior node (`count == 0`): its left child is the next node in the array, its right
/// child is node `left_or_first`. Leaf (`count > 0`): primitives
/// `prim_refs[left_or_first .. left_or_first + count]`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub bmin: [f32; 3],
    pub left_or_first: u32,
    pub bmax: [f32; 3],
    pub count: u32,
}

impl BvhNode {
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// The flattened tree and the primitive order its leaves index.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    pub prim_refs: Vec<PrimRef>,
    /// Longest root-to-leaf path (root = 1); the traversal stack needs at most this many.
    pub depth: u32,
}

/// Deepest tree the build makes (nodes on a root-to-leaf path, the root and the leaf counted);
/// the traversal stacks hold this many (the GPU's one more, for the level
/// [`super::gpu_bvh`] adds where a leaf mixes kinds).
///
/// The bound holds by construction, with small leaves: a node at depth `d` over `n` primitives
/// is split at its median whenever `d` plus the halvings that bring `n` down to [`MAX_LEAF`]
/// ([`levels_to_leaf`]) reaches the bound, so the SAH never leaves more to a subtree than
/// halving can finish within it, and every leaf holds at most `SMALL` primitives (12; at the
/// bound itself, at most [`MAX_LEAF`]). Only pathological inputs (primitives whose sizes or
/// positions grow geometrically, which SAH peels off one by one) get there.
pub const MAX_DEPTH: u32 = 48;
/// Bins per axis for nodes of at least this many primitives; smaller nodes use one bin per
/// primitive, so that the sweep costs no more than the binning pass.
const BINS: usize = 16;
const MAX_LEAF: usize = 4;
/// Cost of visiting a node relative to one primitive test.
const TRAVERSAL_COST: f32 = 1.0;
/// Below this many primitives a subtree is built by one thread.
const PARALLEL_THRESHOLD: usize = 8192;
/// From this many primitives on, a node's binning pass is itself split over threads.
const PARALLEL_BINNING: usize = 1 << 17;

/// Four f32 lanes: an SSE register on x86-64, an array elsewhere. `min` and `max` are those
/// of SSE: `a.min(b)` is `if a < b { a } else { b }`.
///
/// SAFETY of the `unsafe` blocks without a comment of their own: they call SSE and SSE2
/// intrinsics, which every x86-64 processor has.
#[cfg(target_arch = "x86_64")]
mod lanes {
    use std::arch::x86_64::*;

    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct F4(__m128);

    impl F4 {
        #[inline(always)]
        pub fn new(a: [f32; 4]) -> F4 {
            // SAFETY: reads the four floats of `a`.
            F4(unsafe { _mm_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        pub fn splat(v: f32) -> F4 {
            F4(unsafe { _mm_set1_ps(v) })
        }
        #[inline(always)]
        pub fn to_array(self) -> [f32; 4] {
            let mut a = [0.0; 4];
            // SAFETY: writes the four floats of `a`.
            unsafe { _mm_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        /// The first three lanes, the fourth set to 0.
        #[inline(always)]
        pub fn xyz(self) -> F4 {
            F4(unsafe { _mm_and_ps(self.0, _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1))) })
        }
        #[inline(always)]
        pub fn min(self, o: F4) -> F4 {
            F4(unsafe { _mm_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn max(self, o: F4) -> F4 {
            F4(unsafe { _mm_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn add(self, o: F4) -> F4 {
            F4(unsafe { _mm_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn sub(self, o: F4) -> F4 {
            F4(unsafe { _mm_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn mul(self, o: F4) -> F4 {
            F4(unsafe { _mm_mul_ps(self.0, o.0) })
        }
        /// For box extents `e` (lanes x, y, z): `e.x·e.y + e.y·e.z + e.z·e.x`, or 0 if `e.x`
        /// is negative (an empty box).
        #[inline(always)]
        pub fn half_area(self) -> f32 {
            unsafe {
                let e = self.0;
                let p = _mm_mul_ps(e, _mm_shuffle_ps::<0b11_00_10_01>(e, e));
                let s = _mm_add_ss(p, _mm_shuffle_ps::<0b01_01_01_01>(p, p));
                let s = _mm_add_ss(s, _mm_movehl_ps(p, p));
                if _mm_cvtss_f32(e) < 0.0 { 0.0 } else { _mm_cvtss_f32(s) }
            }
        }
        /// Each lane with its four lowest bits replaced by `bits` (< 16).
        #[inline(always)]
        pub fn with_low_bits(self, bits: u32) -> F4 {
            F4(unsafe {
                let kept = _mm_and_ps(self.0, _mm_castsi128_ps(_mm_set1_epi32(!15)));
                _mm_or_ps(kept, _mm_castsi128_ps(_mm_set1_epi32(bits as i32)))
            })
        }
        /// Each lane truncated to an integer; the lanes must lie in [0, 2³¹).
        #[inline(always)]
        pub fn to_u32(self) -> [u32; 4] {
            let mut a = [0u32; 4];
            // SAFETY: writes the four integers of `a`.
            unsafe { _mm_storeu_si128(a.as_mut_ptr().cast(), _mm_cvttps_epi32(self.0)) };
            a
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
mod lanes {
    #[derive(Clone, Copy, Debug)]
    pub struct F4([f32; 4]);

    impl F4 {
        #[inline(always)]
        pub fn new(a: [f32; 4]) -> F4 {
            F4(a)
        }
        #[inline(always)]
        pub fn splat(v: f32) -> F4 {
            F4([v; 4])
        }
        #[inline(always)]
        pub fn to_array(self) -> [f32; 4] {
            self.0
        }
        #[inline(always)]
        pub fn xyz(self) -> F4 {
            F4([self.0[0], self.0[1], self.0[2], 0.0])
        }
        #[inline(always)]
        pub fn min(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| if self.0[k] < o.0[k] { self.0[k] } else { o.0[k] }))
        }
        #[inline(always)]
        pub fn max(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| if self.0[k] > o.0[k] { self.0[k] } else { o.0[k] }))
        }
        #[inline(always)]
        pub fn add(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| self.0[k] + o.0[k]))
        }
        #[inline(always)]
        pub fn sub(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| self.0[k] - o.0[k]))
        }
        #[inline(always)]
        pub fn mul(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| self.0[k] * o.0[k]))
        }
        #[inline(always)]
        pub fn half_area(self) -> f32 {
            let e = self.0;
            if e[0] < 0.0 { 0.0 } else { e[0] * e[1] + e[1] * e[2] + e[2] * e[0] }
        }
        #[inline(always)]
        pub fn with_low_bits(self, bits: u32) -> F4 {
            F4(self.0.map(|v| f32::from_bits(v.to_bits() & !15 | bits)))
        }
        #[inline(always)]
        pub fn to_u32(self) -> [u32; 4] {
            self.0.map(|v| v as u32)
        }
    }
}

use lanes::F4;

/// A box with a fourth lane of padding, so that growing one is two 4-lane min/max.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: F4,
    hi: F4,
}

impl Aabb {
    #[inline(always)]
    fn empty() -> Aabb {
        Aabb { lo: F4::splat(f32::INFINITY), hi: F4::splat(f32::NEG_INFINITY) }
    }
    #[inline(always)]
    fn grow(&mut self, lo: F4, hi: F4) {
        self.lo = lo.min(self.lo);
        self.hi = hi.max(self.hi);
    }
    #[inline(always)]
    fn grow_box(&mut self, o: &Aabb) {
        self.grow(o.lo, o.hi);
    }
    /// Half the surface area (the SAH only compares ratios); 0 for the empty box.
    #[inline(always)]
    fn half_area(&self) -> f32 {
        self.hi.sub(self.lo).half_area()
    }
    fn lo3(&self) -> [f32; 3] {
        let a = self.lo.to_array();
        [a[0], a[1], a[2]]
    }
    fn hi3(&self) -> [f32; 3] {
        let a = self.hi.to_array();
        [a[0], a[1], a[2]]
    }
}

/// Rounds f64 bounds outward to f32, so the f32 box contains the exact primitive.
fn outward(lo: V3<f64>, hi: V3<f64>) -> ([f32; 4], [f32; 4]) {
    let down = |v: f64| {
        let f = v as f32;
        if f as f64 > v { f.next_down() } else { f }
    };
    let up = |v: f64| {
        let f = v as f32;
        if (f as f64) < v { f.next_up() } else { f }
    };
    ([down(lo.x), down(lo.y), down(lo.z), 0.0], [up(hi.x), up(hi.y), up(hi.z), 0.0])
}

/// One primitive during the build: its box (the fourth lanes: the reference's bits, and 0).
/// Its centroid, doubled, is `lo + hi`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Item {
    lo: [f32; 4],
    hi: [f32; 4],
}

impl Item {
    #[inline(always)]
    fn prim(&self) -> PrimRef {
        PrimRef(self.lo[3].to_bits())
    }
    /// The box; the fourth lanes 0 (the reference's bits stay out of the arithmetic).
    #[inline(always)]
    fn lanes(&self) -> (F4, F4) {
        (F4::new(self.lo).xyz(), F4::new(self.hi))
    }
    #[inline(always)]
    fn centroid2(&self, axis: usize) -> f32 {
        self.lo[axis] + self.hi[axis]
    }
}

/// A range of items with the box of their boxes and the box of their doubled centroids.
#[derive(Clone, Copy, Debug)]
struct Span {
    bounds: Aabb,
    centroids: Aabb,
}

impl Span {
    #[inline(always)]
    fn empty() -> Span {
        Span { bounds: Aabb::empty(), centroids: Aabb::empty() }
    }
    #[inline(always)]
    fn add(&mut self, it: &Item) {
        let (lo, hi) = it.lanes();
        self.bounds.grow(lo, hi);
        let c = lo.add(hi);
        self.centroids.grow(c, c);
    }
    fn join(mut self, o: &Span) -> Span {
        self.bounds.grow_box(&o.bounds);
        self.centroids.grow_box(&o.centroids);
        self
    }
    fn of(items: &[Item]) -> Span {
        let mut s = Span::empty();
        for it in items {
            s.add(it);
        }
        s
    }
}

/// Per axis and bin: the bins' boxes and counts (set 0; set 1 is scratch for binning).
struct Bins {
    n: usize,
    boxes: [[[Aabb; BINS]; 3]; 2],
    counts: [[[u32; BINS]; 3]; 2],
}

/// Maps a doubled centroid to its bin on each axis (fourth lanes: scale 0).
#[derive(Clone, Copy)]
struct Binning {
    n: usize,
    lo: F4,
    scale: F4,
    /// The last bin, n − 1.
    top: F4,
    /// Whether the centroids spread on each axis (a zero scale otherwise).
    spread: [bool; 3],
    scale3: [f32; 3],
    lo3: [f32; 3],
}

impl Binning {
    fn new(centroids: &Aabb, count: usize) -> Binning {
        let n = count.clamp(2, BINS);
        let (lo, hi) = (centroids.lo.to_array(), centroids.hi.to_array());
        let scale3: [f32; 3] = std::array::from_fn(|a| {
            let extent = hi[a] - lo[a];
            // Just under n/extent, so that the largest centroid lands in bin n − 1.
            if extent > 0.0 { n as f32 * (1.0 - 1e-6) / extent } else { 0.0 }
        });
        let lo3 = [lo[0], lo[1], lo[2]];
        Binning {
            n,
            lo: F4::new([lo[0], lo[1], lo[2], 0.0]),
            scale: F4::new([scale3[0], scale3[1], scale3[2], 0.0]),
            top: F4::splat((n - 1) as f32),
            spread: scale3.map(|s| s != 0.0),
            scale3,
            lo3,
        }
    }

    /// The bins of doubled centroid `c` on the three axes. The position is clamped to
    /// [0, n − 1] before the conversion (so that it is in range, NaN included, impossible
    /// here); it is below bin k exactly when it is below k before the clamp.
    #[inline(always)]
    fn bins(&self, c: F4) -> [u32; 4] {
        c.sub(self.lo).mul(self.scale).max(F4::splat(0.0)).min(self.top).to_u32()
    }

    /// Whether `it` falls into a bin below `split` on `axis`: the position of [`Self::bins`]
    /// (the same operations, so the same rounding) compared before truncation.
    #[inline(always)]
    fn below(&self, it: &Item, axis: usize, split: f32) -> bool {
        (it.centroid2(axis) - self.lo3[axis]) * self.scale3[axis] < split
    }

    /// Bins `items` into `b` (only its first `n` bins are reset and used). Items alternate
    /// between two sets of bins, merged at the end: neighbouring items often fall into the
    /// same bin, and one set would make each update wait for the previous one's store.
    fn fill_into(&self, items: &[Item], b: &mut Bins) {
        b.n = self.n;
        for set in 0..2 {
            for axis in 0..3 {
                b.boxes[set][axis][..self.n].fill(Aabb::empty());
                b.counts[set][axis][..self.n].fill(0);
            }
        }
        #[inline(always)]
        fn add(binning: &Binning, b: &mut Bins, set: usize, it: &Item) {
            let (lo, hi) = it.lanes();
            let k = binning.bins(lo.add(hi));
            for axis in 0..3 {
                // The mask changes nothing (k < n ≤ BINS) and spares the bounds check.
                let k = k[axis] as usize & (BINS - 1);
                b.boxes[set][axis][k].grow(lo, hi);
                b.counts[set][axis][k] += 1;
            }
        }
        let mut pairs = items.chunks_exact(2);
        for pair in &mut pairs {
            add(self, b, 0, &pair[0]);
            add(self, b, 1, &pair[1]);
        }
        if let [it] = pairs.remainder() {
            add(self, b, 0, it);
        }
        for axis in 0..3 {
            for k in 0..self.n {
                let (second_box, second_count) = (b.boxes[1][axis][k], b.counts[1][axis][k]);
                b.boxes[0][axis][k].grow_box(&second_box);
                b.counts[0][axis][k] += second_count;
            }
        }
    }

    fn fill(&self, items: &[Item]) -> Box<Bins> {
        let mut b = Bins::new();
        self.fill_into(items, &mut b);
        b
    }
}

impl Bins {
    fn new() -> Box<Bins> {
        Box::new(Bins { n: 0, boxes: [[[Aabb::empty(); BINS]; 3]; 2], counts: [[[0; BINS]; 3]; 2] })
    }

    fn merge(mut self: Box<Bins>, o: &Bins) -> Box<Bins> {
        for axis in 0..3 {
            for k in 0..self.n {
                self.boxes[0][axis][k].grow_box(&o.boxes[0][axis][k]);
                self.counts[0][axis][k] += o.counts[0][axis][k];
            }
        }
        self
    }

    /// The cheapest split (axis, first bin of the right side, SAH cost in primitive tests
    /// per ray reaching the node), over axes whose centroids spread.
    fn best(&self, binning: &Binning, parent_half_area: f32) -> Option<(usize, usize, f32)> {
        let n = self.n;
        let mut best: Option<(usize, usize, f32)> = None;
        let inv_parent = 1.0 / parent_half_area.max(f32::MIN_POSITIVE);
        for axis in 0..3 {
            if !binning.spread[axis] {
                continue;
            }
            let (boxes, counts) = (&self.boxes[0][axis], &self.counts[0][axis]);
            // Right-to-left sweep: area and count of bins k.. for each k.
            let mut right = [(0.0f32, 0u32); BINS];
            let (mut acc, mut cnt) = (Aabb::empty(), 0);
            for k in (1..n).rev() {
                acc.grow_box(&boxes[k]);
                cnt += counts[k];
                right[k] = (acc.half_area(), cnt);
            }
            let (mut acc, mut cnt) = (Aabb::empty(), 0);
            for k in 1..n {
                acc.grow_box(&boxes[k - 1]);
                cnt += counts[k - 1];
                let (right_area, right_count) = right[k];
                if cnt == 0 || right_count == 0 {
                    continue;
                }
                let cost =
                    TRAVERSAL_COST + (acc.half_area() * cnt as f32 + right_area * right_count as f32) * inv_parent;
                if best.is_none_or(|b| cost < b.2) {
                    best = Some((axis, k, cost));
                }
            }
        }
        best
    }
}

/// Moves the items of bins below `split` on `axis` to the front; returns how many there are
/// and the spans of both sides.
fn partition(items: &mut [Item], binning: &Binning, axis: usize, split: usize) -> (usize, Span, Span) {
    let split = split as f32;
    let (mut left, mut right) = (Span::empty(), Span::empty());
    let (mut i, mut j) = (0, items.len());
    loop {
        while i < j && binning.below(&items[i], axis, split) {
            left.add(&items[i]);
            i += 1;
        }
        while i < j && !binning.below(&items[j - 1], axis, split) {
            right.add(&items[j - 1]);
            j -= 1;
        }
        if i >= j {
            break;
        }
        items.swap(i, j - 1);
        left.add(&items[i]);
        right.add(&items[j - 1]);
        i += 1;
        j -= 1;
    }
    (i, left, right)
}

/// What to do with a node: a leaf, or children over items[..mid] and items[mid..].
enum Decision {
    Leaf,
    Split { mid: usize, left: Span, right: Span },
}

/// Nodes of at most this many primitives are split exactly instead of by binning: an exact
/// SAH sweep over so few primitives costs less than resetting and sweeping bins.
const SMALL: usize = 12;

/// Sorting networks for 8 and 12 keys: Batcher's odd–even merge sort for 16, cut to the
/// first 8 or 12 inputs, each comparator dropped that the 0-1 principle shows redundant (19
/// and 41 comparators; the least known are 19 and 39). Fewer keys are padded with +∞.
#[rustfmt::skip]
const NET8: [(u8, u8); 19] = [
    (0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (1, 2), (5, 6),
    (0, 4), (1, 5), (2, 6), (3, 7), (2, 4), (3, 5), (1, 2), (3, 4), (5, 6),
];
#[rustfmt::skip]
const NET12: [(u8, u8); 41] = [
    (0, 1), (2, 3), (4, 5), (6, 7), (8, 9), (10, 11), (0, 2), (1, 3), (4, 6), (5, 7),
    (8, 10), (9, 11), (1, 2), (5, 6), (9, 10), (0, 4), (1, 5), (2, 6), (3, 7), (2, 4),
    (3, 5), (1, 2), (3, 4), (5, 6), (0, 8), (1, 9), (2, 10), (3, 11), (4, 8), (5, 9),
    (6, 10), (7, 11), (2, 4), (3, 5), (6, 8), (7, 9), (1, 2), (3, 4), (5, 6), (7, 8),
    (9, 10),
];

/// Sorts `keys` lane by lane with `net`. The keys must be distinct: a comparator keeps the
/// second of two equal keys on both sides.
#[inline(always)]
fn sort_lanes<const N: usize>(keys: &mut [F4; SMALL], net: &[(u8, u8); N]) {
    for &(a, b) in net {
        let (x, y) = (keys[a as usize], keys[b as usize]);
        keys[a as usize] = x.min(y);
        keys[b as usize] = x.max(y);
    }
}

/// The exact-SAH decision for a node of MAX_LEAF + 1 ..= SMALL primitives: per axis the primitives are
/// ordered by centroid and every split position is evaluated; the items end up in the order
/// of the chosen axis.
///
/// The three axes are sorted at once, one per lane, by a sorting network. A key is the
/// doubled centroid with its four lowest mantissa bits replaced by the item's index + 1:
/// distinct keys (none ±0) that carry their item along, in the order of the centroids but
/// for those less than 16 ulps apart, which may come out in either order.
fn decide_small(items: &mut [Item], span: &Span) -> Decision {
    let n = items.len();
    debug_assert!((MAX_LEAF + 1..=SMALL).contains(&n));
    let inv_parent = 1.0 / span.bounds.half_area().max(f32::MIN_POSITIVE);
    let (clo, chi) = (span.centroids.lo.to_array(), span.centroids.hi.to_array());
    let mut keys = [F4::splat(f32::INFINITY); SMALL];
    for (k, (key, it)) in keys.iter_mut().zip(items.iter()).enumerate() {
        let (lo, hi) = it.lanes();
        *key = lo.add(hi).with_low_bits(k as u32 + 1);
    }
    match n {
        ..=8 => sort_lanes(&mut keys, &NET8),
        _ => sort_lanes(&mut keys, &NET12),
    }
    let sorted = keys.map(F4::to_array);
    let mut orders = [[0u8; SMALL]; 3];
    let mut best: Option<(usize, usize, f32)> = None;
    for (axis, order) in orders.iter_mut().enumerate() {
        if !(chi[axis] > clo[axis]) {
            continue;
        }
        for (o, key) in order[..n].iter_mut().zip(&sorted) {
            *o = (key[axis].to_bits() & 15) as u8 - 1;
        }
        let order = &order[..n];
        let mut right = [0.0f32; SMALL];
        let mut acc = Aabb::empty();
        for k in (1..n).rev() {
            let (lo, hi) = items[order[k] as usize].lanes();
            acc.grow(lo, hi);
            right[k] = acc.half_area();
        }
        let mut acc = Aabb::empty();
        for k in 1..n {
            let (lo, hi) = items[order[k - 1] as usize].lanes();
            acc.grow(lo, hi);
            let cost = TRAVERSAL_COST + (acc.half_area() * k as f32 + right[k] * (n - k) as f32) * inv_parent;
            if best.is_none_or(|b| cost < b.2) {
                best = Some((axis, k, cost));
            }
        }
    }
    // Too many primitives for a leaf: split even where no split pays for itself.
    let (axis, mid) = match best {
        Some((axis, mid, _)) => (axis, mid),
        // All centroids coincide: split the list in halves.
        None => {
            let mid = n / 2;
            return Decision::Split { mid, left: Span::of(&items[..mid]), right: Span::of(&items[mid..]) };
        }
    };
    let mut sorted = [items[0]; SMALL];
    for (k, &o) in orders[axis][..n].iter().enumerate() {
        sorted[k] = items[o as usize];
    }
    items.copy_from_slice(&sorted[..n]);
    Decision::Split { mid, left: Span::of(&items[..mid]), right: Span::of(&items[mid..]) }
}

/// The decision for a node of 2..=MAX_LEAF primitives, among every way to split them in
/// two (1, 3 and 7 for 2, 3 and 4 primitives): those of [`decide_small`], which follow
/// a centroid order, and a few more, so never a costlier split. As there, a leaf if no
/// split pays for itself or the centroids coincide.
fn decide_tiny(items: &mut [Item], span: &Span) -> Decision {
    /// The left sides (bit k: item k) of the splits of 2, 3 and 4 items.
    const SIDES: [&[u8]; MAX_LEAF + 1] =
        [&[], &[], &[0b1], &[0b1, 0b10, 0b100], &[0b1, 0b10, 0b100, 0b1000, 0b11, 0b101, 0b1001]];
    let n = items.len();
    debug_assert!((2..=MAX_LEAF).contains(&n));
    let (clo, chi) = (span.centroids.lo.to_array(), span.centroids.hi.to_array());
    if !(0..3).any(|a| chi[a] > clo[a]) {
        return Decision::Leaf;
    }
    let inv_parent = 1.0 / span.bounds.half_area().max(f32::MIN_POSITIVE);
    let boxes: [(F4, F4); MAX_LEAF] = std::array::from_fn(|k| items[k.min(n - 1)].lanes());
    let mut best = (f32::INFINITY, 0u8);
    for &side in SIDES[n] {
        let (mut l, mut r) = (Aabb::empty(), Aabb::empty());
        for (k, &(lo, hi)) in boxes[..n].iter().enumerate() {
            if side >> k & 1 != 0 { l.grow(lo, hi) } else { r.grow(lo, hi) }
        }
        let nl = side.count_ones();
        let cost = TRAVERSAL_COST + (l.half_area() * nl as f32 + r.half_area() * (n as u32 - nl) as f32) * inv_parent;
        if cost < best.0 {
            best = (cost, side);
        }
    }
    let (cost, side) = best;
    if cost >= n as f32 {
        return Decision::Leaf;
    }
    // The left side first, each side in its present order.
    let mut sorted = [items[0]; MAX_LEAF];
    let mut at = 0;
    for left in [true, false] {
        for (k, it) in items.iter().enumerate() {
            if (side >> k & 1 != 0) == left {
                sorted[at] = *it;
                at += 1;
            }
        }
    }
    items.copy_from_slice(&sorted[..n]);
    let mid = side.count_ones() as usize;
    Decision::Split { mid, left: Span::of(&items[..mid]), right: Span::of(&items[mid..]) }
}

/// How many halvings bring `n` primitives down to at most [`MAX_LEAF`]: ceil(log2(ceil(n / 4))).
fn levels_to_leaf(n: usize) -> u32 {
    n.div_ceil(MAX_LEAF).next_power_of_two().trailing_zeros()
}

/// The split of `items` at the median of their centroids on the axis where the centroids
/// spread widest: the halves differ by at most one, so each needs one level fewer
/// ([`levels_to_leaf`]).
fn median_split(items: &mut [Item], span: &Span) -> Decision {
    let (clo, chi) = (span.centroids.lo.to_array(), span.centroids.hi.to_array());
    let axis = (0..3).max_by(|&a, &b| (chi[a] - clo[a]).total_cmp(&(chi[b] - clo[b]))).unwrap_or(0);
    let key = |it: &Item| it.lo[axis] + it.hi[axis];
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| key(a).total_cmp(&key(b)));
    Decision::Split { mid, left: Span::of(&items[..mid]), right: Span::of(&items[mid..]) }
}

/// Chooses between a leaf and the best split of `items` at `depth`; `scratch` holds the bins.
fn decide(items: &mut [Item], span: &Span, depth: u32, scratch: &mut Bins) -> Decision {
    let n = items.len();
    if n <= 1 {
        return Decision::Leaf;
    }
    if n <= MAX_LEAF {
        // At the depth bound a leaf, else the best split of a few.
        return if depth >= MAX_DEPTH { Decision::Leaf } else { decide_tiny(items, span) };
    }
    // No slack left below: halve, so the subtree ends within MAX_DEPTH (see there).
    if depth + levels_to_leaf(n) >= MAX_DEPTH {
        return median_split(items, span);
    }
    if n <= SMALL {
        return decide_small(items, span);
    }
    let binning = Binning::new(&span.centroids, n);
    let merged;
    let bins: &Bins = if n >= PARALLEL_BINNING {
        merged = items
            .par_chunks(PARALLEL_BINNING / 4)
            .map(|chunk| binning.fill(chunk))
            .reduce_with(|a, b| a.merge(&b))
            .expect("a node has items");
        &merged
    } else {
        binning.fill_into(items, scratch);
        scratch
    };
    // Nodes this large (more than SMALL primitives) are always split.
    match bins.best(&binning, span.bounds.half_area()) {
        Some((axis, split, _)) => {
            let (mid, left, right) = partition(items, &binning, axis, split);
            Decision::Split { mid, left, right }
        }
        // All centroids coincide: split the list in halves.
        None => {
            let mid = n / 2;
            let (left, right) = (Span::of(&items[..mid]), Span::of(&items[mid..]));
            Decision::Split { mid, left, right }
        }
    }
}

fn node_of(bounds: &Aabb, left_or_first: u32, count: u32) -> BvhNode {
    BvhNode { bmin: bounds.lo3(), left_or_first, bmax: bounds.hi3(), count }
}

/// Builds the subtree over `items` (starting at `offset` in the final primitive order) on
/// this thread, appending its nodes depth-first to `out` (right-child indices relative to
/// index `start` of `out`); returns its depth.
fn build_serial(
    items: &mut [Item],
    offset: usize,
    span: &Span,
    depth: u32,
    start: usize,
    out: &mut Vec<BvhNode>,
    scratch: &mut Bins,
) -> u32 {
    match decide(items, span, depth, scratch) {
        Decision::Leaf => {
            out.push(node_of(&span.bounds, offset as u32, items.len() as u32));
            depth
        }
        Decision::Split { mid, left, right } => {
            let me = out.len();
            out.push(node_of(&span.bounds, 0, 0));
            let (l, r) = items.split_at_mut(mid);
            let dl = build_serial(l, offset, &left, depth + 1, start, out, scratch);
            out[me].left_or_first = (out.len() - start) as u32;
            let dr = build_serial(r, offset + mid, &right, depth + 1, start, out, scratch);
            dl.max(dr)
        }
    }
}

/// A subtree built in parallel: its top nodes, and below them subtrees built serially, each
/// into the node arena of the thread that built it.
enum Part {
    /// `len` nodes from `start` in arena `arena` (right-child indices relative to `start`).
    Serial { arena: usize, start: usize, len: usize, depth: u32 },
    /// `len`: the nodes of the whole part, this one included.
    Split { node: BvhNode, len: usize, left: Box<Part>, right: Box<Part> },
}

/// One node array per thread, to which the subtrees it builds serially are appended: the
/// nodes are written once into memory that grows in large steps (advised for huge pages),
/// instead of into an array per subtree; [`Part::flatten`] then copies them into place.
struct Arenas(Vec<Mutex<Vec<BvhNode>>>);

impl Arenas {
    fn new(items: usize) -> Arenas {
        let threads = rayon::current_num_threads();
        // Trees have about 1.1 nodes per primitive; an arena that runs out grows.
        let each = items / threads * 5 / 4 + 1024;
        Arenas((0..threads).map(|_| Mutex::new(super::huge_pages::vec_with_capacity(each))).collect())
    }

    /// This thread's arena. Any thread may use any arena; the lock only makes that safe.
    fn mine(&self) -> (usize, MutexGuard<'_, Vec<BvhNode>>) {
        let k = rayon::current_thread_index().unwrap_or(0) % self.0.len();
        (k, self.0[k].lock().unwrap_or_else(|e| e.into_inner()))
    }
}

fn build_parallel(items: &mut [Item], offset: usize, span: &Span, depth: u32, arenas: &Arenas) -> Part {
    if items.len() < PARALLEL_THRESHOLD {
        let (arena, mut out) = arenas.mine();
        let start = out.len();
        let depth = build_serial(items, offset, span, depth, start, &mut out, &mut Bins::new());
        return Part::Serial { arena, start, len: out.len() - start, depth };
    }
    match decide(items, span, depth, &mut Bins::new()) {
        Decision::Leaf => {
            let (arena, mut out) = arenas.mine();
            out.push(node_of(&span.bounds, offset as u32, items.len() as u32));
            Part::Serial { arena, start: out.len() - 1, len: 1, depth }
        }
        Decision::Split { mid, left, right } => {
            let (l, r) = items.split_at_mut(mid);
            let (pl, pr) = rayon::join(
                || build_parallel(l, offset, &left, depth + 1, arenas),
                || build_parallel(r, offset + mid, &right, depth + 1, arenas),
            );
            let len = 1 + pl.len() + pr.len();
            Part::Split { node: node_of(&span.bounds, 0, 0), len, left: Box::new(pl), right: Box::new(pr) }
        }
    }
}

impl Part {
    fn len(&self) -> usize {
        match self {
            Part::Serial { len, .. } | Part::Split { len, .. } => *len,
        }
    }

    fn depth(&self) -> u32 {
        match self {
            Part::Serial { depth, .. } => *depth,
            Part::Split { left, right, .. } => left.depth().max(right.depth()),
        }
    }

    /// Writes the part depth-first into `out` (its `len()` nodes, the first at index `base`
    /// of the whole tree), right-child indices made absolute; both halves of a split at once.
    fn flatten(&self, arenas: &[Vec<BvhNode>], base: usize, out: &mut [MaybeUninit<BvhNode>]) {
        match self {
            Part::Serial { arena, start, len, .. } => {
                for (o, n) in out.iter_mut().zip(&arenas[*arena][*start..start + len]) {
                    let mut n = *n;
                    if !n.is_leaf() {
                        n.left_or_first += base as u32;
                    }
                    o.write(n);
                }
            }
            Part::Split { node, left, right, .. } => {
                let (me, rest) = out.split_first_mut().expect("a split has a node");
                let (l, r) = rest.split_at_mut(left.len());
                let right_base = base + 1 + left.len();
                me.write(BvhNode { left_or_first: right_base as u32, ..*node });
                rayon::join(|| left.flatten(arenas, base + 1, l), || right.flatten(arenas, right_base, r));
            }
        }
    }
}

impl Bvh {
    /// Builds over every bounded primitive of `prims` (planes stay outside).
    pub fn build<R: Real>(prims: &Primitives<R>) -> Bvh {
        let count = prims.bounded_count();
        let mut items: Vec<Item> = super::huge_pages::vec_with_capacity(count);
        items.par_extend((0..count).into_par_iter().with_min_len(4096).map(|i| {
            let prim = prims.bounded_ref(i);
            let (lo, hi) = match prim.kind() {
                // Min and max are exact, so only the conversion to f32 rounds.
                PrimKind::Triangle => {
                    let v = &prims.triangles[prim.index()].shape.v;
                    let lo = v[0].min_elem(v[1]).min_elem(v[2]).to_f64();
                    let hi = v[0].max_elem(v[1]).max_elem(v[2]).to_f64();
                    outward(lo, hi)
                }
                _ => {
                    let (lo, hi) = prims.bounds_f64(prim);
                    outward(lo, hi)
                }
            };
            Item { lo: [lo[0], lo[1], lo[2], f32::from_bits(prim.0)], hi }
        }));
        if items.is_empty() {
            return Bvh::default();
        }
        let span = items.par_chunks(1 << 16).map(Span::of).reduce(Span::empty, |a, b| a.join(&b));
        let arenas = Arenas::new(items.len());
        let root = build_parallel(&mut items, 0, &span, 1, &arenas);
        let arenas: Vec<Vec<BvhNode>> =
            arenas.0.into_iter().map(|a| a.into_inner().unwrap_or_else(|e| e.into_inner())).collect();
        let mut nodes = super::huge_pages::vec_with_capacity(root.len());
        root.flatten(&arenas, 0, &mut nodes.spare_capacity_mut()[..root.len()]);
        // SAFETY: `flatten` wrote each of the part's `len()` nodes.
        unsafe { nodes.set_len(root.len()) };
        let mut prim_refs = super::huge_pages::vec_with_capacity(items.len());
        prim_refs.par_extend(items.par_iter().map(Item::prim));
        Bvh { nodes, prim_refs, depth: root.depth() }
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The tree's SAH cost, in the builder's units (one primitive test = 1, one node visit =
    /// `TRAVERSAL_COST`): Σ over interior nodes of A(node)/A(root)·`TRAVERSAL_COST` plus Σ
    /// over leaves of A(leaf)/A(root)·(primitives in it), the expected work of a ray that
    /// enters the root box (MacDonald & Booth, "Heuristics for ray tracing using space
    /// subdivision", 1990). 0 for an empty tree.
    pub fn sah_cost(&self) -> f64 {
        let area = |n: &BvhNode| {
            let lo = [n.bmin[0], n.bmin[1], n.bmin[2], 0.0];
            let hi = [n.bmax[0], n.bmax[1], n.bmax[2], 0.0];
            Aabb { lo: F4::new(lo), hi: F4::new(hi) }.half_area() as f64
        };
        let Some(root) = self.nodes.first() else { return 0.0 };
        let root_area = area(root).max(f64::MIN_POSITIVE);
        self.nodes
            .iter()
            .map(|n| area(n) / root_area * if n.is_leaf() { n.count as f64 } else { TRAVERSAL_COST as f64 })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::testutil::{TestRays, TestRng};
    use crate::geometry::{Sphere, Triangle};
    use crate::primitives::{Tag, Tagged};

    fn random_triangles(n: usize, seed: u64) -> Primitives<f32> {
        let mut rng = TestRng(seed);
        let mut p = Primitives::default();
        for i in 0..n {
            let c = rng.in_cube(50.0);
            let tri = Triangle { v: [0, 1, 2].map(|_| c + rng.in_cube(1.0)) };
            p.triangles.push(Tagged { shape: tri.cast(), tag: Tag { object: 0, face: i as u32, material: 0 } });
        }
        p
    }

    /// The deepest leaf and the most primitives in one leaf (in any, and in a leaf at the
    /// depth bound).
    fn leaf_stats(bvh: &Bvh) -> (u32, u32, u32) {
        let (mut deepest, mut largest, mut largest_at_bound) = (0, 0, 0);
        let mut stack = vec![(0usize, 1u32)];
        while let Some((i, d)) = stack.pop() {
            let n = &bvh.nodes[i];
            if n.is_leaf() {
                deepest = deepest.max(d);
                largest = largest.max(n.count);
                if d == MAX_DEPTH {
                    largest_at_bound = largest_at_bound.max(n.count);
                }
            } else {
                stack.extend([(i + 1, d + 1), (n.left_or_first as usize, d + 1)]);
            }
        }
        (deepest, largest, largest_at_bound)
    }

    /// A chain that SAH peels off one primitive at a time, ending in identical triangles
    /// ([`crate::scene::procedural::deep_chain_triangles`]): the tree stays within MAX_DEPTH
    /// with small leaves, and its walk returns what brute force does. (Before the bound was
    /// kept by construction, the chain of 43 over 3000 copies reached depth 48 with a leaf of
    /// 94 primitives there, which the GPU's collapse split into three more levels.)
    #[test]
    fn a_pathologically_deep_input_keeps_the_depth_bound_with_small_leaves() {
        for (chain, cluster) in [(43, 0), (43, 100), (43, 3000), (30, 100_000)] {
            let mut prims = Primitives::<f64>::default();
            for (i, t) in crate::scene::procedural::deep_chain_triangles(chain, cluster).into_iter().enumerate() {
                prims.triangles.push(Tagged { shape: t, tag: Tag { object: 0, face: i as u32, material: 0 } });
            }
            let prims: Primitives<f32> = prims.cast();
            let bvh = Bvh::build(&prims);
            let (deepest, largest, at_bound) = leaf_stats(&bvh);
            eprintln!(
                "chain {chain}, cluster {cluster}: depth {deepest}, leaves up to {largest}, at the bound {at_bound}"
            );
            assert!(deepest <= MAX_DEPTH && bvh.depth == deepest, "depth {deepest} (recorded {})", bvh.depth);
            assert!(
                largest as usize <= SMALL && at_bound as usize <= MAX_LEAF,
                "leaves of {largest}, {at_bound} at the bound"
            );
            let mut rng = TestRng(9);
            for _ in 0..200 {
                // In the plane x = 0 the rays enter the boxes of the whole chain; off it, some.
                let x = if rng.unit() < 0.5 { 0.0 } else { rng.range(0.0, 1.0).powi(20) };
                let o = V3::new(x, rng.range(0.0, 1.0), -1.0);
                let ray =
                    crate::math::Ray::new(o.cast(), (V3::new(x, rng.range(0.0, 1.0), 1.0) - o).normalize().cast());
                assert_eq!(
                    super::super::traverse::nearest(&bvh, &prims, &ray, 0.0, f32::INFINITY),
                    prims.nearest_brute(&ray, 0.0, f32::INFINITY)
                );
            }
        }
    }

    #[test]
    fn every_primitive_is_in_exactly_one_leaf_inside_its_bounds() {
        // The larger scene is built by several threads, in parts joined at the end.
        for n in [5000, 40_000] {
            let mut prims = random_triangles(n, 1);
            prims
                .spheres
                .push(Tagged { shape: Sphere { center: V3::new(1.0, 2.0, 3.0), radius: 0.5 }, tag: Tag::default() });
            let bvh = Bvh::build(&prims);
            let mut seen = vec![0u32; bvh.prim_refs.len()];
            // Walked from the root: every node is reached once, leaves cover every primitive
            // once, children lie inside their parent, the depth is the longest path.
            let mut reached = 0;
            let mut depth = 0;
            let mut stack = vec![(0usize, 1u32)];
            while let Some((i, d)) = stack.pop() {
                let node = bvh.nodes[i];
                reached += 1;
                depth = depth.max(d);
                if node.is_leaf() {
                    for k in node.left_or_first..node.left_or_first + node.count {
                        seen[k as usize] += 1;
                        let (lo, hi) = prims.bounds_f64(bvh.prim_refs[k as usize]);
                        for a in 0..3 {
                            assert!(node.bmin[a] as f64 <= lo[a] && hi[a] <= node.bmax[a] as f64);
                        }
                    }
                } else {
                    for c in [i + 1, node.left_or_first as usize] {
                        for a in 0..3 {
                            assert!(node.bmin[a] <= bvh.nodes[c].bmin[a] && bvh.nodes[c].bmax[a] <= node.bmax[a]);
                        }
                        stack.push((c, d + 1));
                    }
                }
            }
            assert_eq!(reached, bvh.nodes.len());
            assert_eq!(depth, bvh.depth);
            assert!(seen.iter().all(|&s| s == 1));
            let mut refs: Vec<u32> = bvh.prim_refs.iter().map(|r| r.0).collect();
            refs.sort();
            assert!(refs == prims.bounded_refs().map(|r| r.0).collect::<Vec<_>>());
            assert!(bvh.depth <= MAX_DEPTH);
            // A SAH tree over uniformly scattered triangles is shallow.
            assert!(bvh.depth < 30, "depth {}", bvh.depth);
        }
    }

    #[test]
    fn identical_primitives_still_build() {
        let mut p = Primitives::<f32>::default();
        for _ in 0..100 {
            p.spheres.push(Tagged { shape: Sphere { center: V3::zero(), radius: 1.0 }, tag: Tag::default() });
        }
        let bvh = Bvh::build(&p);
        assert!(bvh.nodes.iter().filter(|n| n.is_leaf()).all(|n| n.count <= MAX_LEAF as u32));
    }

    #[test]
    fn empty_scene_builds_an_empty_tree() {
        assert!(Bvh::build(&Primitives::<f32>::default()).is_empty());
    }

    /// By the 0-1 principle a comparator network sorts every input if it sorts every input
    /// of zeros and ones.
    #[test]
    fn sorting_networks_sort_every_input_of_zeros_and_ones() {
        fn sorts<const N: usize>(net: &[(u8, u8); N], inputs: usize) -> bool {
            (0u32..1 << inputs).all(|bits| {
                let mut keys = [F4::splat(f32::INFINITY); SMALL];
                for (k, key) in keys[..inputs].iter_mut().enumerate() {
                    // Lane 0: the bit; lanes 1–3: its complement, sorted as well.
                    let b = (bits >> k & 1) as f32;
                    *key = F4::new([b, 1.0 - b, b, 1.0 - b]);
                }
                sort_lanes(&mut keys, net);
                let sorted = keys.map(F4::to_array);
                (1..inputs).all(|k| (0..4).all(|lane| sorted[k - 1][lane] <= sorted[k][lane]))
            })
        }
        assert!(sorts(&NET8, 8) && sorts(&NET12, 12));
        // Fewer keys than inputs, padded with +∞ as `decide_small` pads them.
        assert!(sorts(&NET8, 5) && sorts(&NET12, 9));
        // A network cut short does not sort.
        let cut: [(u8, u8); 40] = NET12[..40].try_into().unwrap();
        assert!(!sorts(&cut, 12));
    }

    /// The split of a small node is the cheapest of all splits of its primitives ordered by
    /// centroid on each axis, found here by sorting in f64; of up to `MAX_LEAF` primitives,
    /// the cheapest of all splits into two.
    #[test]
    fn small_nodes_take_the_exact_sah_split() {
        let mut rng = TestRng(7);
        let mut scratch = Bins::new();
        for trial in 0..3000 {
            let n = 2 + trial % (SMALL - 1);
            let mut items: Vec<Item> = (0..n)
                .map(|k| {
                    let c = rng.in_cube(10.0);
                    let h = rng.in_cube(2.0).abs();
                    let (lo, hi) = outward(c - h, c + h);
                    Item { lo: [lo[0], lo[1], lo[2], f32::from_bits(k as u32)], hi }
                })
                .collect();
            let span = Span::of(&items);
            let area = |its: &[Item]| Span::of(its).bounds.half_area() as f64;
            let parent = area(&items);
            let cost = |l: &[Item], r: &[Item]| 1.0 + (area(l) * l.len() as f64 + area(r) * r.len() as f64) / parent;
            let mut best = f64::INFINITY;
            for axis in 0..3 {
                let mut sorted = items.clone();
                sorted.sort_by(|a, b| (a.centroid2(axis) as f64).total_cmp(&(b.centroid2(axis) as f64)));
                for mid in 1..n {
                    best = best.min(cost(&sorted[..mid], &sorted[mid..]));
                }
            }
            let mut any_split = f64::INFINITY;
            for side in 1..(1u32 << n) - 1 {
                let (l, r): (Vec<Item>, Vec<Item>) = (0..n).map(|k| (side >> k & 1 != 0, items[k])).fold(
                    (vec![], vec![]),
                    |(mut l, mut r), (left, it)| {
                        if left {
                            l.push(it)
                        } else {
                            r.push(it)
                        }
                        (l, r)
                    },
                );
                any_split = any_split.min(cost(&l, &r));
            }
            if n <= MAX_LEAF {
                assert!(any_split <= best);
                best = any_split;
            }
            match decide(&mut items, &span, 1, &mut scratch) {
                Decision::Leaf => assert!(n <= MAX_LEAF && best >= n as f64 * (1.0 - 1e-6), "n {n}: leaf, best {best}"),
                Decision::Split { mid, left, right } => {
                    let got = cost(&items[..mid], &items[mid..]);
                    assert!((got - best).abs() <= 1e-5 * best, "n {n}: split costs {got}, best {best}");
                    let (l, r) = (Span::of(&items[..mid]), Span::of(&items[mid..]));
                    assert_eq!(left.bounds.half_area(), l.bounds.half_area());
                    assert_eq!(right.bounds.half_area(), r.bounds.half_area());
                }
            }
            // The items were only reordered.
            let mut after: Vec<u32> = items.iter().map(|it| it.prim().0).collect();
            after.sort();
            assert_eq!(after, (0..n as u32).collect::<Vec<_>>());
        }
    }
}
