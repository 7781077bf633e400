//! The CPU's walk of the 8-wide tree ([`super::wide`]): nearest hit and occlusion.
//!
//! Per ray, the inverse direction, the near planes and the watertight test's shear are
//! computed once ([`RayPre`]). Each node tests its eight boxes at once; the children entered
//! are visited nearest first, the others stacked with their entry distance and dropped when
//! the search interval has shrunk below it. Leaves test four triangles at once. The occlusion
//! walk stops at the first hit. The lane tests ([`super::simd`]) compute what the scalar
//! routines compute, bit for bit, so [`nearest`] returns exactly [`Primitives::nearest_brute`]'s
//! hit: same `t`, same primitive, ties broken by the smaller [`PrimRef`].

#[cfg(target_arch = "x86_64")]
use super::packet::{self, PACKET};
use super::record::hit_record;
use super::simd::{self, Kernels, RayPre, Scalar, widen};
use super::wide::{EMPTY_PRIM, LANES, LEAF_BIT, LeafBlock, WIDTH, WideBvh};
use super::wide_all::{self, Stack};
use strahl_core::geometry::Part;
use strahl_core::math::Ray;
use strahl_core::math::V3;
use strahl_core::primitives::{Hit, Nearest, PrimRef, Primitives};

/// The nearest hit in (tmin, tmax), identical to [`Primitives::nearest_brute`].
pub fn nearest(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Option<Hit<f32>> {
    #[cfg(target_arch = "x86_64")]
    if simd::has_avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { nearest_avx2(w, prims, ray, tmin, tmax) };
    }
    nearest_scalar(w, prims, ray, tmin, tmax)
}

/// Whether anything is hit in (tmin, tmax): the same answer as `nearest(..).is_some()`,
/// found by stopping at the first hit.
pub fn occluded(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> bool {
    #[cfg(target_arch = "x86_64")]
    if simd::has_avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { occluded_avx2(w, prims, ray, tmin, tmax) };
    }
    if tmin >= 0.0 {
        occluded_with::<Scalar, false>(w, prims, ray, tmin, tmax)
    } else {
        occluded_with::<Scalar, true>(w, prims, ray, tmin, tmax)
    }
}

/// [`occluded`] in (0, tmax) for `n` ≤ 32 rays, `ray(i)` giving ray i and its tmax: bit i of
/// the answer is set where ray i is blocked. The rays are walked one after the other, in one
/// call (where [`occluded`] is a call per ray).
#[inline]
pub fn occluded_mask<'r>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    n: usize,
    ray: impl Fn(usize) -> (&'r Ray<f32>, f32),
) -> u32 {
    debug_assert!(n <= 32);
    #[cfg(target_arch = "x86_64")]
    if simd::has_avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { occluded_mask_avx2(w, prims, n, ray) };
    }
    (0..n).fold(0, |m, i| {
        let (r, tmax) = ray(i);
        m | (occluded_with::<Scalar, false>(w, prims, r, 0.0, tmax) as u32) << i
    })
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn occluded_mask_avx2<'r>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    n: usize,
    ray: impl Fn(usize) -> (&'r Ray<f32>, f32),
) -> u32 {
    (0..n).fold(0, |m, i| {
        let (r, tmax) = ray(i);
        m | (occluded_with::<simd::Avx2, false>(w, prims, r, 0.0, tmax) as u32) << i
    })
}

