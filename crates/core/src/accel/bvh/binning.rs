//! Boxes, the 32-byte primitive records, and binning them on all three axes at once.

use super::*;

/// A box with a fourth lane of padding, so that growing one is two 4-lane min/max.
#[derive(Clone, Copy, Debug)]
pub(super) struct Aabb {
    pub(super) lo: F4,
    pub(super) hi: F4,
}

impl Aabb {
    #[inline(always)]
    pub(super) fn empty() -> Aabb {
        Aabb { lo: F4::splat(f32::INFINITY), hi: F4::splat(f32::NEG_INFINITY) }
    }
    #[inline(always)]
    pub(super) fn grow(&mut self, lo: F4, hi: F4) {
        self.lo = lo.min(self.lo);
        self.hi = hi.max(self.hi);
    }
    #[inline(always)]
    pub(super) fn grow_box(&mut self, o: &Aabb) {
        self.grow(o.lo, o.hi);
    }
    /// Half the surface area (the SAH only compares ratios); 0 for the empty box.
    #[inline(always)]
    pub(super) fn half_area(&self) -> f32 {
        self.hi.sub(self.lo).half_area()
    }
    pub(super) fn lo3(&self) -> [f32; 3] {
        let a = self.lo.to_array();
        [a[0], a[1], a[2]]
    }
    pub(super) fn hi3(&self) -> [f32; 3] {
        let a = self.hi.to_array();
        [a[0], a[1], a[2]]
    }
}

/// Rounds f64 bounds outward to f32, so the f32 box contains the exact primitive.
pub(super) fn outward(lo: V3<f64>, hi: V3<f64>) -> ([f32; 4], [f32; 4]) {
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
pub(super) struct Item {
    pub(super) lo: [f32; 4],
    pub(super) hi: [f32; 4],
}

impl Item {
    #[inline(always)]
    pub(super) fn prim(&self) -> PrimRef {
        PrimRef(self.lo[3].to_bits())
    }
    /// The box; the fourth lanes 0 (the reference's bits stay out of the arithmetic).
    #[inline(always)]
    pub(super) fn lanes(&self) -> (F4, F4) {
        (F4::new(self.lo).xyz(), F4::new(self.hi))
    }
    #[inline(always)]
    pub(super) fn centroid2(&self, axis: usize) -> f32 {
        self.lo[axis] + self.hi[axis]
    }
}

/// A range of items with the box of their boxes and the box of their doubled centroids.
#[derive(Clone, Copy, Debug)]
pub(super) struct Span {
    pub(super) bounds: Aabb,
    pub(super) centroids: Aabb,
}

impl Span {
    #[inline(always)]
    pub(super) fn empty() -> Span {
        Span { bounds: Aabb::empty(), centroids: Aabb::empty() }
    }
    #[inline(always)]
    pub(super) fn add(&mut self, it: &Item) {
        let (lo, hi) = it.lanes();
        self.bounds.grow(lo, hi);
        let c = lo.add(hi);
        self.centroids.grow(c, c);
    }
    pub(super) fn join(mut self, o: &Span) -> Span {
        self.bounds.grow_box(&o.bounds);
        self.centroids.grow_box(&o.centroids);
        self
    }
    pub(super) fn of(items: &[Item]) -> Span {
        let mut s = Span::empty();
        for it in items {
            s.add(it);
        }
        s
    }
}

/// Per axis and bin: the bins' boxes and counts (set 0; set 1 is scratch for binning).
pub(super) struct Bins {
    pub(super) n: usize,
    pub(super) boxes: [[[Aabb; BINS]; 3]; 2],
    pub(super) counts: [[[u32; BINS]; 3]; 2],
}

/// Maps a doubled centroid to its bin on each axis (fourth lanes: scale 0).
#[derive(Clone, Copy)]
pub(super) struct Binning {
    pub(super) n: usize,
    pub(super) lo: F4,
    pub(super) scale: F4,
    /// The last bin, n − 1.
    pub(super) top: F4,
    /// Whether the centroids spread on each axis (a zero scale otherwise).
    pub(super) spread: [bool; 3],
    pub(super) scale3: [f32; 3],
    pub(super) lo3: [f32; 3],
}

impl Binning {
    pub(super) fn new(centroids: &Aabb, count: usize) -> Binning {
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
    pub(super) fn bins(&self, c: F4) -> [u32; 4] {
        c.sub(self.lo).mul(self.scale).max(F4::splat(0.0)).min(self.top).to_u32()
    }

    /// Whether `it` falls into a bin below `split` on `axis`: the position of [`Self::bins`]
    /// (the same operations, so the same rounding) compared before truncation.
    #[inline(always)]
    pub(super) fn below(&self, it: &Item, axis: usize, split: f32) -> bool {
        (it.centroid2(axis) - self.lo3[axis]) * self.scale3[axis] < split
    }

    /// Bins `items` into `b` (only its first `n` bins are reset and used). Items alternate
    /// between two sets of bins, merged at the end: neighbouring items often fall into the
    /// same bin, and one set would make each update wait for the previous one's store.
    pub(super) fn fill_into(&self, items: &[Item], b: &mut Bins) {
        b.n = self.n;
        for set in 0..2 {
            for axis in 0..3 {
                b.boxes[set][axis][..self.n].fill(Aabb::empty());
                b.counts[set][axis][..self.n].fill(0);
            }
        }
        #[inline(always)]
        pub(super) fn add(binning: &Binning, b: &mut Bins, set: usize, it: &Item) {
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

    pub(super) fn fill(&self, items: &[Item]) -> Box<Bins> {
        let mut b = Bins::new();
        self.fill_into(items, &mut b);
        b
    }
}

impl Bins {
    pub(super) fn new() -> Box<Bins> {
        Box::new(Bins { n: 0, boxes: [[[Aabb::empty(); BINS]; 3]; 2], counts: [[[0; BINS]; 3]; 2] })
    }

    pub(super) fn merge(mut self: Box<Bins>, o: &Bins) -> Box<Bins> {
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
    pub(super) fn best(&self, binning: &Binning, parent_half_area: f32) -> Option<(usize, usize, f32)> {
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
pub(super) fn partition(items: &mut [Item], binning: &Binning, axis: usize, split: usize) -> (usize, Span, Span) {
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
