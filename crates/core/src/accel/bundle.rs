//! A bundle of rays of any directions walked through the 8-wide tree ([`super::wide`])
//! together, one ray per SIMD lane: 16 lanes with AVX-512, 8 with AVX2, 4 portable ones
//! elsewhere. It is the traversal of the lane path tracer ([`crate::render::lanes`]), whose
//! secondary rays share no octant, so the packet walk of batch queries ([`super::packet`],
//! which needs one) does not serve them.
//!
//! Each lane keeps its own ray, its own near and far planes (chosen by the signs of its own
//! direction), its own watertight permutation and its own best hit. A node's child boxes are
//! tested one after the other against every lane at once; the children some lane enters are
//! visited nearest first (by the distance of the lowest such lane), the others deferred with
//! the lanes that enter them and their entry distances, and revisited only for the lanes they
//! still may serve. A leaf's triangles, spheres and cylinders are each tested against every
//! lane at once. Where a subtree is entered by at most [`HYBRID`] lanes, those lanes finish it
//! with the one-ray walk ([`super::wide_traverse`]), as Embree's hybrid traversal does (Benthin,
//! Wald, Woop, Ernst & Mark, "Combining Single and Packet-Ray Tracing for Arbitrary Ray
//! Distributions on the Intel MIC Architecture", 2012).
//!
//! Lane for lane the box tests compute [`super::simd::Scalar`]'s values and the primitive
//! tests the IEEE operations of [`crate::geometry`]'s f32 routines in the same order (the
//! loops below are written per lane, and the compiler turns them into vector instructions,
//! which round as the scalar ones do); hits are kept by [`Nearest::offer`]'s total order. So
//! every lane gets exactly the answer of [`super::wide_traverse::nearest`] (and of brute
//! force): the same `t`, the same primitive, the same tie rule. Only tmin = 0 is served.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::simd::{Kernels, RayPre, is_triangle, widen};
use super::wide::{EMPTY_CHILD, EMPTY_PRIM, LANES, LEAF_BIT, LeafBlock, MAX_DEPTH, WIDTH, WideBvh};
use super::wide_traverse;
use crate::geometry::{Cylinder, Part, Sphere};
use crate::math::{Ray, Real};
use crate::primitives::{Nearest, PrimKind, PrimRef, Primitives};
use std::mem::MaybeUninit;

/// The most lanes a bundle has (AVX-512).
pub const MAX_WIDTH: usize = 16;

/// A subtree entered by at most this many lanes is finished by each of them alone (measured
/// in the book's performance chapter).
const HYBRID: u32 = 1;

/// Which lanes this processor runs: the bundle width and the instructions of its walk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// 16 lanes, AVX-512 (F, VL, BW, DQ) with FMA.
    Avx512,
    /// 8 lanes, AVX2 with FMA.
    Avx2,
    /// 4 lanes in whatever vector instructions the target has by default.
    Portable,
}

impl Isa {
    /// The widest this processor has (detected at run time).
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512vl")
                && std::is_x86_feature_detected!("avx512bw")
                && std::is_x86_feature_detected!("avx512dq")
                && super::simd::has_avx2()
            {
                return Isa::Avx512;
            }
            if super::simd::has_avx2() {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }

    /// Lanes per bundle.
    pub fn width(self) -> usize {
        match self {
            Isa::Avx512 => 16,
            Isa::Avx2 => 8,
            Isa::Portable => 4,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Avx512 => "avx512",
            Isa::Avx2 => "avx2",
            Isa::Portable => "portable",
        }
    }

    /// Every lane set this processor can run, widest first (for tests).
    pub fn available() -> Vec<Isa> {
        [Isa::Avx512, Isa::Avx2, Isa::Portable].into_iter().filter(|&i| i.runs_here()).collect()
    }

    /// Whether this processor runs `self`.
    pub fn runs_here(self) -> bool {
        match (self, Isa::detect()) {
            (Isa::Portable, _) => true,
            (Isa::Avx2, Isa::Avx512 | Isa::Avx2) => true,
            (a, b) => a == b,
        }
    }
}

/// Up to [`MAX_WIDTH`] rays field by field: origins `o[axis][lane]`, unit directions `d`.
/// Lanes past those in use hold any finite ray (their answers are not read).
#[derive(Clone, Copy, Debug)]
pub struct BundleRays<const N: usize> {
    pub o: [[f32; N]; 3],
    pub d: [[f32; N]; 3],
}

