//! SplitMix64 (Steele, Lea & Flood 2014): the small deterministic generator behind test rays,
//! the stiff cases and benchmarks. Not for sampling images.

use crate::math::V3;

#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Uniform in the cube [−h, h)³.
    pub fn cube(&mut self, h: f64) -> V3<f64> {
        V3::new(self.range(-h, h), self.range(-h, h), self.range(-h, h))
    }
    /// A uniformly distributed unit vector (rejection from the cube).
    pub fn direction(&mut self) -> V3<f64> {
        loop {
            let v = self.cube(1.0);
            let l = v.length_squared();
            if l > 1e-6 && l <= 1.0 {
                return v.normalize();
            }
        }
    }
    /// A unit vector perpendicular to `d`.
    pub fn perpendicular(&mut self, d: V3<f64>) -> V3<f64> {
        loop {
            let p = d.cross(self.direction());
            if p.length() > 0.1 {
                return p.normalize();
            }
        }
    }
}
