//! Light sources of the path tracer (`emitters.wgsl` is the twin of the sampling half): which
//! emitters exist, how one is chosen, where on it a point is drawn, and the density of that
//! choice, which multiple importance sampling needs for paths that hit an emitter by chance.
//!
//! Area emitters (emissive triangles and spheres) are chosen in proportion to their power
//! (mean radiance × area), then a point is drawn uniformly on the chosen area. For an emitter
//! of radiance L the two steps give the area density (mean(L)·A/W)·(1/A) = mean(L)/W, the same
//! for every triangle or sphere of that radiance: that is
//! [`crate::layout::FrameParams::emitter_norm`] = 1/W.
//!
//! Point and directional lights are not chosen: each is evaluated at every vertex
//! ([`delta_light`]), one shadow ray apiece, as Whitted shading does. Chosen by power among the
//! others they could be starved: a directional light's power had to be guessed from the
//! bounded objects' cross-section, which says nothing of an infinite plane it also lights, so
//! beside one it was drawn once in ~700 vertices and weighted ~700× (fireflies).
//!
//! Emissive cylinders and planes are not sampled (a plane has no finite area): they light the
//! scene through paths that hit them, with MIS weight 1. The emitter table itself is built with
//! the rest of the flattened scene ([`super::flatten`]).

use crate::layout::{
    FlatEmitter, FlatLight, FlatScene, FrameParams, LIGHT_POINT, LIGHT_SPOT, LIGHT_STAND_IN, MATERIAL_TWO_SIDED,
};
use crate::math::V3;
use crate::math::lanes::{F, U};
use crate::primitives::{PrimKind, PrimRef};

/// The mean of a colour's channels: the weight of a radiance in the emitter choice.
pub(super) fn mean(c: [f32; 3]) -> f32 {
    (c[0] + c[1] + c[2]) / 3.0
}

