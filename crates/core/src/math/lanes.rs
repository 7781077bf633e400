//! Values of N lanes: f32 ([`F`]), u32 ([`U`]), a lane mask ([`M`]) and a 3-vector ([`V`]).
//! Every operation is a loop over the lanes of one IEEE operation (or one integer one), which
//! the compiler turns into one vector instruction where the caller's target features allow:
//! each lane rounds exactly as the scalar operation does, so code written with these types
//! computes, lane for lane, what the same formula computes on f32 (`V3<f32>`), provided it
//! performs the same operations in the same order.
//!
//! A formula both tracers use is written once, over these types (its `_lanes` form, next to
//! its one-path form in the stage's file), and the one-path form is its one-lane case: the
//! `From` conversions below carry an f32 or a `V3<f32>` into one lane and back.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::V3;
use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Neg, Not, Shl, Shr, Sub};

#[derive(Clone, Copy, Debug)]
pub struct F<const N: usize>(pub [f32; N]);
#[derive(Clone, Copy, Debug)]
pub struct U<const N: usize>(pub [u32; N]);
/// A lane mask: each lane's word is all ones (true) or zero (false).
#[derive(Clone, Copy, Debug)]
pub struct M<const N: usize>(pub [u32; N]);
#[derive(Clone, Copy, Debug)]
pub struct V<const N: usize> {
    pub x: F<N>,
    pub y: F<N>,
    pub z: F<N>,
}

macro_rules! lanewise {
    ($t:ident, $tr:ident, $f:ident, $op:tt) => {
        impl<const N: usize> $tr for $t<N> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                let mut r = self.0;
                for l in 0..N {
                    r[l] = self.0[l] $op o.0[l];
                }
                $t(r)
            }
        }
    };
}
lanewise!(F, Add, add, +);
lanewise!(F, Sub, sub, -);
lanewise!(F, Mul, mul, *);
lanewise!(F, Div, div, /);
lanewise!(U, BitAnd, bitand, &);
lanewise!(U, BitOr, bitor, |);
lanewise!(U, BitXor, bitxor, ^);
lanewise!(M, BitAnd, bitand, &);
lanewise!(M, BitOr, bitor, |);

impl<const N: usize> Neg for F<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
}

impl<const N: usize> Not for M<N> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = !*x;
        }
        M(r)
    }
}

