//! The BVH as the GPU walks it, collapsed from the binary SAH tree of [`super::bvh`]: each node
//! holds the boxes of its two children, so one 64-byte fetch tests both (the binary layout
//! needs three fetches per step: the node and each child); every leaf holds one kind of
//! primitive, so a leaf loop runs the triangle test or the sphere/cylinder tests, not both; and
//! the triangles are copied in leaf order, vertices only, so a leaf's triangles are one
//! contiguous run without an index lookup. On a SIMD device that runs each invocation in a lane
//! (lavapipe: 8 lanes), memory fetches with a different address per lane are the dominant cost
//! of traversal, and this layout makes fewer and smaller ones.
//!
//! [`nearest`] and [`all`] walk it exactly as `shaders/modules/traverse.wgsl` and `shaders/trace.wgsl`
//! do, so a GPU/CPU difference can be bisected to the traversal; the CPU renderers themselves
//! walk the 8-wide tree ([`super::wide_traverse`]). All return exactly what brute force returns
//! (the tie rule of [`Nearest`] makes the visiting order irrelevant). [`closest`], the nearest
//! surface point of a query point, walks it as `shaders/closest.wgsl` does and returns what
//! [`crate::proximity::closest_brute`] returns (the tie rule of [`Closest::offer`]).

use super::bvh::Bvh;
use super::slab::safe_inverse;
use crate::geometry::{Shape, Triangle};
use crate::math::{Ray, Real, V3};
use crate::primitives::{Hit, Nearest, PrimKind, PrimRef, Primitives, sort_hits};
use crate::proximity::Closest;
use bytemuck::{Pod, Zeroable};

/// Child link flag: the child is a leaf (else the index of an inner node).
pub const LINK_LEAF: u32 = 1 << 31;
/// Leaf flag: the leaf's primitives are shape references (spheres, cylinders) in
/// [`GpuBvh::shape_refs`], else triangles in [`GpuBvh::triangles`].
pub const LINK_SHAPES: u32 = 1 << 30;
/// A leaf's primitive count minus one sits in these bits.
pub const LINK_COUNT_SHIFT: u32 = 26;
/// The most primitives one leaf holds (larger leaves of the binary tree are split).
pub const LEAF_MAX: usize = 16;
/// The first primitive of a leaf sits in the low bits.
pub const LINK_FIRST_MASK: u32 = (1 << LINK_COUNT_SHIFT) - 1;
/// The link of an absent child (a root that is a leaf has one), with an empty box; also the
/// traversal's "no node". No real leaf has it: it would end past the last primitive the layout
/// indexes ([`MAX_PRIMS`]).
pub const LINK_EMPTY: u32 = u32::MAX;
/// The most primitives (triangles, or spheres and cylinders) the layout indexes.
pub const MAX_PRIMS: usize = LINK_FIRST_MASK as usize - LEAF_MAX;
/// Deepest collapsed tree (nodes on a root-to-leaf path), and the length of the traversal
/// stack (`GPU_STACK` in `shaders/modules/traverse.wgsl`), which holds at most one entry per
/// inner node of the path: the binary tree's [`super::bvh::MAX_DEPTH`], whose leaves hold at
/// most 12 primitives (fewer than [`LEAF_MAX`]), plus the one level the collapse adds where a
/// leaf mixes triangles with spheres or cylinders. [`GpuBvh::collapse`] refuses a deeper tree.
pub const MAX_DEPTH: u32 = super::bvh::MAX_DEPTH + 1;

/// One node: the boxes and links of its two children (a and b), 64 bytes, the layout of
/// `Node` in `shaders/modules/types.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuNode {
    pub lo_a: [f32; 3],
    pub link_a: u32,
    pub hi_a: [f32; 3],
    pub link_b: u32,
    pub lo_b: [f32; 3],
    pub _pad_a: u32,
    pub hi_b: [f32; 3],
    pub _pad_b: u32,
}

