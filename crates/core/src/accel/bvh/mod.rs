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

mod binning;
mod lanes;
mod split;
#[cfg(test)]
mod tests;

use binning::*;
use lanes::F4;
use split::*;

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
