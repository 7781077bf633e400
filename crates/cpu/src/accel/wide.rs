//! The CPU's traversal layout: the binary SAH tree of [`super::bvh`] collapsed into 8-wide
//! nodes, whose eight child boxes lie plane by plane (one 8-lane register per box plane), and
//! leaves of blocks of up to four primitives whose triangle vertices lie coordinate by
//! coordinate (one 4-lane register per coordinate), after Wald et al., "Embree: A Kernel
//! Framework for Efficient CPU Ray Tracing" (2014). Walked by [`super::wide_traverse`].
//!
//! The GPU keeps reading the binary tree; both trees have the same boxes, and the leaves hold
//! the same primitives, so the two traversals find the same hits.

use rayon::prelude::*;
use std::mem::MaybeUninit;
use strahl_core::accel::bvh::{Bvh, BvhNode};
use strahl_core::primitives::{PrimKind, PrimRef, Primitives, Tag};

/// Children per node.
pub const WIDTH: usize = 8;
/// Primitives per leaf block.
pub const LANES: usize = 4;
/// Blocks one leaf child may hold (the count has 3 bits in a child word).
pub const MAX_LEAF_BLOCKS: usize = 8;
/// Deepest wide tree the collapse makes: the binary tree's [`strahl_core::accel::bvh::MAX_DEPTH`], plus
/// the levels that would split an oversized binary leaf (at most log₈ of 2³⁰ primitives; the
/// build's leaves hold at most 12, which one wide leaf holds, so its trees need none of them).
pub const MAX_DEPTH: usize = strahl_core::accel::bvh::MAX_DEPTH as usize + 12;

/// A child word: an inner node's byte offset divided by 8 (an address the walk forms
/// without a multiplication), or (top bit set) a leaf.
pub const LEAF_BIT: u32 = 1 << 31;
/// A node's size in the units of inner child words.
const NODE_UNITS: u32 = (size_of::<WideNode>() / 8) as u32;

/// The child word of node `index`.
fn node_word(index: usize) -> u32 {
    let word = index as u64 * NODE_UNITS as u64;
    // Nodes never outnumber primitives, and scenes hold at most 65 million (file::MAX_*).
    assert!(word < LEAF_BIT as u64, "more than {} BVH nodes", LEAF_BIT / NODE_UNITS);
    word as u32
}
/// Leaf words: bits 28–30 hold the block count minus one.
const COUNT_SHIFT: u32 = 28;
/// Leaf words: bit 27 says some lane holds a sphere or cylinder (tested by the scalar code).
pub const OTHER_BIT: u32 = 1 << 27;
/// Leaf words: bits 0–26 hold the first block.
const FIRST_MASK: u32 = OTHER_BIT - 1;
/// The child word of an unused slot (its box is empty, so it is never entered).
pub const EMPTY_CHILD: u32 = u32::MAX;
/// The primitive of an unused lane.
pub const EMPTY_PRIM: u32 = u32::MAX;
/// The largest subtree [`leaf_choice`] may turn into one leaf (four blocks).
const MERGE_MAX: u32 = 4 * LANES as u32;

/// One node: the boxes of up to eight children and what each child is. 256 bytes, aligned to
/// its four cache lines.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideNode {
    /// `bounds[2a]`: the children's lower bounds on axis a; `bounds[2a + 1]`: the upper ones.
    /// An unused slot has lower +∞ and upper −∞, a box no ray enters.
    pub bounds: [[f32; WIDTH]; 6],
    pub child: [u32; WIDTH],
}

impl WideNode {
    const EMPTY: WideNode = WideNode {
        bounds: [
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
        ],
        child: [EMPTY_CHILD; WIDTH],
    };
}

/// Up to four primitives of one leaf. Triangle lanes carry their vertices; sphere and
/// cylinder lanes (and unused ones) carry zeros and are tested through [`Primitives`].
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafBlock {
    /// `v[k][a][lane]`: coordinate a of vertex k of the lane's triangle.
    pub v: [[[f32; LANES]; 3]; 3],
    /// Each lane's [`PrimRef`], or [`EMPTY_PRIM`].
    pub prim_ref: [u32; LANES],
}