impl<const N: usize> F<N> {
    #[inline(always)]
    pub fn splat(v: f32) -> Self {
        F([v; N])
    }
    #[inline(always)]
    pub fn map(self, f: impl Fn(f32) -> f32) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = f(*x);
        }
        F(r)
    }
    #[inline(always)]
    fn cmp(self, o: Self, f: impl Fn(f32, f32) -> bool) -> M<N> {
        let mut r = [0u32; N];
        for l in 0..N {
            r[l] = (f(self.0[l], o.0[l]) as u32).wrapping_neg();
        }
        M(r)
    }
    #[inline(always)]
    pub fn lt(self, o: Self) -> M<N> {
        self.cmp(o, |a, b| a < b)
    }
    #[inline(always)]
    pub fn eq(self, o: Self) -> M<N> {
        self.cmp(o, |a, b| a == b)
    }
    #[inline(always)]
    pub fn le(self, o: Self) -> M<N> {
        self.cmp(o, |a, b| a <= b)
    }
    #[inline(always)]
    pub fn gt(self, o: Self) -> M<N> {
        self.cmp(o, |a, b| a > b)
    }
    #[inline(always)]
    pub fn ge(self, o: Self) -> M<N> {
        self.cmp(o, |a, b| a >= b)
    }
    #[inline(always)]
    pub fn sqrt(self) -> Self {
        self.map(f32::sqrt)
    }
    #[inline(always)]
    pub fn abs(self) -> Self {
        self.map(f32::abs)
    }
    /// f32::max lane by lane (the other operand where one is NaN).
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        let mut r = self.0;
        for l in 0..N {
            r[l] = self.0[l].max(o.0[l]);
        }
        F(r)
    }
    /// f32::min lane by lane.
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        let mut r = self.0;
        for l in 0..N {
            r[l] = self.0[l].min(o.0[l]);
        }
        F(r)
    }
    #[inline(always)]
    pub fn to_bits(self) -> U<N> {
        let mut r = [0u32; N];
        for l in 0..N {
            r[l] = self.0[l].to_bits();
        }
        U(r)
    }
    #[inline(always)]
    pub fn from_bits(u: U<N>) -> Self {
        let mut r = [0.0f32; N];
        for l in 0..N {
            r[l] = f32::from_bits(u.0[l]);
        }
        F(r)
    }
    /// [`crate::math::sin_cos_turns`] in every lane (its one-lane case is that function).
    #[inline(always)]
    pub fn sin_cos_turns(self) -> (Self, Self) {
        let s = F::splat;
        let x = s(8.0) * self;
        let octant = x.map(f32::floor);
        let f = x - octant;
        let half = (octant * s(0.5)).map(f32::floor);
        let odd = (octant - s(2.0) * half).eq(s(1.0));
        let g = odd.select(s(1.0) - f, f);
        let t = g * s(std::f32::consts::FRAC_PI_4);
        let t2 = t * t;
        let sin =
            t + t * t2 * (s(-1.0 / 6.0) + t2 * (s(1.0 / 120.0) + t2 * (s(-1.0 / 5040.0) + t2 * s(1.0 / 362_880.0))));
        let cos = s(1.0)
            + t2 * (s(-0.5)
                + t2 * (s(1.0 / 24.0)
                    + t2 * (s(-1.0 / 720.0) + t2 * (s(1.0 / 40_320.0) + t2 * s(-1.0 / 3_628_800.0)))));
        let sin = odd.select(-sin, sin);
        let quarter = half + odd.select(s(1.0), s(0.0));
        let q = quarter - s(4.0) * (quarter * s(0.25)).map(f32::floor);
        let (q0, q1, q2) = (q.eq(s(0.0)), q.eq(s(1.0)), q.eq(s(2.0)));
        let sn = q0.select(sin, q1.select(cos, q2.select(-sin, -cos)));
        let cs = q0.select(cos, q1.select(-sin, q2.select(-cos, sin)));
        (sn, cs)
    }

    /// [`crate::math::atan2`] of (x, y = self) in every lane (its one-lane case is that
    /// function). Comparisons, not min and max, so that a NaN reaches the quotient.
    #[inline(always)]
    pub fn atan2(self, x: Self) -> Self {
        use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
        let s = F::splat;
        let c = crate::math::ATAN_P;
        let (ax, ay) = (x.abs(), self.abs());
        let steep = ax.lt(ay);
        let (lo, hi) = (steep.select(ax, ay), steep.select(ay, ax));
        let a = hi.eq(s(0.0)).select(s(0.0), lo / hi);
        let turned = a.gt(s(crate::math::TAN_PI_8));
        let t = turned.select((a - s(1.0)) / (a + s(1.0)), a);
        let z = t * t;
        let p = t + t * z * (s(c[0]) + z * (s(c[1]) + z * (s(c[2]) + z * s(c[3]))));
        let r = turned.select(s(FRAC_PI_4) + p, p);
        let r = steep.select(s(FRAC_PI_2) - r, r);
        let r = x.sign_negative().select(s(PI) - r, r);
        self.sign_negative().select(-r, r)
    }
    /// [`crate::math::acos`] in every lane (its one-lane case is that function).
    #[inline(always)]
    pub fn acos(self) -> Self {
        let s = F::splat;
        let x = self.map(|v| v.clamp(-1.0, 1.0));
        ((s(1.0) - x) * (s(1.0) + x)).sqrt().atan2(x)
    }
    /// The lanes whose sign bit is set.
    #[inline(always)]
    pub fn sign_negative(self) -> M<N> {
        let mut r = [0u32; N];
        for l in 0..N {
            r[l] = ((self.0[l].to_bits() as i32) >> 31) as u32;
        }
        M(r)
    }

    /// Lanes `k .. k + N` of `v`.
    #[inline(always)]
    pub fn load(v: &[f32], k: usize) -> Self {
        F(v[k..k + N].try_into().expect("N lanes"))
    }
}

