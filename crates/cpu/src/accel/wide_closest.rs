//! The nearest surface point on the 8-wide tree: the walk of `strahl_core::proximity::closest`
//! with eight box distances per step and the triangles read from the leaf blocks' copies (in
//! leaf order, where the binary walk fetches each from the scene's array, a cache miss apiece
//! in a large mesh). The feet are the same functions', the pruning rule (a box farther than
//! the best foot grown by 2γ(4) is skipped) and the tie rule the same, so it returns exactly
//! what `proximity::closest` and `proximity::closest_brute` return.

use super::wide::{EMPTY_CHILD, EMPTY_PRIM, LANES, LEAF_BIT, WIDTH, WideBvh};
use super::wide_all::Stack;
use strahl_core::geometry::Triangle;
use strahl_core::math::{Real, V3};
use strahl_core::primitives::{PrimKind, PrimRef, Primitives};
use strahl_core::proximity::Closest;

/// The nearest surface point of the scene to `p` (`None` only for an empty scene).
pub fn closest(w: &WideBvh, prims: &Primitives<f32>, p: V3<f32>) -> Option<Closest<f32>> {
    #[cfg(target_arch = "x86_64")]
    if super::simd::has_avx2() {
        // SAFETY: the CPU has AVX2 and FMA.
        return unsafe { closest_avx2(w, prims, p) };
    }
    closest_with(w, prims, p)
}

/// The same walk compiled for AVX2, where the eight box distances are one register each way
/// (Rust contracts no multiply-add, so the results are the scalar build's bit for bit).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn closest_avx2(w: &WideBvh, prims: &Primitives<f32>, p: V3<f32>) -> Option<Closest<f32>> {
    closest_with(w, prims, p)
}

#[inline(always)]
fn closest_with(w: &WideBvh, prims: &Primitives<f32>, p: V3<f32>) -> Option<Closest<f32>> {
    let mut best = None;
    for r in prims.plane_refs() {
        Closest::offer(&mut best, r, prims.closest_of(r, p));
    }
    if w.is_empty() {
        return best;
    }
    let grow = 1.0 + 2.0 * f32::gamma_bound(4);
    let bound = |b: &Option<Closest<f32>>| b.map_or(f32::INFINITY, |b| b.foot.dist2 * grow);
    let mut stack = Stack::new();
    let mut word = 0u32;
    let mut d2 = [0.0f32; WIDTH];
    loop {
        if word & LEAF_BIT == 0 {
            let node = w.node(word);
            let b = &node.bounds;
            // `proximity::box_dist2`'s operations, eight boxes at once.
            for (k, d) in d2.iter_mut().enumerate() {
                let dx = (b[0][k] - p.x).max(p.x - b[1][k]).max(0.0);
                let dy = (b[2][k] - p.y).max(p.y - b[3][k]).max(0.0);
                let dz = (b[4][k] - p.z).max(p.z - b[5][k]).max(0.0);
                *d = dx * dx + dy * dy + dz * dz;
            }
            let limit = bound(&best);
            // The children within the bound, nearest first: it is walked now, the others are
            // deferred farthest first, so the stack pops them nearest first.
            let mut near = [(0.0f32, 0u32); WIDTH];
            let mut n = 0;
            for (&child, &d) in node.child.iter().zip(&d2) {
                if child != EMPTY_CHILD && d <= limit {
                    let mut i = n;
                    while i > 0 && near[i - 1].0 < d {
                        near[i] = near[i - 1];
                        i -= 1;
                    }
                    near[i] = (d, child);
                    n += 1;
                }
            }
            if n > 0 {
                for &(d, child) in &near[..n - 1] {
                    stack.push(child, d);
                }
                word = near[n - 1].1;
                continue;
            }
        } else {
            let (blocks, _) = w.leaf(word);
            for block in blocks {
                for lane in 0..LANES {
                    let r = block.prim_ref[lane];
                    if r == EMPTY_PRIM {
                        continue;
                    }
                    let r = PrimRef(r);
                    let foot = if r.kind() == PrimKind::Triangle {
                        let v = |k: usize| V3::new(block.v[k][0][lane], block.v[k][1][lane], block.v[k][2][lane]);
                        Triangle { v: [v(0), v(1), v(2)] }.closest(p)
                    } else {
                        prims.closest_of(r, p)
                    };
                    Closest::offer(&mut best, r, foot);
                }
            }
        }
        match stack.pop_within(bound(&best)) {
            Some(next) => word = next,
            None => return best,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::accel::Bvh;
    use strahl_core::geometry::testutil::{TestRays, TestRng};
    use strahl_core::primitives::testutil::mixed_scene;
    use strahl_core::proximity::closest_brute;

    #[test]
    fn the_wide_walk_finds_what_brute_force_finds() {
        let prims = mixed_scene(12);
        let bvh = Bvh::build(&prims);
        let wide = WideBvh::new(&bvh, &prims);
        let mut rng = TestRng(31);
        for k in 0..3000 {
            let p = rng.in_cube([10.0, 60.0, 500.0][k % 3]).cast::<f32>();
            assert_eq!(closest(&wide, &prims, p), closest_brute(&prims, p), "point {k}");
        }
        let empty = Primitives::<f32>::default();
        let bvh = Bvh::build(&empty);
        assert_eq!(closest(&WideBvh::new(&bvh, &empty), &empty, V3::new(1.0, 2.0, 3.0)), None);
    }
}
