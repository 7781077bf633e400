//! Binned SAH BVH build (Wald, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies", 2007), parallel with rayon, flattened depth-first into 32-byte nodes.

use crate::math::V3;
use crate::primitives::{PrimRef, Primitives};
use bytemuck::{Pod, Zeroable};

/// One node, 32 bytes, the layout of `BvhNode` in `shaders/types.wgsl`.
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

/// Deepest tree the build makes; the WGSL traversal stack (`TRAVERSAL_STACK`) holds this many.
pub const MAX_DEPTH: u32 = 48;
const BINS: usize = 16;
const MAX_LEAF: usize = 4;
/// Cost of visiting a node relative to one primitive test.
const TRAVERSAL_COST: f32 = 1.0;
/// Below this many primitives a subtree is built on the current thread.
const PARALLEL_THRESHOLD: usize = 4096;

#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl Aabb {
    const EMPTY: Aabb = Aabb { lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3] };
    fn grow(&mut self, o: &Aabb) {
        self.lo = std::array::from_fn(|k| self.lo[k].min(o.lo[k]));
        self.hi = std::array::from_fn(|k| self.hi[k].max(o.hi[k]));
    }
    fn grow_point(&mut self, p: [f32; 3]) {
        self.grow(&Aabb { lo: p, hi: p });
    }
    fn area(&self) -> f32 {
        if self.lo[0] > self.hi[0] {
            return 0.0;
        }
        let e = [self.hi[0] - self.lo[0], self.hi[1] - self.lo[1], self.hi[2] - self.lo[2]];
        2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
    }
}

/// Rounds f64 bounds outward to f32, so the f32 box contains the exact primitive.
fn outward(lo: V3<f64>, hi: V3<f64>) -> Aabb {
    let down = |v: f64| {
        let f = v as f32;
        if f as f64 > v { f.next_down() } else { f }
    };
    let up = |v: f64| {
        let f = v as f32;
        if (f as f64) < v { f.next_up() } else { f }
    };
    Aabb { lo: [down(lo.x), down(lo.y), down(lo.z)], hi: [up(hi.x), up(hi.y), up(hi.z)] }
}

#[derive(Clone, Copy)]
struct Item {
    bounds: Aabb,
    centroid: [f32; 3],
    prim: PrimRef,
}

enum BuildNode {
    Leaf { bounds: Aabb, first: usize, count: usize },
    Interior { bounds: Aabb, children: Box<[BuildNode; 2]> },
}

impl Bvh {
    /// Builds over every bounded primitive of `prims` (planes stay outside).
    pub fn build<R: crate::math::Real>(prims: &Primitives<R>) -> Bvh {
        use rayon::prelude::*;
        let refs: Vec<PrimRef> = prims.bounded_refs().collect();
        let mut items: Vec<Item> = refs
            .par_iter()
            .map(|&prim| {
                let (lo, hi) = prims.bounds_f64(prim);
                let bounds = outward(lo, hi);
                let c = (lo + hi) * 0.5;
                Item { bounds, centroid: [c.x as f32, c.y as f32, c.z as f32], prim }
            })
            .collect();
        if items.is_empty() {
            return Bvh::default();
        }
        let root = build_node(&mut items, 0, 1);
        let mut bvh = Bvh {
            nodes: Vec::with_capacity(2 * refs.len() / MAX_LEAF + 1),
            prim_refs: items.iter().map(|it| it.prim).collect(),
            depth: 0,
        };
        bvh.depth = flatten(&root, &mut bvh.nodes, 1);
        bvh
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
        let area = |n: &BvhNode| Aabb { lo: n.bmin, hi: n.bmax }.area() as f64;
        let Some(root) = self.nodes.first() else { return 0.0 };
        let root_area = area(root).max(f64::MIN_POSITIVE);
        self.nodes
            .iter()
            .map(|n| area(n) / root_area * if n.is_leaf() { n.count as f64 } else { TRAVERSAL_COST as f64 })
            .sum()
    }
}

fn bounds_of(items: &[Item]) -> (Aabb, Aabb) {
    let mut b = Aabb::EMPTY;
    let mut cb = Aabb::EMPTY;
    for it in items {
        b.grow(&it.bounds);
        cb.grow_point(it.centroid);
    }
    (b, cb)
}