impl LeafBlock {
    const EMPTY: LeafBlock = LeafBlock { v: [[[0.0; LANES]; 3]; 3], prim_ref: [EMPTY_PRIM; LANES] };
}

/// The decoded leaf word: blocks `first .. first + count`, and whether any lane is not a
/// triangle.
#[inline(always)]
pub fn leaf_blocks(word: u32) -> (usize, usize, bool) {
    ((word & FIRST_MASK) as usize, ((word >> COUNT_SHIFT) & 7) as usize + 1, word & OTHER_BIT != 0)
}

/// Tags of consecutive triangles: triangle `first + k` (until the next run) has object
/// `object`, face `face + k` and material `material`. A mesh is one run, so the
/// walk finds a hit's tag in this short table instead of loading the triangle again.
#[derive(Clone, Copy, Debug, PartialEq)]
struct TagRun {
    first: u32,
    tag: Tag,
}

/// The collapsed tree. Node 0 is the root (absent for a scene without bounded primitives).
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    nodes: Vec<WideNode>,
    blocks: Vec<LeafBlock>,
    runs: Vec<TagRun>,
    /// Longest root-to-leaf path in nodes; the traversal stack holds 7 entries per level.
    pub depth: usize,
}

impl WideBvh {
    /// Collapses `bvh`, built over `prims`: each node takes up to eight descendants of a
    /// binary node, opening the one of largest surface area first (as Embree's BVH8 builder
    /// does); subtrees of up to four primitives become one leaf block.
    ///
    /// This thread collapses the top levels; every wide subtree below them of at most a
    /// 64th of the primitives is collapsed by a task of its own into arrays of its own, and
    /// the pieces are then copied side by side (their child words moved by their offsets),
    /// each block filled as it lands.
    pub fn new(bvh: &Bvh, prims: &Primitives<f32>) -> WideBvh {
        const MIN_TASK: u32 = 4096;
        let total = bvh.prim_refs.len() as u32;
        WideBvh::collapse(bvh, prims, (total >= 2 * MIN_TASK).then(|| (total / 64).max(MIN_TASK)))
    }

