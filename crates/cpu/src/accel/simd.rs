//! The two inner tests of the CPU walk, each computed for several lanes at once: a ray against
//! the eight child boxes of a [`WideNode`], and against the four triangles of a [`LeafBlock`].
//!
//! [`Scalar`] loops over the lanes; [`Avx2`] (x86-64 with AVX2 and FMA, detected at run time)
//! uses 8-lane boxes and 4-lane triangles, the edge functions formed with fused
//! multiply-adds. The triangle lanes perform exactly the IEEE operations of [`Triangle::intersect`] in
//! the same order, so the distances are those of brute force bit for bit. The box lanes are
//! conservative (see [`far_grow`], [`PARALLEL_INV`], [`widen`]): a box is entered whenever
//! it may hold a hit in the search interval, so the walk finds what brute force finds.

use super::wide::{LANES, LeafBlock, WIDTH, WideNode};
use strahl_core::geometry::Triangle;
use strahl_core::geometry::triangle::Shear;
use strahl_core::math::{Ray, Real, V3};
use strahl_core::primitives::PrimKind;
use strahl_core::primitives::PrimRef;

/// Far slab distances are computed with the inverse direction scaled by this, 1 + 2γ(5)
/// (γ(n) = nu/(1 − nu), u = 2⁻²⁴; pbrt-v3 §3.9.2 scales by 1 + 2γ(3) after the fact): the
/// near distance carries at most three roundings, (1 + u)³ (the inverse, the subtraction, the
/// product), the far one at most five, (1 − u)⁵, and (1 − u)⁵·(1 + 2γ(5)) > (1 + u)³, so a
/// box the ray meets is never missed, flat boxes and edge-on rays included.
#[inline(always)]
pub fn far_grow() -> f32 {
    1.0 + 2.0 * f32::gamma_bound(5)
}

/// For intervals that reach below zero (tmin < 0): a negative far distance grown by
/// [`far_grow`] moves the wrong way, so it is then scaled back by this, 1 − 2γ(10), which
/// more than undoes both.
#[inline(always)]
pub fn negative_fix() -> f32 {
    1.0 - 2.0 * f32::gamma_bound(10)
}

/// The widened upper end of a search interval, for comparison with box entry distances. A
/// box whose computed entry lies above a hit found elsewhere by no more than the rounding of
/// the slab test and of the primitive's own `t` may still hold a hit at or before it; 2⁻¹⁶
/// relative is far more than both (a few ulps each), and costs no measurable visits.
#[inline(always)]
pub fn widen(t: f32) -> f32 {
    const SLACK: f32 = 1.0 / 65536.0;
    if t >= 0.0 { t * (1.0 + SLACK) } else { t * (1.0 - SLACK) }
}

/// Direction components below this magnitude count as zero (as in
/// `traverse::safe_inverse`): the ray runs parallel to that axis.
pub(super) const TINY: f32 = 1e-30;
/// The inverse used on an axis the ray runs parallel to: infinity, with the sign of the
/// component (+ for ±0). On that axis the near planes are measured from the origin moved
/// forward by [`parallel_shift`], the far planes from it moved back, so that no plane lies at
/// distance zero (0·∞ would be NaN): a box whose slab holds the origin, even on one of its
/// face planes, gets slab distances of −∞ and +∞ (it bounds nothing, at any distance, as in
/// `traverse::slab`), a box beside the ray by more than the shift +∞ or −∞ (ruled out). A box
/// beside the ray by less than the shift is entered, which costs visits, never hits; one with
/// a plane exactly at the moved origin gets a NaN, which keeps or rules out that box, both
/// right for a box beside the ray. A finite stand-in inverse would cut boxes off at a finite
/// distance (10³⁸ · shift) that a hit far away can exceed.
const PARALLEL_INV: f32 = f32::INFINITY;

/// The shift of [`PARALLEL_INV`]: 2⁻¹⁶ of the coordinate (many ulps, so the moved origin
/// differs from the origin), at least 10⁻⁶.
pub(super) fn parallel_shift(o: f32) -> f32 {
    (o.abs() * (1.0 / 65536.0)).max(1e-6)
}