impl BundleRays<MAX_WIDTH> {
    /// `rays` (at most [`MAX_WIDTH`]), the last repeated in the lanes past them.
    pub fn from_rays(rays: &[Ray<f32>]) -> Self {
        let ray = |l: usize| rays[l.min(rays.len().saturating_sub(1))];
        let field = |f: &dyn Fn(&Ray<f32>) -> [f32; 3]| -> [[f32; MAX_WIDTH]; 3] {
            std::array::from_fn(|a| std::array::from_fn(|l| if rays.is_empty() { 0.0 } else { f(&ray(l))[a] }))
        };
        Self { o: field(&|r| r.origin.to_array()), d: field(&|r| r.dir.to_array()) }
    }

    /// The first `N` lanes.
    #[inline(always)]
    fn first<const N: usize>(&self) -> BundleRays<N> {
        BundleRays {
            o: std::array::from_fn(|a| std::array::from_fn(|l| self.o[a][l])),
            d: std::array::from_fn(|a| std::array::from_fn(|l| self.d[a][l])),
        }
    }
}

/// The nearest hit in (0, ∞) of each of `rays` (at most `isa.width()`), into `out`: exactly
/// what [`wide_traverse::nearest`] finds (its record is [`Primitives::hit`] of it).
///
/// # Panics
/// If `isa` does not run here, or `rays` is longer than its width or than `out`.
pub fn nearest(isa: Isa, w: &WideBvh, prims: &Primitives<f32>, rays: &[Ray<f32>], out: &mut [Nearest<f32>]) {
    assert!(rays.len() <= MAX_WIDTH);
    nearest_lanes(isa, w, prims, &BundleRays::from_rays(rays), rays.len(), out)
}

/// [`nearest`] for the first `count` lanes of `rays`.
pub fn nearest_lanes(
    isa: Isa,
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &BundleRays<MAX_WIDTH>,
    count: usize,
    out: &mut [Nearest<f32>],
) {
    assert!(isa.runs_here() && count <= isa.width() && out.len() >= count);
    if count == 0 {
        return;
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the processor has AVX-512 and AVX2 (asserted above).
        Isa::Avx512 => unsafe { x86::nearest_avx512(w, prims, rays, count, out) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above, AVX2.
        Isa::Avx2 => unsafe { x86::nearest_avx2(w, prims, rays, count, out) },
        _ => nearest_n::<4, super::simd::Scalar>(w, prims, &rays.first(), count, out),
    }
}

/// Whether anything lies in (0, tmax[i]) along each of `rays` (at most `isa.width()`): bit i
/// set for ray i, exactly where [`wide_traverse::occluded`] says so.
///
/// # Panics
/// As [`nearest`], and if `tmax` is shorter than `rays`.
pub fn occluded(isa: Isa, w: &WideBvh, prims: &Primitives<f32>, rays: &[Ray<f32>], tmax: &[f32]) -> u32 {
    assert!(rays.len() <= MAX_WIDTH && tmax.len() >= rays.len());
    let mut t = [0.0f32; MAX_WIDTH];
    t[..rays.len()].copy_from_slice(&tmax[..rays.len()]);
    occluded_lanes(isa, w, prims, &BundleRays::from_rays(rays), &t, rays.len())
}

/// [`occluded`] for the first `count` lanes of `rays`, each up to `tmax[lane]`.
pub fn occluded_lanes(
    isa: Isa,
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &BundleRays<MAX_WIDTH>,
    tmax: &[f32; MAX_WIDTH],
    count: usize,
) -> u32 {
    assert!(isa.runs_here() && count <= isa.width());
    if count == 0 {
        return 0;
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `nearest_lanes`.
        Isa::Avx512 => unsafe { x86::occluded_avx512(w, prims, rays, tmax, count) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `nearest_lanes`.
        Isa::Avx2 => unsafe { x86::occluded_avx2(w, prims, rays, tmax, count) },
        _ => occluded_n::<4>(w, prims, &rays.first(), &std::array::from_fn(|l| tmax[l]), count),
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::*;
    use crate::accel::simd::Avx2;

    #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn nearest_avx512(
        w: &WideBvh,
        prims: &Primitives<f32>,
        rays: &BundleRays<MAX_WIDTH>,
        count: usize,
        out: &mut [Nearest<f32>],
    ) {
        nearest_n::<16, Avx2>(w, prims, &rays.first(), count, out)
    }

    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn nearest_avx2(
        w: &WideBvh,
        prims: &Primitives<f32>,
        rays: &BundleRays<MAX_WIDTH>,
        count: usize,
        out: &mut [Nearest<f32>],
    ) {
        nearest_n::<8, Avx2>(w, prims, &rays.first(), count, out)
    }

    #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn occluded_avx512(
        w: &WideBvh,
        prims: &Primitives<f32>,
        rays: &BundleRays<MAX_WIDTH>,
        tmax: &[f32; MAX_WIDTH],
        count: usize,
    ) -> u32 {
        occluded_n::<16>(w, prims, &rays.first(), &std::array::from_fn(|l| tmax[l]), count)
    }

    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn occluded_avx2(
        w: &WideBvh,
        prims: &Primitives<f32>,
        rays: &BundleRays<MAX_WIDTH>,
        tmax: &[f32; MAX_WIDTH],
        count: usize,
    ) -> u32 {
        occluded_n::<8>(w, prims, &rays.first(), &std::array::from_fn(|l| tmax[l]), count)
    }
}

/// The bit mask of the lanes whose word is nonzero (lane words are 0 or −1: what the lane
/// loops below write). One instruction on x86-64 where the width is a register's.
#[inline(always)]
fn mask_of<const N: usize>(b: &[i32; N]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: the loads read N = 16, 8 or 4 words of `b`; 16 lanes only run in the AVX-512
    // walk, 8 in the AVX2 one, and 4 are SSE, which every x86-64 has.
    unsafe {
        use std::arch::x86_64::*;
        if N == 16 {
            return _mm512_movepi32_mask(_mm512_loadu_si512(b.as_ptr().cast())) as u32;
        }
        if N == 8 {
            return _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_loadu_si256(b.as_ptr().cast()))) as u32;
        }
        if N == 4 {
            return _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(b.as_ptr().cast()))) as u32;
        }
    }
    let mut m = 0u32;
    for (l, &x) in b.iter().enumerate() {
        m |= ((x != 0) as u32) << l;
    }
    m
}