impl<const N: usize> U<N> {
    #[inline(always)]
    pub fn splat(v: u32) -> Self {
        U([v; N])
    }
    #[inline(always)]
    pub fn load(v: &[u32], k: usize) -> Self {
        U(v[k..k + N].try_into().expect("N lanes"))
    }
    #[inline(always)]
    pub fn wrapping_mul(self, o: Self) -> Self {
        let mut r = self.0;
        for l in 0..N {
            r[l] = self.0[l].wrapping_mul(o.0[l]);
        }
        U(r)
    }
    #[inline(always)]
    pub fn wrapping_add(self, o: Self) -> Self {
        let mut r = self.0;
        for l in 0..N {
            r[l] = self.0[l].wrapping_add(o.0[l]);
        }
        U(r)
    }
    #[inline(always)]
    pub fn eq(self, o: Self) -> M<N> {
        let mut r = [0u32; N];
        for l in 0..N {
            r[l] = ((self.0[l] == o.0[l]) as u32).wrapping_neg();
        }
        M(r)
    }
    #[inline(always)]
    pub fn le(self, o: Self) -> M<N> {
        let mut r = [0u32; N];
        for l in 0..N {
            r[l] = ((self.0[l] <= o.0[l]) as u32).wrapping_neg();
        }
        M(r)
    }
    /// `u as f32` (rounded to nearest where u > 2²⁴).
    #[inline(always)]
    pub fn to_f32(self) -> F<N> {
        let mut r = [0.0f32; N];
        for l in 0..N {
            r[l] = self.0[l] as f32;
        }
        F(r)
    }
    /// `(u >> 8) as f32`: exact for every u32.
    #[inline(always)]
    pub fn top24_f32(self) -> F<N> {
        let mut r = [0.0f32; N];
        for l in 0..N {
            r[l] = (self.0[l] >> 8) as f32;
        }
        F(r)
    }
}

impl<const N: usize> Shr for U<N> {
    type Output = Self;
    #[inline(always)]
    fn shr(self, o: Self) -> Self {
        let mut r = self.0;
        for l in 0..N {
            r[l] = self.0[l] >> (o.0[l] & 31);
        }
        U(r)
    }
}

impl<const N: usize> Shl for U<N> {
    type Output = Self;
    #[inline(always)]
    fn shl(self, o: Self) -> Self {
        let mut r = self.0;
        for l in 0..N {
            r[l] = self.0[l] << (o.0[l] & 31);
        }
        U(r)
    }
}

impl<const N: usize> M<N> {
    #[inline(always)]
    pub fn from_bools(b: &[bool; N]) -> Self {
        let mut r = [0u32; N];
        for l in 0..N {
            r[l] = (b[l] as u32).wrapping_neg();
        }
        M(r)
    }
    #[inline(always)]
    pub fn lane(&self, l: usize) -> bool {
        self.0[l] != 0
    }
    /// `a` where the mask is set, else `b`.
    #[inline(always)]
    pub fn select(self, a: F<N>, b: F<N>) -> F<N> {
        let mut r = b.0;
        for l in 0..N {
            r[l] = f32::from_bits((a.0[l].to_bits() & self.0[l]) | (b.0[l].to_bits() & !self.0[l]));
        }
        F(r)
    }
    #[inline(always)]
    pub fn select_u(self, a: U<N>, b: U<N>) -> U<N> {
        let mut r = b.0;
        for l in 0..N {
            r[l] = (a.0[l] & self.0[l]) | (b.0[l] & !self.0[l]);
        }
        U(r)
    }
    #[inline(always)]
    pub fn select_v(self, a: V<N>, b: V<N>) -> V<N> {
        V { x: self.select(a.x, b.x), y: self.select(a.y, b.y), z: self.select(a.z, b.z) }
    }
}

impl<const N: usize> V<N> {
    #[inline(always)]
    pub fn new(x: F<N>, y: F<N>, z: F<N>) -> Self {
        Self { x, y, z }
    }
    #[inline(always)]
    pub fn splat(v: [f32; 3]) -> Self {
        Self::new(F::splat(v[0]), F::splat(v[1]), F::splat(v[2]))
    }
    #[inline(always)]
    pub fn load(v: &[Vec<f32>; 3], k: usize) -> Self {
        Self::new(F::load(&v[0], k), F::load(&v[1], k), F::load(&v[2], k))
    }
    #[inline(always)]
    pub fn from_rows(r: &[[f32; N]; 3]) -> Self {
        Self::new(F(r[0]), F(r[1]), F(r[2]))
    }
    /// Vector `j` of rows holding vectors side by side (x, y, z of vector 0, then of 1, ...).
    #[inline(always)]
    pub fn nth(r: &[[f32; N]], j: usize) -> Self {
        Self::new(F(r[3 * j]), F(r[3 * j + 1]), F(r[3 * j + 2]))
    }
    #[inline(always)]
    pub fn rows(self) -> [[f32; N]; 3] {
        [self.x.0, self.y.0, self.z.0]
    }
    /// `V3::dot`: (x·x' + y·y') + z·z'.
    #[inline(always)]
    pub fn dot(self, o: Self) -> F<N> {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline(always)]
    pub fn mul_elem(self, o: Self) -> Self {
        Self::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    #[inline(always)]
    pub fn scale(self, s: F<N>) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
    /// `V3::normalize`: the vector times 1/|v|.
    #[inline(always)]
    pub fn normalize(self) -> Self {
        self.scale(F::splat(1.0) / self.dot(self).sqrt())
    }
    /// `V3::max_component`: max(max(x, y), z).
    #[inline(always)]
    pub fn max_component(self) -> F<N> {
        self.x.max(self.y).max(self.z)
    }
}

impl<const N: usize> Add for V<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl<const N: usize> Sub for V<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl<const N: usize> Div<F<N>> for V<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, s: F<N>) -> Self {
        Self::new(self.x / s, self.y / s, self.z / s)
    }
}