    /// [`WideBvh::new`], with subtrees of at most `cut` primitives left to tasks (none:
    /// everything collapsed by this thread).
    fn collapse(bvh: &Bvh, prims: &Primitives<f32>, cut: Option<u32>) -> WideBvh {
        if bvh.nodes.is_empty() {
            return WideBvh::default();
        }
        let info = node_info(bvh);
        let mut top = Collapse::new(bvh, &info, cut);
        // The root is always a wide node (with one leaf child if the binary root is a leaf),
        // so the walk starts with a box test of its children.
        top.node_over(0, 0, 1);
        let tasks = std::mem::take(&mut top.tasks);
        let parts: Vec<Collapse> = tasks
            .par_iter()
            .map(|t| {
                let mut c = Collapse::new(bvh, &info, None);
                // About what collapses make (on the bumpy torus 0.05 nodes and 0.28 blocks per
                // primitive), so that the arrays seldom grow.
                let count = (info[t.bin] & !INFO_LEAF) as usize;
                c.nodes.reserve(count / 12 + 8);
                c.spans.reserve(count / 3 + 8);
                c.node_over(t.bin, t.first, t.depth);
                c
            })
            .collect();
        // Where each part lands, in nodes and in blocks.
        let (mut node_count, mut block_count) = (top.nodes.len(), top.spans.len());
        let mut bases = Vec::with_capacity(parts.len());
        for (t, part) in tasks.iter().zip(&parts) {
            top.nodes[t.node].child[t.slot] = node_word(node_count);
            bases.push((node_word(node_count), block_count as u32));
            (node_count, block_count) = (node_count + part.nodes.len(), block_count + part.spans.len());
        }
        // Both counts fit their fields of the child words.
        node_word(node_count);
        assert!(block_count <= FIRST_MASK as usize + 1, "more than {} leaf blocks", FIRST_MASK as usize + 1);
        let depth = parts.iter().map(|p| p.depth).fold(top.depth, usize::max);

        let mut nodes = strahl_core::accel::huge_pages::vec_with_capacity(node_count);
        let mut blocks = strahl_core::accel::huge_pages::vec_with_capacity(block_count);
        {
            let mut nodes_left = &mut nodes.spare_capacity_mut()[..node_count];
            let mut blocks_left = &mut blocks.spare_capacity_mut()[..block_count];
            let mut node_jobs = Vec::with_capacity(parts.len() + 1);
            let mut block_jobs = Vec::new();
            for (part, base) in std::iter::once((&top, (0, 0))).chain(parts.iter().zip(bases.iter().copied())) {
                let (n, rest) = std::mem::take(&mut nodes_left).split_at_mut(part.nodes.len());
                nodes_left = rest;
                node_jobs.push((n, &part.nodes[..], base));
                let (b, rest) = std::mem::take(&mut blocks_left).split_at_mut(part.spans.len());
                blocks_left = rest;
                block_jobs.extend(b.chunks_mut(BLOCK_JOB).zip(part.spans.chunks(BLOCK_JOB)));
            }
            node_jobs.into_par_iter().for_each(|(out, nodes, (node_base, block_base))| {
                for (o, n) in out.iter_mut().zip(nodes) {
                    let mut n = *n;
                    for w in &mut n.child {
                        *w = relocate(*w, node_base, block_base);
                    }
                    o.write(n);
                }
            });
            block_jobs.into_par_iter().for_each(|(out, spans)| fill_blocks(out, spans, bvh, prims));
        }
        // SAFETY: the jobs above wrote every one of the first `node_count` nodes and
        // `block_count` blocks (the pieces cover them side by side).
        unsafe {
            nodes.set_len(node_count);
            blocks.set_len(block_count);
        }
        WideBvh { nodes, blocks, runs: tag_runs(prims), depth }
    }

