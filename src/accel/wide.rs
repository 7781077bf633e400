//! The CPU's traversal layout: the binary SAH tree of [`super::bvh`] collapsed into 8-wide
//! nodes, whose eight child boxes lie plane by plane (one 8-lane register per box plane), and
//! leaves of blocks of up to four primitives whose triangle vertices lie coordinate by
//! coordinate (one 4-lane register per coordinate), after Wald et al., "Embree: A Kernel
//! Framework for Efficient CPU Ray Tracing" (2014). Walked by [`super::wide_traverse`].
//!
//! The GPU keeps reading the binary tree; both trees have the same boxes, and the leaves hold
//! the same primitives, so the two traversals find the same hits.

use super::bvh::Bvh;
use crate::primitives::{PrimKind, PrimRef, Primitives, Tag};
use rayon::prelude::*;

/// Children per node.
pub const WIDTH: usize = 8;
/// Primitives per leaf block.
pub const LANES: usize = 4;
/// Blocks one leaf child may hold (the count has 3 bits in a child word).
pub const MAX_LEAF_BLOCKS: usize = 8;
/// Deepest wide tree the collapse makes: the binary tree's [`super::bvh::MAX_DEPTH`], plus
/// the levels that split an oversized binary leaf (at most log₈ of 2³⁰ primitives).
pub const MAX_DEPTH: usize = super::bvh::MAX_DEPTH as usize + 12;

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
    pub fn new(bvh: &Bvh, prims: &Primitives<f32>) -> WideBvh {
        if bvh.nodes.is_empty() {
            return WideBvh::default();
        }
        let (count, first) = subtree_ranges(bvh);
        let leaf = leaf_choice(bvh, &count);
        let mut c =
            Collapse { bvh, count: &count, first: &first, leaf: &leaf, nodes: Vec::new(), spans: Vec::new(), depth: 0 };
        // Room for more nodes than collapses make (about a tenth of the binary ones), so that
        // the advice for huge pages covers them; untouched room costs no memory.
        c.nodes = super::huge_pages::vec_with_capacity(bvh.nodes.len() / 4 + 64);
        c.spans.reserve(bvh.prim_refs.len() / 2 + 1);
        // The root is always a wide node (with one leaf child if the binary root is a leaf),
        // so the walk starts with a box test of its children.
        c.node_over(0, 1);
        let Collapse { nodes, spans, depth, .. } = c;
        let refs = |&(first, n): &(u32, u8)| &bvh.prim_refs[first as usize..first as usize + n as usize];
        // The triangles are read in leaf order, far from their order in `prims`: the loads of
        // a block 16 ahead are started early, so that their misses overlap.
        const AHEAD: usize = 16;
        let mut blocks = super::huge_pages::vec_with_capacity(spans.len());
        blocks.resize(spans.len(), LeafBlock::EMPTY);
        blocks.par_chunks_mut(4096).zip(spans.par_chunks(4096)).for_each(|(out, spans)| {
            for (i, (b, span)) in out.iter_mut().zip(spans).enumerate() {
                for r in spans.get(i + AHEAD).map_or(&[][..], refs) {
                    if r.kind() == PrimKind::Triangle {
                        super::simd::prefetch(&prims.triangles[r.index()]);
                    }
                }
                *b = block(refs(span), prims);
            }
        });
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

/// Which binary nodes become leaves of the wide tree: binary leaves, and subtrees of at most
/// `MERGE_MAX` primitives whose SAH cost as one leaf (a 4-lane block test per 4 primitives)
/// is below that of opening them (a share of a node test, plus their children's best cost).
/// Computed bottom-up. The blocks of a leaf are tested independently of each other, so a block
/// costs about what a node visit costs; with these weights subtrees of up to 8 primitives
/// (sometimes 16) become leaves, which on the bumpy torus gave the same camera-ray speed as
/// smaller leaves, faster random rays and 18 % less memory.
fn leaf_choice(bvh: &Bvh, count: &[u32]) -> Vec<bool> {
    const BLOCK: f32 = 1.0;
    const OPEN: f32 = 1.0;
    let area = |i: usize| {
        let n = &bvh.nodes[i];
        let e = [n.bmax[0] - n.bmin[0], n.bmax[1] - n.bmin[1], n.bmax[2] - n.bmin[2]];
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    };
    let mut cost = vec![0.0f32; bvh.nodes.len()];
    let mut leaf = vec![false; bvh.nodes.len()];
    for i in (0..bvh.nodes.len()).rev() {
        let n = &bvh.nodes[i];
        let as_leaf = area(i) * BLOCK * count[i].div_ceil(LANES as u32) as f32;
        if n.is_leaf() {
            (cost[i], leaf[i]) = (as_leaf, true);
            continue;
        }
        let open = area(i) * OPEN + cost[i + 1] + cost[n.left_or_first as usize];
        leaf[i] = count[i] <= MERGE_MAX && as_leaf <= open;
        cost[i] = if leaf[i] { as_leaf } else { open };
    }
    leaf
}

/// The primitives under each binary node: how many, and the first (the leaves of a subtree
/// hold a contiguous range of `prim_refs`, starting at its leftmost leaf's). Children follow
/// their parents in the array, so one backward pass suffices.
fn subtree_ranges(bvh: &Bvh) -> (Vec<u32>, Vec<u32>) {
    let mut count = vec![0u32; bvh.nodes.len()];
    let mut first = vec![0u32; bvh.nodes.len()];
    for i in (0..bvh.nodes.len()).rev() {
        let n = &bvh.nodes[i];
        (count[i], first[i]) = if n.is_leaf() {
            (n.count, n.left_or_first)
        } else {
            (count[i + 1] + count[n.left_or_first as usize], first[i + 1])
        };
    }
    (count, first)
}

struct Collapse<'a> {
    bvh: &'a Bvh,
    count: &'a [u32],
    first: &'a [u32],
    leaf: &'a [bool],
    nodes: Vec<WideNode>,
    /// Per leaf block: first primitive (index into `prim_refs`) and how many.
    spans: Vec<(u32, u8)>,
    depth: usize,
}