/// A lane word of `mask_of`'s input.
#[inline(always)]
fn word(b: bool) -> i32 {
    -(b as i32)
}

/// What the tests of every lane share, per lane: the ray, its box-test planes and inverse
/// direction ([`RayPre`]'s values), and its watertight permutation and shear.
struct Lanes<const N: usize> {
    /// The lanes that hold a ray.
    on: u32,
    org: [[f32; N]; 3],
    dir: [[f32; N]; 3],
    org_near: [[f32; N]; 3],
    org_far: [[f32; N]; 3],
    inv: [[f32; N]; 3],
    inv_far: [[f32; N]; 3],
    /// Per axis: the lane's near plane is the box's upper bound (its direction is negative).
    neg: [[bool; N]; 3],
    /// The permutation: axis index kx, ky, kz per lane.
    k: [[u32; N]; 3],
    sx: [f32; N],
    sy: [f32; N],
    sz: [f32; N],
}

impl<const N: usize> Lanes<N> {
    /// [`RayPre::new`]'s values, lane by lane, by its operations, for the first `count` of
    /// the rays `r` (the others stay off).
    #[inline(always)]
    fn new(r: &BundleRays<N>, count: usize) -> Self {
        debug_assert!(count > 0 && count <= N);
        let mut s = Self {
            on: ((1u64 << count) - 1) as u32,
            org: r.o,
            dir: r.d,
            org_near: [[0.0; N]; 3],
            org_far: [[0.0; N]; 3],
            inv: [[0.0; N]; 3],
            inv_far: [[0.0; N]; 3],
            neg: [[false; N]; 3],
            k: [[0; N]; 3],
            sx: [0.0; N],
            sy: [0.0; N],
            sz: [0.0; N],
        };
        for l in 0..N {
            let (o, d) = ([r.o[0][l], r.o[1][l], r.o[2][l]], [r.d[0][l], r.d[1][l], r.d[2][l]]);
            for a in 0..3 {
                let parallel = d[a].abs() < super::simd::TINY;
                let pinv = if d[a] < 0.0 { -f32::INFINITY } else { f32::INFINITY };
                let inv = if parallel { pinv } else { 1.0 / d[a] };
                let shift = super::simd::parallel_shift(o[a]).copysign(inv);
                let shift = if parallel { shift } else { 0.0 };
                s.inv[a][l] = inv;
                s.inv_far[a][l] = if parallel { inv } else { inv * super::simd::far_grow() };
                s.neg[a][l] = inv < 0.0;
                s.org_near[a][l] = o[a] + shift;
                s.org_far[a][l] = o[a] - shift;
            }
            let m = d.map(f32::abs);
            let kz = if m[0] >= m[1] && m[0] >= m[2] {
                0
            } else if m[1] >= m[2] {
                1
            } else {
                2
            };
            let pick = |k: u32| {
                if k == 0 {
                    d[0]
                } else if k == 1 {
                    d[1]
                } else {
                    d[2]
                }
            };
            let kz: u32 = kz;
            let (kx, ky) = (if kz == 2 { 0 } else { kz + 1 }, if kz == 0 { 2 } else { kz - 1 });
            let dz = pick(kz);
            let (kx, ky) = if dz < 0.0 { (ky, kx) } else { (kx, ky) };
            let sz = 1.0 / dz;
            s.k[0][l] = kx;
            s.k[1][l] = ky;
            s.k[2][l] = kz;
            s.sx[l] = pick(kx) * sz;
            s.sy[l] = pick(ky) * sz;
            s.sz[l] = sz;
        }
        s
    }

