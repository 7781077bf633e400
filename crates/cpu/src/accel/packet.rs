//! Eight coherent rays walked through the 8-wide tree together (AVX2): the batch query's path
//! for rays that share their octant and their watertight permutation, such as a camera's.
//!
//! One ray at a time ([`super::wide_traverse`]) pays, at every node, for ordering the children
//! and for the stack, and at every leaf for loading the triangles; rays through neighbouring
//! pixels pay it for the same nodes and leaves. Here one lane holds one ray: a node's child
//! boxes are tested one after the other, each against the eight rays at once, and a leaf's
//! triangles likewise, so the ordering, the stack and the loads are shared by the rays of the
//! packet (Wald, Slusallek, Benthin & Wagner, "Interactive Rendering with Coherent Ray
//! Tracing", 2001, for binary trees). Each lane keeps its own search interval: a child is
//! entered for the lanes whose own interval it meets, a deferred child is revisited only for
//! the lanes it still may serve.
//!
//! Lane for lane the box and triangle tests are the IEEE operations of the one-ray kernels
//! ([`super::simd`]), in the same order, and hits are kept by [`Nearest::offer`]'s total order,
//! so every ray gets exactly the answer of [`super::wide_traverse::nearest`], and so of brute
//! force: same `t`, same primitive, same tie rule.

use super::record::hit_record;
use super::simd::{is_triangle, widen};
use super::wide::{EMPTY_CHILD, EMPTY_PRIM, LANES, LEAF_BIT, LeafBlock, MAX_DEPTH, WIDTH, WideBvh, WideNode};
use std::arch::x86_64::*;
use std::mem::MaybeUninit;
use strahl_core::geometry::Part;
use strahl_core::math::Ray;
use strahl_core::primitives::{Hit, Nearest, PrimRef, Primitives};

/// Rays in a packet: one per AVX2 lane.
pub const PACKET: usize = 8;

/// Room for the children a walk defers: at most seven per level.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// Whether the rays (at most [`PACKET`]) can be walked as one packet: the same sign of each
/// direction component (so one row of each node holds every lane's near plane) and the same
/// watertight permutation (so one row of each triangle holds every lane's kx, ky, kz
/// coordinate), and no component so small that the ray counts as parallel to an axis.
/// Neighbouring camera rays almost always qualify; random rays almost never do, and keep the
/// one-ray walk.
pub fn coherent(rays: &[Ray<f32>]) -> bool {
    // SAFETY: AVX2 is checked first.
    super::simd::has_avx2() && unsafe { Lanes::new(rays) }.is_some()
}

/// A deferred child: its word, the lanes that enter it, and their entry distances.
#[derive(Clone, Copy)]
struct Entry {
    tn: [f32; PACKET],
    word: u32,
    mask: u32,
}

/// What [`super::simd::RayPre`] holds for one ray, for the eight rays of a packet, one lane
/// each, computed with the same operations (so lane for lane the same values).
struct Lanes {
    org_near: [__m256; 3],
    org_far: [__m256; 3],
    inv: [__m256; 3],
    inv_far: [__m256; 3],
    org_k: [__m256; 3],
    sx: __m256,
    sy: __m256,
    sz: __m256,
    /// Byte offsets of the near and far rows of a node, and of the kx, ky, kz rows of a
    /// vertex, shared by the lanes.
    near: [usize; 3],
    far: [usize; 3],
    row_k: [usize; 3],
}

