//! The lane tests of the bundle walk ([`super`]): each ray's box-test planes, permutation
//! and shear ([`Lanes::new`], `RayPre::new`'s values), and a node's child box, a triangle, a
//! sphere and a cylinder tested against every lane at once, each by the operations of its
//! one-ray routine, lane by lane.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::BundleRays;
use crate::accel::wide::{LeafBlock, WideNode};
use strahl_core::geometry::{Cylinder, Part, Sphere};
use strahl_core::math::{Ray, Real};

/// The bit mask of the lanes whose word is nonzero (lane words are 0 or −1: what the lane
/// loops below write). One instruction on x86-64 where the width is a register's.
#[inline(always)]
pub(super) fn mask_of<const N: usize>(b: &[i32; N]) -> u32 {
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
pub(super) fn word(b: bool) -> i32 {
    -(b as i32)
}

/// What the tests of every lane share, per lane: the ray, its box-test planes and inverse
/// direction ([`RayPre`]'s values), and its watertight permutation and shear.
pub(super) struct Lanes<const N: usize> {
    /// The lanes that hold a ray.
    pub(super) on: u32,
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
    pub(super) fn new(r: &BundleRays<N>, count: usize) -> Self {
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
                let parallel = d[a].abs() < super::super::simd::TINY;
                let pinv = if d[a] < 0.0 { -f32::INFINITY } else { f32::INFINITY };
                let inv = if parallel { pinv } else { 1.0 / d[a] };
                let shift = super::super::simd::parallel_shift(o[a]).copysign(inv);
                let shift = if parallel { shift } else { 0.0 };
                s.inv[a][l] = inv;
                s.inv_far[a][l] = if parallel { inv } else { inv * super::super::simd::far_grow() };
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
    pub(super) fn ray(&self, l: usize) -> Ray<f32> {
        Ray::new(
            strahl_core::math::V3::new(self.org[0][l], self.org[1][l], self.org[2][l]),
            strahl_core::math::V3::new(self.dir[0][l], self.dir[1][l], self.dir[2][l]),
        )
    }

    /// Which lanes of `mask` enter child `c` of `node` within [0, cull] (by
    /// [`super::simd::Scalar::boxes`]' arithmetic), with their entry distances in `tn`.
    #[inline(always)]
    pub(super) fn child_box(&self, node: &WideNode, c: usize, cull: &[f32; N], tn: &mut [f32; N]) -> u32 {
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
    /// [`strahl_core::geometry::Triangle::intersect`]'s operations.
    #[inline(always)]
    pub(super) fn triangle(&self, block: &LeafBlock, lane: usize, bound: &[f32; N], t: &mut [f32; N]) -> u32 {
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
            let tie = strahl_core::geometry::triangle::edge_tie::<f32>;
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
    pub(super) fn sphere(&self, s: &Sphere<f32>, bound: &[f32; N], t: &mut [f32; N]) -> u32 {
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
    pub(super) fn cylinder(&self, cy: &Cylinder<f32>, bound: &[f32; N], t: &mut [f32; N], part: &mut [u8; N]) -> u32 {
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
                let cap = |cx: f32, cyy: f32, cz: f32, n: strahl_core::math::V3<f32>| {
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

/// [`strahl_core::geometry::stable_quadratic`]'s operations, branch-free: whether there are roots,
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