/// Index of the emitter `u` ∈ [0, 1) selects: the first whose cdf exceeds `u`.
#[inline]
pub fn select(emitters: &[FlatEmitter], u: f32) -> usize {
    let (mut lo, mut hi) = (0usize, emitters.len() - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if u < emitters[mid].cdf {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// A light sample seen from a shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction towards the light.
    pub dir: V3<f32>,
    /// Distance to the sampled point (f32::MAX for directional lights).
    pub dist: f32,
    /// Radiance (area emitters) or irradiance at normal incidence (point, directional)
    /// arriving, divided by `pdf`.
    pub value: V3<f32>,
    /// Solid-angle density of this direction (area emitters, selection included); 1 for a
    /// point or directional light, which is not chosen (and which no other technique can
    /// find: its MIS weight is 1).
    pub pdf: f32,
}

/// What reaches a point `dist` away in direction −`dir` from point light `l` (`dir` points from
/// the point to the light), as a share of its intensity: 1, or for a spot light the cone's
/// falloff clamp(cos θ·scale + offset, 0, 1)² of `KHR_lights_punctual` (its recommended
/// implementation), and within a `range` its window clamp(1 − (dist / range)⁴, 0, 1)².
#[inline]
pub fn spot_factor(l: &FlatLight, dir: V3<f32>, dist: f32) -> f32 {
    let mut f = 1.0;
    if l.flags & LIGHT_SPOT != 0 {
        let cos = -dir.dot(V3::from_array(l.axis));
        let a = (cos * l.cone_scale + l.cone_offset).clamp(0.0, 1.0);
        f = a * a;
    }
    if l.range > 0.0 {
        let r = dist / l.range;
        let w = (1.0 - r * r * r * r).clamp(0.0, 1.0);
        f *= w * w;
    }
    f
}

/// Point or directional light `l` seen from shading point `p`: its direction, distance and
/// irradiance at normal incidence. None for a Whitted stand-in (path mode samples the
/// emissive object itself) and for a point light at `p`.
pub fn delta_light(l: &FlatLight, p: V3<f32>) -> Option<LightSample> {
    if l.flags & LIGHT_STAND_IN != 0 {
        return None;
    }
    let i = V3::from_array(l.intensity);
    if l.kind == LIGHT_POINT {
        let to = V3::from_array(l.vector) - p;
        let d2 = to.dot(to);
        if !(d2 > 0.0) {
            return None;
        }
        let dist = d2.sqrt();
        let dir = to / dist;
        return Some(LightSample { dir, dist, value: i / d2 * spot_factor(l, dir, dist), pdf: 1.0 });
    }
    Some(LightSample { dir: -V3::from_array(l.vector), dist: f32::MAX, value: i, pdf: 1.0 })
}

/// Draws an area-light sample for shading point `p` from three uniform numbers; None when the
/// sampled point faces away or the scene has no area emitters.
pub fn sample(g: &FlatScene, frame: &FrameParams, p: V3<f32>, u: [f32; 3]) -> Option<LightSample> {
    let mut u0 = u[0];
    if let Some(env) = g.environment.first() {
        // The environment with probability `select`, else an area emitter with u[0] rescaled.
        if frame.num_emitters == 0 || u0 < env.select_prob {
            let (dir, value, pdf) = super::environment::sample(g, frame, u[1], u[2])?;
            return Some(LightSample { dir, dist: f32::MAX, value, pdf });
        }
        u0 = (u0 - env.select_prob) / (1.0 - env.select_prob);
    }
    if frame.num_emitters == 0 {
        return None;
    }
    let e = &g.emitters[select(&g.emitters[..frame.num_emitters as usize], u0)];
    let r = PrimRef(e.source);
    let (q, n, material) = match r.kind() {
        PrimKind::Triangle => {
            let t = &g.triangles[r.index()];
            let (a, b, c) = (V3::from_array(t.va), V3::from_array(t.vb), V3::from_array(t.vc));
            // Uniform on the triangle (Turk 1990 / pbrt-v4 A.5.5).
            let su = u[1].sqrt();
            let b0 = 1.0 - su;
            let (b1, b2) = (u[2] * su, 1.0 - b0 - u[2] * su);
            (a * b0 + b * b1 + c * b2, (b - a).cross(c - a).normalize(), t.material)
        }
        _ => {
            let s = &g.spheres[r.index()];
            let z = 1.0 - 2.0 * u[1];
            let rad = (1.0 - z * z).max(0.0).sqrt();
            let (sin_phi, cos_phi) = crate::math::sin_cos_turns(u[2]);
            let n = V3::new(rad * cos_phi, rad * sin_phi, z);
            (V3::from_array(s.center) + n * s.radius, n, s.material)
        }
    };
    let m = &g.materials[material as usize];
    let to = q - p;
    let d2 = to.dot(to);
    let dist = d2.sqrt();
    let dir = to / dist;
    let cos_l = emitted_cos(m.flags, -dir.dot(n));
    if cos_l <= 0.0 || d2 <= 0.0 {
        return None;
    }
    let pdf = area_pdf(frame, m.radiance, d2, cos_l);
    // The emission texture at the sampled point (its density is that of the untextured
    // radiance, which both sampling and MIS use).
    let radiance = super::surface::emission(g, m, r, q);
    Some(LightSample { dir, dist, value: radiance / pdf, pdf })
}

/// The cosine at the emitter that counts: `cos` for one-sided emitters (≤ 0 from behind),
/// |cos| for two-sided ones.
#[inline]
pub fn emitted_cos(material_flags: u32, cos: f32) -> f32 {
    emitted_cos_lanes::<1>(material_flags.into(), cos.into()).into()
}

/// [`emitted_cos`] in every lane.
#[inline(always)]
pub fn emitted_cos_lanes<const N: usize>(material_flags: U<N>, cos: F<N>) -> F<N> {
    let one_sided = (material_flags & U::splat(MATERIAL_TWO_SIDED)).eq(U::splat(0));
    one_sided.select(cos, cos.abs())
}

/// Solid-angle density with which [`sample`] picks a point at squared distance `d2` and
/// emitter cosine `cos_l` on an area emitter of radiance `radiance`.
#[inline]
pub fn area_pdf(frame: &FrameParams, radiance: [f32; 3], d2: f32, cos_l: f32) -> f32 {
    mean(radiance) * frame.emitter_norm * d2 / cos_l
}

/// The power heuristic with β = 2 for a sample drawn with density `pdf_a` against a second
/// technique of density `pdf_b`.
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    power_heuristic_lanes::<1>(pdf_a.into(), pdf_b.into()).into()
}

/// [`power_heuristic`] in every lane.
#[inline(always)]
pub fn power_heuristic_lanes<const N: usize>(pdf_a: F<N>, pdf_b: F<N>) -> F<N> {
    let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
    (a + b).gt(F::splat(0.0)).select(a / (a + b), F::splat(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selection_inverts_the_cdf() {
        let e = |cdf| FlatEmitter { cdf, ..Default::default() };
        let table = [e(0.25), e(0.5), e(1.0)];
        assert_eq!(select(&table, 0.0), 0);
        assert_eq!(select(&table, 0.2499), 0);
        assert_eq!(select(&table, 0.25), 1);
        assert_eq!(select(&table, 0.7), 2);
        assert_eq!(select(&table, 0.999_999_94), 2);
        assert_eq!(select(&table[..1], 0.9), 0);
    }
}