/// [`nearest`] with the portable lanes, whatever the CPU (for tests and comparisons).
pub fn nearest_scalar(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Option<Hit<f32>> {
    if tmin >= 0.0 {
        nearest_with::<Scalar, false>(w, prims, ray, tmin, tmax)
    } else {
        nearest_with::<Scalar, true>(w, prims, ray, tmin, tmax)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn nearest_avx2(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> Option<Hit<f32>> {
    if tmin >= 0.0 {
        nearest_with::<simd::Avx2, false>(w, prims, ray, tmin, tmax)
    } else {
        nearest_with::<simd::Avx2, true>(w, prims, ray, tmin, tmax)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn occluded_avx2(w: &WideBvh, prims: &Primitives<f32>, ray: &Ray<f32>, tmin: f32, tmax: f32) -> bool {
    if tmin >= 0.0 {
        occluded_with::<simd::Avx2, false>(w, prims, ray, tmin, tmax)
    } else {
        occluded_with::<simd::Avx2, true>(w, prims, ray, tmin, tmax)
    }
}

/// Visits the children entered (`mask`, distances `tnear`) of `node`: returns the nearest,
/// after stacking the others farthest first.
#[inline(always)]
fn order_children(child: &[u32; WIDTH], mut mask: u32, tnear: &[f32; WIDTH], stack: &mut Stack) -> u32 {
    let first = mask.trailing_zeros() as usize;
    mask &= mask - 1;
    if mask == 0 {
        return child[first];
    }
    let second = mask.trailing_zeros() as usize;
    mask &= mask - 1;
    if mask == 0 {
        // Two children, the common case: no sort.
        let (near, far) = if tnear[second] < tnear[first] { (second, first) } else { (first, second) };
        stack.push(child[far], tnear[far]);
        return child[near];
    }
    // Three or more: insertion sort by distance, farthest first, on keys that hold the
    // distance's bits above the child word (distances here are ≥ 0, whose bits order as the
    // values do; a negative one only changes the visiting order).
    let key = |i: usize| (tnear[i].to_bits() as u64) << 32 | child[i] as u64;
    let mut list = [0u64; WIDTH];
    list[0] = key(first);
    list[1] = key(second);
    let mut n = 2;
    while mask != 0 {
        let i = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        list[n] = key(i);
        n += 1;
    }
    for i in 1..n {
        let x = list[i];
        let mut j = i;
        while j > 0 && list[j - 1] < x {
            list[j] = list[j - 1];
            j -= 1;
        }
        list[j] = x;
    }
    for &k in &list[..n - 1] {
        stack.push(k as u32, f32::from_bits((k >> 32) as u32));
    }
    list[n - 1] as u32
}

/// One ray's nearest-hit search, advanced a step (a node or a leaf) at a time, so that
/// [`nearest_many`] can interleave the searches of several rays.
struct NearestWalk<'a> {
    w: &'a WideBvh,
    prims: &'a Primitives<f32>,
    pre: RayPre,
    tmin: f32,
    best: Nearest<f32>,
    /// `best`'s search bound, and its widening for box entry distances.
    bound: f32,
    cull: f32,
    /// The next child word to visit.
    word: u32,
    running: bool,
    /// The block of the best triangle hit so far, for its hit record.
    from_block: Option<&'a LeafBlock>,
    stack: Stack,
}

impl<'a> NearestWalk<'a> {
    #[inline(always)]
    fn new(w: &'a WideBvh, prims: &'a Primitives<f32>) -> Self {
        let ray = Ray::new(V3::zero(), V3::new(0.0, 0.0, 1.0));
        Self {
            w,
            prims,
            pre: RayPre::new(&ray),
            tmin: 0.0,
            best: Nearest::new(0.0),
            bound: 0.0,
            cull: 0.0,
            word: 0,
            running: false,
            from_block: None,
            stack: Stack::new(),
        }
    }

    /// Starts the search for `ray` in (tmin, tmax); planes are tested here.
    #[inline(always)]
    fn start(&mut self, ray: &Ray<f32>, tmin: f32, tmax: f32) {
        self.best = Nearest::new(tmax);
        for r in self.prims.plane_refs() {
            self.prims.offer_nearest(r, ray, tmin, &mut self.best);
        }
        self.pre = RayPre::new(ray);
        // +0 for −0: the integer form of the box test (see simd::Avx2::boxes) needs it.
        self.tmin = tmin + 0.0;
        self.bound = self.best.search_bound();
        self.cull = widen(self.bound);
        self.word = 0; // the root node
        self.running = !self.w.is_empty();
        self.from_block = None;
        self.stack.clear();
    }

    /// Visits the next node or leaf; false once the search is over.
    #[inline(always)]
    fn step<K: Kernels, const NEG: bool>(&mut self) -> bool {
        let word = self.word;
        let next = if word & LEAF_BIT == 0 {
            let node = self.w.node(word);
            let mut tnear = [0.0f32; WIDTH];
            // SAFETY: K's features are present (the caller dispatched on them).
            let mask = unsafe { K::boxes::<NEG>(node, &self.pre, self.tmin, self.cull, &mut tnear) };
            (mask != 0).then(|| order_children(&node.child, mask, &tnear, &mut self.stack))
        } else {
            self.leaf::<K>(word);
            None
        };
        self.word = match next {
            Some(n) => n,
            None => match self.stack.pop_within(self.cull) {
                Some(n) => n,
                None => {
                    self.running = false;
                    return false;
                }
            },
        };
        true
    }

    #[inline(always)]
    fn leaf<K: Kernels>(&mut self, word: u32) {
        let (blocks, other) = self.w.leaf(word);
        let mut t = [0.0f32; LANES];
        // Every block is tested against the bound at the leaf's entry, so that the tests do
        // not wait on each other; the offers keep the nearest.
        let bound = self.bound;
        for block in blocks {
            // SAFETY: as in `step`.
            let mut hits = unsafe { K::triangles(block, &self.pre, self.tmin, bound, &mut t) };
            if hits != 0 {
                let before = self.best.prim_ref;
                while hits != 0 {
                    let lane = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    self.best.offer(t[lane], PrimRef(block.prim_ref[lane]), Part::Surface);
                }
                if self.best.prim_ref != before {
                    self.from_block = Some(block);
                }
            }
            if other {
                for &p in &block.prim_ref {
                    if p != EMPTY_PRIM && !simd::is_triangle(p) {
                        self.prims.offer_nearest(PrimRef(p), &self.pre.ray, self.tmin, &mut self.best);
                    }
                }
            }
        }
        self.bound = self.best.search_bound();
        self.cull = widen(self.bound);
    }

    /// The hit record of the search's result.
    #[inline(always)]
    fn hit(&self) -> Option<Hit<f32>> {
        hit_record(self.w, self.prims, &self.pre.ray, &self.best, self.from_block)
    }
}

#[inline(always)]
fn nearest_with<K: Kernels, const NEG: bool>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    tmin: f32,
    tmax: f32,
) -> Option<Hit<f32>> {
    let mut walk = NearestWalk::new(w, prims);
    walk.start(ray, tmin, tmax);
    if walk.running {
        while walk.step::<K, NEG>() {}
    }
    walk.hit()
}

/// Goes on with a nearest-hit search in (0, ∞) for `pre`'s ray from child word `word`, with
/// `best` the best hit so far (updated): the bundle walk's ending for a subtree that few of
/// its lanes enter ([`super::bundle`]).
#[inline(always)]
pub(super) fn nearest_from<K: Kernels>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    pre: &RayPre,
    word: u32,
    best: &mut Nearest<f32>,
) {
    let bound = best.search_bound();
    let mut walk = NearestWalk {
        w,
        prims,
        pre: *pre,
        tmin: 0.0,
        best: *best,
        bound,
        cull: widen(bound),
        word,
        running: true,
        from_block: None,
        stack: Stack::new(),
    };
    while walk.step::<K, false>() {}
    *best = walk.best;
}

/// [`nearest`] for each of `rays` in (tmin, tmax), into `out` (as long as `rays`); the
/// answers are those of [`nearest`]. With AVX2 and tmin ≥ 0, each group of eight coherent
/// rays (a camera's neighbours) is walked as one packet ([`packet`]), which shares each node's
/// loads among the eight. The other rays advance several searches ([`IN_FLIGHT`]) side by side,
/// so that the processor overlaps the memory latency of one with the work of the others: this
/// pays where the tree does not fit in the caches (random rays). Both gains are in the book's
/// performance chapter ("Design choices measured").
pub fn nearest_many(
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &[Ray<f32>],
    tmin: f32,
    tmax: f32,
    out: &mut [Option<Hit<f32>>],
) {
    assert_eq!(rays.len(), out.len(), "one answer per ray");
    #[cfg(target_arch = "x86_64")]
    if simd::has_avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { nearest_many_avx2(w, prims, rays, tmin, tmax, out) };
    }
    if tmin >= 0.0 {
        nearest_many_with::<Scalar, false>(w, prims, rays, tmin, tmax, out)
    } else {
        nearest_many_with::<Scalar, true>(w, prims, rays, tmin, tmax, out)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn nearest_many_avx2(
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &[Ray<f32>],
    tmin: f32,
    tmax: f32,
    out: &mut [Option<Hit<f32>>],
) {
    if tmin < 0.0 {
        return nearest_many_with::<simd::Avx2, true>(w, prims, rays, tmin, tmax, out);
    }
    // Groups of coherent rays go through the packet walk; the runs of other groups through
    // the interleaved one-ray walks.
    let mut run = 0;
    for (i, group) in rays.chunks(PACKET).enumerate() {
        let first = i * PACKET;
        let end = first + group.len();
        // SAFETY: the CPU has AVX2 (this function's feature).
        if unsafe { packet::nearest_packet(w, prims, group, tmin, tmax, &mut out[first..end]) } {
            if run < first {
                nearest_many_with::<simd::Avx2, false>(w, prims, &rays[run..first], tmin, tmax, &mut out[run..first]);
            }
            run = end;
        }
    }
    if run < rays.len() {
        nearest_many_with::<simd::Avx2, false>(w, prims, &rays[run..], tmin, tmax, &mut out[run..]);
    }
}

#[inline(always)]
fn nearest_many_with<K: Kernels, const NEG: bool>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &[Ray<f32>],
    tmin: f32,
    tmax: f32,
    out: &mut [Option<Hit<f32>>],
) {
    let mut walks: [NearestWalk; IN_FLIGHT] = std::array::from_fn(|_| NearestWalk::new(w, prims));
    let mut slots = [usize::MAX; IN_FLIGHT];
    let mut next = 0;
    let mut feed = Feed { rays, tmin, tmax, next: &mut next };
    for (walk, slot) in walks.iter_mut().zip(&mut slots) {
        feed.refill(walk, slot, out);
    }
    while walks.iter().any(|w| w.running) {
        for (walk, slot) in walks.iter_mut().zip(&mut slots) {
            if walk.running {
                if walk.step::<K, NEG>() {
                    // The other searches' steps come before this one's next: time for the
                    // node or leaf it visits next to arrive.
                    w.prefetch_word(walk.word);
                } else {
                    feed.refill(walk, slot, out);
                }
            }
        }
    }
}

/// Searches [`nearest_many`] advances side by side: each asks for its next node or leaf
/// ([`WideBvh::prefetch_word`]) and waits for it while the others take a step, so that up to
/// this many cache misses are under way at once; few enough that their stacks stay in the
/// first-level cache. Measured in the book's performance chapter (four without the prefetch,
/// eight with it).
const IN_FLIGHT: usize = 8;

/// The rays [`nearest_many`] has yet to start.
struct Feed<'r, 'n> {
    rays: &'r [Ray<f32>],
    tmin: f32,
    tmax: f32,
    next: &'n mut usize,
}

impl Feed<'_, '_> {
    /// Writes the answer of the stopped `walk` for ray `slot` (if any), then starts the next
    /// rays in it until one needs the tree.
    #[inline(always)]
    fn refill(&mut self, walk: &mut NearestWalk, slot: &mut usize, out: &mut [Option<Hit<f32>>]) {
        if *slot != usize::MAX {
            out[*slot] = walk.hit();
            *slot = usize::MAX;
        }
        while *self.next < self.rays.len() {
            walk.start(&self.rays[*self.next], self.tmin, self.tmax);
            *slot = *self.next;
            *self.next += 1;
            if walk.running {
                return;
            }
            out[*slot] = walk.hit();
            *slot = usize::MAX;
        }
    }
}

/// The walk of every hit ([`wide_all::walk_with`]), stopped by the first.
#[inline(always)]
fn occluded_with<K: Kernels, const NEG: bool>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    tmin: f32,
    tmax: f32,
) -> bool {
    struct AnyHit<'a> {
        prims: &'a Primitives<f32>,
        ray: &'a Ray<f32>,
        tmin: f32,
        tmax: f32,
    }
    impl wide_all::Sink for AnyHit<'_> {
        #[inline(always)]
        fn triangles(&mut self, _: &LeafBlock, _: u32, _: &[f32; LANES]) -> bool {
            true
        }
        #[inline(always)]
        fn other(&mut self, r: PrimRef) -> bool {
            self.prims.roots(r, self.ray, self.tmin, self.tmax).len > 0
        }
    }
    wide_all::walk_with::<K, NEG>(w, prims, ray, tmin, tmax, &mut AnyHit { prims, ray, tmin, tmax })
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::accel::Bvh;
    use strahl_core::geometry::testutil::{TestRays, TestRng, ray_f32};
    use strahl_core::math::V3;
    use strahl_core::primitives::testutil::mixed_scene;

    /// The test scene of `mixed_scene(seed)` and its wide tree.
    fn tree_over_mixed_scene(seed: u64) -> (Primitives<f32>, WideBvh) {
        let prims = mixed_scene(seed);
        let w = WideBvh::new(&Bvh::build(&prims), &prims);
        (prims, w)
    }

    /// Runs `check` with each lane implementation this CPU has.
    fn each_kernel(check: impl Fn(&str, &dyn Fn(&WideBvh, &Primitives<f32>, &Ray<f32>) -> Option<Hit<f32>>)) {
        check("scalar", &|w, p, r| nearest_with::<Scalar, false>(w, p, r, 0.0, f32::INFINITY));
        #[cfg(target_arch = "x86_64")]
        if simd::has_avx2() {
            check("avx2", &|w, p, r| unsafe { nearest_avx2(w, p, r, 0.0, f32::INFINITY) });
        }
    }

    #[test]
    fn occlusion_agrees_with_nearest_within_the_interval() {
        let (prims, w) = tree_over_mixed_scene(7);
        let mut rng = TestRng(17);
        let mut blocked = 0;
        for i in 0..20_000 {
            let ray = ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0));
            let tmax = [f32::INFINITY, 40.0, 80.0, 120.0][i % 4];
            let want = prims.nearest_brute(&ray, 0.0, tmax).is_some();
            assert_eq!(occluded(&w, &prims, &ray, 0.0, tmax), want, "ray {i}");
            assert_eq!(occluded_with::<Scalar, false>(&w, &prims, &ray, 0.0, tmax), want, "ray {i}");
            blocked += want as usize;
        }
        assert!(blocked > 5_000 && blocked < 19_000, "{blocked} blocked: the test would prove little");
    }

    /// The mask of a group of rays has the bit of each ray that `occluded` finds blocked, for
    /// groups of 1 to 32 rays with their own interval ends.
    #[test]
    fn the_mask_of_a_group_is_each_rays_occlusion() {
        let (prims, w) = tree_over_mixed_scene(9);
        let mut rng = TestRng(23);
        let (mut blocked, mut free) = (0, 0);
        for n in (1..=32).chain([16; 40]) {
            let rays: Vec<(Ray<f32>, f32)> = (0..n)
                .map(|i| (ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0)), [f32::INFINITY, 40.0, 80.0][i % 3]))
                .collect();
            let want =
                rays.iter().enumerate().fold(0u32, |m, (i, (r, t))| m | (occluded(&w, &prims, r, 0.0, *t) as u32) << i);
            assert_eq!(occluded_mask(&w, &prims, n, |i| (&rays[i].0, rays[i].1)), want, "{n} rays");
            blocked += want.count_ones();
            free += n as u32 - want.count_ones();
        }
        assert!(blocked > 200 && free > 200, "{blocked} blocked, {free} free: the test would prove little");
    }

    /// Intervals that start behind the origin and end short of infinity: the far planes'
    /// correction for negative distances, and the search bound, must lose no hit.
    #[test]
    fn windows_reaching_behind_the_origin_find_the_brute_force_hit() {
        let (prims, w) = tree_over_mixed_scene(11);
        let mut rng = TestRng(12);
        let mut found = 0;
        for i in 0..20_000 {
            let ray = ray_f32(&rng.ray_towards(40.0, V3::zero(), 50.0));
            let tmin = rng.range(-60.0, 10.0) as f32;
            let tmax = tmin + rng.range(0.5, 80.0) as f32;
            let want = prims.nearest_brute(&ray, tmin, tmax);
            assert_eq!(nearest(&w, &prims, &ray, tmin, tmax), want, "ray {i} in ({tmin}, {tmax})");
            assert_eq!(nearest_scalar(&w, &prims, &ray, tmin, tmax), want, "scalar, ray {i}");
            assert_eq!(occluded(&w, &prims, &ray, tmin, tmax), want.is_some(), "occlusion, ray {i}");
            found += want.is_some_and(|h| h.t < 0.0) as usize;
        }
        assert!(found > 1000, "only {found} hits behind the origin: the test would prove little");
    }

    /// A grid of unit squares (two triangles each) in the planes z = 0 and x = 0, every
    /// triangle twice (the copies after the originals), and its wide tree.
    fn doubled_grid() -> (Primitives<f32>, WideBvh) {
        use strahl_core::geometry::Triangle;
        use strahl_core::primitives::{Tag, Tagged};
        let mut p = Primitives::<f32>::default();
        let mut quad = |a: V3<f32>, b: V3<f32>, c: V3<f32>, d: V3<f32>| {
            for tri in [[a, b, c], [a, c, d]] {
                let n = p.triangles.len() as u32;
                p.triangles.push(Tagged { shape: Triangle { v: tri }, tag: Tag { object: 0, face: n, material: 0 } });
            }
        };
        for i in -4..4 {
            for j in -4..4 {
                let (x, y) = (i as f32, j as f32);
                quad(
                    V3::new(x, y, 0.0),
                    V3::new(x + 1.0, y, 0.0),
                    V3::new(x + 1.0, y + 1.0, 0.0),
                    V3::new(x, y + 1.0, 0.0),
                );
                quad(
                    V3::new(0.0, x, y),
                    V3::new(0.0, x + 1.0, y),
                    V3::new(0.0, x + 1.0, y + 1.0),
                    V3::new(0.0, x, y + 1.0),
                );
            }
        }
        let copies = p.triangles.clone();
        p.triangles.extend(copies);
        let w = WideBvh::new(&Bvh::build(&p), &p);
        (p, w)
    }

    /// On the grid of [`doubled_grid`], rays start on box planes (integer coordinates, so slab
    /// distances of ±0 occur), run along them or through shared edges and vertices, and every
    /// hit is a tie between two copies, which the smaller reference must win.
    #[test]
    fn rays_on_box_planes_and_through_edges_find_the_brute_force_hit() {
        let (p, w) = doubled_grid();
        let mut rng = TestRng(33);
        let mut hits = 0;
        for i in 0..20_000 {
            let o = V3::new(rng.range(-5.0, 5.0).round(), rng.range(-5.0, 5.0).round(), rng.range(-5.0, 5.0).round());
            let d = match i % 4 {
                // Along an axis, either way.
                0 => [V3::new(1.0, 0.0, 0.0), V3::new(0.0, -1.0, 0.0), V3::new(0.0, 0.0, -1.0)][i / 4 % 3],
                // Towards a grid vertex or edge midpoint.
                1 => V3::new(rng.range(-4.0, 4.0).round() * 0.5, rng.range(-4.0, 4.0).round() * 0.5, 0.0) - o,
                _ => rng.unit_vector(),
            };
            if d.length() == 0.0 {
                continue;
            }
            let ray = ray_f32(&Ray::new(o, d.normalize()));
            let want = p.nearest_brute(&ray, 0.0, f32::INFINITY);
            assert_eq!(nearest(&w, &p, &ray, 0.0, f32::INFINITY), want, "ray {i}: {ray:?}");
            assert_eq!(nearest_scalar(&w, &p, &ray, 0.0, f32::INFINITY), want, "scalar, ray {i}: {ray:?}");
            assert_eq!(occluded(&w, &p, &ray, 0.0, f32::INFINITY), want.is_some(), "occlusion, ray {i}");
            if let Some(h) = want {
                assert!(h.prim_ref.index() < p.triangles.len() / 2, "the first copy wins the tie");
                hits += 1;
            }
        }
        assert!(hits > 5_000, "{hits} hits");
    }

    /// The interleaved batch answers exactly as ray-by-ray search (and so as brute force),
    /// whatever the mix of rays that hit, miss, or meet no box at all.
    #[test]
    fn batches_answer_as_single_rays() {
        let (prims, w) = tree_over_mixed_scene(13);
        let mut rng = TestRng(14);
        let rays: Vec<Ray<f32>> = (0..5_001)
            .map(|i| {
                let r = rng.ray_towards(80.0, V3::zero(), 50.0);
                // Every seventh ray points away from the scene.
                let r = if i % 7 == 0 { Ray::new(r.origin * 3.0, r.origin.normalize()) } else { r };
                ray_f32(&r)
            })
            .collect();
        for (tmin, tmax) in [(0.0, f32::INFINITY), (-20.0, 90.0)] {
            let mut out = vec![None; rays.len()];
            nearest_many(&w, &prims, &rays, tmin, tmax, &mut out);
            for (i, (ray, got)) in rays.iter().zip(&out).enumerate() {
                assert_eq!(*got, prims.nearest_brute(ray, tmin, tmax), "ray {i} in ({tmin}, {tmax})");
            }
        }
        let mut none: Vec<Option<Hit<f32>>> = Vec::new();
        nearest_many(&w, &prims, &[], 0.0, 1.0, &mut none);
        let empty = WideBvh::new(&Bvh::default(), &Primitives::default());
        let mut out = vec![None; 3];
        nearest_many(&empty, &Primitives::default(), &rays[..3], 0.0, f32::INFINITY, &mut out);
        assert_eq!(out, vec![None; 3]);
    }

    #[test]
    fn both_kernels_find_the_brute_force_hit() {
        let (prims, w) = tree_over_mixed_scene(3);
        each_kernel(|name, f| {
            let mut rng = TestRng(4);
            for i in 0..20_000 {
                let ray = ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0));
                assert_eq!(f(&w, &prims, &ray), prims.nearest_brute(&ray, 0.0, f32::INFINITY), "{name}: ray {i}");
            }
        });
    }

    /// Rays parallel to two axes from up to 3·10³⁸ away, lying in box face planes (integer
    /// coordinates on the grid of [`doubled_grid`]): the parallel axes must bound no box at any
    /// distance (a finite stand-in inverse of 10³⁸ cut boxes off at 10³²–10³⁴, and the walk
    /// missed hits on the far side of that), and the tie between edge-sharing triangles is
    /// brute force's.
    #[test]
    fn far_rays_in_box_face_planes_find_the_brute_force_hit() {
        let (p, w) = doubled_grid();
        let mut rng = TestRng(41);
        let mut hits = 0;
        for i in 0..4_000 {
            let far = [1e33f32, 1e36, 1e38, 3e38][i % 4];
            let (u, v) = (rng.range(-5.0, 5.0).round() as f32, (rng.range(-10.0, 10.0).round() * 0.5) as f32);
            let s = if i / 4 % 2 == 0 { 1.0 } else { -1.0 };
            // Towards the grid in the plane x = 0, or the one in z = 0.
            let ray = if i / 8 % 2 == 0 {
                Ray::new(V3::new(s * far, u, v), V3::new(-s, 0.0, 0.0))
            } else {
                Ray::new(V3::new(u, v, s * far), V3::new(0.0, 0.0, -s))
            };
            let want = p.nearest_brute(&ray, 0.0, f32::INFINITY);
            assert_eq!(nearest(&w, &p, &ray, 0.0, f32::INFINITY), want, "ray {i}: {ray:?}");
            assert_eq!(nearest_scalar(&w, &p, &ray, 0.0, f32::INFINITY), want, "scalar, ray {i}: {ray:?}");
            assert_eq!(occluded(&w, &p, &ray, 0.0, f32::INFINITY), want.is_some(), "occlusion, ray {i}");
            hits += want.is_some() as usize;
        }
        assert!(hits > 1_500, "{hits} hits: the test would prove little");
    }
}
