//! glTF's metallic-roughness material and the rough (GGX) mirror in lanes:
//! [`strahl_core::render::pbr::pbr_lobes`], the materials' `bsdf::eval` and `bsdf::sample` over
//! SIMD lanes, each by the scalar routine's operations in its order (so every lane computes
//! what the one-path tracer computes, bit for bit). The albedo table is read lane after lane;
//! the visible-normal sample's angle is a fraction of a turn whose sine and cosine are
//! [`strahl_core::math::sin_cos_turns`] in lanes, as in [`microfacet::ggx_sample_visible`].

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use strahl_core::math::lanes::{F, M, V};
use strahl_core::render::bsdf::basis_lanes as basis;
use strahl_core::render::microfacet::{
    ggx_d_lanes as ggx_d, ggx_lambda_lanes as ggx_lambda, ggx_sample_visible_lanes as sample_visible,
    schlick_lanes as schlick,
};
use strahl_core::render::pbr::{PbrLobesLanes as Lobes, pbr_fresnel_lanes};

const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

/// `bsdf::pbr_eval` with the lobes `l` already taken at cos θ_o = wo·ns: f·cos θ_i and the
/// density, 0 where either cosine is not positive.
#[inline(always)]
pub(super) fn eval<const N: usize>(l: &Lobes<N>, wo: V<N>, wi: V<N>, ns: V<N>) -> (V<N>, F<N>) {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let (cos_o, cos_i) = (wo.dot(ns), wi.dot(ns));
    let f_cos = l.diffuse.scale(cos_i * F::splat(INV_PI));
    let pdf = (one - l.p_spec) * cos_i * F::splat(INV_PI);
    let h = (wo + wi).normalize();
    let cos_h = h.dot(ns);
    let d = ggx_d(l.alpha, cos_h);
    let (lo, li) = (ggx_lambda(l.alpha, cos_o), ggx_lambda(l.alpha, cos_i));
    let k = d / (F::splat(4.0) * cos_o);
    let cos_oh = wo.dot(h);
    let f = pbr_fresnel_lanes(l, cos_oh);
    let lobe = cos_h.gt(zero);
    let f_cos = lobe.select_v(f_cos + f.scale(k / (one + lo + li)), f_cos);
    let pdf = lobe.select(pdf + l.p_spec * k / (one + lo), pdf);
    // (Not `> 0`: a NaN cosine goes on, as in the scalar test.) No lobe: nothing (`bsdf::pbr_eval`).
    let above = !(cos_o.le(zero) | cos_i.le(zero)) & !(l.p_spec.le(zero) & l.diffuse.max_component().le(zero));
    (above.select_v(f_cos, V::splat([0.0; 3])), above.select(pdf, zero))
}

/// A visible normal of GGX roughness `alpha` about `ns` seen from `wo` (from `u1`, `u2`), and
/// `wo` mirrored about it: `to_world(ggx_sample_visible(α, to_local(wo, ns), u1, u2), ns)` and
/// `reflect(−wo, h)` of `bsdf`.
#[inline(always)]
fn ggx_reflect<const N: usize>(alpha: F<N>, wo: V<N>, ns: V<N>, u1: F<N>, u2: F<N>) -> (V<N>, V<N>) {
    let (t, b) = basis(ns);
    let local = V::new(wo.dot(t), wo.dot(b), wo.dot(ns));
    let m = sample_visible(alpha, local, u1, u2);
    let h = t.scale(m.x) + b.scale(m.y) + ns.scale(m.z);
    let d = -wo;
    (d - h.scale(F::splat(2.0) * d.dot(h)), h)
}

/// `bsdf::pbr_sample`'s direction: by `u0` the GGX lobe (a visible normal from `u1`, `u2`,
/// `wo` mirrored about it) or the diffuse base (`cosine`: the cosine-weighted direction about
/// `ns` the caller drew from `u1`, `u2`).
#[inline(always)]
pub(super) fn sample_dir<const N: usize>(l: &Lobes<N>, wo: V<N>, ns: V<N>, u: [F<N>; 3], cosine: V<N>) -> V<N> {
    let (spec, _) = ggx_reflect(l.alpha, wo, ns, u[1], u[2]);
    u[0].lt(l.p_spec).select_v(spec, cosine)
}