impl Lanes {
    /// The lanes of `rays` (1 to [`PACKET`]; missing lanes repeat the last ray), or `None`
    /// where they are not [`coherent`].
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn new(rays: &[Ray<f32>]) -> Option<Self> {
        debug_assert!(!rays.is_empty() && rays.len() <= PACKET);
        // SAFETY: AVX2 is present (see `nearest_packet`); rows hold eight f32.
        unsafe {
            let mut rows = [[0.0f32; PACKET]; 6];
            for k in 0..PACKET {
                let r = &rays[k.min(rays.len() - 1)];
                (rows[0][k], rows[1][k], rows[2][k]) = (r.origin.x, r.origin.y, r.origin.z);
                (rows[3][k], rows[4][k], rows[5][k]) = (r.dir.x, r.dir.y, r.dir.z);
            }
            let o: [__m256; 3] = std::array::from_fn(|a| _mm256_loadu_ps(rows[a].as_ptr()));
            let d: [__m256; 3] = std::array::from_fn(|a| _mm256_loadu_ps(rows[3 + a].as_ptr()));
            let all = |m: __m256| match _mm256_movemask_ps(m) {
                0 => Some(false),
                0xff => Some(true),
                _ => None,
            };
            let zero = _mm256_setzero_ps();
            let m = d.map(|c| _mm256_andnot_ps(_mm256_set1_ps(-0.0), c));
            // RayPre::new's parallel axes (|d| < TINY) keep the one-ray walk.
            let tiny = _mm256_set1_ps(super::simd::TINY);
            if _mm256_movemask_ps(_mm256_or_ps(
                _mm256_or_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(m[0], tiny), _mm256_cmp_ps::<_CMP_LT_OQ>(m[1], tiny)),
                _mm256_cmp_ps::<_CMP_LT_OQ>(m[2], tiny),
            )) != 0
            {
                return None;
            }
            let neg = [0, 1, 2].map(|a| all(_mm256_cmp_ps::<_CMP_LT_OQ>(d[a], zero)));
            let [Some(n0), Some(n1), Some(n2)] = neg else { return None };
            let neg = [n0, n1, n2];
            // The dominant axis as RayPre::new chooses it, the same in every lane.
            let ge = |a: __m256, b: __m256| _mm256_cmp_ps::<_CMP_GE_OQ>(a, b);
            let kz = if all(_mm256_and_ps(ge(m[0], m[1]), ge(m[0], m[2])))? {
                0
            } else if all(ge(m[1], m[2]))? {
                1
            } else {
                2
            };
            let (mut kx, mut ky) = ([1, 2, 0][kz], [2, 0, 1][kz]);
            if neg[kz] {
                std::mem::swap(&mut kx, &mut ky);
            }
            let one = _mm256_set1_ps(1.0);
            let inv = d.map(|c| _mm256_div_ps(one, c));
            let grow = _mm256_set1_ps(super::simd::far_grow());
            let sz = _mm256_div_ps(one, d[kz]);
            const ROW: usize = size_of::<[f32; WIDTH]>();
            const LANE_ROW: usize = size_of::<[f32; LANES]>();
            Some(Self {
                // o + 0 and o − 0: RayPre's origins moved by a shift of 0 (−0 + 0 is +0).
                org_near: o.map(|c| _mm256_add_ps(c, zero)),
                org_far: o.map(|c| _mm256_sub_ps(c, zero)),
                inv,
                inv_far: inv.map(|c| _mm256_mul_ps(c, grow)),
                org_k: [o[kx], o[ky], o[kz]],
                sx: _mm256_mul_ps(d[kx], sz),
                sy: _mm256_mul_ps(d[ky], sz),
                sz,
                near: [0, 1, 2].map(|a| ROW * (2 * a + neg[a] as usize)),
                far: [0, 1, 2].map(|a| ROW * (2 * a + !neg[a] as usize)),
                row_k: [kx * LANE_ROW, ky * LANE_ROW, kz * LANE_ROW],
            })
        }
    }
}

/// The nearest hits in (tmin, tmax), tmin ≥ 0, of `rays` (1 to [`PACKET`]) into `out`: for
/// each ray what [`super::wide_traverse::nearest`] returns. False, and nothing written, where
/// the rays are not [`coherent`].
///
/// # Safety
/// The CPU must have AVX2 and FMA ([`super::simd::has_avx2`] checks both).
#[target_feature(enable = "avx2,fma")]
pub unsafe fn nearest_packet(
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &[Ray<f32>],
    tmin: f32,
    tmax: f32,
    out: &mut [Option<Hit<f32>>],
) -> bool {
    debug_assert!(tmin >= 0.0 && out.len() == rays.len());
    // SAFETY: AVX2 is present (this function's contract).
    let Some(lanes) = (unsafe { Lanes::new(rays) }) else { return false };
    // +0 for −0: the integer form of the box test needs it (see simd::Avx2::boxes).
    let tmin = tmin + 0.0;
    let mut best: [Nearest<f32>; PACKET] = std::array::from_fn(|_| Nearest::new(tmax));
    for (b, ray) in best.iter_mut().zip(rays) {
        for r in prims.plane_refs() {
            prims.offer_nearest(r, ray, tmin, b);
        }
    }
    let mut from_block: [Option<&LeafBlock>; PACKET] = [None; PACKET];
    if !w.is_empty() {
        let mut walk = Walk { w, prims, rays, tmin, best: &mut best, from_block: &mut from_block };
        // SAFETY: as above.
        unsafe { walk.run(&lanes, (1 << rays.len()) - 1) };
    }
    for (i, o) in out.iter_mut().enumerate() {
        *o = hit_record(w, prims, &rays[i], &best[i], from_block[i]);
    }
    true
}