    /// The tag of triangle `index` (as `prims.triangles[index].tag` of the primitives this
    /// tree was built over).
    #[inline]
    pub fn triangle_tag(&self, index: usize) -> Tag {
        let r = &self.runs[self.runs.partition_point(|r| r.first as usize <= index) - 1];
        Tag { face: r.tag.face + (index as u32 - r.first), ..r.tag }
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    /// The leaf blocks of a leaf's child word.
    #[inline(always)]
    pub fn leaf(&self, word: u32) -> (&[LeafBlock], bool) {
        let (first, count, other) = leaf_blocks(word);
        (&self.blocks[first..first + count], other)
    }

    /// The inner node of child word `word`.
    #[inline(always)]
    pub(crate) fn node(&self, word: u32) -> &WideNode {
        debug_assert!(word.is_multiple_of(NODE_UNITS) && ((word / NODE_UNITS) as usize) < self.nodes.len());
        // SAFETY: every inner child word is a node's offset in units of 8 bytes (see
        // `node_word`); the walk reads only child words of this tree, starting at the root, 0.
        unsafe { &*self.nodes.as_ptr().cast::<u8>().add(word as usize * 8).cast::<WideNode>() }
    }

    /// Asks for the cache lines of what child word `word` names, ahead of its visit: the four
    /// lines of a node, or the first two blocks of a leaf (a hint; nothing where unsupported).
    #[inline(always)]
    pub fn prefetch_word(&self, word: u32) {
        let (start, len) = if word & LEAF_BIT == 0 {
            (self.nodes.as_ptr().cast::<u8>().wrapping_add(word as usize * 8), size_of::<WideNode>())
        } else {
            let (first, count, _) = leaf_blocks(word);
            (self.blocks.as_ptr().wrapping_add(first).cast::<u8>(), count.min(2) * size_of::<LeafBlock>())
        };
        for offset in (0..len).step_by(64) {
            prefetch_address(start.wrapping_add(offset));
        }
    }

    /// Bytes held: nodes and leaf blocks (the blocks carry the triangles' vertices and
    /// references, so this is the whole of what the CPU walk reads but for spheres and
    /// cylinders).
    pub fn bytes(&self) -> usize {
        self.nodes.len() * size_of::<WideNode>()
            + self.blocks.len() * size_of::<LeafBlock>()
            + self.runs.len() * size_of::<TagRun>()
    }

    /// Used lanes over all lanes of the leaf blocks.
    pub fn block_fill(&self) -> f64 {
        let used = self.blocks.iter().flat_map(|b| b.prim_ref).filter(|&p| p != EMPTY_PRIM).count();
        used as f64 / (self.blocks.len() * LANES).max(1) as f64
    }
}

/// The runs of [`WideBvh::triangle_tag`].
fn tag_runs(prims: &Primitives<f32>) -> Vec<TagRun> {
    let mut runs: Vec<TagRun> = Vec::new();
    for (i, t) in prims.triangles.iter().enumerate() {
        let continues = runs.last().is_some_and(|r| {
            let k = i as u32 - r.first;
            r.tag.object == t.tag.object
                && r.tag.material == t.tag.material
                && r.tag.face.checked_add(k) == Some(t.tag.face)
        });
        if !continues {
            runs.push(TagRun { first: i as u32, tag: t.tag });
        }
    }
    runs
}

/// The block of the primitives `refs` (at most four).
fn block(refs: &[PrimRef], prims: &Primitives<f32>) -> LeafBlock {
    let mut b = LeafBlock::EMPTY;
    for (lane, r) in refs.iter().enumerate() {
        b.prim_ref[lane] = r.0;
        if r.kind() == PrimKind::Triangle {
            let tri = &prims.triangles[r.index()].shape;
            for k in 0..3 {
                for a in 0..3 {
                    b.v[k][a][lane] = tri.v[k][a];
                }
            }
        }
    }
    b
}

/// Blocks filled per task.
const BLOCK_JOB: usize = 4096;

/// Fills `out` with the blocks of `spans` (first primitive in `prim_refs`, count).
fn fill_blocks(out: &mut [MaybeUninit<LeafBlock>], spans: &[(u32, u8)], bvh: &Bvh, prims: &Primitives<f32>) {
    let refs = |&(first, n): &(u32, u8)| &bvh.prim_refs[first as usize..first as usize + n as usize];
    // The triangles are read in leaf order, far from their order in `prims`: the loads of a
    // block 16 ahead are started early, so that their misses overlap.
    const AHEAD: usize = 16;
    for (i, (b, span)) in out.iter_mut().zip(spans).enumerate() {
        for r in spans.get(i + AHEAD).map_or(&[][..], refs) {
            if r.kind() == PrimKind::Triangle {
                prefetch(&prims.triangles[r.index()]);
            }
        }
        b.write(block(refs(span), prims));
    }
}

/// A child word of a piece collapsed on its own, moved to where the piece lands: inner
/// words by `node_base` (in word units), leaf words by `block_base` blocks.
fn relocate(word: u32, node_base: u32, block_base: u32) -> u32 {
    if word == EMPTY_CHILD {
        word
    } else if word & LEAF_BIT != 0 {
        word + block_base
    } else {
        word + node_base
    }
}

/// [`node_info`]: the binary node becomes a leaf of the wide tree.
const INFO_LEAF: u32 = 1 << 31;

/// Per binary node: how many primitives lie under it, and (bit [`INFO_LEAF`]) whether it
/// becomes a leaf of the wide tree: binary leaves, and subtrees of at most `MERGE_MAX`
/// primitives whose SAH cost as one leaf (a 4-lane block test per 4 primitives) is below
/// that of opening them (a share of a node test, plus their children's best cost). Computed
/// bottom-up, the two children of large subtrees in parallel. The blocks of a leaf are
/// tested independently of each other, so a block costs about what a node visit costs;
/// with these weights subtrees of up to 8 primitives (sometimes 16) become leaves: camera rays
/// as fast as with smaller leaves, random rays faster, and less memory (the book's performance
/// chapter, "Design choices measured").
fn node_info(bvh: &Bvh) -> Vec<u32> {
    let n = bvh.nodes.len();
    let mut info = strahl_core::accel::huge_pages::vec_with_capacity(n);
    info_of(bvh, 0, &mut info.spare_capacity_mut()[..n]);
    // SAFETY: `info_of` writes one entry per node of the subtree of node 0: every node.
    unsafe { info.set_len(n) };
    info
}

/// Fills `out`, the entries of the subtree of binary node `i` (which occupies `i ..` up to
/// the end of its right subtree, depth first); returns its primitive count and SAH cost.
fn info_of(bvh: &Bvh, i: usize, out: &mut [MaybeUninit<u32>]) -> (u32, f32) {
    const BLOCK: f32 = 1.0;
    const OPEN: f32 = 1.0;
    /// Subtrees of more nodes than this have their halves done in parallel.
    const PARALLEL: usize = 1 << 14;
    let n = &bvh.nodes[i];
    let area = half_area(n);
    let (me, rest) = out.split_first_mut().expect("a subtree has a node");
    if n.is_leaf() {
        me.write(n.count | INFO_LEAF);
        return (n.count, area * BLOCK * n.count.div_ceil(LANES as u32) as f32);
    }
    let right = n.left_or_first as usize;
    let (l, r) = rest.split_at_mut(right - i - 1);
    let ((count_l, cost_l), (count_r, cost_r)) = if l.len() + r.len() > PARALLEL {
        rayon::join(|| info_of(bvh, i + 1, l), || info_of(bvh, right, r))
    } else {
        (info_of(bvh, i + 1, l), info_of(bvh, right, r))
    };
    let count = count_l + count_r;
    let as_leaf = area * BLOCK * count.div_ceil(LANES as u32) as f32;
    let open = area * OPEN + cost_l + cost_r;
    let leaf = count <= MERGE_MAX && as_leaf <= open;
    me.write(count | if leaf { INFO_LEAF } else { 0 });
    (count, if leaf { as_leaf } else { open })
}

fn half_area(n: &BvhNode) -> f32 {
    let e = [n.bmax[0] - n.bmin[0], n.bmax[1] - n.bmin[1], n.bmax[2] - n.bmin[2]];
    e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
}

/// A wide subtree left to a task: below binary node `bin` (whose primitives start at
/// `first`), at wide depth `depth`, the child `slot` of node `node` of the top.
struct Task {
    bin: usize,
    first: u32,
    depth: usize,
    node: usize,
    slot: usize,
}

/// One piece of the collapse: its nodes (child words relative to its own arrays) and leaf
/// blocks.
struct Collapse<'a> {
    bvh: &'a Bvh,
    info: &'a [u32],
    /// Wide subtrees of at most this many primitives are left to [`Task`]s.
    cut: Option<u32>,
    tasks: Vec<Task>,
    nodes: Vec<WideNode>,
    /// Per leaf block: first primitive (index into `prim_refs`) and how many.
    spans: Vec<(u32, u8)>,
    depth: usize,
}

