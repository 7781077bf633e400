//! What a ray sees where it hits a triangle (`surface.wgsl` is the twin): the material with its
//! textures and vertex colours applied, and the shading normal from the mesh's vertex normals
//! and the material's normal map. Other primitives, and triangles without attributes, show the
//! plain material and their geometric normal.
//!
//! **Shading normals** are the vertex normals interpolated at the hit's barycentric weights
//! and normalised, turned to the side of the face's normal n where the file disagrees with its
//! winding. A normal map perturbs them in the tangent frame glTF uses: the tangent along
//! ∂p/∂u, the bitangent on the side of −∂p/∂v (glTF's v runs down an image, its maps' green
//! runs up), both from the triangle's edges and texture coordinates (as glTF viewers derive it
//! when a file gives no tangents; the file's `TANGENT` is not read). A perturbed normal that
//! leaves n's hemisphere is not used. How the integrators keep shading normals from leaking
//! light is in [`super::path`].

use super::texture::{barycentrics, sample_rgba};
use crate::layout::{
    ATTR_COLORS, ATTR_NORMALS, FlatMaterial, FlatScene, FlatTexture, FlatTriangleAttrs, MATERIAL_ALPHA_BLEND,
    MATERIAL_ALPHA_MASK, MATERIAL_UNLIT, TEXTURE_UV1,
};
use crate::math::V3;
use crate::primitives::{PrimKind, PrimRef};
use crate::scene::MaterialKind;

/// A hit as shading sees it.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// The material with textures and vertex colours applied.
    pub m: FlatMaterial,
    /// The unit shading normal, on the side of the geometric normal the hit was given.
    pub normal: V3<f32>,
    /// The material's alpha times its colour texture's and the vertex colours' alpha.
    pub alpha: f32,
}

/// Decodes [`crate::layout::encode_octahedral`] (as WGSL's `unpack2x16snorm` reads the
/// codes), not normalised.
#[inline]
pub fn decode_octahedral(w: u32) -> V3<f32> {
    let snorm = |h: u32| ((h as u16 as i16) as f32 / 32767.0).max(-1.0);
    let (x, y) = (snorm(w & 0xffff), snorm(w >> 16));
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    let sx = if x >= 0.0 { -t } else { t };
    let sy = if y >= 0.0 { -t } else { t };
    V3::new(x + sx, y + sy, z)
}

/// Four 8-bit unorms (`unpack4x8unorm`).
#[inline]
fn decode_unorm8x4(w: u32) -> [f32; 4] {
    [0, 8, 16, 24].map(|s| ((w >> s) & 255) as f32 / 255.0)
}