/// What a ray's tests share, computed once per ray: origin, inverse direction (and the grown
/// one for far planes), which box plane is the near one per axis, and the watertight test's
/// permutation and shear.
#[derive(Clone, Copy, Debug)]
pub struct RayPre {
    pub ray: Ray<f32>,
    pub inv: [f32; 3],
    pub inv_far: [f32; 3],
    /// The origin near and far planes are measured from: the origin, or on axes the ray runs
    /// parallel to, the origin moved forward and back (see [`PARALLEL_INV`]).
    pub org_near: [f32; 3],
    pub org_far: [f32; 3],
    /// Byte offsets in a [`WideNode`] of the rows of `bounds` holding the near and the far
    /// plane of each axis (always inside the node's bounds).
    pub near: [usize; 3],
    pub far: [usize; 3],
    pub shear: Shear<f32>,
    /// The origin's coordinates on axes kx, ky, kz of the shear.
    pub org_k: [f32; 3],
    /// Byte offsets in a vertex of a [`LeafBlock`] of the rows of axes kx, ky, kz.
    pub row_k: [usize; 3],
}

impl RayPre {
    #[inline(always)]
    pub fn new(ray: &Ray<f32>) -> Self {
        let d = ray.dir.to_array();
        let parallel = d.map(|c| c.abs() < TINY);
        let inv: [f32; 3] = std::array::from_fn(|a| match parallel[a] {
            true if d[a] < 0.0 => -PARALLEL_INV,
            true => PARALLEL_INV,
            false => 1.0 / d[a],
        });
        // inv is never ±0, so its sign decides which plane is met first.
        const ROW: usize = size_of::<[f32; WIDTH]>();
        let near = std::array::from_fn(|a| ROW * (2 * a + (inv[a] < 0.0) as usize));
        let far = std::array::from_fn(|a| ROW * (2 * a + (inv[a] >= 0.0) as usize));
        let inv_far = std::array::from_fn(|a| if parallel[a] { inv[a] } else { inv[a] * far_grow() });
        let o = ray.origin.to_array();
        let shift = |a: usize| if parallel[a] { parallel_shift(o[a]).copysign(inv[a]) } else { 0.0 };
        let org_near = std::array::from_fn(|a| o[a] + shift(a));
        let org_far = std::array::from_fn(|a| o[a] - shift(a));
        // Shear::new's arithmetic on arrays, without its per-component dispatch.
        let m = d.map(f32::abs);
        let kz = if m[0] >= m[1] && m[0] >= m[2] {
            0
        } else if m[1] >= m[2] {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ([1, 2, 0][kz], [2, 0, 1][kz]);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = 1.0 / d[kz];
        let shear = Shear { kx, ky, kz, sx: d[kx] * sz, sy: d[ky] * sz, sz };
        const LANE_ROW: usize = size_of::<[f32; LANES]>();
        let row_k = [kx * LANE_ROW, ky * LANE_ROW, kz * LANE_ROW];
        Self { ray: *ray, inv, inv_far, org_near, org_far, near, far, shear, org_k: [o[kx], o[ky], o[kz]], row_k }
    }
}

/// The lane tests. Implementations must return, lane for lane, what the scalar reference
/// returns.
pub trait Kernels {
    /// Which of the node's children's boxes the ray meets within [tmin, tmax] (tmax already
    /// widened): a bit mask, with the entry distances in `tnear`. `NEG`: tmin may be
    /// negative (see [`negative_fix`]).
    ///
    /// # Safety
    /// The CPU must have the features the implementation is compiled for.
    unsafe fn boxes<const NEG: bool>(
        node: &WideNode,
        r: &RayPre,
        tmin: f32,
        tmax: f32,
        tnear: &mut [f32; WIDTH],
    ) -> u32;
    /// Which triangle lanes of `block` the ray hits within (tmin, tmax): a bit mask, with
    /// the distances in `t`.
    ///
    /// # Safety
    /// As for [`Kernels::boxes`].
    unsafe fn triangles(block: &LeafBlock, r: &RayPre, tmin: f32, tmax: f32, t: &mut [f32; LANES]) -> u32;
}

/// One lane after the other, with the scalar reference's own code.
pub struct Scalar;

impl Kernels for Scalar {
    #[inline(always)]
    unsafe fn boxes<const NEG: bool>(
        node: &WideNode,
        r: &RayPre,
        tmin: f32,
        tmax: f32,
        tnear: &mut [f32; WIDTH],
    ) -> u32 {
        let mut mask = 0;
        for (i, tn_out) in tnear.iter_mut().enumerate() {
            let (mut tn, mut tf) = (tmin, f32::INFINITY);
            for a in 0..3 {
                let row = |off: usize| node.bounds[off / size_of::<[f32; WIDTH]>()][i];
                let t0 = (row(r.near[a]) - r.org_near[a]) * r.inv[a];
                let t1 = (row(r.far[a]) - r.org_far[a]) * r.inv_far[a];
                tn = if t0 > tn { t0 } else { tn };
                tf = if t1 < tf { t1 } else { tf };
            }
            if NEG {
                let fixed = tf * negative_fix();
                tf = if fixed > tf { fixed } else { tf };
            }
            let tf = if tmax < tf { tmax } else { tf };
            *tn_out = tn;
            mask |= ((tn <= tf) as u32) << i;
        }
        mask
    }