impl<'a> Collapse<'a> {
    fn new(bvh: &'a Bvh, info: &'a [u32], cut: Option<u32>) -> Collapse<'a> {
        Collapse { bvh, info, cut, tasks: Vec::new(), nodes: Vec::new(), spans: Vec::new(), depth: 0 }
    }

    /// Whether binary node `i` becomes a leaf child (small enough, or a binary leaf).
    fn is_leaf(&self, i: usize) -> bool {
        self.info[i] & INFO_LEAF != 0
    }

    fn count(&self, i: usize) -> u32 {
        self.info[i] & !INFO_LEAF
    }

    /// A wide node over the descendants of binary node `bin`, whose primitives start at
    /// `first` (over `bin` itself when it is to be a leaf, which only the root can be
    /// here). Returns the node's child word.
    fn node_over(&mut self, bin: usize, first: u32, depth: usize) -> u32 {
        self.depth = self.depth.max(depth);
        let me = self.nodes.len();
        self.nodes.push(WideNode::EMPTY);
        // Binary nodes and their first primitives, and the surface area of those that may
        // be opened (None for leaves).
        let mut kids = [(0usize, 0u32); WIDTH];
        let mut areas = [None; WIDTH];
        let mut len = 1;
        if self.is_leaf(bin) {
            kids[0] = (bin, first);
        } else {
            [kids[0], kids[1]] = self.children(bin, first);
            (areas[0], areas[1]) = (self.openable_area(kids[0].0), self.openable_area(kids[1].0));
            len = 2;
        }
        // Open the child of largest surface area (the last of equals) until eight are
        // gathered.
        while len < WIDTH {
            let mut open: Option<(usize, f32)> = None;
            for (k, a) in areas[..len].iter().enumerate() {
                if let Some(a) = *a
                    && open.is_none_or(|(_, b)| a.total_cmp(&b).is_ge())
                {
                    open = Some((k, a));
                }
            }
            let Some((k, _)) = open else { break };
            [kids[k], kids[len]] = self.children(kids[k].0, kids[k].1);
            (areas[k], areas[len]) = (self.openable_area(kids[k].0), self.openable_area(kids[len].0));
            len += 1;
        }
        for (slot, &(k, first)) in kids[..len].iter().enumerate() {
            let n = self.bvh.nodes[k];
            set_box(&mut self.nodes[me], slot, n.bmin, n.bmax);
            let word = if self.is_leaf(k) {
                self.leaf(first, self.count(k), (n.bmin, n.bmax), depth)
            } else if self.cut.is_some_and(|cut| self.count(k) <= cut) {
                self.tasks.push(Task { bin: k, first, depth: depth + 1, node: me, slot });
                EMPTY_CHILD
            } else {
                self.node_over(k, first, depth + 1)
            };
            self.nodes[me].child[slot] = word;
        }
        node_word(me)
    }

    /// The surface area of binary node `i`, unless it becomes a leaf.
    fn openable_area(&self, i: usize) -> Option<f32> {
        (!self.is_leaf(i)).then(|| half_area(&self.bvh.nodes[i]))
    }

    /// The children of binary node `i` and their first primitives.
    fn children(&self, i: usize, first: u32) -> [(usize, u32); 2] {
        [(i + 1, first), (self.bvh.nodes[i].left_or_first as usize, first + self.count(i + 1))]
    }

    /// The child word of a leaf over `prim_refs[first .. first + n]`, whose box is `bounds`.
    /// A leaf too large for one word becomes a node of smaller leaves, each with the whole
    /// leaf's box (the build's leaves never are: it keeps them at 12 primitives or fewer).
    fn leaf(&mut self, first: u32, n: u32, bounds: ([f32; 3], [f32; 3]), depth: usize) -> u32 {
        let max = (MAX_LEAF_BLOCKS * LANES) as u32;
        if n > max {
            self.depth = self.depth.max(depth + 1);
            let me = self.nodes.len();
            self.nodes.push(WideNode::EMPTY);
            let per = n.div_ceil(WIDTH as u32).max(max);
            for (slot, at) in (first..first + n).step_by(per as usize).enumerate() {
                let take = per.min(first + n - at);
                set_box(&mut self.nodes[me], slot, bounds.0, bounds.1);
                self.nodes[me].child[slot] = self.leaf(at, take, bounds, depth + 1);
            }
            return node_word(me);
        }
        let first_block = self.spans.len() as u32;
        let mut other = false;
        for at in (first..first + n).step_by(LANES) {
            let take = (first + n - at).min(LANES as u32);
            self.spans.push((at, take as u8));
            other |= (at..at + take).any(|i| self.bvh.prim_refs[i as usize].kind() != PrimKind::Triangle);
        }
        let blocks = n.div_ceil(LANES as u32);
        LEAF_BIT | ((blocks - 1) << COUNT_SHIFT) | if other { OTHER_BIT } else { 0 } | first_block
    }
}

