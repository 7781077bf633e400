//! Precision-generic arithmetic.
//!
//! Every intersection routine in [`crate::geometry`] is written once over [`Real`] and
//! instantiated twice: `f32`, the mirror of what the WGSL shaders compute, and `f64`, the
//! oracle the f32 results are judged against.

pub mod lanes;

use std::fmt::{Debug, Display};
use std::ops::{Add, AddAssign, Div, Index, Mul, MulAssign, Neg, Sub, SubAssign};

/// A floating-point scalar: `f32` (GPU mirror) or `f64` (oracle).
pub trait Real:
    Copy
    + Debug
    + Display
    + Default
    + PartialOrd
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    const ZERO: Self;
    const ONE: Self;
    const INFINITY: Self;
    /// Unit roundoff (half the machine epsilon): the relative error of one rounded operation.
    const UNIT_ROUNDOFF: Self;
    fn from_f64(v: f64) -> Self;
    fn to_f64(self) -> f64;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn is_finite(self) -> bool;
    fn min(self, other: Self) -> Self;
    fn max(self, other: Self) -> Self;
    fn signum_nonzero(self) -> Self {
        if self < Self::ZERO { -Self::ONE } else { Self::ONE }
    }
    /// a·b − c·d with the sign of the exact value, whatever the rounding (so that
    /// `diff_of_products(a, b, c, d) == -diff_of_products(c, d, a, b)` in sign, and is zero
    /// exactly when a·b = c·d): the edge functions of the watertight triangle test need this.
    /// Kahan's algorithm with fused multiply-adds (Jeannerod, Louvet & Muller 2013: relative
    /// error ≤ 2u, so the sign is exact), in f32 the very operations of the shaders'
    /// `diff_of_products` (shaders/modules/triangle.wgsl), so that the CPU mirror's edge
    /// functions are the GPU's bit for bit.
    fn diff_of_products(a: Self, b: Self, c: Self, d: Self) -> Self;
    /// pbrt's γ(n) = n·u / (1 − n·u), the bound on the relative error of n chained operations.
    fn gamma_bound(n: u32) -> Self {
        let nu = Self::from_f64(n as f64) * Self::UNIT_ROUNDOFF;
        nu / (Self::ONE - nu)
    }
}

macro_rules! impl_real {
    ($t:ty, $dop:expr) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const INFINITY: Self = <$t>::INFINITY;
            const UNIT_ROUNDOFF: Self = <$t>::EPSILON * 0.5;
            #[inline(always)]
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline(always)]
            fn min(self, other: Self) -> Self {
                <$t>::min(self, other)
            }
            #[inline(always)]
            fn max(self, other: Self) -> Self {
                <$t>::max(self, other)
            }
            #[inline(always)]
            fn diff_of_products(a: Self, b: Self, c: Self, d: Self) -> Self {
                ($dop)(a, b, c, d)
            }
        }
    };
}
impl_real!(f32, |a: f32, b: f32, c: f32, d: f32| {
    let cd = c * d;
    let err = (-c).mul_add(d, cd);
    a.mul_add(b, -cd) + err
});
impl_real!(f64, |a: f64, b: f64, c: f64, d: f64| {
    let cd = c * d;
    let err = (-c).mul_add(d, cd);
    a.mul_add(b, -cd) + err
});

/// The sine and cosine of 2πu for u in [0, 1), the angle a sampler draws as a fraction of a
/// turn. The turn is cut into octants exactly (8u, its floor and the remainder are exact in
/// f32, and so is 1 − remainder on odd octants), so the polynomials only see θ ∈ [0, π/4]:
/// Taylor series to θ⁹ and θ¹⁰ (truncation below 2·10⁻⁹; Muller, "Elementary Functions",
/// ch. 11, for the octant reduction), in multiplies and adds only, so that the lane path
/// tracer (`math/lanes.rs`, `F::sin_cos_turns`) computes the same bits in every lane.
/// Absolute error at most 3·2⁻²⁴ (tested against f64 in `sin_cos_turns_is_accurate`); the
/// GPU computes `sin(2πu)` and `cos(2πu)` with its own functions.
#[inline]
pub fn sin_cos_turns(u: f32) -> (f32, f32) {
    let (s, c) = lanes::F::<1>::from(u).sin_cos_turns();
    (s.into(), c.into())
}

/// tan(π/8): arguments above it are turned by π/4 before the polynomial.
pub(crate) const TAN_PI_8: f32 = 0.414_213_57;