    #[inline(always)]
    unsafe fn triangles(block: &LeafBlock, r: &RayPre, tmin: f32, tmax: f32, t: &mut [f32; LANES]) -> u32 {
        let mut mask = 0;
        for (lane, t_out) in t.iter_mut().enumerate() {
            if !is_triangle(block.prim_ref[lane]) {
                continue;
            }
            let v = |k: usize| V3::new(block.v[k][0][lane], block.v[k][1][lane], block.v[k][2][lane]);
            let tri = Triangle { v: [v(0), v(1), v(2)] };
            if let Some(hit) = tri.intersect(&r.ray, &r.shear, tmin, tmax) {
                *t_out = hit;
                mask |= 1 << lane;
            }
        }
        mask
    }
}

#[inline(always)]
pub fn is_triangle(prim: u32) -> bool {
    prim >> PrimRef::INDEX_BITS == PrimKind::Triangle as u32
}

/// Whether this CPU runs [`Avx2`].
#[inline]
pub fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// AVX2 lanes: eight boxes in one register per plane, four triangles in one register per
/// coordinate.
#[cfg(target_arch = "x86_64")]
pub struct Avx2;

#[cfg(target_arch = "x86_64")]
impl Kernels for Avx2 {
    #[inline(always)]
    unsafe fn boxes<const NEG: bool>(
        node: &WideNode,
        r: &RayPre,
        tmin: f32,
        tmax: f32,
        tnear: &mut [f32; WIDTH],
    ) -> u32 {
        unsafe { avx2::boxes::<NEG>(node, r, tmin, tmax, tnear) }
    }
    #[inline(always)]
    unsafe fn triangles(block: &LeafBlock, r: &RayPre, tmin: f32, tmax: f32, t: &mut [f32; LANES]) -> u32 {
        unsafe { avx2::triangles(block, r, tmin, tmax, t) }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use std::arch::x86_64::*;

    // These are `inline(always)` without `target_feature` of their own: they are only
    // reached through `Avx2`, inlined into the walk, which is compiled with AVX2.

    #[inline(always)]
    pub unsafe fn boxes<const NEG: bool>(
        node: &WideNode,
        r: &RayPre,
        tmin: f32,
        tmax: f32,
        tnear: &mut [f32; WIDTH],
    ) -> u32 {
        // SAFETY: WideNode is 32-byte aligned and each row holds eight f32; tnear holds eight.
        unsafe {
            let b = (node as *const WideNode).cast::<u8>();
            // RayPre's offsets select rows inside the node.
            let slab = |off: usize, o: f32, inv: f32| {
                let d = _mm256_sub_ps(_mm256_load_ps(b.add(off).cast()), _mm256_set1_ps(o));
                _mm256_mul_ps(d, _mm256_set1_ps(inv))
            };
            let near = |a: usize| slab(r.near[a], r.org_near[a], r.inv[a]);
            let far = |a: usize| slab(r.far[a], r.org_far[a], r.inv_far[a]);
            let (t0x, t0y, t0z) = (near(0), near(1), near(2));
            let (t1x, t1y, t1z) = (far(0), far(1), far(2));
            let (tn, tf) = if NEG {
                let tn = _mm256_max_ps(_mm256_max_ps(t0x, t0y), _mm256_max_ps(t0z, _mm256_set1_ps(tmin)));
                let tf = _mm256_min_ps(_mm256_min_ps(t1x, t1y), t1z);
                let tf = _mm256_max_ps(tf, _mm256_mul_ps(tf, _mm256_set1_ps(negative_fix())));
                (tn, _mm256_min_ps(tf, _mm256_set1_ps(tmax)))
            } else {
                // With tmin = +0 or more, integer max and min on the bits (a cycle shorter
                // than the float ones) give the same tn: negative candidates lose to tmin,
                // non-negative floats order as their bits do. tf may differ from the float
                // minimum only when it is negative (or −0), where the float comparison
                // below decides the same way.
                let i = _mm256_castps_si256;
                let tn = _mm256_max_epi32(
                    _mm256_max_epi32(i(t0x), i(t0y)),
                    _mm256_max_epi32(i(t0z), i(_mm256_set1_ps(tmin))),
                );
                let tf = _mm256_min_epi32(
                    _mm256_min_epi32(i(t1x), i(t1y)),
                    _mm256_min_epi32(i(t1z), i(_mm256_set1_ps(tmax))),
                );
                (_mm256_castsi256_ps(tn), _mm256_castsi256_ps(tf))
            };
            _mm256_storeu_ps(tnear.as_mut_ptr(), tn);
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, tf)) as u32
        }
    }

