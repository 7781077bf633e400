//! Four f32 lanes for the build's boxes and bin positions.

/// Four f32 lanes: an SSE register on x86-64, an array elsewhere. `min` and `max` are those
/// of SSE: `a.min(b)` is `if a < b { a } else { b }`.
///
/// SAFETY of the `unsafe` blocks without a comment of their own: they call SSE and SSE2
/// intrinsics, which every x86-64 processor has.
#[cfg(target_arch = "x86_64")]
mod imp {
    use std::arch::x86_64::*;

    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct F4(__m128);

    impl F4 {
        #[inline(always)]
        pub fn new(a: [f32; 4]) -> F4 {
            // SAFETY: reads the four floats of `a`.
            F4(unsafe { _mm_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        pub fn splat(v: f32) -> F4 {
            F4(unsafe { _mm_set1_ps(v) })
        }
        #[inline(always)]
        pub fn to_array(self) -> [f32; 4] {
            let mut a = [0.0; 4];
            // SAFETY: writes the four floats of `a`.
            unsafe { _mm_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        /// The first three lanes, the fourth set to 0.
        #[inline(always)]
        pub fn xyz(self) -> F4 {
            F4(unsafe { _mm_and_ps(self.0, _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1))) })
        }
        #[inline(always)]
        pub fn min(self, o: F4) -> F4 {
            F4(unsafe { _mm_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn max(self, o: F4) -> F4 {
            F4(unsafe { _mm_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn add(self, o: F4) -> F4 {
            F4(unsafe { _mm_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn sub(self, o: F4) -> F4 {
            F4(unsafe { _mm_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn mul(self, o: F4) -> F4 {
            F4(unsafe { _mm_mul_ps(self.0, o.0) })
        }
        /// For box extents `e` (lanes x, y, z): `e.x·e.y + e.y·e.z + e.z·e.x`, or 0 if `e.x`
        /// is negative (an empty box).
        #[inline(always)]
        pub fn half_area(self) -> f32 {
            unsafe {
                let e = self.0;
                let p = _mm_mul_ps(e, _mm_shuffle_ps::<0b11_00_10_01>(e, e));
                let s = _mm_add_ss(p, _mm_shuffle_ps::<0b01_01_01_01>(p, p));
                let s = _mm_add_ss(s, _mm_movehl_ps(p, p));
                if _mm_cvtss_f32(e) < 0.0 { 0.0 } else { _mm_cvtss_f32(s) }
            }
        }
        /// Each lane with its four lowest bits replaced by `bits` (< 16).
        #[inline(always)]
        pub fn with_low_bits(self, bits: u32) -> F4 {
            F4(unsafe {
                let kept = _mm_and_ps(self.0, _mm_castsi128_ps(_mm_set1_epi32(!15)));
                _mm_or_ps(kept, _mm_castsi128_ps(_mm_set1_epi32(bits as i32)))
            })
        }
        /// Each lane truncated to an integer; the lanes must lie in [0, 2³¹).
        #[inline(always)]
        pub fn to_u32(self) -> [u32; 4] {
            let mut a = [0u32; 4];
            // SAFETY: writes the four integers of `a`.
            unsafe { _mm_storeu_si128(a.as_mut_ptr().cast(), _mm_cvttps_epi32(self.0)) };
            a
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
mod imp {
    #[derive(Clone, Copy, Debug)]
    pub struct F4([f32; 4]);

    impl F4 {
        #[inline(always)]
        pub fn new(a: [f32; 4]) -> F4 {
            F4(a)
        }
        #[inline(always)]
        pub fn splat(v: f32) -> F4 {
            F4([v; 4])
        }
        #[inline(always)]
        pub fn to_array(self) -> [f32; 4] {
            self.0
        }
        #[inline(always)]
        pub fn xyz(self) -> F4 {
            F4([self.0[0], self.0[1], self.0[2], 0.0])
        }
        #[inline(always)]
        pub fn min(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| if self.0[k] < o.0[k] { self.0[k] } else { o.0[k] }))
        }
        #[inline(always)]
        pub fn max(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| if self.0[k] > o.0[k] { self.0[k] } else { o.0[k] }))
        }
        #[inline(always)]
        pub fn add(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| self.0[k] + o.0[k]))
        }
        #[inline(always)]
        pub fn sub(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| self.0[k] - o.0[k]))
        }
        #[inline(always)]
        pub fn mul(self, o: F4) -> F4 {
            F4(std::array::from_fn(|k| self.0[k] * o.0[k]))
        }
        #[inline(always)]
        pub fn half_area(self) -> f32 {
            let e = self.0;
            if e[0] < 0.0 { 0.0 } else { e[0] * e[1] + e[1] * e[2] + e[2] * e[0] }
        }
        #[inline(always)]
        pub fn with_low_bits(self, bits: u32) -> F4 {
            F4(self.0.map(|v| f32::from_bits(v.to_bits() & !15 | bits)))
        }
        #[inline(always)]
        pub fn to_u32(self) -> [u32; 4] {
            self.0.map(|v| v as u32)
        }
    }
}

pub(super) use imp::F4;