/// A triangle in leaf order: its vertices, its index in the scene-order triangle array (which
/// names it in hits and breaks ties) and its material (so that shading a hit fetches nothing
/// more), 48 bytes, `LeafTriangle` in `shaders/modules/types.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLeafTriangle {
    pub va: [f32; 3],
    pub index: u32,
    pub vb: [f32; 3],
    pub material: u32,
    pub vc: [f32; 3],
    pub _pad: u32,
}

/// The collapsed tree. Node 0 is the root.
#[derive(Clone, Debug, Default)]
pub struct GpuBvh {
    pub nodes: Vec<GpuNode>,
    pub triangles: Vec<GpuLeafTriangle>,
    /// [`PrimRef`]s of the spheres and cylinders, in leaf order.
    pub shape_refs: Vec<u32>,
    /// Longest root-to-leaf path in nodes (root = 1).
    pub depth: u32,
}

/// The box of an absent child: inverted, so that no real box contains it; the walk never tests
/// it (it checks the link first).
const EMPTY_LO: [f32; 3] = [f32::MAX; 3];
const EMPTY_HI: [f32; 3] = [-f32::MAX; 3];

/// The decoded form of a child link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Link {
    Inner(usize),
    Triangles { first: usize, count: usize },
    Shapes { first: usize, count: usize },
}

impl Link {
    pub fn decode(link: u32) -> Link {
        if link & LINK_LEAF == 0 {
            return Link::Inner(link as usize);
        }
        let first = (link & LINK_FIRST_MASK) as usize;
        let count = (((link & !LINK_LEAF & !LINK_SHAPES) >> LINK_COUNT_SHIFT) + 1) as usize;
        if link == LINK_EMPTY {
            Link::Triangles { first: 0, count: 0 }
        } else if link & LINK_SHAPES != 0 {
            Link::Shapes { first, count }
        } else {
            Link::Triangles { first, count }
        }
    }
}

/// Why a tree cannot be collapsed.
#[derive(Debug, thiserror::Error)]
pub enum CollapseError {
    #[error("the scene has {0} primitives in its BVH, more than the GPU layout indexes ({MAX_PRIMS})")]
    TooMany(usize),
    #[error("the scene's BVH is {0} levels deep, more than the GPU's traversal stack holds ({MAX_DEPTH})")]
    TooDeep(u32),
}

struct Collapse<'a> {
    bvh: &'a Bvh,
    prims: &'a Primitives<f32>,
    out: GpuBvh,
}

