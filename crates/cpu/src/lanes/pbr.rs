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
use strahl_core::render::microfacet::{self, COS_STEPS, ROUGHNESS_STEPS};
use strahl_core::render::pbr::{MIN_PBR_ALPHA, PBR_F0};

const PI: f32 = std::f32::consts::PI;
const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

/// `f32::clamp(0, 1)` lane by lane (NaN stays NaN).
#[inline(always)]
pub(super) fn clamp01<const N: usize>(x: F<N>) -> F<N> {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let x = x.lt(zero).select(zero, x);
    x.gt(one).select(one, x)
}

/// [`microfacet::lookup`] in every lane.
#[inline(always)]
fn lookup<const N: usize>(r: F<N>, cos_o: F<N>) -> (F<N>, F<N>) {
    let t = microfacet::table();
    let x = clamp01(r) * F::splat((ROUGHNESS_STEPS - 1) as f32);
    let y = clamp01(cos_o) * F::splat((COS_STEPS - 1) as f32);
    let x0 = x.map(f32::floor).min(F::splat((ROUGHNESS_STEPS - 2) as f32));
    let y0 = y.map(f32::floor).min(F::splat((COS_STEPS - 2) as f32));
    let (fx, fy) = (x - x0, y - y0);
    // Lane after lane: the four entries of each table.
    let mut e = [[0.0f32; N]; 8];
    for l in 0..N {
        let k = x0.0[l] as usize * COS_STEPS + y0.0[l] as usize;
        for (j, base) in [0, ROUGHNESS_STEPS * COS_STEPS].into_iter().enumerate() {
            let i = (base + k).min(t.len() - COS_STEPS - 2);
            e[4 * j][l] = t[i];
            e[4 * j + 1][l] = t[i + 1];
            e[4 * j + 2][l] = t[i + COS_STEPS];
            e[4 * j + 3][l] = t[i + COS_STEPS + 1];
        }
    }
    (bilerp(&e[..4], fx, fy), bilerp(&e[4..], fx, fy))
}

/// The four table entries `e` (the corners (0, 0), (0, 1), (1, 0), (1, 1)) interpolated at
/// (fx, fy), as `microfacet::lookup` does. (A function, not a closure: the compiler left the
/// closure out of line, in code without the ISA's instructions.)
#[inline(always)]
fn bilerp<const N: usize>(e: &[[f32; N]], fx: F<N>, fy: F<N>) -> F<N> {
    let one = F::splat(1.0);
    let top = F(e[0]) * (one - fy) + F(e[1]) * fy;
    let bottom = F(e[2]) * (one - fy) + F(e[3]) * fy;
    top * (one - fx) + bottom * fx
}

/// [`strahl_core::render::pbr::PbrLobes`] in lanes.
#[derive(Clone, Copy)]
pub(super) struct Lobes<const N: usize> {
    pub alpha: F<N>,
    pub reflectance: V<N>,
    pub metal_weight: V<N>,
    pub coat_weight: F<N>,
    pub diffuse: V<N>,
    pub p_spec: F<N>,
}

#[inline(always)]
fn luminance<const N: usize>(c: V<N>) -> F<N> {
    F::splat(0.2126) * c.x + F::splat(0.7152) * c.y + F::splat(0.0722) * c.z
}

/// [`strahl_core::render::pbr::pbr_lobes`] of base colour `base`, metalness `metallic` and
/// roughness `roughness` at cos θ_o = `cos_o`.
#[inline(always)]
pub(super) fn lobes<const N: usize>(base: V<N>, metallic: F<N>, roughness: F<N>, cos_o: F<N>) -> Lobes<N> {
    let one = F::splat(1.0);
    let metal = clamp01(metallic);
    let r = clamp01(roughness);
    let alpha = (r * r).max(F::splat(MIN_PBR_ALPHA));
    let (e1, e5) = lookup(r, cos_o);
    let e1 = e1.max(F::splat(1e-3));
    let lost = (one - e1) / e1;
    let metal_weight = (V::splat([1.0; 3]) + base.scale(lost)).scale(metal);
    let coat_comp = one + F::splat(PBR_F0) * lost;
    let coat_weight = (one - metal) * coat_comp;
    let coat = coat_comp * (F::splat(PBR_F0) * e1 + F::splat(1.0 - PBR_F0) * e5);
    let diffuse = base.scale((one - metal) * (one - coat).max(F::splat(0.0)));
    let metal_albedo = (base.scale(e1) + (V::splat([1.0; 3]) - base).scale(e5)).mul_elem(metal_weight);
    let c = (one - metal) * coat;
    let spec_albedo = metal_albedo + V::new(c, c, c);
    let (ls, ld) = (luminance(spec_albedo), luminance(diffuse));
    let p_spec = (ls + ld).gt(F::splat(0.0)).select(ls / (ls + ld), F::splat(0.0));
    Lobes { alpha, reflectance: base, metal_weight, coat_weight, diffuse, p_spec }
}