    /// The ray of lane `l`.
    #[inline(always)]
    fn ray(&self, l: usize) -> Ray<f32> {
        Ray::new(
            crate::math::V3::new(self.org[0][l], self.org[1][l], self.org[2][l]),
            crate::math::V3::new(self.dir[0][l], self.dir[1][l], self.dir[2][l]),
        )
    }

    /// Which lanes of `mask` enter child `c` of `node` within [0, cull] (by
    /// [`super::simd::Scalar::boxes`]' arithmetic), with their entry distances in `tn`.
    #[inline(always)]
    fn child_box(&self, node: &super::wide::WideNode, c: usize, cull: &[f32; N], tn: &mut [f32; N]) -> u32 {
        let lo: [f32; 3] = std::array::from_fn(|a| node.bounds[2 * a][c]);
        let hi: [f32; 3] = std::array::from_fn(|a| node.bounds[2 * a + 1][c]);
        let mut enter = [0i32; N];
        for l in 0..N {
            let (mut near, mut far) = (0.0f32, f32::INFINITY);
            for a in 0..3 {
                let (np, fp) = if self.neg[a][l] { (hi[a], lo[a]) } else { (lo[a], hi[a]) };
                let t0 = (np - self.org_near[a][l]) * self.inv[a][l];
                let t1 = (fp - self.org_far[a][l]) * self.inv_far[a][l];
                near = if t0 > near { t0 } else { near };
                far = if t1 < far { t1 } else { far };
            }
            let far = if cull[l] < far { cull[l] } else { far };
            tn[l] = near;
            enter[l] = word(near <= far);
        }
        mask_of(&enter)
    }

    /// Triangle `lane` of `block` against every lane: hits in (0, bound) and their `t`, by
    /// [`crate::geometry::Triangle::intersect`]'s operations.
    #[inline(always)]
    fn triangle(&self, block: &LeafBlock, lane: usize, bound: &[f32; N], t: &mut [f32; N]) -> u32 {
        let vert = |k: usize| -> [f32; 3] { std::array::from_fn(|a| block.v[k][a][lane]) };
        let (va, vb, vc) = (vert(0), vert(1), vert(2));
        let mut hit = [0i32; N];
        for l in 0..N {
            let o = [self.org[0][l], self.org[1][l], self.org[2][l]];
            let (kx, ky, kz) = (self.k[0][l], self.k[1][l], self.k[2][l]);
            let pick = |v: [f32; 3], k: u32| {
                if k == 0 {
                    v[0]
                } else if k == 1 {
                    v[1]
                } else {
                    v[2]
                }
            };
            let rel = |v: [f32; 3]| [v[0] - o[0], v[1] - o[1], v[2] - o[2]];
            let (a, b, c) = (rel(va), rel(vb), rel(vc));
            let (sx, sy, sz) = (self.sx[l], self.sy[l], self.sz[l]);
            let ax = pick(a, kx) - sx * pick(a, kz);
            let ay = pick(a, ky) - sy * pick(a, kz);
            let bx = pick(b, kx) - sx * pick(b, kz);
            let by = pick(b, ky) - sy * pick(b, kz);
            let cx = pick(c, kx) - sx * pick(c, kz);
            let cy = pick(c, ky) - sy * pick(c, kz);
            let u = f32::diff_of_products(cx, by, cy, bx);
            let v = f32::diff_of_products(ax, cy, ay, cx);
            let w = f32::diff_of_products(bx, ay, by, ax);
            let tie = crate::geometry::triangle::edge_tie::<f32>;
            let (su, sv, sw) = (tie(u, cx - bx, cy - by), tie(v, ax - cx, ay - cy), tie(w, bx - ax, by - ay));
            let outside = (su < 0.0 || sv < 0.0 || sw < 0.0) && (su > 0.0 || sv > 0.0 || sw > 0.0);
            let det = u + v + w;
            let (az, bz, cz) = (sz * pick(a, kz), sz * pick(b, kz), sz * pick(c, kz));
            let tt = (u * az + v * bz + w * cz) / det;
            t[l] = tt;
            hit[l] = word(!outside && det != 0.0 && tt > 0.0 && tt < bound[l]);
        }
        mask_of(&hit)
    }