impl Collapse<'_> {
    /// Appends the node for binary inner node `i`; returns its index.
    fn inner(&mut self, i: usize, depth: u32) -> u32 {
        let me = self.out.nodes.len();
        self.out.nodes.push(GpuNode::default());
        let n = &self.bvh.nodes[i];
        let (l, r) = (i + 1, n.left_or_first as usize);
        let (lo_a, hi_a, link_a) = self.child(l, depth + 1);
        let (lo_b, hi_b, link_b) = self.child(r, depth + 1);
        self.out.nodes[me] = GpuNode { lo_a, link_a, hi_a, link_b, lo_b, _pad_a: 0, hi_b, _pad_b: 0 };
        me as u32
    }

    /// Box and link of binary node `i` as a child at `depth`.
    fn child(&mut self, i: usize, depth: u32) -> ([f32; 3], [f32; 3], u32) {
        let n = self.bvh.nodes[i];
        let link = if n.is_leaf() {
            let refs = &self.bvh.prim_refs[n.left_or_first as usize..(n.left_or_first + n.count) as usize];
            self.leaf(n.bmin, n.bmax, refs, depth)
        } else {
            self.inner(i, depth)
        };
        (n.bmin, n.bmax, link)
    }

    /// The link of a leaf over `refs` inside the box (lo, hi) at `depth`: one leaf when the
    /// primitives are of one kind and few enough, else an inner node over the parts (each with
    /// the whole box).
    fn leaf(&mut self, lo: [f32; 3], hi: [f32; 3], refs: &[PrimRef], depth: u32) -> u32 {
        self.out.depth = self.out.depth.max(depth);
        let tris = refs.iter().all(|r| r.kind() == PrimKind::Triangle);
        let shapes = refs.iter().all(|r| r.kind() != PrimKind::Triangle);
        if (tris || shapes) && refs.len() <= LEAF_MAX {
            let count = ((refs.len() as u32 - 1) << LINK_COUNT_SHIFT) | LINK_LEAF;
            return if tris {
                let first = self.out.triangles.len() as u32;
                for r in refs {
                    let t = &self.prims.triangles[r.index()];
                    let [va, vb, vc] = t.shape.v.map(|v| v.to_array());
                    let (index, material) = (r.index() as u32, t.tag.material);
                    self.out.triangles.push(GpuLeafTriangle { va, index, vb, material, vc, _pad: 0 });
                }
                count | first
            } else {
                let first = self.out.shape_refs.len() as u32;
                self.out.shape_refs.extend(refs.iter().map(|r| r.0));
                count | LINK_SHAPES | first
            };
        }
        let (a, b): (Vec<PrimRef>, Vec<PrimRef>) = if tris || shapes {
            let (a, b) = refs.split_at(refs.len() / 2);
            (a.to_vec(), b.to_vec())
        } else {
            refs.iter().partition(|r| r.kind() == PrimKind::Triangle)
        };
        let me = self.out.nodes.len();
        self.out.nodes.push(GpuNode::default());
        let link_a = self.leaf(lo, hi, &a, depth + 1);
        let link_b = self.leaf(lo, hi, &b, depth + 1);
        self.out.nodes[me] = GpuNode { lo_a: lo, link_a, hi_a: hi, link_b, lo_b: lo, _pad_a: 0, hi_b: hi, _pad_b: 0 };
        me as u32
    }
}

impl GpuBvh {
    /// Collapses `bvh`, built over `prims`. An empty tree gives an empty layout.
    pub fn collapse(bvh: &Bvh, prims: &Primitives<f32>) -> Result<GpuBvh, CollapseError> {
        if bvh.prim_refs.len() > MAX_PRIMS {
            return Err(CollapseError::TooMany(bvh.prim_refs.len()));
        }
        if bvh.is_empty() {
            return Ok(GpuBvh::default());
        }
        let mut c = Collapse {
            bvh,
            prims,
            out: GpuBvh {
                nodes: Vec::with_capacity(bvh.nodes.len() / 2 + 1),
                triangles: Vec::with_capacity(prims.triangles.len()),
                shape_refs: Vec::new(),
                depth: 1,
            },
        };
        let root = bvh.nodes[0];
        if root.is_leaf() {
            // A root that is a leaf becomes child a of a node whose child b is empty.
            c.out.nodes.push(GpuNode::default());
            let link_a = c.leaf(root.bmin, root.bmax, &bvh.prim_refs, 2);
            c.out.nodes[0] = GpuNode {
                lo_a: root.bmin,
                link_a,
                hi_a: root.bmax,
                link_b: LINK_EMPTY,
                lo_b: EMPTY_LO,
                _pad_a: 0,
                hi_b: EMPTY_HI,
                _pad_b: 0,
            };
        } else {
            c.inner(0, 1);
        }
        // The build bounds the depth (see MAX_DEPTH); a tree from anywhere else is checked, as
        // the shaders' stack has no room past it.
        if c.out.depth > MAX_DEPTH {
            return Err(CollapseError::TooDeep(c.out.depth));
        }
        Ok(c.out)
    }

    /// The triangle in leaf slot `k` as a shape.
    fn triangle(&self, k: usize) -> Triangle<f32> {
        let t = &self.triangles[k];
        Triangle { v: [t.va, t.vb, t.vc].map(|v| V3::new(v[0], v[1], v[2])) }
    }
}