/// `microfacet::schlick`.
#[inline(always)]
pub(super) fn schlick<const N: usize>(f0: V<N>, cos: F<N>) -> V<N> {
    let m = clamp01(F::splat(1.0) - cos);
    let m5 = m * m * m * m * m;
    f0 + (V::splat([1.0; 3]) - f0).scale(m5)
}

/// `microfacet::ggx_d`.
#[inline(always)]
fn ggx_d<const N: usize>(alpha: F<N>, cos_h: F<N>) -> F<N> {
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let den = c2 * (a2 - F::splat(1.0)) + F::splat(1.0);
    a2 / (F::splat(PI) * den * den)
}

/// `microfacet::ggx_lambda`.
#[inline(always)]
fn ggx_lambda<const N: usize>(alpha: F<N>, cos: F<N>) -> F<N> {
    let c2 = (cos * cos).max(F::splat(1e-12));
    let a2_tan2 = alpha * alpha * (F::splat(1.0) - c2).max(F::splat(0.0)) / c2;
    F::splat(0.5) * ((F::splat(1.0) + a2_tan2).sqrt() - F::splat(1.0))
}

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
    let f = schlick(l.reflectance, cos_oh).mul_elem(l.metal_weight)
        + schlick(V::splat([PBR_F0; 3]), cos_oh).scale(l.coat_weight);
    let lobe = cos_h.gt(zero);
    let f_cos = lobe.select_v(f_cos + f.scale(k / (one + lo + li)), f_cos);
    let pdf = lobe.select(pdf + l.p_spec * k / (one + lo), pdf);
    // (Not `> 0`: a NaN cosine goes on, as in the scalar test.)
    let above = !(cos_o.le(zero) | cos_i.le(zero));
    (above.select_v(f_cos, V::splat([0.0; 3])), above.select(pdf, zero))
}

/// `bsdf::basis` (Duff et al. 2017).
#[inline(always)]
pub(super) fn basis<const N: usize>(n: V<N>) -> (V<N>, V<N>) {
    let one = F::splat(1.0);
    let sign = n.z.ge(F::splat(0.0)).select(one, -one);
    let a = -one / (sign + n.z);
    let b = n.x * n.y * a;
    (V::new(one + sign * n.x * n.x * a, sign * b, -sign * n.x), V::new(b, sign + n.y * n.y * a, -n.y))
}

/// `microfacet::ggx_sample_visible` in every lane (the angle's cosine and sine lane after
/// lane).
#[inline(always)]
fn sample_visible<const N: usize>(alpha: F<N>, wo: V<N>, u1: F<N>, u2: F<N>) -> V<N> {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let vh = V::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let len = lensq.sqrt();
    let has = lensq.gt(zero);
    let t1 = V::new(has.select(-vh.y / len, one), has.select(vh.x / len, zero), has.select(zero / len, zero));
    let t2 = V::new(vh.y * t1.z - vh.z * t1.y, vh.z * t1.x - vh.x * t1.z, vh.x * t1.y - vh.y * t1.x);
    let r = u1.sqrt();
    let (sin, cos) = u2.sin_cos_turns();
    let p1 = r * cos;
    let s = F::splat(0.5) * (one + vh.z);
    let p2 = (one - s) * (one - p1 * p1).max(zero).sqrt() + s * (r * sin);
    let nh = t1.scale(p1) + t2.scale(p2) + vh.scale((one - p1 * p1 - p2 * p2).max(zero).sqrt());
    V::new(alpha * nh.x, alpha * nh.y, nh.z.max(zero)).normalize()
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
            let l = lobes(base, F(m.map(|m| m.metallic)), F(m.map(|m| m.roughness)), cos_o);
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
                let (wf, wp) = bsdf::eval(&m[k], wo[k], wi[k], ns[k]);
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
                let (wf, wp) = bsdf::eval(&m[k], wo[k], wi[k], ns[k]);
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