    /// Sphere `s` against every lane: the first root in (0, bound) of
    /// [`Sphere`]'s `roots`, by its operations.
    #[inline(always)]
    fn sphere(&self, s: &Sphere<f32>, bound: &[f32; N], t: &mut [f32; N]) -> u32 {
        let (c, r) = (s.center, s.radius);
        let mut hit = [0i32; N];
        for l in 0..N {
            let (dx, dy, dz) = (self.dir[0][l], self.dir[1][l], self.dir[2][l]);
            let (fx, fy, fz) = (self.org[0][l] - c.x, self.org[1][l] - c.y, self.org[2][l] - c.z);
            let a = dx * dx + dy * dy + dz * dz;
            let beta = dx * fx + dy * fy + dz * fz;
            let cc = (fx * fx + fy * fy + fz * fz) - r * r;
            let ba = beta / a;
            let (lx, ly, lz) = (fx - dx * ba, fy - dy * ba, fz - dz * ba);
            let disc = a * (r * r - (lx * lx + ly * ly + lz * lz));
            let (ok, t0, t1) = quadratic(a, beta, cc, disc);
            let in0 = ok && t0 > 0.0 && t0 < bound[l];
            let in1 = ok && t1 != t0 && t1 > 0.0 && t1 < bound[l];
            t[l] = if in0 { t0 } else { t1 };
            hit[l] = word(in0 || in1);
        }
        mask_of(&hit)
    }

    /// Cylinder `cy` against every lane: the first root in (0, bound) of [`Cylinder`]'s
    /// `roots` (side roots, then the caps, the earlier one at equal `t`), and its part.
    #[inline(always)]
    fn cylinder(&self, cy: &Cylinder<f32>, bound: &[f32; N], t: &mut [f32; N], part: &mut [u8; N]) -> u32 {
        let (axis, len) = cy.axis();
        let (p1, p2, r) = (cy.p1, cy.p2, cy.radius);
        let r2 = r * r;
        let naxis = -axis;
        let mut hit = [0i32; N];
        for l in 0..N {
            let (dx, dy, dz) = (self.dir[0][l], self.dir[1][l], self.dir[2][l]);
            let (px, py, pz) = (self.org[0][l], self.org[1][l], self.org[2][l]);
            let (ox, oy, oz) = (px - p1.x, py - p1.y, pz - p1.z);
            let cross =
                |x: f32, y: f32, z: f32| (y * axis.z - z * axis.y, z * axis.x - x * axis.z, x * axis.y - y * axis.x);
            let (oax, oay, oaz) = cross(ox, oy, oz);
            let (dax, day, daz) = cross(dx, dy, dz);
            let a = dax * dax + day * day + daz * daz;
            let beta = oax * dax + oay * day + oaz * daz;
            let c = (oax * oax + oay * oay + oaz * oaz) - r2;
            let e = oax * dx + oay * dy + oaz * dz;
            let disc = a * r2 - e * e;
            let (ok, t0, t1) = quadratic(a, beta, c, disc);
            let o_axial = ox * axis.x + oy * axis.y + oz * axis.z;
            let d_axial = dx * axis.x + dy * axis.y + dz * axis.z;
            let (mut best, mut best_part, mut any) = (f32::INFINITY, Part::Surface as u8, false);
            let mut take = |cand: bool, tc: f32, pc: u8| {
                let keep = cand && tc > 0.0 && tc < bound[l] && (!any || tc < best);
                best = if keep { tc } else { best };
                best_part = if keep { pc } else { best_part };
                any |= keep;
            };
            let side = |tc: f32| {
                let alpha = (o_axial + tc * d_axial) / len;
                (0.0..=1.0).contains(&alpha)
            };
            take(ok && side(t0), t0, Part::Surface as u8);
            take(ok && t1 != t0 && side(t1), t1, Part::Surface as u8);
            if cy.caps {
                // cap_root(ray, p1, −â), then cap_root(ray, p2, +â).
                let cap = |cx: f32, cyy: f32, cz: f32, n: crate::math::V3<f32>| {
                    let dn = dx * n.x + dy * n.y + dz * n.z;
                    let tc = ((cx - px) * n.x + (cyy - py) * n.y + (cz - pz) * n.z) / dn;
                    let (qx, qy, qz) = ((px - cx) + dx * tc, (py - cyy) + dy * tc, (pz - cz) + dz * tc);
                    (dn != 0.0 && qx * qx + qy * qy + qz * qz <= r2, tc)
                };
                let (ok1, tc1) = cap(p1.x, p1.y, p1.z, naxis);
                take(ok1, tc1, Part::CapP1 as u8);
                let (ok2, tc2) = cap(p2.x, p2.y, p2.z, axis);
                take(ok2, tc2, Part::CapP2 as u8);
            }
            t[l] = best;
            part[l] = best_part;
            hit[l] = word(any);
        }
        mask_of(&hit)
    }
}