    /// a·b − c·d per lane by `<f32 as Real>::diff_of_products`'s operations (Kahan's
    /// algorithm with fused multiply-adds).
    #[inline(always)]
    unsafe fn diff_of_products(a: __m128, b: __m128, c: __m128, d: __m128) -> __m128 {
        // SAFETY: reached with FMA present (see above).
        unsafe {
            let cd = _mm_mul_ps(c, d);
            // fma(−c, d, cd) and fma(a, b, −cd).
            let err = _mm_fnmadd_ps(c, d, cd);
            _mm_add_ps(_mm_fmsub_ps(a, b, cd), err)
        }
    }

    /// `triangle::edge_tie` lane by lane: `e`, or where it is 0 the sign of `ey`, or where
    /// that is 0 too, of −`ex`.
    #[inline(always)]
    unsafe fn edge_tie(e: __m128, ex: __m128, ey: __m128) -> __m128 {
        // SAFETY: SSE4.1 blends, present with AVX2.
        unsafe {
            let zero = _mm_setzero_ps();
            let alt = _mm_blendv_ps(_mm_xor_ps(ex, _mm_set1_ps(-0.0)), ey, _mm_cmpneq_ps(ey, zero));
            _mm_blendv_ps(alt, e, _mm_cmpneq_ps(e, zero))
        }
    }

