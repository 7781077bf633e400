//! Binned SAH BVH build (Wald, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies", 2007), parallel over subtrees with rayon, flattened depth-first into 32-byte
//! nodes.
//!
//! The build works on one array of 32-byte primitive records, partitioned in place. A node
//! bins its primitives' centroids on all three axes in one pass, sweeps the bins for the
//! cheapest split, and partitions the records in a second pass that also gathers both
//! children's bounds, so no pass is spent on bounds alone and nothing is allocated per node.
//! Subtrees below `PARALLEL_THRESHOLD` primitives are built by one thread straight into their
//! own node array; the arrays are joined once at the end.

use crate::math::{Real, V3};
use crate::primitives::{PrimKind, PrimRef, Primitives};
use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

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

/// Deepest tree the build makes; the traversal stacks hold this many (the GPU's more, for the
/// levels [`super::gpu_bvh`] adds).
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

/// A box with a fourth lane of padding, so that growing one is two 4-lane min/max.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: [f32; 4],
    hi: [f32; 4],
}

impl Aabb {
    const EMPTY: Aabb = Aabb { lo: [f32::INFINITY; 4], hi: [f32::NEG_INFINITY; 4] };
    #[inline(always)]
    fn grow(&mut self, lo: &[f32; 4], hi: &[f32; 4]) {
        for k in 0..4 {
            self.lo[k] = if lo[k] < self.lo[k] { lo[k] } else { self.lo[k] };
            self.hi[k] = if hi[k] > self.hi[k] { hi[k] } else { self.hi[k] };
        }
    }
    #[inline(always)]
    fn grow_box(&mut self, o: &Aabb) {
        self.grow(&o.lo, &o.hi);
    }
    /// Half the surface area (the SAH only compares ratios).
    #[inline(always)]
    fn half_area(&self) -> f32 {
        if self.lo[0] > self.hi[0] {
            return 0.0;
        }
        let e = [self.hi[0] - self.lo[0], self.hi[1] - self.lo[1], self.hi[2] - self.lo[2]];
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }
    fn lo3(&self) -> [f32; 3] {
        [self.lo[0], self.lo[1], self.lo[2]]
    }
    fn hi3(&self) -> [f32; 3] {
        [self.hi[0], self.hi[1], self.hi[2]]
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
    const EMPTY: Span = Span { bounds: Aabb::EMPTY, centroids: Aabb::EMPTY };
    #[inline(always)]
    fn add(&mut self, it: &Item) {
        self.bounds.grow(&it.lo, &it.hi);
        let c = [it.lo[0] + it.hi[0], it.lo[1] + it.hi[1], it.lo[2] + it.hi[2], 0.0];
        self.centroids.grow(&c, &c);
    }
    fn join(mut self, o: &Span) -> Span {
        self.bounds.grow_box(&o.bounds);
        self.centroids.grow_box(&o.centroids);
        self
    }
    fn of(items: &[Item]) -> Span {
        let mut s = Span::EMPTY;
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

/// Maps a doubled centroid to its bin on each axis (fourth lanes: padding, scale 0).
#[derive(Clone, Copy)]
struct Binning {
    n: usize,
    lo: [f32; 4],
    scale: [f32; 4],
}

impl Binning {
    fn new(centroids: &Aabb, count: usize) -> Binning {
        let n = count.clamp(2, BINS);
        let scale = std::array::from_fn(|a| {
            let extent = centroids.hi[a] - centroids.lo[a];
            // Just under n/extent, so that the largest centroid lands in bin n − 1.
            if a < 3 && extent > 0.0 { n as f32 * (1.0 - 1e-6) / extent } else { 0.0 }
        });
        Binning { n, lo: [centroids.lo[0], centroids.lo[1], centroids.lo[2], 0.0], scale }
    }

    #[inline(always)]
    fn bin(&self, it: &Item, axis: usize) -> usize {
        let f = (it.centroid2(axis) - self.lo[axis]) * self.scale[axis];
        // Clamped to [0, n − 1] first (NaN, impossible here, would become n − 1), so the
        // conversion is in range.
        let f = f.min((self.n - 1) as f32).max(0.0);
        // SAFETY: f is finite and within [0, n − 1].
        unsafe { f.to_int_unchecked::<u32>() as usize }
    }

    /// Bins `items` into `b` (only its first `n` bins are reset and used). Items alternate
    /// between two sets of bins, merged at the end: neighbouring items often fall into the
    /// same bin, and one set would make each update wait for the previous one's store.
    fn fill_into(&self, items: &[Item], b: &mut Bins) {
        b.n = self.n;
        for set in 0..2 {
            for axis in 0..3 {
                b.boxes[set][axis][..self.n].fill(Aabb::EMPTY);
                b.counts[set][axis][..self.n].fill(0);
            }
        }
        #[inline(always)]
        fn add(binning: &Binning, b: &mut Bins, set: usize, it: &Item) {
            for axis in 0..3 {
                let k = binning.bin(it, axis);
                b.boxes[set][axis][k].grow(&it.lo, &it.hi);
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
        Box::new(Bins { n: 0, boxes: [[[Aabb::EMPTY; BINS]; 3]; 2], counts: [[[0; BINS]; 3]; 2] })
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
            if binning.scale[axis] == 0.0 {
                continue;
            }
            let (boxes, counts) = (&self.boxes[0][axis], &self.counts[0][axis]);
            // Right-to-left sweep: area and count of bins k.. for each k.
            let mut right = [(0.0f32, 0u32); BINS];
            let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
            for k in (1..n).rev() {
                acc.grow_box(&boxes[k]);
                cnt += counts[k];
                right[k] = (acc.half_area(), cnt);
            }
            let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
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
    let (mut left, mut right) = (Span::EMPTY, Span::EMPTY);
    let (mut i, mut j) = (0, items.len());
    loop {
        while i < j && binning.bin(&items[i], axis) < split {
            left.add(&items[i]);
            i += 1;
        }
        while i < j && binning.bin(&items[j - 1], axis) >= split {
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

/// Nodes of at most this many primitives are split by sorting instead of binning: an exact
/// SAH sweep over so few primitives costs less than resetting and sweeping bins.
const SMALL: usize = 12;

/// The exact-SAH decision for a node of 2..=SMALL primitives: per axis the primitives are
/// sorted by centroid and every split position is evaluated; the items end up in the order
/// of the chosen axis.
fn decide_small(items: &mut [Item], span: &Span) -> Decision {
    let n = items.len();
    let inv_parent = 1.0 / span.bounds.half_area().max(f32::MIN_POSITIVE);
    let mut orders = [[0u8; SMALL]; 3];
    let mut best: Option<(usize, usize, f32)> = None;
    for (axis, order) in orders.iter_mut().enumerate() {
        if !(span.centroids.hi[axis] > span.centroids.lo[axis]) {
            continue;
        }
        let order = &mut order[..n];
        for (k, o) in order.iter_mut().enumerate() {
            *o = k as u8;
        }
        order
            .sort_unstable_by(|&a, &b| items[a as usize].centroid2(axis).total_cmp(&items[b as usize].centroid2(axis)));
        let mut right = [0.0f32; SMALL];
        let mut acc = Aabb::EMPTY;
        for k in (1..n).rev() {
            let it = &items[order[k] as usize];
            acc.grow(&it.lo, &it.hi);
            right[k] = acc.half_area();
        }
        let mut acc = Aabb::EMPTY;
        for k in 1..n {
            let it = &items[order[k - 1] as usize];
            acc.grow(&it.lo, &it.hi);
            let cost = TRAVERSAL_COST + (acc.half_area() * k as f32 + right[k] * (n - k) as f32) * inv_parent;
            if best.is_none_or(|b| cost < b.2) {
                best = Some((axis, k, cost));
            }
        }
    }
    let (axis, mid) = match best {
        Some((_, _, cost)) if n <= MAX_LEAF && cost >= n as f32 => return Decision::Leaf,
        Some((axis, mid, _)) => (axis, mid),
        None if n <= MAX_LEAF => return Decision::Leaf,
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

/// Chooses between a leaf and the best split of `items`; `scratch` holds the bins.
fn decide(items: &mut [Item], span: &Span, depth: u32, scratch: &mut Bins) -> Decision {
    let n = items.len();
    if n <= 1 || depth >= MAX_DEPTH {
        return Decision::Leaf;
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
    match bins.best(&binning, span.bounds.half_area()) {
        // Stay a leaf when no split pays for itself, if the leaf is small enough.
        Some((_, _, cost)) if n <= MAX_LEAF && cost >= n as f32 => Decision::Leaf,
        Some((axis, split, _)) => {
            let (mid, left, right) = partition(items, &binning, axis, split);
            Decision::Split { mid, left, right }
        }
        None if n <= MAX_LEAF => Decision::Leaf,
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
/// `out`'s start); returns its depth.
fn build_serial(
    items: &mut [Item],
    offset: usize,
    span: &Span,
    depth: u32,
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
            let dl = build_serial(l, offset, &left, depth + 1, out, scratch);
            out[me].left_or_first = out.len() as u32;
            let dr = build_serial(r, offset + mid, &right, depth + 1, out, scratch);
            dl.max(dr)
        }
    }
}

/// A subtree built in parallel: its top nodes, and below them node arrays built serially.
enum Part {
    Serial { nodes: Vec<BvhNode>, depth: u32 },
    Split { node: BvhNode, left: Box<Part>, right: Box<Part> },
}

fn build_parallel(items: &mut [Item], offset: usize, span: &Span, depth: u32) -> Part {
    if items.len() < PARALLEL_THRESHOLD {
        let mut nodes = Vec::with_capacity(items.len());
        let depth = build_serial(items, offset, span, depth, &mut nodes, &mut Bins::new());
        return Part::Serial { nodes, depth };
    }
    match decide(items, span, depth, &mut Bins::new()) {
        Decision::Leaf => Part::Serial { nodes: vec![node_of(&span.bounds, offset as u32, items.len() as u32)], depth },
        Decision::Split { mid, left, right } => {
            let (l, r) = items.split_at_mut(mid);
            let (pl, pr) = rayon::join(
                || build_parallel(l, offset, &left, depth + 1),
                || build_parallel(r, offset + mid, &right, depth + 1),
            );
            Part::Split { node: node_of(&span.bounds, 0, 0), left: Box::new(pl), right: Box::new(pr) }
        }
    }
}

impl Part {
    fn len(&self) -> usize {
        match self {
            Part::Serial { nodes, .. } => nodes.len(),
            Part::Split { left, right, .. } => 1 + left.len() + right.len(),
        }
    }
    /// Appends the subtree depth-first, right-child indices made absolute; returns its depth.
    fn flatten_into(self, out: &mut Vec<BvhNode>) -> u32 {
        match self {
            Part::Serial { nodes, depth } => {
                let base = out.len() as u32;
                out.extend(nodes.into_iter().map(|mut n| {
                    if !n.is_leaf() {
                        n.left_or_first += base;
                    }
                    n
                }));
                depth
            }
            Part::Split { mut node, left, right } => {
                let me = out.len();
                node.left_or_first = (me + 1 + left.len()) as u32;
                out.push(node);
                left.flatten_into(out).max(right.flatten_into(out))
            }
        }
    }
}

impl Bvh {
    /// Builds over every bounded primitive of `prims` (planes stay outside).
    pub fn build<R: Real>(prims: &Primitives<R>) -> Bvh {
        let refs: Vec<PrimRef> = prims.bounded_refs().collect();
        let mut items: Vec<Item> = super::huge_pages::vec_with_capacity(refs.len());
        items.par_extend(refs.par_iter().with_min_len(4096).map(|&prim| {
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
        let span = items.par_chunks(1 << 16).map(Span::of).reduce(|| Span::EMPTY, |a, b| a.join(&b));
        let root = build_parallel(&mut items, 0, &span, 1);
        let mut nodes = super::huge_pages::vec_with_capacity(root.len());
        let depth = root.flatten_into(&mut nodes);
        let mut prim_refs = super::huge_pages::vec_with_capacity(items.len());
        prim_refs.par_extend(items.par_iter().map(Item::prim));
        Bvh { nodes, prim_refs, depth }
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
            Aabb { lo, hi }.half_area() as f64
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

    #[test]
    fn every_primitive_is_in_exactly_one_leaf_inside_its_bounds() {
        let mut prims = random_triangles(5000, 1);
        prims
            .spheres
            .push(Tagged { shape: Sphere { center: V3::new(1.0, 2.0, 3.0), radius: 0.5 }, tag: Tag::default() });
        let bvh = Bvh::build(&prims);
        let mut seen = vec![0u32; bvh.prim_refs.len()];
        for (i, node) in bvh.nodes.iter().enumerate() {
            if node.is_leaf() {
                for k in node.left_or_first..node.left_or_first + node.count {
                    seen[k as usize] += 1;
                    let (lo, hi) = prims.bounds_f64(bvh.prim_refs[k as usize]);
                    for a in 0..3 {
                        assert!(node.bmin[a] as f64 <= lo[a] && hi[a] <= node.bmax[a] as f64);
                    }
                }
            } else {
                // Children lie inside their parent.
                for c in [i + 1, node.left_or_first as usize] {
                    for a in 0..3 {
                        assert!(node.bmin[a] <= bvh.nodes[c].bmin[a] && bvh.nodes[c].bmax[a] <= node.bmax[a]);
                    }
                }
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
        assert_eq!(bvh.prim_refs.len(), 5001);
        assert!(bvh.depth <= MAX_DEPTH);
        // A SAH tree over uniformly scattered triangles is shallow.
        assert!(bvh.depth < 30, "depth {}", bvh.depth);
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
}