impl<const N: usize> Neg for V<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}

/// `f32::clamp(0, 1)` lane by lane (NaN stays NaN).
#[inline(always)]
pub fn clamp01<const N: usize>(x: F<N>) -> F<N> {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let x = x.lt(zero).select(zero, x);
    x.gt(one).select(one, x)
}

/// `v − ⌊v⌋` lane by lane.
#[inline(always)]
pub fn fract<const N: usize>(v: F<N>) -> F<N> {
    v - v.map(f32::floor)
}

impl From<f32> for F<1> {
    #[inline(always)]
    fn from(x: f32) -> Self {
        F([x])
    }
}

impl From<F<1>> for f32 {
    #[inline(always)]
    fn from(x: F<1>) -> f32 {
        x.0[0]
    }
}

impl From<u32> for U<1> {
    #[inline(always)]
    fn from(x: u32) -> Self {
        U([x])
    }
}

impl From<U<1>> for u32 {
    #[inline(always)]
    fn from(x: U<1>) -> u32 {
        x.0[0]
    }
}

impl From<bool> for M<1> {
    #[inline(always)]
    fn from(b: bool) -> Self {
        M([(b as u32).wrapping_neg()])
    }
}

impl From<V3<f32>> for V<1> {
    #[inline(always)]
    fn from(v: V3<f32>) -> Self {
        V::new(F([v.x]), F([v.y]), F([v.z]))
    }
}

impl From<V<1>> for V3<f32> {
    #[inline(always)]
    fn from(v: V<1>) -> V3<f32> {
        V3::new(v.x.0[0], v.y.0[0], v.z.0[0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lanes' sine and cosine are the scalar ones bit for bit, over a whole turn and at
    /// the octant edges.
    #[test]
    fn lane_sin_cos_equals_the_scalar_one() {
        let mut u: Vec<f32> = (0..1 << 16).map(|k| k as f32 / 65536.0).collect();
        for o in 0..8 {
            let edge = o as f32 / 8.0;
            u.extend([
                edge,
                f32::from_bits(edge.to_bits().wrapping_sub(1)).max(0.0),
                f32::from_bits(edge.to_bits() + 1),
            ]);
        }
        u.push(f32::from_bits(1.0f32.to_bits() - 1));
        for chunk in u.chunks_exact(8) {
            let (s, c) = F::<8>(chunk.try_into().unwrap()).sin_cos_turns();
            for (l, &x) in chunk.iter().enumerate() {
                let (ws, wc) = crate::math::sin_cos_turns(x);
                assert_eq!((s.0[l].to_bits(), c.0[l].to_bits()), (ws.to_bits(), wc.to_bits()), "u = {x}");
            }
        }
    }

    /// The lanes' arc tangent and arc cosine are the scalar ones bit for bit, on a grid, at
    /// signed zeros, at the octant edges and at NaN.
    #[test]
    fn lane_atan2_and_acos_equal_the_scalar_ones() {
        let edge = crate::math::TAN_PI_8;
        let mut v: Vec<f32> = (0..=256).map(|k| k as f32 / 64.0 - 2.0).collect();
        v.extend([0.0, -0.0, edge, -edge, f32::from_bits(edge.to_bits() + 1), f32::NAN, f32::INFINITY]);
        let pairs: Vec<(f32, f32)> = v.iter().flat_map(|&y| v.iter().map(move |&x| (y, x))).collect();
        for chunk in pairs.chunks(16) {
            let mut y = F::<16>::splat(0.0);
            let mut x = F::<16>::splat(1.0);
            for (l, &(a, b)) in chunk.iter().enumerate() {
                (y.0[l], x.0[l]) = (a, b);
            }
            let (t, c) = (y.atan2(x), x.acos());
            for (l, &(a, b)) in chunk.iter().enumerate() {
                assert_eq!(t.0[l].to_bits(), crate::math::atan2(a, b).to_bits(), "atan2({a}, {b})");
                assert_eq!(c.0[l].to_bits(), crate::math::acos(b).to_bits(), "acos({b})");
            }
        }
    }
}