/// [`crate::geometry::stable_quadratic`]'s operations, branch-free: whether there are roots,
/// and the two in ascending order.
#[inline(always)]
fn quadratic(a: f32, beta: f32, c: f32, disc: f32) -> (bool, f32, f32) {
    let ok = disc >= 0.0 && a != 0.0;
    let s = if beta < 0.0 { -1.0f32 } else { 1.0 };
    let q = -(beta + s * disc.sqrt());
    let (t1, t2) = (q / a, c / q);
    let (lo, hi) = if t1 <= t2 { (t1, t2) } else { (t2, t1) };
    let zero = q == 0.0;
    (ok, if zero { 0.0 } else { lo }, if zero { 0.0 } else { hi })
}

/// A deferred child: its word, the lanes that enter it and their entry distances.
#[derive(Clone, Copy)]
struct Entry<const N: usize> {
    tn: [f32; N],
    word: u32,
    mask: u32,
}

/// Room for the children a walk defers: at most seven per level.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

struct Stack<const N: usize> {
    entry: [MaybeUninit<Entry<N>>; STACK],
    len: usize,
}

impl<const N: usize> Stack<N> {
    #[inline(always)]
    fn new() -> Self {
        Self { entry: [const { MaybeUninit::uninit() }; STACK], len: 0 }
    }
    #[inline(always)]
    fn push(&mut self, e: Entry<N>) {
        self.entry[self.len] = MaybeUninit::new(e);
        self.len += 1;
    }
    /// The most recently deferred child some of whose lanes still enter it within `cull`
    /// (and are in `live`), with those lanes.
    #[inline(always)]
    fn pop_within(&mut self, cull: &[f32; N], live: u32) -> Option<(u32, u32)> {
        while self.len > 0 {
            self.len -= 1;
            // SAFETY: entries below `len` were written by `push`.
            let e = unsafe { self.entry[self.len].assume_init_ref() };
            let mut within = [0i32; N];
            for l in 0..N {
                within[l] = word(e.tn[l] <= cull[l]);
            }
            let mask = e.mask & mask_of(&within) & live;
            if mask != 0 {
                return Some((e.word, mask));
            }
        }
        None
    }
}

/// The best hits of the lanes.
struct Best<const N: usize> {
    t: [f32; N],
    prim: [u32; N],
    part: [u8; N],
    found: [bool; N],
    /// [`Nearest::search_bound`] per lane, and its widening for box entry distances.
    bound: [f32; N],
    cull: [f32; N],
}

impl<const N: usize> Best<N> {
    #[inline(always)]
    fn lane(&self, l: usize) -> Nearest<f32> {
        let part = match self.part[l] {
            0 => Part::Surface,
            1 => Part::CapP1,
            _ => Part::CapP2,
        };
        Nearest { t: self.t[l], prim_ref: PrimRef(self.prim[l]), part, found: self.found[l] }
    }

    #[inline(always)]
    fn set_lane(&mut self, l: usize, n: &Nearest<f32>) {
        self.t[l] = n.t;
        self.prim[l] = n.prim_ref.0;
        self.part[l] = n.part as u8;
        self.found[l] = n.found;
        self.bound[l] = n.search_bound();
        self.cull[l] = widen(self.bound[l]);
    }

    /// [`Nearest::offer`] of primitive `prim` at `t[l]` (part `part[l]`) for lanes `hits`.
    #[inline(always)]
    fn offer(&mut self, hits: u32, prim: u32, t: &[f32; N], part: &[u8; N]) {
        let mut changed = [0i32; N];
        for l in 0..N {
            let on = hits >> l & 1 != 0;
            let take = on && (t[l] < self.t[l] || (t[l] == self.t[l] && prim < self.prim[l]));
            self.t[l] = if take { t[l] } else { self.t[l] };
            self.prim[l] = if take { prim } else { self.prim[l] };
            self.part[l] = if take { part[l] } else { self.part[l] };
            self.found[l] |= take;
            changed[l] = word(take);
        }
        let mut m = mask_of(&changed);
        while m != 0 {
            let l = m.trailing_zeros() as usize;
            m &= m - 1;
            // primitives::next_up for the f32 it sees (t > 0 here).
            self.bound[l] = self.t[l].next_up();
            self.cull[l] = widen(self.bound[l]);
        }
    }
}

/// The nearest-hit walk of up to N rays; `K`: the one-ray walk's kernels for the lanes that
/// finish a subtree alone.
#[inline(always)]
fn nearest_n<const N: usize, K: Kernels>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &BundleRays<N>,
    count: usize,
    out: &mut [Nearest<f32>],
) {
    let lanes = Lanes::<N>::new(rays, count);
    let mut best = Best::<N> {
        t: [f32::INFINITY; N],
        prim: [u32::MAX; N],
        part: [0; N],
        found: [false; N],
        bound: [f32::INFINITY; N],
        cull: [f32::INFINITY; N],
    };
    if !prims.planes.is_empty() {
        for l in 0..count {
            let mut n = best.lane(l);
            for r in prims.plane_refs() {
                prims.offer_nearest(r, &lanes.ray(l), 0.0, &mut n);
            }
            best.set_lane(l, &n);
        }
    }
    if !w.is_empty() {
        walk_nearest::<N, K>(w, prims, &lanes, &mut best);
    }
    for (l, o) in out[..count].iter_mut().enumerate() {
        *o = best.lane(l);
    }
}