/// `bsdf::eval` of the rough conductor (a mirror of GGX α = `alpha` ≥ `MIN_ROUGHNESS` and
/// colour `f0`): f·cos θ_i and the density.
#[inline(always)]
pub(super) fn conductor_eval<const N: usize>(alpha: F<N>, f0: V<N>, wo: V<N>, wi: V<N>, ns: V<N>) -> (V<N>, F<N>) {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let cos_i = wi.dot(ns);
    let cos_o = wo.dot(ns);
    let h = (wo + wi).normalize();
    let cos_h = h.dot(ns);
    let d = ggx_d(alpha, cos_h);
    let (lo, li) = (ggx_lambda(alpha, cos_o), ggx_lambda(alpha, cos_i));
    let g2 = one / (one + lo + li);
    let g1 = one / (one + lo);
    let f = schlick(f0, wo.dot(h));
    let k = d / (F::splat(4.0) * cos_o);
    let ok = !cos_i.le(zero) & !(cos_o.le(zero) | cos_h.le(zero));
    (ok.select_v(f.scale(k * g2), V::splat([0.0; 3])), ok.select(k * g1, zero))
}

/// `bsdf::sample` of the rough conductor from `u1`, `u2`: the lanes with a sample, its
/// direction, weight and density.
#[inline(always)]
pub(super) fn conductor_sample<const N: usize>(
    alpha: F<N>,
    f0: V<N>,
    wo: V<N>,
    ns: V<N>,
    u1: F<N>,
    u2: F<N>,
) -> (M<N>, V<N>, V<N>, F<N>) {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let cos_o = wo.dot(ns);
    let (dir, h) = ggx_reflect(alpha, wo, ns, u1, u2);
    let cos_i = dir.dot(ns);
    let ok = !(cos_i.le(zero) | cos_o.le(zero));
    let (lo, li) = (ggx_lambda(alpha, cos_o), ggx_lambda(alpha, cos_i));
    let weight = schlick(f0, wo.dot(h)).scale((one + lo) / (one + lo + li));
    let pdf = ggx_d(alpha, h.dot(ns)) / ((one + lo) * F::splat(4.0) * cos_o);
    (ok, dir, weight, pdf)
}

/// Lanes where `bsdf::pbr_sample` gives a direction at all (before its density test).
#[inline(always)]
pub(super) fn samples<const N: usize>(l: &Lobes<N>, cos_o: F<N>) -> M<N> {
    let zero = F::splat(0.0);
    !cos_o.le(zero) & !(l.p_spec.le(zero) & l.diffuse.max_component().le(zero))
}

#[cfg(test)]
mod tests {
    use super::super::unit_direction;
    use super::*;
    use strahl_core::layout::FlatMaterial;
    use strahl_core::math::V3;
    use strahl_core::render::bsdf;
    use strahl_core::render::pbr::pbr_lobes;
    use strahl_core::render::sampler::Sampler;
    use strahl_core::scene::MaterialKind;

    const N: usize = 8;

    fn v(a: [V3<f32>; N]) -> V<N> {
        V::new(F(a.map(|p| p.x)), F(a.map(|p| p.y)), F(a.map(|p| p.z)))
    }

    fn lane(x: V<N>, l: usize) -> [u32; 3] {
        [x.x.0[l].to_bits(), x.y.0[l].to_bits(), x.z.0[l].to_bits()]
    }