/// The angle of (x, y) in (−π, π], as `f32::atan2` (atan2(±0, −0) = ±π, NaN in, NaN out), in
/// multiplies, adds and divides only, so that the lane path tracer (`F::atan2`) computes the
/// same bits in every lane. a = min(|x|, |y|) / max(|x|, |y|) ∈ [0, 1]; above tan(π/8) it is
/// replaced by (a − 1)/(a + 1) and π/4 added (Muller, "Elementary Functions", ch. 11), so the
/// polynomial only sees |t| ≤ tan(π/8): atan t ≈ t + t·t²·P(t²), P of degree 3 fitted for
/// least maximum relative error (Lawson's iteration; 2.1·10⁻⁸ in exact arithmetic, under
/// one f32 ulp evaluated in f32). The octant is then restored: π/2 − r, π − r, the sign of y.
/// Absolute error at most 3·2⁻²³ (tested against f64 in `atan2_and_acos_are_accurate`); the
/// GPU uses its own `atan2`.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    lanes::F::<1>::from(y).atan2(x.into()).into()
}

/// The coefficients of [`atan2`]'s polynomial P.
pub(crate) const ATAN_P: [f32; 4] = [-0.333_329_5, 0.199_777_1, -0.138_776_8, 0.080_537_22];

/// arccos of x clamped to [−1, 1], as atan2(√((1 − x)(1 + x)), x): [`atan2`]'s error, and
/// accurate near ±1 where arccos is steep (1 − x is exact there). Absolute error at most
/// 3·2⁻²³ (`atan2_and_acos_are_accurate`).
#[inline]
pub fn acos(x: f32) -> f32 {
    lanes::F::<1>::from(x).acos().into()
}

/// A 3-vector of [`Real`]s.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V3<R> {
    pub x: R,
    pub y: R,
    pub z: R,
}

impl<R: Real> V3<R> {
    #[inline(always)]
    pub const fn new(x: R, y: R, z: R) -> Self {
        Self { x, y, z }
    }
    #[inline(always)]
    pub fn splat(v: R) -> Self {
        Self::new(v, v, v)
    }
    pub fn zero() -> Self {
        Self::splat(R::ZERO)
    }
    pub fn from_f64(v: [f64; 3]) -> Self {
        Self::new(R::from_f64(v[0]), R::from_f64(v[1]), R::from_f64(v[2]))
    }
    pub fn from_array(v: [R; 3]) -> Self {
        Self::new(v[0], v[1], v[2])
    }
    pub fn to_array(self) -> [R; 3] {
        [self.x, self.y, self.z]
    }
    pub fn to_f64(self) -> V3<f64> {
        V3::new(self.x.to_f64(), self.y.to_f64(), self.z.to_f64())
    }
    /// Converts to another precision (rounding to nearest).
    pub fn cast<S: Real>(self) -> V3<S> {
        V3::new(S::from_f64(self.x.to_f64()), S::from_f64(self.y.to_f64()), S::from_f64(self.z.to_f64()))
    }
    #[inline(always)]
    pub fn dot(self, o: Self) -> R {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        Self::new(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)
    }
    #[inline(always)]
    pub fn length_squared(self) -> R {
        self.dot(self)
    }
    #[inline(always)]
    pub fn length(self) -> R {
        self.dot(self).sqrt()
    }
    #[inline(always)]
    pub fn normalize(self) -> Self {
        self * (R::ONE / self.length())
    }
    #[inline(always)]
    pub fn mul_elem(self, o: Self) -> Self {
        Self::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    pub fn min_elem(self, o: Self) -> Self {
        Self::new(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }
    pub fn max_elem(self, o: Self) -> Self {
        Self::new(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }
    pub fn abs(self) -> Self {
        Self::new(self.x.abs(), self.y.abs(), self.z.abs())
    }
    pub fn max_component(self) -> R {
        self.x.max(self.y).max(self.z)
    }
    /// Index (0, 1 or 2) of the component of largest magnitude.
    pub fn max_abs_axis(self) -> usize {
        let a = self.abs();
        if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        }
    }
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
}

impl<R> Index<usize> for V3<R> {
    type Output = R;
    #[inline(always)]
    fn index(&self, i: usize) -> &R {
        match i {
            0 => &self.x,
            1 => &self.y,
            _ => &self.z,
        }
    }
}

impl<R: Real> Add for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<R: Real> AddAssign for V3<R> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<R: Real> Sub for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<R: Real> Neg for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}
impl<R: Real> Mul<R> for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: R) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}
impl<R: Real> Div<R> for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn div(self, s: R) -> Self {
        Self::new(self.x / s, self.y / s, self.z / s)
    }
}

/// A ray p = p0 + μd (the lecture's notation). `d` is unit length wherever strahl builds a
/// ray, so μ (called `t` in code) is the distance from p0.
#[derive(Clone, Copy, Debug)]
pub struct Ray<R> {
    pub origin: V3<R>,
    pub dir: V3<R>,
}