/// Builds the subtree over `items`, which start at `offset` in the final primitive order.
fn build_node(items: &mut [Item], offset: usize, depth: u32) -> BuildNode {
    let (bounds, cbounds) = bounds_of(items);
    let n = items.len();
    let leaf = BuildNode::Leaf { bounds, first: offset, count: n };
    if n <= 1 || depth >= MAX_DEPTH {
        return leaf;
    }
    let split = best_split(items, &bounds, &cbounds);
    let mid = match split {
        Some((axis, pos, cost)) => {
            // Stay a leaf when no split pays for itself, if the leaf is small enough.
            if n <= MAX_LEAF && cost >= n as f32 {
                return leaf;
            }
            partition(items, |it| it.centroid[axis] < pos)
        }
        None if n <= MAX_LEAF => return leaf,
        // All centroids coincide: split the list in halves.
        None => n / 2,
    };
    let mid = if mid == 0 || mid == n { n / 2 } else { mid };
    let (left, right) = items.split_at_mut(mid);
    let (l, r) = if n >= PARALLEL_THRESHOLD {
        rayon::join(|| build_node(left, offset, depth + 1), || build_node(right, offset + mid, depth + 1))
    } else {
        (build_node(left, offset, depth + 1), build_node(right, offset + mid, depth + 1))
    };
    BuildNode::Interior { bounds, children: Box::new([l, r]) }
}

/// The SAH-best binned split: (axis, centroid position, cost in primitive tests per ray that
/// reaches this node).
fn best_split(items: &[Item], bounds: &Aabb, cb: &Aabb) -> Option<(usize, f32, f32)> {
    let parent_area = bounds.area();
    let mut best: Option<(usize, f32, f32)> = None;
    for axis in 0..3 {
        let (lo, hi) = (cb.lo[axis], cb.hi[axis]);
        if !(hi > lo) {
            continue;
        }
        let scale = BINS as f32 / (hi - lo);
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        for it in items {
            let b = (((it.centroid[axis] - lo) * scale) as usize).min(BINS - 1);
            bins[b].0.grow(&it.bounds);
            bins[b].1 += 1;
        }
        // Sweep from the right, then from the left, evaluating the SAH at each bin boundary.
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc.grow(&bins[i].0);
            cnt += bins[i].1;
            right_area[i] = acc.area();
            right_count[i] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in 1..BINS {
            acc.grow(&bins[i - 1].0);
            cnt += bins[i - 1].1;
            if cnt == 0 || right_count[i] == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (acc.area() * cnt as f32 + right_area[i] * right_count[i] as f32)
                    / parent_area.max(f32::MIN_POSITIVE);
            if best.is_none_or(|b| cost < b.2) {
                best = Some((axis, lo + i as f32 / scale, cost));
            }
        }
    }
    best
}

/// Moves the items satisfying `left` to the front; returns how many there are.
fn partition(items: &mut [Item], left: impl Fn(&Item) -> bool) -> usize {
    let mut i = 0;
    for j in 0..items.len() {
        if left(&items[j]) {
            items.swap(i, j);
            i += 1;
        }
    }
    i
}

/// Appends `node`'s subtree depth-first; returns its depth.
fn flatten(node: &BuildNode, out: &mut Vec<BvhNode>, depth: u32) -> u32 {
    match node {
        BuildNode::Leaf { bounds, first, count } => {
            out.push(BvhNode { bmin: bounds.lo, left_or_first: *first as u32, bmax: bounds.hi, count: *count as u32 });
            depth
        }
        BuildNode::Interior { bounds, children } => {
            let me = out.len();
            out.push(BvhNode { bmin: bounds.lo, left_or_first: 0, bmax: bounds.hi, count: 0 });
            let dl = flatten(&children[0], out, depth + 1);
            out[me].left_or_first = out.len() as u32;
            let dr = flatten(&children[1], out, depth + 1);
            dl.max(dr)
        }
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
            p.triangles.push(Tagged { shape: tri.cast(), tag: Tag { object: 0, prim: i as u32, material: 0 } });
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