/// How much of a ray the surface stops, from its alpha and the material's mode: 1 for opaque
/// materials and MASK alpha at or above the cut-off, 0 below it, alpha itself (clamped) for
/// BLEND.
#[inline]
pub fn coverage(m: &FlatMaterial, alpha: f32) -> f32 {
    if m.flags & MATERIAL_ALPHA_MASK != 0 {
        if alpha >= m.alpha_cutoff { 1.0 } else { 0.0 }
    } else if m.flags & MATERIAL_ALPHA_BLEND != 0 {
        alpha.clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Whether a normalised vector came out as one (not NaN from a zero vector): the test the
/// shader makes, `all(abs(v) <= 1)`.
#[inline]
fn unit(v: V3<f32>) -> bool {
    v.x.abs() <= 1.0 && v.y.abs() <= 1.0 && v.z.abs() <= 1.0
}

/// Texture coordinates through a use's transform.
#[inline]
fn transformed(t: &FlatTexture, uv: [f32; 2]) -> [f32; 2] {
    let [a, b, d, e] = t.linear;
    [a * uv[0] + b * uv[1] + t.offset_uv[0], d * uv[0] + e * uv[1] + t.offset_uv[1]]
}

#[inline]
fn lerp_uv(uv: &[[f32; 2]; 3], w: [f32; 3]) -> [f32; 2] {
    [0, 1].map(|k| uv[0][k] * w[0] + uv[1][k] * w[1] + uv[2][k] * w[2])
}

/// Texture `texture` (1 + index; 0: none, then 1) at weights `w` of a triangle with attributes
/// `a`, through the coordinates and transform of its use.
#[inline]
fn texture_at(g: &FlatScene, a: &FlatTriangleAttrs, texture: u32, w: [f32; 3]) -> [f32; 4] {
    if texture == 0 {
        return [1.0; 4];
    }
    let t = &g.textures[texture as usize - 1];
    let uv = if t.flags & TEXTURE_UV1 != 0 { &a.second_uv } else { &a.uv };
    let [u, v] = transformed(t, lerp_uv(uv, w));
    sample_rgba(&g.texels, t, u, v)
}

/// The radiance an area light (an emissive or pbr material, not unlit) of material `m` gives
/// off at point `p` of primitive `prim`: what [`surface`] gives as `m.radiance`, without the
/// rest of its work (next-event estimation asks at every sampled light point).
pub fn emission(g: &FlatScene, m: &FlatMaterial, prim: PrimRef, p: V3<f32>) -> V3<f32> {
    let radiance = V3::from_array(m.radiance);
    if m.radiance_texture == 0 || prim.kind() != PrimKind::Triangle || g.triangle_attrs.is_empty() {
        return radiance;
    }
    let i = prim.index();
    let tri = &g.triangles[i];
    let (beta, gamma) = barycentrics(V3::from_array(tri.va), V3::from_array(tri.vb), V3::from_array(tri.vc), p);
    let r = texture_at(g, &g.triangle_attrs[i], m.radiance_texture, [1.0 - beta - gamma, beta, gamma]);
    radiance.mul_elem(V3::new(r[0], r[1], r[2]))
}

/// Material `m` at the point `p` of primitive `prim`, whose geometric normal there is `n`.
pub fn surface(g: &FlatScene, m: &FlatMaterial, prim: PrimRef, p: V3<f32>, n: V3<f32>) -> Surface {
    let mut s = Surface { m: *m, normal: n, alpha: m.alpha };
    if prim.kind() != PrimKind::Triangle || g.triangle_attrs.is_empty() {
        return s;
    }
    let i = prim.index();
    let tri = &g.triangles[i];
    let (va, vb, vc) = (V3::from_array(tri.va), V3::from_array(tri.vb), V3::from_array(tri.vc));
    let (beta, gamma) = barycentrics(va, vb, vc, p);
    let w = [1.0 - beta - gamma, beta, gamma];
    let a = &g.triangle_attrs[i];
    let uv_set = |t: &FlatTexture| if t.flags & TEXTURE_UV1 != 0 { &a.second_uv } else { &a.uv };
    let look = |texture: u32| texture_at(g, a, texture, w);
    let mut vertex = V3::splat(1.0);
    let mut vertex_alpha = 1.0;
    if a.flags & ATTR_COLORS != 0 {
        let k = a.color.map(decode_unorm8x4);
        let vc = |c: usize| k[0][c] * w[0] + k[1][c] * w[1] + k[2][c] * w[2];
        vertex = V3::new(vc(0), vc(1), vc(2));
        vertex_alpha = vc(3);
    }
    let c = look(m.color_texture);
    s.alpha = m.alpha * c[3] * vertex_alpha;
    s.m.color = V3::from_array(m.color).mul_elem(V3::new(c[0], c[1], c[2])).mul_elem(vertex).to_array();
    let r = look(m.radiance_texture);
    let mut radiance = V3::from_array(m.radiance).mul_elem(V3::new(r[0], r[1], r[2]));
    if m.flags & MATERIAL_UNLIT != 0 {
        // An unlit material shows its base colour, vertex colours included.
        radiance = radiance.mul_elem(vertex);
    }
    s.m.radiance = radiance.to_array();
    if m.metal_rough_texture != 0 {
        let mr = look(m.metal_rough_texture);
        s.m.roughness = m.roughness * mr[1];
        s.m.metallic = m.metallic * mr[2];
    }
    let mut ns = n;
    if a.flags & ATTR_NORMALS != 0 {
        let k = a.normal.map(decode_octahedral);
        let v = (k[0] * w[0] + k[1] * w[1] + k[2] * w[2]).normalize();
        if unit(v) {
            ns = if v.dot(n) < 0.0 { -v } else { v };
        }
    }
    if m.normal_texture != 0 {
        let t = &g.textures[m.normal_texture as usize - 1];
        let uv = uv_set(t).map(|c| transformed(t, c));
        let (d1, d2) = ([uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]], [uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]]);
        let det = d1[0] * d2[1] - d1[1] * d2[0];
        let (e1, e2) = (vb - va, vc - va);
        if det != 0.0 {
            let dpdu = (e1 * d2[1] - e2 * d1[1]) / det;
            let dpdv = (e2 * d1[0] - e1 * d2[0]) / det;
            let tangent = (dpdu - ns * ns.dot(dpdu)).normalize();
            let b0 = ns.cross(tangent);
            let bitangent = if b0.dot(dpdv) > 0.0 { -b0 } else { b0 };
            let c = look(m.normal_texture);
            let (x, y, z) =
                ((2.0 * c[0] - 1.0) * m.normal_scale, (2.0 * c[1] - 1.0) * m.normal_scale, 2.0 * c[2] - 1.0);
            let mapped = (tangent * x + bitangent * y + ns * z).normalize();
            if unit(mapped) && mapped.dot(n) > 0.0 {
                ns = mapped;
            }
        }
    }
    s.normal = ns;
    s
}