/// Entry distance of the ray into the box (lo, hi) within [tmin, tmax], or -1: the slab test
/// of [`super::slab::slab`] (an axis the ray runs parallel to, `inv` 0, bounds nothing while
/// the origin lies within the box on it and rules the box out otherwise), as `slab` in
/// `shaders/modules/traverse.wgsl` computes it.
#[inline]
pub fn slab(lo: &[f32; 3], hi: &[f32; 3], o: V3<f32>, inv: V3<f32>, tmin: f32, tmax: f32) -> f32 {
    // SLAB_GROW in traverse.wgsl.
    let grow = 1.0 + 2.0 * <f32 as Real>::gamma_bound(3);
    let mut tnear = tmin;
    let mut tfar = tmax;
    for a in 0..3 {
        if inv[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return -1.0;
            }
            continue;
        }
        let t0 = (lo[a] - o[a]) * inv[a];
        let t1 = (hi[a] - o[a]) * inv[a];
        tnear = tnear.max(t0.min(t1));
        tfar = tfar.min(t0.max(t1) * grow);
    }
    if tnear <= tfar { tnear } else { -1.0 }
}

/// Calls `leaf(link)` for every leaf whose box the ray enters within [tmin, bound()], nearer
/// child first, as `nearest_hit` in `shaders/modules/traverse.wgsl` orders them.
fn walk(bvh: &GpuBvh, ray: &Ray<f32>, tmin: f32, bound: &mut dyn FnMut() -> f32, leaf: &mut dyn FnMut(Link)) {
    if bvh.nodes.is_empty() {
        return;
    }
    let inv = safe_inverse(ray.dir);
    let mut stack: Vec<(u32, f32)> = Vec::with_capacity(MAX_DEPTH as usize);
    let mut cur = Some(0u32);
    while let Some(link) = cur {
        cur = None;
        match Link::decode(link) {
            Link::Inner(i) => {
                let n = &bvh.nodes[i];
                let tb = bound();
                let ha = slab(&n.lo_a, &n.hi_a, ray.origin, inv, tmin, tb);
                // Only a root that is a leaf has an absent child (b).
                let hb = if n.link_b == LINK_EMPTY { -1.0 } else { slab(&n.lo_b, &n.hi_b, ray.origin, inv, tmin, tb) };
                match (ha >= 0.0, hb >= 0.0) {
                    (true, true) => {
                        let (near, far, tfar) =
                            if hb < ha { (n.link_b, n.link_a, ha) } else { (n.link_a, n.link_b, hb) };
                        stack.push((far, tfar));
                        cur = Some(near);
                    }
                    (true, false) => cur = Some(n.link_a),
                    (false, true) => cur = Some(n.link_b),
                    (false, false) => {}
                }
            }
            leaf_link => leaf(leaf_link),
        }
        if cur.is_none() {
            while let Some((link, t)) = stack.pop() {
                if t <= bound() {
                    cur = Some(link);
                    break;
                }
            }
        }
    }
}

