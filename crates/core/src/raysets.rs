//! The ray sets of `strahl bench rays` and `benches/bvh_build.rs`, made as the Embree anchor
//! benchmark (`embree_bench.py`, the Embree 4 comparison) makes its own: camera rays (coherent) and
//! random rays (incoherent).

use crate::math::{Ray, V3};
use crate::render::camera;
use crate::rng::SplitMix64;
use crate::scene::Camera;
use rayon::prelude::*;

/// The f32 ray strahl traces for an f64 origin and direction: origin rounded, direction
/// normalised, rounded and normalised again in f32 (as every ray strahl makes is).
pub fn ray_f32(o: V3<f64>, d: V3<f64>) -> Ray<f32> {
    Ray::new(o.cast(), d.normalize().cast::<f32>().normalize())
}

/// One ray per pixel centre of `cam` on a `width` × `height` image, row by row from the top:
/// the primary rays of the renderers' first sample.
pub fn camera_rays(cam: &Camera, width: u32, height: u32) -> Vec<Ray<f32>> {
    let frame = camera::frame(cam, width, height);
    (0..height)
        .into_par_iter()
        .flat_map_iter(|y| (0..width).map(move |x| camera::primary_ray(&frame, x, y, 0)))
        .collect()
}

/// The image size for about `count` camera rays at aspect `width / height`, as the anchor
/// script chooses it: width ⌊√(count·aspect)⌋, height ⌊count / width⌋ (both at least 1).
pub fn camera_size(count: u64, aspect: f64) -> (u32, u32) {
    let w = ((count as f64 * aspect).sqrt() as u64).clamp(1, u32::MAX as u64);
    let h = (count / w).clamp(1, u32::MAX as u64);
    (w as u32, h as u32)
}

/// `n` rays from points on a sphere of radius 1.5·|hi − lo| around the box centre, aimed at
/// uniform points of the box `lo`–`hi` (the anchor script's `random_rays`), from `seed`.
pub fn random_rays(n: usize, lo: V3<f64>, hi: V3<f64>, seed: u64) -> Vec<Ray<f32>> {
    let c = (lo + hi) * 0.5;
    let radius = 1.5 * (hi - lo).length();
    let e = hi - lo;
    // Chunks with their own generators, so the set does not depend on the thread count.
    const CHUNK: usize = 1 << 16;
    (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .flat_map_iter(|k| {
            let mut rng = SplitMix64(seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            (0..CHUNK.min(n - k * CHUNK)).map(move |_| {
                let o = c + rng.direction() * radius;
                let t = lo + V3::new(e.x * rng.unit(), e.y * rng.unit(), e.z * rng.unit());
                ray_f32(o, t - o)
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::BvhNode;
    use crate::accel::slab::{safe_inverse, slab};

    #[test]
    fn camera_size_follows_the_anchor_script() {
        // embree_bench.py: w = int(sqrt(n * 4 / 3)), h = n // w.
        assert_eq!(camera_size(4_000_000, 4.0 / 3.0), (2309, 1732));
        assert_eq!(camera_size(1, 4.0 / 3.0), (1, 1));
    }

    #[test]
    fn random_rays_start_on_the_sphere_and_aim_into_the_box() {
        let (lo, hi) = (V3::new(-1.0, -2.0, -3.0), V3::new(1.0, 2.0, 3.0));
        let rays = random_rays(70_000, lo, hi, 1);
        assert_eq!(rays.len(), 70_000);
        let r = 1.5 * (hi - lo).length();
        let node = BvhNode { bmin: [-1.0, -2.0, -3.0], left_or_first: 0, bmax: [1.0, 2.0, 3.0], count: 1 };
        for ray in &rays {
            let o = ray.origin.to_f64();
            assert!((o.length() - r).abs() < 1e-5 * r);
            // The ray passes through the box.
            let inv = safe_inverse(ray.dir);
            assert!(slab(&node, ray, inv, 0.0, f32::INFINITY).is_some(), "{ray:?}");
        }
        let again = random_rays(70_000, lo, hi, 1);
        assert!(rays.iter().zip(&again).all(|(a, b)| a.origin == b.origin && a.dir == b.dir), "same seed, same set");
    }
}
