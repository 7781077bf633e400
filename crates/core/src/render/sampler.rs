//! Random numbers of the path tracer (`sampler.wgsl` is the twin): a counter-based generator
//! whose stream depends only on (pixel, sample index, seed), so the CPU and the GPU draw the
//! same numbers for the same pixel and sample, whatever order the work runs in.
//!
//! The stream is PCG-RXS-M-XS 32 (O'Neill 2014) started from a hash of the counters, as in
//! Jarzynski & Olano, "Hash Functions for GPU Rendering" (JCGT 2020), whose `pcg_hash` is the
//! best-quality 32-bit hash of their survey at this cost. Everything is u32 arithmetic, exact
//! on both backends.

use crate::math::lanes::{F, M, U, fract};

pub const PCG_MULT: u32 = 747_796_405;
pub const PCG_INC: u32 = 2_891_336_453;

/// One PCG step of `v` followed by its RXS-M-XS output permutation.
#[inline]
pub fn pcg_hash(v: u32) -> u32 {
    pcg_hash_lanes::<1>(v.into()).into()
}

/// [`pcg_hash`] in every lane.
#[inline(always)]
pub fn pcg_hash_lanes<const N: usize>(v: U<N>) -> U<N> {
    permute(v.wrapping_mul(U::splat(PCG_MULT)).wrapping_add(U::splat(PCG_INC)))
}

/// PCG's RXS-M-XS output permutation of the state.
#[inline(always)]
fn permute<const N: usize>(state: U<N>) -> U<N> {
    let shift = (state >> U::splat(28)).wrapping_add(U::splat(4));
    let word = ((state >> shift) ^ state).wrapping_mul(U::splat(277_803_737));
    (word >> U::splat(22)) ^ word
}

/// The state [`Sampler::new`] starts from, in every lane (one seed).
#[inline(always)]
pub fn stream_lanes<const N: usize>(pixel: U<N>, sample: U<N>, seed: u32) -> U<N> {
    pcg_hash_lanes(pixel ^ pcg_hash_lanes(sample.wrapping_add(U::splat(pcg_hash(seed)))))
}

/// [`Sampler::next_f32`] in every lane: each stream is advanced where `on`, and every lane's
/// number is returned.
#[inline(always)]
pub fn next_f32_lanes<const N: usize>(state: &mut U<N>, on: M<N>) -> F<N> {
    let old = *state;
    *state = on.select_u(old.wrapping_mul(U::splat(PCG_MULT)).wrapping_add(U::splat(PCG_INC)), old);
    permute(old).top24_f32() * F::splat(1.0 / 16_777_216.0)
}

/// The random stream of one pixel sample.
#[derive(Clone, Debug)]
pub struct Sampler {
    state: u32,
}

impl Sampler {
    /// The stream of sample `sample` of pixel `pixel` (row-major index) under `seed`.
    #[inline]
    pub fn new(pixel: u32, sample: u32, seed: u32) -> Self {
        Self { state: stream_lanes::<1>(pixel.into(), sample.into(), seed).into() }
    }

    /// The stream at the point `state` was read from (for paths kept lane by lane).
    #[inline(always)]
    pub fn from_state(state: u32) -> Self {
        Self { state }
    }

    /// Where the stream is: [`Sampler::from_state`] of it goes on from here.
    #[inline(always)]
    pub fn state(&self) -> u32 {
        self.state
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULT).wrapping_add(PCG_INC);
        permute::<1>(old.into()).into()
    }

    /// Uniform in [0, 1): the top 24 bits, so the conversion is exact on both backends.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        let mut state = U::from(self.state);
        let u = next_f32_lanes::<1>(&mut state, true.into());
        self.state = state.into();
        u.into()
    }
}

/// Sub-pixel position of sample `s` of pixel `pixel`: the R2 low-discrepancy sequence
/// (Roberts 2018) shifted by a per-pixel random offset (Cranley–Patterson rotation), so each
/// pixel's samples stay evenly spread as they accumulate while neighbouring pixels do not
/// share one pattern.
#[inline]
pub fn pixel_jitter(pixel: u32, s: u32, seed: u32) -> (f32, f32) {
    let (ox, oy) = pixel_jitter_lanes::<1>(pixel.into(), s.into(), seed);
    (ox.into(), oy.into())
}

/// [`pixel_jitter`] in every lane, for one seed.
#[inline(always)]
pub fn pixel_jitter_lanes<const N: usize>(pixel: U<N>, s: U<N>, seed: u32) -> (F<N>, F<N>) {
    let h = pcg_hash_lanes(pixel ^ U::splat(pcg_hash(seed ^ 0x5bd1_e995)));
    let scale = F::splat(1.0 / 16_777_216.0);
    let rx = h.top24_f32() * scale;
    let ry = pcg_hash_lanes(h).top24_f32() * scale;
    let (ox, oy) = super::camera::sample_offset_lanes(s);
    (fract(ox + rx), fract(oy + ry))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_uniform_and_independent_of_neighbours() {
        // Mean and variance of 2^16 draws over many streams: U[0,1) has 1/2 and 1/12.
        let (mut sum, mut sum2, mut n) = (0.0f64, 0.0f64, 0.0f64);
        let mut corr = 0.0f64;
        for pixel in 0..256u32 {
            let mut a = Sampler::new(pixel, 0, 7);
            let mut b = Sampler::new(pixel + 1, 0, 7);
            for _ in 0..256 {
                let (x, y) = (a.next_f32() as f64, b.next_f32() as f64);
                assert!((0.0..1.0).contains(&x));
                sum += x;
                sum2 += x * x;
                corr += (x - 0.5) * (y - 0.5);
                n += 1.0;
            }
        }
        let mean = sum / n;
        let var = sum2 / n - mean * mean;
        // Standard errors: mean 1/sqrt(12 n) ≈ 0.0011, so 5 sigma is 0.006.
        assert!((mean - 0.5).abs() < 0.006, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.003, "variance {var}");
        // Covariance of neighbouring pixels' streams: 0 ± 1/(12 sqrt n) ≈ 0.0003.
        assert!((corr / n).abs() < 0.0017, "covariance {}", corr / n);
    }

    #[test]
    fn different_samples_and_seeds_give_different_streams() {
        let first = |p, s, seed| Sampler::new(p, s, seed).next_u32();
        assert_ne!(first(0, 0, 0), first(0, 1, 0));
        assert_ne!(first(0, 0, 0), first(1, 0, 0));
        assert_ne!(first(0, 0, 0), first(0, 0, 1));
        // Same counters, same stream.
        assert_eq!(first(5, 9, 3), first(5, 9, 3));
    }

    #[test]
    fn jitter_stays_in_the_pixel_and_covers_it() {
        let mut quadrants = [0u32; 4];
        for s in 0..64 {
            let (x, y) = pixel_jitter(17, s, 0);
            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
            quadrants[(x >= 0.5) as usize + 2 * (y >= 0.5) as usize] += 1;
        }
        // Low discrepancy: 64 points put 16 ± a few in each quadrant (random points: ± 7).
        assert!(quadrants.iter().all(|&q| (13..=19).contains(&q)), "{quadrants:?}");
    }
}