impl<R: Real> Ray<R> {
    pub fn new(origin: V3<R>, dir: V3<R>) -> Self {
        Self { origin, dir }
    }
    #[inline(always)]
    pub fn at(&self, t: R) -> V3<R> {
        self.origin + self.dir * t
    }
    pub fn cast<S: Real>(&self) -> Ray<S> {
        Ray::new(self.origin.cast(), self.dir.cast())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cross_follows_the_right_hand_rule() {
        let x = V3::<f64>::new(1.0, 0.0, 0.0);
        let y = V3::new(0.0, 1.0, 0.0);
        assert_eq!(x.cross(y), V3::new(0.0, 0.0, 1.0));
        assert_eq!(y.cross(x), V3::new(0.0, 0.0, -1.0));
    }

    #[test]
    fn difference_of_products_has_the_exact_sign() {
        // a·b and c·d differ in their last bits only: the naive form rounds both to the same
        // float and returns 0; the exact difference is 2⁻⁴⁸ (f32 inputs).
        let (a, b) = (1.0f32 + f32::EPSILON, 1.0f32 - f32::EPSILON);
        let (c, d) = (1.0f32, 1.0f32);
        assert_eq!(a * b - c * d, 0.0);
        let dop = f32::diff_of_products(a, b, c, d);
        assert_eq!(dop, -f32::EPSILON * f32::EPSILON);
        assert_eq!(f32::diff_of_products(c, d, a, b), -dop);
        let (a, b) = (1.0f64 + f64::EPSILON, 1.0f64 - f64::EPSILON);
        assert_eq!(a * b - 1.0, 0.0);
        assert_eq!(f64::diff_of_products(a, b, 1.0, 1.0), -f64::EPSILON * f64::EPSILON);
    }

    #[test]
    fn sin_cos_turns_is_accurate() {
        let mut worst = 0.0f64;
        for k in 0..(1 << 20) {
            // Every 2⁻²⁰ of a turn, and the sampler's finest steps near the octant edges.
            for u in [k as f32 / (1 << 20) as f32, (k as f32 + 0.999_94) / (1 << 20) as f32] {
                if u >= 1.0 {
                    continue;
                }
                let (s, c) = sin_cos_turns(u);
                let a = 2.0 * std::f64::consts::PI * u as f64;
                worst = worst.max((s as f64 - a.sin()).abs()).max((c as f64 - a.cos()).abs());
            }
        }
        assert!(worst <= 3.0 / 16_777_216.0, "worst absolute error {worst:e}");
        assert_eq!(sin_cos_turns(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(0.25), (1.0, 0.0));
        assert_eq!(sin_cos_turns(0.5), (0.0, -1.0));
    }

    #[test]
    fn atan2_and_acos_are_accurate() {
        let mut worst = (0.0f64, 0.0f64);
        let n = 1 << 12;
        for i in 0..=n {
            for j in 0..=n {
                // A grid over [−2, 2]², and the unit circle's finest angles near the axes.
                let (y, x) = (4.0 * i as f32 / n as f32 - 2.0, 4.0 * j as f32 / n as f32 - 2.0);
                let a = (i as f64 + j as f64 / n as f64) / n as f64 * std::f64::consts::TAU;
                for (y, x) in [(y, x), (a.sin() as f32, a.cos() as f32)] {
                    let want = (y as f64).atan2(x as f64);
                    worst.0 = worst.0.max((atan2(y, x) as f64 - want).abs());
                }
            }
            let x = 2.0 * i as f32 / n as f32 - 1.0;
            for x in [x, f32::from_bits(x.to_bits() ^ 1)] {
                worst.1 = worst.1.max((acos(x) as f64 - (x as f64).clamp(-1.0, 1.0).acos()).abs());
            }
        }
        assert!(worst.0 <= 3.0 / 8_388_608.0 && worst.1 <= 3.0 / 8_388_608.0, "worst absolute errors {worst:?}");
        // The edges f32::atan2 defines.
        for (y, x) in [(0.0f32, 0.0f32), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, -1.0)] {
            assert_eq!(atan2(y, x).to_bits(), y.atan2(x).to_bits(), "atan2({y}, {x})");
        }
        assert_eq!((acos(1.0), acos(-1.0), acos(2.0)), (0.0, std::f32::consts::PI, 0.0));
        assert!(atan2(f32::NAN, 1.0).is_nan() && atan2(1.0, f32::NAN).is_nan() && acos(f32::NAN).is_nan());
    }

    #[test]
    fn gamma_bounds_grow_with_operation_count() {
        assert!(f32::gamma_bound(3) > f32::gamma_bound(1));
        assert!((f64::gamma_bound(1) - f64::EPSILON * 0.5).abs() < 1e-30);
    }
}
