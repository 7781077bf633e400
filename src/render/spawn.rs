//! Origins of secondary rays (`spawn.wgsl` is the twin).

use crate::math::V3;

/// Moves a hit point off its surface along the normal `n` (pointing to the side the new ray
/// leaves from), instead of the lecture's ε chosen by eye: Wächter & Binder, "A Fast and
/// Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6. Far from the origin
/// the step is a fixed number of ULPs (integer arithmetic on the float's bits, which no
/// compiler can fuse or reassociate away), so it scales with the rounding error of p itself;
/// near the origin, where ULPs are tiny, it is a fixed 1/65536 along n.
#[inline]
pub fn offset_ray_origin(p: V3<f32>, n: V3<f32>) -> V3<f32> {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let step = |p: f32, n: f32| -> f32 {
        if p.abs() < ORIGIN {
            return p + FLOAT_SCALE * n;
        }
        let of = (INT_SCALE * n) as i32;
        let bits = p.to_bits() as i32;
        f32::from_bits(bits.wrapping_add(if p < 0.0 { -of } else { of }) as u32)
    };
    V3::new(step(p.x, n.x), step(p.y, n.y), step(p.z, n.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_to_the_normal_side_by_a_few_ulps() {
        let p = V3::new(1000.0f32, -1000.0, 0.0);
        let n = V3::new(1.0, -1.0, 0.0).normalize();
        let q = offset_ray_origin(p, n);
        assert!(q.x > p.x && q.y < p.y && q.z == 0.0);
        let ulps = (q.x.to_bits() as i64 - p.x.to_bits() as i64).abs();
        assert_eq!(ulps, (256.0 * n.x) as i64);
    }
}
