//! Where a node splits: the SAH over bins, exact splits of small nodes by sorting
//! networks, and the median split that bounds the depth.

use super::*;

/// What to do with a node: a leaf, or children over items[..mid] and items[mid..].
pub(super) enum Decision {
    Leaf,
    Split { mid: usize, left: Span, right: Span },
}

/// Nodes of at most this many primitives are split exactly instead of by binning: an exact
/// SAH sweep over so few primitives costs less than resetting and sweeping bins.
pub(super) const SMALL: usize = 12;

/// Sorting networks for 8 and 12 keys: Batcher's odd–even merge sort for 16, cut to the
/// first 8 or 12 inputs, each comparator dropped that the 0-1 principle shows redundant (19
/// and 41 comparators; the least known are 19 and 39). Fewer keys are padded with +∞.
#[rustfmt::skip]
pub(super) const NET8: [(u8, u8); 19] = [
    (0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (1, 2), (5, 6),
    (0, 4), (1, 5), (2, 6), (3, 7), (2, 4), (3, 5), (1, 2), (3, 4), (5, 6),
];
#[rustfmt::skip]
pub(super) const NET12: [(u8, u8); 41] = [
    (0, 1), (2, 3), (4, 5), (6, 7), (8, 9), (10, 11), (0, 2), (1, 3), (4, 6), (5, 7),
    (8, 10), (9, 11), (1, 2), (5, 6), (9, 10), (0, 4), (1, 5), (2, 6), (3, 7), (2, 4),
    (3, 5), (1, 2), (3, 4), (5, 6), (0, 8), (1, 9), (2, 10), (3, 11), (4, 8), (5, 9),
    (6, 10), (7, 11), (2, 4), (3, 5), (6, 8), (7, 9), (1, 2), (3, 4), (5, 6), (7, 8),
    (9, 10),
];

/// Sorts `keys` lane by lane with `net`. The keys must be distinct: a comparator keeps the
/// second of two equal keys on both sides.
#[inline(always)]
pub(super) fn sort_lanes<const N: usize>(keys: &mut [F4; SMALL], net: &[(u8, u8); N]) {
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
pub(super) fn decide_small(items: &mut [Item], span: &Span) -> Decision {
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
pub(super) fn decide_tiny(items: &mut [Item], span: &Span) -> Decision {
    /// The left sides (bit k: item k) of the splits of 2, 3 and 4 items.
    pub(super) const SIDES: [&[u8]; MAX_LEAF + 1] =
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
pub(super) fn levels_to_leaf(n: usize) -> u32 {
    n.div_ceil(MAX_LEAF).next_power_of_two().trailing_zeros()
}

/// The split of `items` at the median of their centroids on the axis where the centroids
/// spread widest: the halves differ by at most one, so each needs one level fewer
/// ([`levels_to_leaf`]).
pub(super) fn median_split(items: &mut [Item], span: &Span) -> Decision {
    let (clo, chi) = (span.centroids.lo.to_array(), span.centroids.hi.to_array());
    let axis = (0..3).max_by(|&a, &b| (chi[a] - clo[a]).total_cmp(&(chi[b] - clo[b]))).unwrap_or(0);
    let key = |it: &Item| it.lo[axis] + it.hi[axis];
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| key(a).total_cmp(&key(b)));
    Decision::Split { mid, left: Span::of(&items[..mid]), right: Span::of(&items[mid..]) }
}

/// Chooses between a leaf and the best split of `items` at `depth`; `scratch` holds the bins.
pub(super) fn decide(items: &mut [Item], span: &Span, depth: u32, scratch: &mut Bins) -> Decision {
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