/// The nearest hit in (tmin, tmax), walking the collapsed tree: identical to
/// [`Primitives::nearest_brute`] (and to the binary tree's walk in `strahl-cpu`).
pub fn nearest(bvh: &GpuBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Option<Hit<f32>> {
    let mut best = Nearest::new(tmax);
    for r in prims.plane_refs() {
        prims.offer_nearest(r, ray, tmin, &mut best);
    }
    let best_cell = std::cell::Cell::new(best);
    walk(bvh, ray, tmin, &mut || best_cell.get().search_bound(), &mut |link| {
        let mut b = best_cell.get();
        match link {
            Link::Triangles { first, count } => {
                for k in first..first + count {
                    let r = PrimRef::new(PrimKind::Triangle, bvh.triangles[k].index as usize);
                    if let Some((t, part)) = bvh.triangle(k).roots(ray, tmin, b.search_bound()).first() {
                        b.offer(t, r, part);
                    }
                }
            }
            Link::Shapes { first, count } => {
                for &r in &bvh.shape_refs[first..first + count] {
                    prims.offer_nearest(PrimRef(r), ray, tmin, &mut b);
                }
            }
            Link::Inner(_) => unreachable!("walk passes leaves only"),
        }
        best_cell.set(b);
    });
    best = best_cell.get();
    best.found.then(|| prims.hit(best.prim_ref, ray, best.t, best.part))
}

/// Whether anything lies in (tmin, tmax) along the ray: the walk of [`nearest`] ended at the
/// first hit it meets (`occluded` in `shaders/modules/traverse.wgsl`, for shadow rays).
pub fn occluded(bvh: &GpuBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> bool {
    let mut best = Nearest::new(tmax);
    for r in prims.plane_refs() {
        prims.offer_nearest(r, ray, tmin, &mut best);
    }
    let found = std::cell::Cell::new(best.found);
    walk(bvh, ray, tmin, &mut || if found.get() { f32::NEG_INFINITY } else { tmax }, &mut |link| {
        let mut b = Nearest::new(tmax);
        match link {
            Link::Triangles { first, count } => {
                for k in first..first + count {
                    let r = PrimRef::new(PrimKind::Triangle, bvh.triangles[k].index as usize);
                    if let Some((t, part)) = bvh.triangle(k).roots(ray, tmin, tmax).first() {
                        b.offer(t, r, part);
                    }
                }
            }
            Link::Shapes { first, count } => {
                for &r in &bvh.shape_refs[first..first + count] {
                    prims.offer_nearest(PrimRef(r), ray, tmin, &mut b);
                }
            }
            Link::Inner(_) => unreachable!("walk passes leaves only"),
        }
        found.set(found.get() || b.found);
    });
    found.get()
}

/// Every hit in (tmin, tmax), sorted as [`Primitives::all_brute`] sorts them.
pub fn all(bvh: &GpuBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Vec<Hit<f32>> {
    let mut hits = Vec::new();
    for r in prims.plane_refs() {
        prims.collect_hits(r, ray, tmin, tmax, &mut hits);
    }
    walk(bvh, ray, tmin, &mut || tmax, &mut |link| match link {
        Link::Triangles { first, count } => {
            for k in first..first + count {
                let r = PrimRef::new(PrimKind::Triangle, bvh.triangles[k].index as usize);
                prims.collect_hits(r, ray, tmin, tmax, &mut hits);
            }
        }
        Link::Shapes { first, count } => {
            for &r in &bvh.shape_refs[first..first + count] {
                prims.collect_hits(PrimRef(r), ray, tmin, tmax, &mut hits);
            }
        }
        Link::Inner(_) => unreachable!("walk passes leaves only"),
    });
    sort_hits(&mut hits);
    hits
}

/// 1 + 2γ(4) in f32: the growth of the best squared distance a box's squared distance is
/// compared with in the point walks ([`crate::proximity::closest`], [`closest`] and
/// `CLOSEST_GROW` in `shaders/closest.wgsl`), which covers the box distance's rounding (γ(4)
/// relative: three squares summed), so that no box holding an equally near foot is skipped.
pub fn closest_grow() -> f32 {
    1.0 + 2.0 * <f32 as Real>::gamma_bound(4)
}

/// Squared distance from `p` to the box (lo, hi), 0 inside it: the sum of the squared
/// per-axis gaps of [`crate::proximity::box_dist2`] in the same order, capped at `f32::MAX`
/// (WGSL cannot spell infinity: a gap that overflows compares as the largest float, against a
/// bound that is `f32::MAX` until a foot is found), as `box_dist2` in `shaders/closest.wgsl`.
#[inline]
pub fn box_dist2(lo: &[f32; 3], hi: &[f32; 3], p: V3<f32>) -> f32 {
    let mut d2 = 0.0f32;
    for a in 0..3 {
        let d = (lo[a] - p[a]).max(p[a] - hi[a]).max(0.0);
        d2 += d * d;
    }
    d2.min(f32::MAX)
}

/// The nearest surface point of the scene to `p` (`None` only for an empty scene), walking the
/// collapsed tree as `closest_point` in `shaders/closest.wgsl` does: the planes first, then
/// depth first from the root, at each node the children whose boxes lie within the bound
/// (the best squared distance grown by [`closest_grow`], `f32::MAX` before any foot), the
/// nearer first (b where its box is strictly nearer, else a), the other pushed with its box
/// distance and dropped when popped beyond the bound of then. Identical to
/// [`crate::proximity::closest_brute`] (and to [`crate::proximity::closest`] on the binary
/// tree, whose boxes these are): the bound only skips boxes farther than the best foot, and
/// [`Closest::offer`]'s tie rule makes the order of the offers irrelevant.
pub fn closest(bvh: &GpuBvh, prims: &Primitives<f32>, p: V3<f32>) -> Option<Closest<f32>> {
    let mut best = None;
    for r in prims.plane_refs() {
        Closest::offer(&mut best, r, prims.closest_of(r, p));
    }
    if bvh.nodes.is_empty() {
        return best;
    }
    let grow = closest_grow();
    let bound = |best: &Option<Closest<f32>>| best.map_or(f32::MAX, |b| b.foot.dist2 * grow);
    let mut stack: Vec<(u32, f32)> = Vec::with_capacity(MAX_DEPTH as usize);
    let mut cur = Some(0u32);
    while let Some(link) = cur {
        cur = None;
        match Link::decode(link) {
            Link::Inner(i) => {
                let n = &bvh.nodes[i];
                let tb = bound(&best);
                let da = box_dist2(&n.lo_a, &n.hi_a, p);
                let db = box_dist2(&n.lo_b, &n.hi_b, p);
                // Only a root that is a leaf has an absent child (b), whose empty box would
                // measure f32::MAX.
                match (da <= tb, n.link_b != LINK_EMPTY && db <= tb) {
                    (true, true) => {
                        let (near, far, dfar) =
                            if db < da { (n.link_b, n.link_a, da) } else { (n.link_a, n.link_b, db) };
                        stack.push((far, dfar));
                        cur = Some(near);
                    }
                    (true, false) => cur = Some(n.link_a),
                    (false, true) => cur = Some(n.link_b),
                    (false, false) => {}
                }
            }
            Link::Triangles { first, count } => {
                for k in first..first + count {
                    let r = PrimRef::new(PrimKind::Triangle, bvh.triangles[k].index as usize);
                    Closest::offer(&mut best, r, bvh.triangle(k).closest(p));
                }
            }
            Link::Shapes { first, count } => {
                for &r in &bvh.shape_refs[first..first + count] {
                    Closest::offer(&mut best, PrimRef(r), prims.closest_of(PrimRef(r), p));
                }
            }
        }
        if cur.is_none() {
            let tb = bound(&best);
            while let Some((link, d)) = stack.pop() {
                if d <= tb {
                    cur = Some(link);
                    break;
                }
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::testutil::{TestRays, TestRng, ray_f32};
    use crate::geometry::{Cylinder, Sphere};
    use crate::primitives::{Tag, Tagged};

    /// Triangles, spheres and cylinders mixed in one cloud, so that leaves of the binary tree
    /// hold several kinds and the collapse must split them.
    fn mixed(n: usize, seed: u64) -> Primitives<f32> {
        let mut rng = TestRng(seed);
        let mut p = Primitives::<f64>::default();
        for i in 0..n {
            let c = rng.in_cube(20.0);
            let tag = Tag { object: i as u32, face: 0, material: i as u32 % 7 };
            match i % 5 {
                0 => p.spheres.push(Tagged { shape: Sphere { center: c, radius: 0.4 }, tag }),
                1 => p.cylinders.push(Tagged {
                    shape: Cylinder { p1: c, p2: c + rng.in_cube(1.0), radius: 0.2, caps: i % 2 == 0 },
                    tag,
                }),
                _ => p.triangles.push(Tagged { shape: Triangle { v: [0, 1, 2].map(|_| c + rng.in_cube(1.0)) }, tag }),
            }
        }
        p.cast()
    }

    #[test]
    fn collapse_keeps_every_primitive_once_in_a_leaf_of_one_kind_inside_its_box() {
        let prims = mixed(3000, 7);
        let bvh = Bvh::build(&prims);
        let g = GpuBvh::collapse(&bvh, &prims).unwrap();
        let mut seen_tris = vec![0u32; prims.triangles.len()];
        let mut seen_shapes = std::collections::HashMap::new();
        let mut check = |lo: &[f32; 3], hi: &[f32; 3], link: u32| {
            let inside = |r: PrimRef| {
                let (a, b) = prims.bounds_f64(r);
                (0..3).all(|k| lo[k] as f64 <= a[k] && b[k] <= hi[k] as f64)
            };
            match Link::decode(link) {
                Link::Inner(i) => assert!(i < g.nodes.len()),
                Link::Triangles { first, count } => {
                    assert!(count <= LEAF_MAX);
                    for t in &g.triangles[first..first + count] {
                        seen_tris[t.index as usize] += 1;
                        assert!(inside(PrimRef::new(PrimKind::Triangle, t.index as usize)));
                    }
                }
                Link::Shapes { first, count } => {
                    assert!(count <= LEAF_MAX);
                    for &r in &g.shape_refs[first..first + count] {
                        assert_ne!(PrimRef(r).kind(), PrimKind::Triangle);
                        *seen_shapes.entry(r).or_insert(0) += 1;
                        assert!(inside(PrimRef(r)));
                    }
                }
            }
        };
        for n in &g.nodes {
            check(&n.lo_a, &n.hi_a, n.link_a);
            check(&n.lo_b, &n.hi_b, n.link_b);
        }
        assert!(seen_tris.iter().all(|&s| s == 1));
        assert_eq!(seen_shapes.len(), prims.spheres.len() + prims.cylinders.len());
        assert!(seen_shapes.values().all(|&s| s == 1));
        assert!(g.depth <= MAX_DEPTH && g.depth >= bvh.depth, "{} vs {}", g.depth, bvh.depth);
        // Leaf-order triangles carry the vertices and material of the scene-order triangle they
        // name.
        for t in &g.triangles {
            let src = &prims.triangles[t.index as usize];
            assert_eq!([t.va, t.vb, t.vc], src.shape.v.map(|p| p.to_array()));
            assert_eq!(t.material, src.tag.material);
        }
    }

    #[test]
    fn walks_return_exactly_what_brute_force_returns() {
        let prims = mixed(2000, 11);
        let bvh = Bvh::build(&prims);
        let g = GpuBvh::collapse(&bvh, &prims).unwrap();
        let mut rng = TestRng(3);
        for _ in 0..3000 {
            let ray = ray_f32(&rng.ray_towards(25.0, V3::zero(), 20.0));
            let want = prims.nearest_brute(&ray, 0.0, f32::INFINITY);
            assert_eq!(nearest(&g, &prims, &ray, 0.0, f32::INFINITY), want, "{ray:?}");
            assert_eq!(all(&g, &prims, &ray, 0.0, 1e30), prims.all_brute(&ray, 0.0, 1e30), "{ray:?}");
            let reach = rng.range(0.0, 60.0) as f32;
            let blocked = prims.nearest_brute(&ray, 0.0, reach).is_some();
            assert_eq!(occluded(&g, &prims, &ray, 0.0, reach), blocked, "{ray:?} to {reach}");
        }
    }

    #[test]
    fn a_leaf_root_and_an_oversized_leaf_collapse_and_walk() {
        // Identical spheres: the binary tree cannot split them by centroid and halves the list,
        // down to leaves of MAX_LEAF; a one-leaf tree of three primitives has a leaf root.
        for n in [3usize, 100] {
            let mut p = Primitives::<f32>::default();
            for i in 0..n {
                let tag = Tag { object: i as u32, face: 0, material: 0 };
                p.spheres.push(Tagged { shape: Sphere { center: V3::new(0.0, 0.0, 5.0), radius: 1.0 }, tag });
            }
            let bvh = Bvh::build(&p);
            let g = GpuBvh::collapse(&bvh, &p).unwrap();
            let ray = Ray::new(V3::new(0.0, 0.0, 0.0), V3::new(0.0, 0.0, 1.0));
            let hit = nearest(&g, &p, &ray, 0.0, f32::INFINITY).expect("hits");
            assert_eq!((hit.t, hit.prim_ref), (4.0, PrimRef::new(PrimKind::Sphere, 0)));
            assert_eq!(all(&g, &p, &ray, 0.0, f32::INFINITY).len(), 2 * n);
        }
    }

    #[test]
    fn the_point_walk_returns_exactly_what_brute_force_returns() {
        use crate::proximity::{closest as binary_closest, closest_brute};
        let prims = crate::primitives::testutil::mixed_scene(5);
        let bvh = Bvh::build(&prims);
        let g = GpuBvh::collapse(&bvh, &prims).unwrap();
        let mut rng = TestRng(17);
        for k in 0..4000 {
            let p = match k % 6 {
                // On a surface (a foot of a random point), and just off one.
                0 => closest_brute(&prims, rng.in_cube(55.0).cast()).unwrap().foot.point,
                1 => {
                    closest_brute(&prims, rng.in_cube(55.0).cast()).unwrap().foot.point
                        + rng.unit_vector().cast() * 1e-3
                }
                // Inside the scene's cube, around it, far from it, and so far that squared
                // distances overflow (every foot at infinity: the tie rule alone decides).
                2 => rng.in_cube(50.0).cast(),
                3 => rng.in_cube(120.0).cast(),
                4 => rng.in_cube(1e4).cast(),
                _ => rng.in_cube(1e25).cast(),
            };
            let want = closest_brute(&prims, p);
            assert!(want.is_some());
            assert_eq!(closest(&g, &prims, p), want, "point {k} at {p:?}");
            assert_eq!(binary_closest(&bvh, &prims, p), want, "point {k} at {p:?}");
        }
    }

    #[test]
    fn the_point_walk_of_a_leaf_root_an_oversized_leaf_and_an_empty_scene() {
        use crate::proximity::closest_brute;
        for n in [0usize, 1, 3, 100] {
            let mut p = Primitives::<f32>::default();
            for i in 0..n {
                let tag = Tag { object: i as u32, face: 0, material: 0 };
                let center = V3::new(0.0, 0.0, 5.0 + (i % 3) as f32);
                p.spheres.push(Tagged { shape: Sphere { center, radius: 1.0 }, tag });
            }
            let bvh = Bvh::build(&p);
            let g = GpuBvh::collapse(&bvh, &p).unwrap();
            for q in [V3::new(0.0, 0.0, 0.0), V3::new(0.0, 0.0, 5.5), V3::new(3.0, -2.0, 40.0)] {
                let got = closest(&g, &p, q);
                assert_eq!(got, closest_brute(&p, q), "{n} spheres, point {q:?}");
                assert_eq!(got.is_none(), n == 0);
            }
        }
    }

    #[test]
    fn links_decode_what_the_collapse_encodes() {
        let leaf = LINK_LEAF | (3 << LINK_COUNT_SHIFT) | 17;
        assert_eq!(Link::decode(leaf), Link::Triangles { first: 17, count: 4 });
        assert_eq!(Link::decode(leaf | LINK_SHAPES), Link::Shapes { first: 17, count: 4 });
        assert_eq!(Link::decode(42), Link::Inner(42));
        assert_eq!(Link::decode(LINK_EMPTY), Link::Triangles { first: 0, count: 0 });
        // The last leaf the layout can index is not the empty link.
        let last = LINK_LEAF | LINK_SHAPES | ((LEAF_MAX as u32 - 1) << LINK_COUNT_SHIFT) | MAX_PRIMS as u32;
        assert_eq!(Link::decode(last), Link::Shapes { first: MAX_PRIMS, count: LEAF_MAX });
        assert_ne!(last, LINK_EMPTY);
    }
}