    #[inline(always)]
    pub unsafe fn triangles(block: &LeafBlock, r: &RayPre, tmin: f32, tmax: f32, t: &mut [f32; LANES]) -> u32 {
        // SAFETY: LeafBlock is 16-byte aligned and each coordinate row holds four f32.
        unsafe {
            let s = &r.shear;
            let (okx, oky, okz) = (_mm_set1_ps(r.org_k[0]), _mm_set1_ps(r.org_k[1]), _mm_set1_ps(r.org_k[2]));
            let (sx, sy, sz) = (_mm_set1_ps(s.sx), _mm_set1_ps(s.sy), _mm_set1_ps(s.sz));
            // Vertex k translated to the origin, permuted and sheared: (x, y, z) as in
            // Triangle::intersect.
            // RayPre's offsets select rows inside vertex k.
            let vertex = |k: usize| {
                let v = block.v[k].as_ptr().cast::<u8>();
                let dx = _mm_sub_ps(_mm_load_ps(v.add(r.row_k[0]).cast()), okx);
                let dy = _mm_sub_ps(_mm_load_ps(v.add(r.row_k[1]).cast()), oky);
                let dz = _mm_sub_ps(_mm_load_ps(v.add(r.row_k[2]).cast()), okz);
                (_mm_sub_ps(dx, _mm_mul_ps(sx, dz)), _mm_sub_ps(dy, _mm_mul_ps(sy, dz)), _mm_mul_ps(sz, dz))
            };
            let (ax, ay, az) = vertex(0);
            let (bx, by, bz) = vertex(1);
            let (cx, cy, cz) = vertex(2);
            let u = diff_of_products(cx, by, cy, bx);
            let v = diff_of_products(ax, cy, ay, cx);
            let w = diff_of_products(bx, ay, by, ax);
            let zero = _mm_setzero_ps();
            let det = _mm_add_ps(_mm_add_ps(u, v), w);
            // An edge function of exactly 0 counts with the sign of `edge_tie`. That is rare
            // on real triangles (det ≠ 0; lanes without a triangle have det = 0 and are
            // rejected anyway), so the tie signs are only formed when some lane needs them.
            let on_edge = _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)), _mm_cmpeq_ps(w, zero));
            let (u_s, v_s, w_s) = if _mm_movemask_ps(_mm_and_ps(on_edge, _mm_cmpneq_ps(det, zero))) == 0 {
                (u, v, w)
            } else {
                (
                    edge_tie(u, _mm_sub_ps(cx, bx), _mm_sub_ps(cy, by)),
                    edge_tie(v, _mm_sub_ps(ax, cx), _mm_sub_ps(ay, cy)),
                    edge_tie(w, _mm_sub_ps(bx, ax), _mm_sub_ps(by, ay)),
                )
            };
            let neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u_s, zero), _mm_cmplt_ps(v_s, zero)), _mm_cmplt_ps(w_s, zero));
            let pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u_s, zero), _mm_cmpgt_ps(v_s, zero)), _mm_cmpgt_ps(w_s, zero));
            let num = _mm_add_ps(_mm_add_ps(_mm_mul_ps(u, az), _mm_mul_ps(v, bz)), _mm_mul_ps(w, cz));
            let tt = _mm_div_ps(num, det);
            let inside = _mm_andnot_ps(_mm_and_ps(neg, pos), _mm_cmpneq_ps(det, zero));
            let range = _mm_and_ps(_mm_cmpgt_ps(tt, _mm_set1_ps(tmin)), _mm_cmplt_ps(tt, _mm_set1_ps(tmax)));
            _mm_storeu_ps(t.as_mut_ptr(), tt);
            // Lanes without a triangle hold three equal vertices: all edge functions are
            // exactly 0, det = 0, and the lane is rejected above like a degenerate triangle.
            _mm_movemask_ps(_mm_and_ps(inside, range)) as u32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::geometry::testutil::{TestRays, TestRng, ray_f32};

    #[test]
    fn ray_precomputation_matches_the_triangle_tests_shear() {
        let mut rng = TestRng(5);
        let axis = [V3::new(1.0, 0.0, 0.0), V3::new(0.0, -1.0, 0.0), V3::new(0.0, 0.0, 1.0), V3::new(1.0, 1.0, -1.0)];
        for i in 0..10_000 {
            let ray = match axis.get(i) {
                Some(a) => Ray::new(V3::zero(), a.normalize()),
                None => ray_f32(&rng.ray_towards(5.0, V3::zero(), 1.0)),
            };
            let (p, s) = (RayPre::new(&ray), Shear::new(ray.dir));
            assert_eq!((p.shear.kx, p.shear.ky, p.shear.kz), (s.kx, s.ky, s.kz), "{ray:?}");
            assert_eq!((p.shear.sx, p.shear.sy, p.shear.sz), (s.sx, s.sy, s.sz), "{ray:?}");
            assert_eq!(p.org_k, [ray.origin[s.kx], ray.origin[s.ky], ray.origin[s.kz]]);
        }
    }
}
