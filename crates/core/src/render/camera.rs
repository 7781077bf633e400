//! Primary rays: the pinhole camera of the scene file (`camera.wgsl` is the twin of
//! [`primary_ray`]).

use crate::layout::FrameParams;
use crate::math::lanes::{F, U, V, fract};
use crate::math::{Ray, V3};
use crate::scene::Camera;

/// The camera frame for a `width`×`height` image. +x of the view appears on the right and
/// +y up; the view looks along `look_at − eye`.
pub fn frame(cam: &Camera, width: u32, height: u32) -> FrameParams {
    let forward = (cam.look_at - cam.eye).normalize();
    let right = cam.up.cross(forward).normalize();
    let up = forward.cross(right);
    let half_h = (cam.fov_y.to_radians() * 0.5).tan();
    let half_w = half_h * width as f64 / height as f64;
    FrameParams {
        eye: cam.eye.cast::<f32>().to_array(),
        width,
        forward: forward.cast::<f32>().to_array(),
        height,
        right: (right * half_w).cast::<f32>().to_array(),
        up: (up * half_h).cast::<f32>().to_array(),
        ..FrameParams::default()
    }
}

/// Sub-pixel position of sample `s`: the R2 low-discrepancy sequence (Roberts 2018), whose
/// first point is the pixel centre, so one sample per pixel shoots through the centre.
#[inline]
pub fn sample_offset(s: u32) -> (f32, f32) {
    let (ox, oy) = sample_offset_lanes::<1>(s.into());
    (ox.into(), oy.into())
}

/// [`sample_offset`] in every lane.
#[inline(always)]
pub fn sample_offset_lanes<const N: usize>(s: U<N>) -> (F<N>, F<N>) {
    let sf = s.to_f32();
    (fract(F::splat(0.5) + sf * F::splat(0.754_877_7)), fract(F::splat(0.5) + sf * F::splat(0.569_840_3)))
}

/// The primary ray p = p_v + μd through pixel (x, y) (row 0 at the top) for sample `s`.
#[inline]
pub fn primary_ray(f: &FrameParams, x: u32, y: u32, s: u32) -> Ray<f32> {
    let (ox, oy) = sample_offset(s);
    ray_through(f, x, y, ox, oy)
}

/// The ray through sub-pixel position (ox, oy) ∈ [0, 1)² of pixel (x, y).
#[inline]
pub fn ray_through(f: &FrameParams, x: u32, y: u32, ox: f32, oy: f32) -> Ray<f32> {
    let dir = ray_through_lanes::<1>(f, x.into(), y, ox.into(), oy.into());
    Ray::new(V3::from_array(f.eye), dir.into())
}

/// The direction of [`ray_through`] in every lane (pixels (`x[l]`, `y`) of one row; the ray
/// leaves the eye).
#[inline(always)]
pub fn ray_through_lanes<const N: usize>(f: &FrameParams, x: U<N>, y: u32, ox: F<N>, oy: F<N>) -> V<N> {
    let (one, two) = (F::splat(1.0), F::splat(2.0));
    let u = two * (x.to_f32() + ox) / F::splat(f.width as f32) - one;
    let v = one - two * (F::splat(y as f32) + oy) / F::splat(f.height as f32);
    (V::splat(f.forward) + V::splat(f.right).scale(u) + V::splat(f.up).scale(v)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera { eye: V3::new(0.0, 0.0, -10.0), look_at: V3::zero(), up: V3::new(0.0, 1.0, 0.0), fov_y: 90.0 }
    }

    #[test]
    fn centre_pixel_looks_at_the_target_and_corners_span_the_fov() {
        let f = frame(&cam(), 3, 3);
        let c = primary_ray(&f, 1, 1, 0);
        assert_eq!(c.dir, V3::new(0.0, 0.0, 1.0));
        // Top-left pixel centre: u = v = ±2/3 of tan(45°) = 1.
        let tl = primary_ray(&f, 0, 0, 0);
        assert!(tl.dir.x < 0.0 && tl.dir.y > 0.0, "+x is on the right, +y up: {:?}", tl.dir);
        assert!(((tl.dir.x / tl.dir.z) as f64 + 2.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn sample_offsets_stay_inside_the_pixel() {
        assert_eq!(sample_offset(0), (0.5, 0.5));
        for s in 0..10_000 {
            let (x, y) = sample_offset(s);
            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
        }
    }
}