struct Walk<'a, 'b> {
    w: &'a WideBvh,
    prims: &'a Primitives<f32>,
    rays: &'b [Ray<f32>],
    tmin: f32,
    best: &'b mut [Nearest<f32>; PACKET],
    from_block: &'b mut [Option<&'a LeafBlock>; PACKET],
}

/// The lanes of a bit mask as a vector mask.
#[inline(always)]
unsafe fn lanes_of(mask: u32) -> __m256 {
    // SAFETY: AVX2 is present (see `nearest_packet`).
    unsafe {
        let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let m = _mm256_and_si256(_mm256_set1_epi32(mask as i32), bits);
        _mm256_castsi256_ps(_mm256_cmpeq_epi32(m, bits))
    }
}

/// a·b − c·d per lane by `<f32 as Real>::diff_of_products`'s operations (Kahan's algorithm
/// with fused multiply-adds).
#[inline(always)]
unsafe fn diff_of_products(a: __m256, b: __m256, c: __m256, d: __m256) -> __m256 {
    // SAFETY: FMA is present (see `nearest_packet`).
    unsafe {
        let cd = _mm256_mul_ps(c, d);
        // fma(−c, d, cd) and fma(a, b, −cd).
        let err = _mm256_fnmadd_ps(c, d, cd);
        _mm256_add_ps(_mm256_fmsub_ps(a, b, cd), err)
    }
}

/// `triangle::edge_tie` lane by lane: `e`, or where it is 0 the sign of `ey`, or where that
/// is 0 too, of −`ex`.
#[inline(always)]
unsafe fn edge_tie(e: __m256, ex: __m256, ey: __m256) -> __m256 {
    // SAFETY: AVX is present (see `nearest_packet`).
    unsafe {
        let zero = _mm256_setzero_ps();
        let alt = _mm256_blendv_ps(_mm256_xor_ps(ex, _mm256_set1_ps(-0.0)), ey, _mm256_cmp_ps::<_CMP_NEQ_UQ>(ey, zero));
        _mm256_blendv_ps(alt, e, _mm256_cmp_ps::<_CMP_NEQ_UQ>(e, zero))
    }
}

