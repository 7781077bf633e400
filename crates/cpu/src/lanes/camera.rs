//! A batch's camera rays and random streams, lane by lane: what [`crate::path::camera_ray`]
//! and [`strahl_core::render::sampler::Sampler::new`] compute for each (pixel, sample), by their
//! operations.

use super::paths::Paths;
use strahl_core::layout::FrameParams;
use strahl_core::math::lanes::{F, U, V};
use strahl_core::render::sampler::{PCG_INC, PCG_MULT, pcg_hash};

/// [`pcg_hash`] in every lane.
#[inline(always)]
fn hash<const N: usize>(v: U<N>) -> U<N> {
    let state = v.wrapping_mul(U::splat(PCG_MULT)).wrapping_add(U::splat(PCG_INC));
    let shift = (state >> U::splat(28)).wrapping_add(U::splat(4));
    let word = ((state >> shift) ^ state).wrapping_mul(U::splat(277_803_737));
    (word >> U::splat(22)) ^ word
}

/// `v − ⌊v⌋`.
#[inline(always)]
fn fract<const N: usize>(v: F<N>) -> F<N> {
    v - v.map(f32::floor)
}

/// Starts paths `k .. k + N` of `p` at pixels (`x[l]`, `y`) and samples `s[l]`: the camera ray
/// through the sample's sub-pixel position, a fresh path state and the sample's random
/// stream; slot `slot0 + l`. Lanes past `p.len` are written too (and stay unused).
#[inline(always)]
pub(super) fn start<const N: usize>(f: &FrameParams, p: &mut Paths, k: usize, x: U<N>, y: u32, s: U<N>, slot0: u32) {
    let pixel = U::splat(y.wrapping_mul(f.width)).wrapping_add(x);
    // Sampler::new(pixel, s, seed).
    let rng = hash(pixel ^ hash(s.wrapping_add(U::splat(pcg_hash(f.seed)))));
    // sampler::pixel_jitter(pixel, s, seed).
    let h = hash(pixel ^ U::splat(pcg_hash(f.seed ^ 0x5bd1_e995)));
    let scale = F::splat(1.0 / 16_777_216.0);
    let rx = h.top24_f32() * scale;
    let ry = hash(h).top24_f32() * scale;
    // camera::sample_offset(s).
    let sf = s.to_f32();
    let ox = fract(F::splat(0.5) + sf * F::splat(0.754_877_7));
    let oy = fract(F::splat(0.5) + sf * F::splat(0.569_840_3));
    let (ox, oy) = (fract(ox + rx), fract(oy + ry));
    // camera::ray_through(f, x, y, ox, oy).
    let one = F::splat(1.0);
    let two = F::splat(2.0);
    let u = two * (x.to_f32() + ox) / F::splat(f.width as f32) - one;
    let v = one - two * (F::splat(y as f32) + oy) / F::splat(f.height as f32);
    let dir = (V::splat(f.forward) + V::splat(f.right).scale(u) + V::splat(f.up).scale(v)).normalize();
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