fn set_box(node: &mut WideNode, slot: usize, lo: [f32; 3], hi: [f32; 3]) {
    for a in 0..3 {
        node.bounds[2 * a][slot] = lo[a];
        node.bounds[2 * a + 1][slot] = hi[a];
    }
}

/// Asks for the cache line at `p` ahead of its use (a hint; nothing where unsupported).
#[inline(always)]
pub fn prefetch<T>(p: &T) {
    prefetch_address((p as *const T).cast());
}

/// Asks for every cache line `p` spans.
#[inline(always)]
pub fn prefetch_all<T>(p: &T) {
    let start: *const u8 = (p as *const T).cast();
    let size = std::mem::size_of::<T>();
    for offset in (0..size).step_by(64) {
        prefetch_address(start.wrapping_add(offset));
    }
    // The last line, where the object does not start on a line's first byte.
    prefetch_address(start.wrapping_add(size.saturating_sub(1)));
}

/// Asks for the cache line holding `p`, which need not point into anything: a prefetch never
/// faults, so no address is read or written.
#[inline(always)]
fn prefetch_address(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults, whatever the address; SSE is part of x86-64.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast())
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::geometry::Triangle;
    use strahl_core::geometry::testutil::{TestRays, TestRng};
    use strahl_core::primitives::Tagged;
    use strahl_core::primitives::testutil::mixed_scene;

    /// The subtree under child word `word`: boxes and child structure, and per leaf its
    /// primitives, in slot order (independent of where the nodes and blocks lie).
    fn shape(w: &WideBvh, word: u32, out: &mut Vec<u32>) {
        if word & LEAF_BIT != 0 {
            let (blocks, other) = w.leaf(word);
            out.extend([u32::MAX, blocks.len() as u32, other as u32]);
            out.extend(blocks.iter().flat_map(|b| b.prim_ref));
            return;
        }
        let n = w.node(word);
        out.extend(n.bounds.iter().flatten().map(|v| v.to_bits()));
        for &c in &n.child {
            if c != EMPTY_CHILD {
                shape(w, c, out);
            }
        }
    }

    /// Collapsed in pieces by tasks, the tree is the one collapsed by one thread, and every
    /// primitive lies in exactly one block.
    #[test]
    fn collapsing_in_pieces_gives_the_same_tree() {
        let mut prims = mixed_scene(3);
        let mut rng = TestRng(11);
        for face in 0..40_000 {
            let c = rng.in_cube(60.0);
            let tri = Triangle { v: [0, 1, 2].map(|_| c + rng.in_cube(0.7)) };
            prims
                .triangles
                .push(Tagged { shape: tri.cast(), tag: strahl_core::primitives::Tag { object: 9, face, material: 0 } });
        }
        let bvh = Bvh::build(&prims);
        let whole = WideBvh::collapse(&bvh, &prims, None);
        for cut in [Some(4096), Some(700)] {
            let pieces = WideBvh::collapse(&bvh, &prims, cut);
            assert_eq!(pieces.node_count(), whole.node_count());
            assert_eq!(pieces.block_count(), whole.block_count());
            assert_eq!(pieces.depth, whole.depth);
            let (mut a, mut b) = (Vec::new(), Vec::new());
            shape(&pieces, node_word(0), &mut a);
            shape(&whole, node_word(0), &mut b);
            assert!(a == b, "cut {cut:?}: the trees differ");
        }
        let pieces = WideBvh::new(&bvh, &prims);
        let mut held: Vec<u32> = pieces.blocks.iter().flat_map(|b| b.prim_ref).filter(|&r| r != EMPTY_PRIM).collect();
        held.sort();
        let mut all: Vec<u32> = prims.bounded_refs().map(|r| r.0).collect();
        all.sort();
        assert!(held == all);
    }
}
