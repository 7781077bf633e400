//! A batch's camera rays and random streams, lane by lane: what [`crate::path::camera_ray`]
//! and [`strahl_core::render::sampler::Sampler::new`] compute for each (pixel, sample), by the
//! lane forms of the same routines.

use super::paths::Paths;
use strahl_core::layout::FrameParams;
use strahl_core::math::lanes::{F, U, V};
use strahl_core::render::camera::ray_through_lanes;
use strahl_core::render::sampler::{pixel_jitter_lanes, stream_lanes};

/// Starts paths `k .. k + N` of `p` at pixels (`x[l]`, `y`) and samples `s[l]`: the camera ray
/// through the sample's sub-pixel position, a fresh path state and the sample's random
/// stream; slot `slot0 + l`. Lanes past `p.len` are written too (and stay unused).
#[inline(always)]
pub(super) fn start<const N: usize>(f: &FrameParams, p: &mut Paths, k: usize, x: U<N>, y: u32, s: U<N>, slot0: u32) {
    let pixel = U::splat(y.wrapping_mul(f.width)).wrapping_add(x);
    let rng = stream_lanes(pixel, s, f.seed);
    let (ox, oy) = pixel_jitter_lanes(pixel, s, f.seed);
    let dir = ray_through_lanes(f, x, y, ox, oy);
    let one = F::splat(1.0);
    let eye = V::<N>::splat(f.eye);
    let store = |dst: &mut Vec<f32>, v: F<N>| dst[k..k + N].copy_from_slice(&v.0);
    for (a, (e, d)) in [(eye.x, dir.x), (eye.y, dir.y), (eye.z, dir.z)].into_iter().enumerate() {
        store(&mut p.o[a], e);
        store(&mut p.d[a], d);
        store(&mut p.beta[a], one);
        store(&mut p.sum[a], F::splat(0.0));
    }
    store(&mut p.pdf, F::splat(0.0));
    p.seg[k..k + N].fill(1);
    p.specular[k..k + N].fill(1);
    p.rng[k..k + N].copy_from_slice(&rng.0);
    for (l, slot) in p.slot[k..k + N].iter_mut().enumerate() {
        *slot = slot0 + l as u32;
    }
}