impl Collapse<'_> {
    fn area(&self, i: usize) -> f32 {
        let n = &self.bvh.nodes[i];
        let e = [n.bmax[0] - n.bmin[0], n.bmax[1] - n.bmin[1], n.bmax[2] - n.bmin[2]];
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }

    /// Whether binary node `i` becomes a leaf child (small enough, or a binary leaf).
    fn is_leaf(&self, i: usize) -> bool {
        self.leaf[i]
    }

    /// A wide node over the descendants of binary node `bin` (over `bin` itself when it is
    /// to be a leaf, which only the root can be here). Returns the node's index.
    fn node_over(&mut self, bin: usize, depth: usize) -> u32 {
        self.depth = self.depth.max(depth);
        let me = self.nodes.len();
        self.nodes.push(WideNode::EMPTY);
        let mut kids = [0usize; WIDTH];
        let mut len = 1;
        if self.is_leaf(bin) {
            kids[0] = bin;
        } else {
            [kids[0], kids[1]] = self.children(bin);
            len = 2;
        }
        // Open the child of largest surface area until eight are gathered.
        while len < WIDTH {
            let open = (0..len)
                .filter(|&k| !self.is_leaf(kids[k]))
                .max_by(|&a, &b| self.area(kids[a]).total_cmp(&self.area(kids[b])));
            let Some(k) = open else { break };
            [kids[k], kids[len]] = self.children(kids[k]);
            len += 1;
        }
        for (slot, &k) in kids[..len].iter().enumerate() {
            let n = self.bvh.nodes[k];
            set_box(&mut self.nodes[me], slot, n.bmin, n.bmax);
            let word = if self.is_leaf(k) {
                self.leaf(self.first[k], self.count[k], (n.bmin, n.bmax), depth)
            } else {
                self.node_over(k, depth + 1)
            };
            self.nodes[me].child[slot] = word;
        }
        node_word(me)
    }

    fn children(&self, i: usize) -> [usize; 2] {
        [i + 1, self.bvh.nodes[i].left_or_first as usize]
    }

    /// The child word of a leaf over `prim_refs[first .. first + n]`, whose box is `bounds`.
    /// A leaf too large for one word (only binary leaves cut off at the depth limit) becomes
    /// a node of smaller leaves, each with the whole leaf's box.
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