    /// Lobes, eval and sampled directions equal the scalar routines' bit for bit, over random
    /// materials (smooth to rough, metal to dielectric, black to white) and directions,
    /// including directions below the surface.
    #[test]
    fn lanes_equal_the_scalar_material() {
        let mut rng = Sampler::new(11, 12, 13);
        let mut compared = 0;
        for _ in 0..2000 {
            let m: [FlatMaterial; N] = std::array::from_fn(|_| FlatMaterial {
                kind: MaterialKind::Pbr as u32,
                color: [rng.next_f32(), rng.next_f32(), rng.next_f32() * 1.2],
                metallic: rng.next_f32() * 1.1 - 0.05,
                roughness: rng.next_f32().powi(2) * 1.1,
                ..Default::default()
            });
            let ns: [V3<f32>; N] = std::array::from_fn(|_| unit_direction(&mut rng));
            let wo: [V3<f32>; N] = std::array::from_fn(|_| unit_direction(&mut rng));
            let wi: [V3<f32>; N] = std::array::from_fn(|_| unit_direction(&mut rng));
            let u: [F<N>; 3] = std::array::from_fn(|_| F(std::array::from_fn(|_| rng.next_f32())));
            let base = v(m.map(|m| V3::from_array(m.color)));
            let (vwo, vwi, vns) = (v(wo), v(wi), v(ns));
            let cos_o = vwo.dot(vns);
            let l = strahl_core::render::pbr::pbr_lobes_lanes(
                base,
                F(m.map(|m| m.metallic)),
                F(m.map(|m| m.roughness)),
                cos_o,
            );
            let (f_cos, pdf) = eval(&l, vwo, vwi, vns);
            let cosine = {
                let (sin_phi, cos_phi) = u[2].sin_cos_turns();
                let r = u[1].sqrt();
                let local = V::new(r * cos_phi, r * sin_phi, (F::splat(1.0) - u[1]).max(F::splat(0.0)).sqrt());
                let (t, b) = basis(vns);
                (t.scale(local.x) + b.scale(local.y) + vns.scale(local.z)).normalize()
            };
            let dir = sample_dir(&l, vwo, vns, u, cosine);
            let (sf, sp) = eval(&l, vwo, dir, vns);
            let ok = samples(&l, cos_o);
            for k in 0..N {
                let want = pbr_lobes(&m[k], wo[k].dot(ns[k]));
                assert_eq!(l.p_spec.0[k].to_bits(), want.p_spec.to_bits(), "lane {k}: p_spec");
                assert_eq!(lane(l.diffuse, k), want.diffuse.to_array().map(f32::to_bits), "lane {k}: diffuse");
                let (wf, wp) = bsdf::eval(&m[k], wo[k], wi[k], ns[k], true);
                assert_eq!(lane(f_cos, k), wf.to_array().map(f32::to_bits), "lane {k}: f cos");
                assert_eq!(pdf.0[k].to_bits(), wp.to_bits(), "lane {k}: pdf");
                let s = bsdf::sample(&m[k], wo[k], ns[k], true, [u[0].0[k], u[1].0[k], u[2].0[k]]);
                let got = (ok.lane(k) && sp.0[k] > 0.0).then(|| {
                    let w = sf / sp;
                    (lane(dir, k), lane(w, k), sp.0[k].to_bits())
                });
                let want = s.map(|s| {
                    (s.dir.to_array().map(f32::to_bits), s.weight.to_array().map(f32::to_bits), s.pdf.to_bits())
                });
                assert_eq!(got, want, "lane {k}: sample");
                compared += s.is_some() as usize;
            }
        }
        assert!(compared > 2000 * N / 4, "only {compared} samples compared");
    }

    /// The rough conductor's eval and samples equal `bsdf`'s bit for bit.
    #[test]
    fn lanes_equal_the_scalar_rough_conductor() {
        let mut rng = Sampler::new(21, 22, 23);
        let mut compared = 0;
        for _ in 0..2000 {
            let m: [FlatMaterial; N] = std::array::from_fn(|_| FlatMaterial {
                kind: MaterialKind::Mirror as u32,
                color: [rng.next_f32(), rng.next_f32(), rng.next_f32()],
                roughness: bsdf::MIN_ROUGHNESS + rng.next_f32().powi(2),
                ..Default::default()
            });
            let ns: [V3<f32>; N] = std::array::from_fn(|_| unit_direction(&mut rng));
            let wo: [V3<f32>; N] = std::array::from_fn(|_| unit_direction(&mut rng));
            let wi: [V3<f32>; N] = std::array::from_fn(|_| unit_direction(&mut rng));
            let u: [F<N>; 2] = std::array::from_fn(|_| F(std::array::from_fn(|_| rng.next_f32())));
            let (alpha, f0) = (F(m.map(|m| m.roughness)), v(m.map(|m| V3::from_array(m.color))));
            let (f_cos, pdf) = conductor_eval(alpha, f0, v(wo), v(wi), v(ns));
            let (ok, dir, weight, sp) = conductor_sample(alpha, f0, v(wo), v(ns), u[0], u[1]);
            for k in 0..N {
                let (wf, wp) = bsdf::eval(&m[k], wo[k], wi[k], ns[k], true);
                assert_eq!(lane(f_cos, k), wf.to_array().map(f32::to_bits), "lane {k}: f cos");
                assert_eq!(pdf.0[k].to_bits(), wp.to_bits(), "lane {k}: pdf");
                let s = bsdf::sample(&m[k], wo[k], ns[k], true, [0.5, u[0].0[k], u[1].0[k]]);
                let got = ok.lane(k).then(|| (lane(dir, k), lane(weight, k), sp.0[k].to_bits()));
                let want = s.map(|s| {
                    (s.dir.to_array().map(f32::to_bits), s.weight.to_array().map(f32::to_bits), s.pdf.to_bits())
                });
                assert_eq!(got, want, "lane {k}: sample");
                compared += s.is_some() as usize;
            }
        }
        assert!(compared > 2000 * N / 4, "only {compared} samples compared");
    }
}