#[inline(always)]
fn walk_nearest<const N: usize, K: Kernels>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    lanes: &Lanes<N>,
    best: &mut Best<N>,
) {
    let mut stack = Stack::<N>::new();
    let (mut word, mut mask) = (0u32, lanes.on);
    let mut t = [0.0f32; N];
    let mut part = [0u8; N];
    loop {
        if mask.count_ones() <= HYBRID {
            // Few lanes left in this subtree: each finishes it alone.
            let mut m = mask;
            while m != 0 {
                let l = m.trailing_zeros() as usize;
                m &= m - 1;
                let mut n = best.lane(l);
                wide_traverse::nearest_from::<K>(w, prims, &RayPre::new(&lanes.ray(l)), word, &mut n);
                best.set_lane(l, &n);
            }
        } else if word & LEAF_BIT == 0 {
            let node = w.node(word);
            let mut tn = [[0.0f32; N]; WIDTH];
            let mut entered = [(0u32, 0.0f32, 0usize); WIDTH];
            let mut n_in = 0;
            for c in 0..WIDTH {
                if node.child[c] == EMPTY_CHILD {
                    continue;
                }
                let m = lanes.child_box(node, c, &best.cull, &mut tn[c]) & mask;
                if m != 0 {
                    entered[n_in] = (m, tn[c][m.trailing_zeros() as usize], c);
                    n_in += 1;
                }
            }
            if n_in > 0 {
                // Farthest first onto the stack; visit the nearest now.
                let list = &mut entered[..n_in];
                list.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
                for &(m, _, c) in &list[..n_in - 1] {
                    stack.push(Entry { tn: tn[c], word: node.child[c], mask: m });
                }
                let (m, _, c) = list[n_in - 1];
                (word, mask) = (node.child[c], m);
                continue;
            }
        } else {
            leaf_nearest(w, prims, lanes, word, mask, best, &mut t, &mut part);
        }
        match stack.pop_within(&best.cull, lanes.on) {
            Some((wd, m)) => (word, mask) = (wd, m),
            None => return,
        }
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn leaf_nearest<const N: usize>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    lanes: &Lanes<N>,
    word: u32,
    mask: u32,
    best: &mut Best<N>,
    t: &mut [f32; N],
    part: &mut [u8; N],
) {
    let (blocks, _) = w.leaf(word);
    let surface = [Part::Surface as u8; N];
    for block in blocks {
        for j in 0..LANES {
            let p = block.prim_ref[j];
            if p == EMPTY_PRIM {
                continue;
            }
            let hits = if is_triangle(p) {
                lanes.triangle(block, j, &best.bound, t) & mask
            } else {
                let r = PrimRef(p);
                match r.kind() {
                    PrimKind::Sphere => lanes.sphere(&prims.spheres[r.index()].shape, &best.bound, t) & mask,
                    PrimKind::Cylinder => {
                        let h = lanes.cylinder(&prims.cylinders[r.index()].shape, &best.bound, t, part) & mask;
                        if h != 0 {
                            best.offer(h, p, t, part);
                        }
                        continue;
                    }
                    _ => 0,
                }
            };
            if hits != 0 {
                best.offer(hits, p, t, &surface);
            }
        }
    }
}

/// The occlusion walk of up to N rays: every leaf a live lane's box test enters, until each
/// lane has a hit.
#[inline(always)]
fn occluded_n<const N: usize>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    rays: &BundleRays<N>,
    bound: &[f32; N],
    count: usize,
) -> u32 {
    let lanes = Lanes::<N>::new(rays, count);
    let bound = *bound;
    let cull: [f32; N] = std::array::from_fn(|l| widen(bound[l]));
    let mut done = 0u32;
    if !prims.planes.is_empty() {
        for l in 0..count {
            if prims.plane_refs().any(|r| prims.roots(r, &lanes.ray(l), 0.0, bound[l]).len > 0) {
                done |= 1 << l;
            }
        }
    }
    if w.is_empty() || done == lanes.on {
        return done;
    }
    let mut stack = Stack::<N>::new();
    let (mut word, mut mask) = (0u32, lanes.on & !done);
    let mut t = [0.0f32; N];
    let mut part = [0u8; N];
    loop {
        if word & LEAF_BIT == 0 {
            let node = w.node(word);
            let mut tn = [0.0f32; N];
            let mut first: Option<(u32, u32)> = None;
            for c in 0..WIDTH {
                if node.child[c] == EMPTY_CHILD {
                    continue;
                }
                let m = lanes.child_box(node, c, &cull, &mut tn) & mask;
                if m != 0 {
                    // Every child entered is visited: the order does not matter.
                    match first {
                        None => first = Some((node.child[c], m)),
                        Some(_) => stack.push(Entry { tn, word: node.child[c], mask: m }),
                    }
                }
            }
            if let Some((wd, m)) = first {
                (word, mask) = (wd, m);
                continue;
            }
        } else {
            let (blocks, _) = w.leaf(word);
            'blocks: for block in blocks {
                for j in 0..LANES {
                    let p = block.prim_ref[j];
                    if p == EMPTY_PRIM {
                        continue;
                    }
                    let hits = if is_triangle(p) {
                        lanes.triangle(block, j, &bound, &mut t)
                    } else {
                        let r = PrimRef(p);
                        match r.kind() {
                            PrimKind::Sphere => lanes.sphere(&prims.spheres[r.index()].shape, &bound, &mut t),
                            PrimKind::Cylinder => {
                                lanes.cylinder(&prims.cylinders[r.index()].shape, &bound, &mut t, &mut part)
                            }
                            _ => 0,
                        }
                    };
                    done |= hits & mask;
                    mask &= !hits;
                    if mask == 0 {
                        break 'blocks;
                    }
                }
            }
            if done == lanes.on {
                return done;
            }
        }
        match stack.pop_within(&cull, lanes.on & !done) {
            Some((wd, m)) => (word, mask) = (wd, m),
            None => return done,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Bvh;
    use crate::geometry::testutil::{TestRays, TestRng, ray_f32};
    use crate::math::V3;
    use crate::primitives::Hit;
    use crate::primitives::testutil::mixed_scene;

    /// Random rays (any octant, bundled in arrival order) through spheres, cylinders (capped
    /// and open), triangles and a plane: each lane's nearest hit equals the one-ray walk's,
    /// field for field, and its occlusion answer too, with every lane set this CPU runs and
    /// bundles of every length.
    #[test]
    fn bundles_answer_as_the_one_ray_walk() {
        let prims = mixed_scene(41);
        let w = WideBvh::new(&Bvh::build(&prims), &prims);
        let mut rng = TestRng(42);
        let rays: Vec<Ray<f32>> = (0..6_000).map(|_| ray_f32(&rng.ray_towards(80.0, V3::zero(), 50.0))).collect();
        // Inside-out rays too: origins inside the scene's cluster.
        let inner: Vec<Ray<f32>> = (0..2_000).map(|_| ray_f32(&rng.ray_towards(10.0, V3::zero(), 50.0))).collect();
        let rays: Vec<Ray<f32>> = rays.into_iter().chain(inner).collect();
        let want: Vec<Option<Hit<f32>>> =
            rays.iter().map(|r| wide_traverse::nearest(&w, &prims, r, 0.0, f32::INFINITY)).collect();
        let tmax: Vec<f32> = rays.iter().enumerate().map(|(i, _)| [f32::INFINITY, 30.0, 60.0, 90.0][i % 4]).collect();
        let blocked: Vec<bool> =
            rays.iter().zip(&tmax).map(|(r, &t)| wide_traverse::occluded(&w, &prims, r, 0.0, t)).collect();
        let (hits, blocks) = (want.iter().flatten().count(), blocked.iter().filter(|&&b| b).count());
        assert!(hits > 4_000 && hits < 7_900, "{hits} hits: the test would prove little");
        assert!(blocks > 3_000 && blocks < 7_900, "{blocks} blocked");
        let mut caps = 0;
        for isa in Isa::available() {
            let width = isa.width();
            let mut start = 0;
            let mut len = 1;
            while start < rays.len() {
                let end = (start + len).min(rays.len());
                let mut out = vec![Nearest::<f32>::new(0.0); end - start];
                nearest(isa, &w, &prims, &rays[start..end], &mut out);
                for (i, b) in out.iter().enumerate() {
                    let got = b.found.then(|| prims.hit(b.prim_ref, &rays[start + i], b.t, b.part));
                    assert_eq!(got, want[start + i], "{isa:?}: ray {}", start + i);
                    caps += got.is_some_and(|h| h.part != Part::Surface) as usize;
                }
                let m = occluded(isa, &w, &prims, &rays[start..end], &tmax[start..end]);
                for i in 0..end - start {
                    assert_eq!(m >> i & 1 != 0, blocked[start + i], "{isa:?}: shadow ray {}", start + i);
                }
                start = end;
                len = len % width + 1;
            }
        }
        assert!(caps > 10, "{caps} cap hits: the caps went untested");
    }
}
