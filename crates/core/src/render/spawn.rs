//! Origins of secondary rays (`spawn.wgsl` is the twin).

use crate::math::lanes::{F, U, V};
use crate::math::{Ray, V3};

/// ULPs of the offset, after Wächter & Binder (RTG ch. 6), see [`spawn_origin`].
const INT_SCALE: f32 = 32.0;
/// The smallest ULP the offset uses: that of the smallest normal f32 (2⁻¹²⁶). Below it, ULPs
/// are those of subnormals, which GPUs may flush to zero; a scene would have to be about 10⁻³⁰
/// units across for it to matter.
pub const MIN_ULP: f32 = f32::MIN_POSITIVE;

/// One ULP of the positive finite float `m` in every lane, exactly (integer arithmetic on its
/// bits).
#[inline(always)]
fn ulp<const N: usize>(m: F<N>) -> F<N> {
    F::from_bits(m.to_bits().wrapping_add(U::splat(1))) - m
}

/// The origin of a ray leaving the hit point p = p0 + μd of `ray` on the side of the unit
/// normal `n`: instead of the lecture's ε chosen by eye, p is moved along n by a fixed number
/// of ULPs per axis (Wächter & Binder, "A Fast and Robust Method for Avoiding
/// Self-Intersection", Ray Tracing Gems ch. 6). The offset is relative to the ray's scale at
/// every scale: a scene shrunk to 10⁻⁶ units renders as it does at 1.
///
/// Three changes to the paper, all measured by `strahl stiff`:
/// - The ULPs are those of |p0ᵢ| + |μ|, not of pᵢ: pᵢ is formed from p0ᵢ and μdᵢ, so its
///   error is a few ULPs of those terms, which can be far larger than pᵢ when they cancel (a
///   cylinder at x ≈ 6·10³ hit from 5·10⁵ away: the paper's offset is a tenth of the error
///   there, and spawned rays re-hit the surface). The ULP is found by integer arithmetic on
///   the float's bits, so no compiler rewriting can shrink it.
/// - 32 steps, not 256: without instance transforms the error is a few ULPs
///   (γ(2)(|p0ᵢ| + |μdᵢ|) + |dᵢ||Δμ|, with |Δμ| a few ULPs of μ); 8 steps re-hit, 32 did not in
///   10⁶ spawned rays, and 256 ULPs is two whole units at 10⁵, detaching shadows from their
///   casters in a scene moved there.
/// - No fixed step near the origin: the paper moves p by 1/65536 where |pᵢ| < 1/32, because its
///   ULPs of pᵢ vanish there while the error does not. The ULPs of |p0ᵢ| + |μ| bound the
///   error there too (μ > 0 at a hit), and a fixed step is larger than a scene 10⁻⁵ across:
///   the seed scene scaled by 10⁻⁶ had 35.5 % of its pixels more than 2 codes off (glass
///   black, shadows gone).
#[inline]
pub fn spawn_origin(ray: &Ray<f32>, t: f32, n: V3<f32>) -> V3<f32> {
    spawn_origin_lanes::<1>(ray.origin.into(), ray.dir.into(), t.into(), n.into()).into()
}

/// [`spawn_origin`] in every lane, for the rays (`o`, `d`) hit at `t`.
#[inline(always)]
pub fn spawn_origin_lanes<const N: usize>(o: V<N>, d: V<N>, t: F<N>, n: V<N>) -> V<N> {
    let p = o + d.scale(t);
    V::new(spawn_axis(p.x, o.x, n.x, t), spawn_axis(p.y, o.y, n.y, t), spawn_axis(p.z, o.z, n.z, t))
}

/// One axis of [`spawn_origin_lanes`]. A function of its own, not a closure: LLVM kept a
/// closure here out of line, where it lacks the calling lane set's target features, three
/// calls a vertex (the cost is in the book's performance chapter).
#[inline(always)]
fn spawn_axis<const N: usize>(p: F<N>, o: F<N>, n: F<N>, t: F<N>) -> F<N> {
    let min_ulp = F::splat(MIN_ULP);
    let m = (o.abs() + t.abs()).max(p.abs()).max(min_ulp);
    p + F::splat(INT_SCALE) * n * ulp(m).max(min_ulp)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One ULP of `m`, through the lanes' routine.
    fn ulp1(m: f32) -> f32 {
        ulp::<1>(m.into()).into()
    }

    #[test]
    fn offset_moves_to_the_normal_side_by_ulps_of_the_inputs() {
        // Ray from the origin, hit at distance 1000: 32 ULPs of 1000 along n's components.
        let ray = Ray::new(V3::zero(), V3::new(1.0f32, -1.0, 0.0).normalize());
        let t = 1000.0;
        let n = V3::new(1.0, -1.0, 0.0).normalize();
        let p = ray.at(t);
        let q = spawn_origin(&ray, t, n);
        assert!(q.x > p.x && q.y < p.y && q.z == 0.0);
        let step = 32.0 * n.x * ulp1(1000.0);
        assert!(((q.x - p.x) - step).abs() <= ulp1(p.x), "{} vs {step}", q.x - p.x);
    }

    #[test]
    fn offset_covers_cancellation() {
        // p.x is small but formed from two terms of size 1e5: the step follows 1e5's ULP.
        let ray = Ray::new(V3::new(1.0e5f32, 0.0, 0.0), V3::new(-1.0, 0.0, 0.0));
        let q = spawn_origin(&ray, 99_990.0, V3::new(1.0, 0.0, 0.0));
        assert!(q.x - 10.0 >= 32.0 * ulp1(2.0e5) * 0.99, "{}", q.x - 10.0);
    }

    /// Near the origin the step is still 32 ULPs of |p0ᵢ| + |μ|: relative to the scene, not a
    /// fixed distance that can exceed a tiny scene.
    #[test]
    fn near_the_origin_the_step_stays_relative() {
        for scale in [1e-3f32, 1e-6, 1e-9] {
            let ray = Ray::new(V3::zero(), V3::new(0.0f32, 0.0, 1.0));
            let q = spawn_origin(&ray, scale, V3::new(0.0, 0.0, -1.0));
            assert_eq!(q.z, scale - 32.0 * ulp1(scale), "at {scale}");
            assert!(scale - q.z < 1e-5 * scale);
        }
        // At zero the ULP of the smallest normal float: never a zero step.
        let q = spawn_origin(&Ray::new(V3::zero(), V3::new(1.0f32, 0.0, 0.0)), 0.0, V3::new(0.0, 1.0, 0.0));
        assert_eq!(q.y, 32.0 * f32::MIN_POSITIVE);
    }
}
