//! The ray/box slab test every walk of the BVH shares: the CPU's binary walk
//! (`strahl-cpu`), the GPU layout's walk ([`super::gpu_bvh`], the twin of
//! `shaders/modules/traverse.wgsl`) and the benchmark's ray sets.

use super::bvh::BvhNode;
use crate::math::{Ray, Real, V3};

/// 1/d per axis, with components below 1e-30 in magnitude (the ray runs parallel to that
/// axis) set to 0, which [`slab`] takes apart: 0·∞ would be NaN, and a finite stand-in such as
/// 1e30 gives slab distances of 1e30·(gap) that real hits can exceed (a ray from 1e38 away).
#[inline]
pub fn safe_inverse<R: Real>(d: V3<R>) -> V3<R> {
    let tiny = R::from_f64(1e-30);
    let inv = |v: R| if v.abs() < tiny { R::ZERO } else { R::ONE / v };
    V3::new(inv(d.x), inv(d.y), inv(d.z))
}

/// Ray/box slab test over [tmin, tmax]; returns the entry distance or `None`. The far
/// distance is scaled by 1 + 2γ(3) (pbrt-v3 §3.9.2), which covers the rounding of the three
/// operations behind each slab distance, so a box is never missed where its contents are hit.
/// An axis the ray runs parallel to (`inv` 0) bounds nothing while the origin lies within the
/// box on it, and rules the box out otherwise: exact at any distance.
#[inline]
pub fn slab<R: Real>(node: &BvhNode, ray: &Ray<R>, inv: V3<R>, tmin: R, tmax: R) -> Option<R> {
    let grow = R::ONE + R::from_f64(2.0) * R::gamma_bound(3);
    let mut tnear = tmin;
    let mut tfar = tmax;
    for a in 0..3 {
        let lo = R::from_f64(node.bmin[a] as f64);
        let hi = R::from_f64(node.bmax[a] as f64);
        if inv[a] == R::ZERO {
            if ray.origin[a] < lo || ray.origin[a] > hi {
                return None;
            }
            continue;
        }
        let t0 = (lo - ray.origin[a]) * inv[a];
        let t1 = (hi - ray.origin[a]) * inv[a];
        let (t0, t1) = if t0 > t1 { (t1, t0) } else { (t0, t1) };
        tnear = if t0 > tnear { t0 } else { tnear };
        let t1 = t1 * grow;
        tfar = if t1 < tfar { t1 } else { tfar };
    }
    (tnear <= tfar).then_some(tnear)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_test_has_no_nan_for_rays_on_box_faces() {
        let node = BvhNode { bmin: [0.0; 3], left_or_first: 0, bmax: [1.0; 3], count: 1 };
        // A ray lying in the box's x = 0 face, parallel to it.
        let ray = Ray::new(V3::<f32>::new(0.0, 0.5, -1.0), V3::new(0.0, 0.0, 1.0));
        assert_eq!(slab(&node, &ray, safe_inverse(ray.dir), 0.0, f32::INFINITY), Some(1.0));
        let outside = Ray::new(V3::<f32>::new(-0.1, 0.5, -1.0), V3::new(0.0, 0.0, 1.0));
        assert_eq!(slab(&node, &outside, safe_inverse(outside.dir), 0.0, f32::INFINITY), None);
    }
}