impl<'a> Walk<'a, '_> {
    /// The walk from the root for the lanes of `active`.
    #[inline(always)]
    unsafe fn run(&mut self, l: &Lanes, active: u32) {
        // SAFETY: AVX2 is present (see `nearest_packet`); node rows and the stack are read
        // within their bounds.
        unsafe {
            let tmin_v = _mm256_set1_ps(self.tmin);
            let mut bound = [0.0f32; PACKET];
            let mut cull = [0.0f32; PACKET];
            for i in 0..PACKET {
                bound[i] = self.best[i].search_bound();
                cull[i] = widen(bound[i]);
            }
            let mut stack: [MaybeUninit<Entry>; STACK] = [const { MaybeUninit::uninit() }; STACK];
            let mut len = 0usize;
            let (mut word, mut mask) = (0u32, active);
            loop {
                if word & LEAF_BIT == 0 {
                    let node: &WideNode = self.w.node(word);
                    let rows = (node as *const WideNode).cast::<u8>();
                    let cull_v = _mm256_loadu_ps(cull.as_ptr());
                    let live = lanes_of(mask);
                    // Every child is tested, without a branch on its outcome (which lanes
                    // enter which child is hard to predict); then the entered ones, in child
                    // order.
                    let mut tns = [_mm256_setzero_ps(); WIDTH];
                    let mut masks = [0u32; WIDTH];
                    let mut any = 0u32;
                    for j in 0..WIDTH {
                        let plane = |off: usize| _mm256_broadcast_ss(&*rows.add(off).cast::<f32>().add(j));
                        let slab =
                            |off: usize, o: __m256, inv: __m256| _mm256_mul_ps(_mm256_sub_ps(plane(off), o), inv);
                        let t0 = |a: usize| _mm256_castps_si256(slab(l.near[a], l.org_near[a], l.inv[a]));
                        let t1 = |a: usize| _mm256_castps_si256(slab(l.far[a], l.org_far[a], l.inv_far[a]));
                        // As in simd::Avx2::boxes with tmin ≥ +0: integer max and min on the
                        // bits order non-negative floats as the float ones do.
                        let tn = _mm256_max_epi32(
                            _mm256_max_epi32(t0(0), t0(1)),
                            _mm256_max_epi32(t0(2), _mm256_castps_si256(tmin_v)),
                        );
                        let tf = _mm256_min_epi32(
                            _mm256_min_epi32(t1(0), t1(1)),
                            _mm256_min_epi32(t1(2), _mm256_castps_si256(cull_v)),
                        );
                        let tn = _mm256_castsi256_ps(tn);
                        let hit = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, _mm256_castsi256_ps(tf)), live);
                        let m = _mm256_movemask_ps(hit) as u32;
                        tns[j] = tn;
                        masks[j] = m;
                        any |= ((m != 0) as u32) << j;
                    }
                    // Only children that exist, whatever their boxes hold.
                    let empty = _mm256_cmpeq_epi32(
                        _mm256_loadu_si256(node.child.as_ptr().cast()),
                        _mm256_set1_epi32(EMPTY_CHILD as i32),
                    );
                    any &= !(_mm256_movemask_ps(_mm256_castsi256_ps(empty)) as u32);
                    let mut keys = [0u64; WIDTH];
                    let mut entered = [0usize; WIDTH];
                    let mut count = 0;
                    while any != 0 {
                        let j = any.trailing_zeros() as usize;
                        any &= any - 1;
                        // Asked for now: the nearest is visited next, the others after it.
                        self.w.prefetch_word(node.child[j]);
                        // Ordered by the entry distance of the first lane entering (as good
                        // as the nearest one for coherent rays, and cheaper).
                        let first = _mm256_set1_epi32(masks[j].trailing_zeros() as i32);
                        let near = _mm256_cvtss_f32(_mm256_permutevar8x32_ps(tns[j], first));
                        keys[count] = (near.to_bits() as u64) << 32 | count as u64;
                        entered[count] = j;
                        count += 1;
                    }
                    if count > 0 {
                        // Farthest first onto the stack; the nearest is visited next.
                        let keys = &mut keys[..count];
                        if count > 1 {
                            keys.sort_unstable_by(|a, b| b.cmp(a));
                        }
                        for &k in &keys[..count - 1] {
                            let j = entered[(k & 0xff) as usize];
                            let mut e = Entry { tn: [0.0; PACKET], word: node.child[j], mask: masks[j] };
                            _mm256_storeu_ps(e.tn.as_mut_ptr(), tns[j]);
                            stack[len] = MaybeUninit::new(e);
                            len += 1;
                        }
                        let j = entered[(keys[count - 1] & 0xff) as usize];
                        (word, mask) = (node.child[j], masks[j]);
                        continue;
                    }
                } else {
                    self.leaf(word, mask, l, &mut bound, &mut cull);
                }
                // The deferred child last pushed that some lane still needs: one whose entry
                // lies within that lane's (possibly shrunk) interval.
                let cull_v = _mm256_loadu_ps(cull.as_ptr());
                loop {
                    if len == 0 {
                        return;
                    }
                    len -= 1;
                    let e = stack[len].assume_init_ref();
                    let still = _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_loadu_ps(e.tn.as_ptr()), cull_v);
                    let m = e.mask & _mm256_movemask_ps(still) as u32;
                    if m != 0 {
                        (word, mask) = (e.word, m);
                        break;
                    }
                }
            }
        }
    }

    /// Tests the triangles (and other primitives) of leaf `word` against the lanes of `mask`,
    /// each lane against its interval at the leaf's entry, as the one-ray walk does.
    #[inline(always)]
    unsafe fn leaf(&mut self, word: u32, mask: u32, l: &Lanes, bound: &mut [f32; PACKET], cull: &mut [f32; PACKET]) {
        // SAFETY: AVX2 is present (see `nearest_packet`); vertex rows are read within the
        // block.
        unsafe {
            let (blocks, other) = self.w.leaf(word);
            let zero = _mm256_setzero_ps();
            let tmin_v = _mm256_set1_ps(self.tmin);
            let bound_v = _mm256_loadu_ps(bound.as_ptr());
            let live = lanes_of(mask);
            let mut t = [0.0f32; PACKET];
            for block in blocks {
                for tri in 0..LANES {
                    let p = block.prim_ref[tri];
                    if !is_triangle(p) {
                        continue;
                    }
                    // Vertex k translated to each ray's origin, permuted and sheared: (x, y, z)
                    // as in Triangle::intersect.
                    let vertex = |k: usize| {
                        let v = block.v[k].as_ptr().cast::<u8>();
                        let c = |a: usize| _mm256_broadcast_ss(&*v.add(l.row_k[a]).cast::<f32>().add(tri));
                        let dx = _mm256_sub_ps(c(0), l.org_k[0]);
                        let dy = _mm256_sub_ps(c(1), l.org_k[1]);
                        let dz = _mm256_sub_ps(c(2), l.org_k[2]);
                        (
                            _mm256_sub_ps(dx, _mm256_mul_ps(l.sx, dz)),
                            _mm256_sub_ps(dy, _mm256_mul_ps(l.sy, dz)),
                            _mm256_mul_ps(l.sz, dz),
                        )
                    };
                    let (ax, ay, az) = vertex(0);
                    let (bx, by, bz) = vertex(1);
                    let (cx, cy, cz) = vertex(2);
                    let u = diff_of_products(cx, by, cy, bx);
                    let v = diff_of_products(ax, cy, ay, cx);
                    let w = diff_of_products(bx, ay, by, ax);
                    let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
                    let is = |x: __m256| _mm256_cmp_ps::<_CMP_EQ_OQ>(x, zero);
                    let det_ok = _mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero);
                    let on_edge = _mm256_or_ps(_mm256_or_ps(is(u), is(v)), is(w));
                    // Tie signs only where some lane needs them (rare), as in the one-ray test.
                    let (u_s, v_s, w_s) = if _mm256_movemask_ps(_mm256_and_ps(on_edge, det_ok)) == 0 {
                        (u, v, w)
                    } else {
                        (
                            edge_tie(u, _mm256_sub_ps(cx, bx), _mm256_sub_ps(cy, by)),
                            edge_tie(v, _mm256_sub_ps(ax, cx), _mm256_sub_ps(ay, cy)),
                            edge_tie(w, _mm256_sub_ps(bx, ax), _mm256_sub_ps(by, ay)),
                        )
                    };
                    let lt = |x: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(x, zero);
                    let gt = |x: __m256| _mm256_cmp_ps::<_CMP_GT_OQ>(x, zero);
                    let neg = _mm256_or_ps(_mm256_or_ps(lt(u_s), lt(v_s)), lt(w_s));
                    let pos = _mm256_or_ps(_mm256_or_ps(gt(u_s), gt(v_s)), gt(w_s));
                    let inside = _mm256_and_ps(_mm256_andnot_ps(_mm256_and_ps(neg, pos), det_ok), live);
                    if _mm256_movemask_ps(inside) == 0 {
                        continue;
                    }
                    let num =
                        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(u, az), _mm256_mul_ps(v, bz)), _mm256_mul_ps(w, cz));
                    let tt = _mm256_div_ps(num, det);
                    let range = _mm256_and_ps(
                        _mm256_cmp_ps::<_CMP_GT_OQ>(tt, tmin_v),
                        _mm256_cmp_ps::<_CMP_LT_OQ>(tt, bound_v),
                    );
                    let mut hits = _mm256_movemask_ps(_mm256_and_ps(inside, range)) as u32;
                    if hits == 0 {
                        continue;
                    }
                    _mm256_storeu_ps(t.as_mut_ptr(), tt);
                    while hits != 0 {
                        let r = hits.trailing_zeros() as usize;
                        hits &= hits - 1;
                        let before = self.best[r].prim_ref;
                        self.best[r].offer(t[r], PrimRef(p), Part::Surface);
                        if self.best[r].prim_ref != before {
                            self.from_block[r] = Some(block);
                        }
                    }
                }
                if other {
                    for &p in &block.prim_ref {
                        if p == EMPTY_PRIM || is_triangle(p) {
                            continue;
                        }
                        let mut m = mask;
                        while m != 0 {
                            let r = m.trailing_zeros() as usize;
                            m &= m - 1;
                            self.prims.offer_nearest(PrimRef(p), &self.rays[r], self.tmin, &mut self.best[r]);
                        }
                    }
                }
            }
            let mut m = mask;
            while m != 0 {
                let r = m.trailing_zeros() as usize;
                m &= m - 1;
                bound[r] = self.best[r].search_bound();
                cull[r] = widen(bound[r]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::simd::has_avx2;
    use crate::accel::wide_traverse::nearest_many;
    use strahl_core::accel::Bvh;
    use strahl_core::geometry::Triangle;
    use strahl_core::math::V3;
    use strahl_core::primitives::testutil::mixed_scene;
    use strahl_core::primitives::{Tag, Tagged};

    /// Pinhole rays from `eye` through a `w`×`h` grid on the plane at `target`, row by row.
    fn camera(eye: V3<f32>, target: V3<f32>, half: f32, w: usize, h: usize) -> Vec<Ray<f32>> {
        let mut rays = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (u, v) = ((x as f32 + 0.5) / w as f32 * 2.0 - 1.0, (y as f32 + 0.5) / h as f32 * 2.0 - 1.0);
                let p = target + V3::new(u * half, v * half, 0.0);
                rays.push(Ray::new(eye, (p - eye).normalize()));
            }
        }
        rays
    }

    /// How many groups of `PACKET` rays the batch query walks as packets.
    fn packets(rays: &[Ray<f32>]) -> usize {
        rays.chunks(PACKET).filter(|g| coherent(g)).count()
    }

    fn check(prims: &Primitives<f32>, rays: &[Ray<f32>], tmin: f32, tmax: f32) -> usize {
        let w = WideBvh::new(&Bvh::build(prims), prims);
        let mut out = vec![None; rays.len()];
        nearest_many(&w, prims, rays, tmin, tmax, &mut out);
        let mut hits = 0;
        for (i, (ray, got)) in rays.iter().zip(&out).enumerate() {
            assert_eq!(*got, prims.nearest_brute(ray, tmin, tmax), "ray {i} in ({tmin}, {tmax}): {ray:?}");
            hits += got.is_some() as usize;
        }
        hits
    }

    /// Camera rays over spheres, cylinders, triangles and a plane: every packet lane finds
    /// brute force's hit, in open and in bounded intervals (where lanes drop out of deferred
    /// children at different times), with a short last packet (111 × 37 is odd).
    #[test]
    fn camera_packets_find_the_brute_force_hit() {
        if !has_avx2() {
            return;
        }
        let prims = mixed_scene(21);
        for (eye, target) in [
            (V3::new(3.0, 5.0, -120.0), V3::zero()),
            (V3::new(0.0, 0.0, 0.0), V3::new(10.0, -60.0, 40.0)),
            (V3::new(-90.0, 20.0, 70.0), V3::new(0.0, -10.0, 0.0)),
        ] {
            let rays = camera(eye, target, 55.0, 111, 37);
            let groups = rays.len().div_ceil(PACKET);
            assert!(
                packets(&rays) * 4 > groups * 3,
                "{} of {groups} groups are packets: the test would prove little",
                packets(&rays)
            );
            let hits = check(&prims, &rays, 0.0, f32::INFINITY);
            assert!(hits > rays.len() / 10, "{hits} hits");
            check(&prims, &rays, 20.0, 110.0);
        }
    }

    /// A grid of unit squares, each twice (the copies tie at every hit, and the smaller
    /// reference must win), with camera rays through its vertices and edges: the packet lanes
    /// keep the watertight test's tie rule and never slip between two triangles.
    #[test]
    fn packets_through_shared_edges_keep_the_tie_rule() {
        if !has_avx2() {
            return;
        }
        let mut prims = Primitives::<f32>::default();
        for i in -8..8 {
            for j in -8..8 {
                let (x, y) = (i as f32, j as f32);
                let [a, b, c, d] =
                    [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(|(u, v)| V3::new(x + u, y + v, 0.0));
                for v in [[a, b, c], [a, c, d]] {
                    let face = prims.triangles.len() as u32;
                    prims.triangles.push(Tagged { shape: Triangle { v }, tag: Tag { object: 0, face, material: 0 } });
                }
            }
        }
        let copies = prims.triangles.clone();
        prims.triangles.extend(copies);
        // From (0.25, 0.25, 4) through points half a unit apart: vertices, edge midpoints and
        // diagonals' midpoints of the grid, in coherent rows.
        let eye = V3::new(0.25, 0.25, 4.0);
        let mut rays = Vec::new();
        for j in 0..16 {
            for i in 0..16 {
                let p = V3::new(0.5 + i as f32 * 0.5, 0.25 - j as f32 * 0.5 - 0.25, 0.0);
                rays.push(Ray::new(eye, p - eye));
            }
        }
        assert!(packets(&rays) * 2 > rays.len().div_ceil(PACKET), "too few packets");
        let hits = check(&prims, &rays, 0.0, f32::INFINITY);
        assert!(hits > rays.len() * 9 / 10, "{hits} hits");
    }
}