/// The geometric normal and the shading normal on `wo`'s side of a surface whose face normal
/// is `n` and interpolated or mapped normal `shading` (on n's side): the shading normal where
/// `wo` lies above it, else the face's (a normal bent away from the viewer would see its back).
/// Dielectrics refract about the face's normal. Mirrors and pbr surfaces reflect about a normal
/// bent back towards the face's as far as [`reflecting_normal`] needs.
#[inline]
pub fn shading_frame(m: &FlatMaterial, front: bool, n: V3<f32>, shading: V3<f32>, wo: V3<f32>) -> (V3<f32>, V3<f32>) {
    let ng = if front { n } else { -n };
    let ns = if front { shading } else { -shading };
    if m.kind() == MaterialKind::Dielectric || ns.dot(wo) <= 0.0 {
        return (ng, ng);
    }
    if matches!(m.kind(), MaterialKind::Mirror | MaterialKind::Pbr) {
        return (ng, reflecting_normal(ng, wo, ns));
    }
    (ng, ns)
}

/// `ns` turned towards `ng` (in the plane of the two) just far enough that `wo` mirrored about
/// it leaves the face at least min(0.9·(wo·ng), 0.01) above it; `ns` itself where it already
/// does. Without this a normal map that tilts far from the face sends mirror reflections into
/// the surface, where the path ends: black rims on the bumps of a normal-mapped metal. (The
/// same remedy as Cycles' "valid specular reflection"; the solution here is our own.) With
/// n = cos φ·ng + sin φ·x (x the unit part of ns orthogonal to ng) and wo = (w_x, w_z) in that
/// frame, the mirror direction's height above the face is
/// 2(wo·n)(n·ng) − wo·ng = w_x sin 2φ + w_z cos 2φ = A cos(2φ − δ), A = |(w_x, w_z)|,
/// δ = atan2(w_x, w_z); it is w_z ≥ the threshold t at φ = 0 and first falls to t at
/// φ = (δ + acos(t / A)) / 2, the angle kept (at most ns's own).
#[inline]
pub fn reflecting_normal(ng: V3<f32>, wo: V3<f32>, ns: V3<f32>) -> V3<f32> {
    let wz = wo.dot(ng);
    let t = (0.9 * wz).min(0.01);
    let c0 = ns.dot(ng);
    if 2.0 * wo.dot(ns) * c0 - wz >= t {
        return ns;
    }
    let tangential = ns - ng * c0;
    let s0 = tangential.length();
    if !(s0 > 0.0) {
        return ns;
    }
    let x = tangential / s0;
    let wx = wo.dot(x);
    let a = (wx * wx + wz * wz).sqrt();
    let phi = (0.5 * (wx.atan2(wz) + (t / a).clamp(-1.0, 1.0).acos())).clamp(0.0, s0.atan2(c0));
    (ng * phi.cos() + x * phi.sin()).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::encode_octahedral;

    /// A normal tilted so far that the mirror direction would enter the surface is bent back
    /// until it leaves at the threshold, no further; one that reflects above is kept.
    #[test]
    fn reflecting_normals_keep_mirror_directions_above_the_face() {
        let ng = V3::new(0.0, 0.0, 1.0);
        let wo = V3::new(0.0, 0.0, 1.0);
        for tilt in [10.0f32, 44.0, 50.0, 70.0, 89.0] {
            let (s, c) = tilt.to_radians().sin_cos();
            let ns = V3::new(s, 0.0, c);
            let n = reflecting_normal(ng, wo, ns);
            let r = n * (2.0 * wo.dot(n)) - wo;
            if tilt < 45.0 {
                assert_eq!(n, ns, "tilt {tilt}: reflects above the face already");
            } else {
                assert!((r.dot(ng) - 0.01).abs() < 1e-4, "tilt {tilt}: leaves at {}", r.dot(ng));
                assert!(n.x > 0.0 && n.y.abs() < 1e-6, "tilt {tilt}: bent within the plane of ns and ng: {n:?}");
            }
        }
        // A grazing view (wo·ng = 0.01): the threshold is 0.9·(wo·ng).
        let wo = V3::new(-0.9999f32.sqrt(), 0.0, 0.01);
        let ns = V3::new(0.005, 0.0, (1.0f32 - 0.000025).sqrt());
        assert!((ns * (2.0 * wo.dot(ns)) - wo).z < 0.009, "the case must need bending");
        let n = reflecting_normal(ng, wo, ns);
        let r = n * (2.0 * wo.dot(n)) - wo;
        assert!((r.dot(ng) - 0.009).abs() < 2e-4, "{}", r.dot(ng));
    }

    #[test]
    fn octahedral_codes_round_trip_within_their_precision() {
        let mut worst = 0.0f32;
        for k in 0..2000 {
            // Points spread over the sphere (a Fibonacci spiral), poles and axes included.
            let z = 1.0 - 2.0 * (k as f32 + 0.5) / 2000.0;
            let phi = k as f32 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            let n = V3::new(r * phi.cos(), r * phi.sin(), z);
            let back = decode_octahedral(encode_octahedral(n.to_array())).normalize();
            // The angle from its sine, in f64 (f32's acos cannot resolve angles below 3·10⁻⁴).
            worst = worst.max(back.to_f64().cross(n.to_f64()).length() as f32);
        }
        for n in [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]] {
            let back = decode_octahedral(encode_octahedral(n)).normalize();
            assert!((back - V3::from_array(n)).length() < 1e-4, "{n:?} → {back:?}");
        }
        assert!(worst < 1e-4, "largest angle {worst} rad");
    }

    #[test]
    fn unorm_colours_round_trip() {
        let w = crate::layout::encode_unorm8x4([0.0, 0.5, 1.0, 0.2]);
        let c = decode_unorm8x4(w);
        for (got, want) in c.iter().zip([0.0, 0.5, 1.0, 0.2]) {
            assert!((got - want).abs() <= 0.5 / 255.0 + 1e-6, "{got} vs {want}");
        }
    }
}
