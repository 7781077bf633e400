//! Image textures (`texture.wgsl` is the twin): texture coordinates at a triangle hit, and
//! bilinear lookups with glTF's wrap modes, in the arithmetic the shader uses, on the packed
//! texels both backends read.
//!
//! **How texels reach the GPU.** Every image is packed into one storage buffer of 32-bit words
//! ([`FlatScene::texels`]): first the sRGB → linear table of the 256 codes (f32 bits), then each
//! colour texture at one word per texel (its 8-bit sRGB codes), then the environment map at
//! three words per texel (linear f32 RGB). A small table ([`FlatScene::textures`]) gives each
//! image's size, first word and flags. Lookups are done by hand in the shader (no sampler, no
//! texture object), so the CPU reproduces them operation for operation: a colour texel is the
//! table entry of each code (exactly the value the CPU decodes), and the bilinear weights come
//! from the same f32 operations. All images together must fit one storage binding (lavapipe:
//! 128 MiB, 32 M colour texels); the error says so before anything is allocated.

use crate::layout::{
    ATTR_COLORS, ATTR_NORMALS, FlatTexture, FlatTriangleAttrs, SRGB_TABLE_WORDS, TEXTURE_DATA, TEXTURE_LINEAR_RGB,
    TEXTURE_NEAREST, TEXTURE_UV1, TEXTURE_WRAP_U_SHIFT, TEXTURE_WRAP_V_SHIFT, encode_octahedral, encode_unorm8x4,
};
use crate::math::V3;
use crate::primitives::Primitives;
use crate::scene::texture::{Texels, Wrap, srgb_to_linear};
use crate::scene::{Geometry, Scene, Texture};
use std::collections::HashMap;
use std::sync::Arc;

/// The texture table and the texel buffer of `textures` (uses of images), in order; uses of
/// one image (the same shared texels) share its words.
pub fn pack<'a>(textures: impl Iterator<Item = &'a Texture>) -> (Vec<FlatTexture>, Vec<u32>) {
    let mut texels: Vec<u32> = (0..=255u8).map(|c| srgb_to_linear(c).to_bits()).collect();
    debug_assert_eq!(texels.len(), SRGB_TABLE_WORDS as usize);
    let mut infos = Vec::new();
    let mut packed: HashMap<*const Texels, u32> = HashMap::new();
    for t in textures {
        let mut flags = (t.wrap[0] as u32) << TEXTURE_WRAP_U_SHIFT | (t.wrap[1] as u32) << TEXTURE_WRAP_V_SHIFT;
        if t.nearest {
            flags |= TEXTURE_NEAREST;
        }
        if t.data {
            flags |= TEXTURE_DATA;
        }
        if t.texcoord == 1 {
            flags |= TEXTURE_UV1;
        }
        if matches!(*t.texels, Texels::Linear(_)) {
            flags |= TEXTURE_LINEAR_RGB;
        }
        let offset = *packed.entry(Arc::as_ptr(&t.texels)).or_insert_with(|| {
            let offset = texels.len() as u32;
            match &*t.texels {
                Texels::Rgba8(px) => texels.extend(px.iter().map(|p| u32::from_le_bytes(*p))),
                Texels::Linear(px) => texels.extend(px.iter().flat_map(|p| p.map(f32::to_bits))),
            }
            offset
        });
        let [a, b, c, d, e, f] = t.transform;
        infos.push(FlatTexture {
            width: t.width,
            height: t.height,
            offset,
            flags,
            linear: [a, b, d, e],
            offset_uv: [c, f],
            _pad: [0; 2],
        });
    }
    (infos, texels)
}

/// What every triangle of `prims` (scene order) carries from the mesh it came from (texture
/// coordinates, shading normals, colours); zeros and no flags for triangles without any.
pub fn triangle_attrs(scene: &Scene, prims: &Primitives<f32>) -> Vec<FlatTriangleAttrs> {
    prims
        .triangles
        .iter()
        .map(|t| match &scene.objects[t.tag.object as usize].geometry {
            Geometry::Mesh { attrs, .. } => {
                let f = t.tag.face as usize;
                let mut out = FlatTriangleAttrs::default();
                if let Some(uv) = attrs.uvs.get(f) {
                    out.uv = *uv;
                }
                if let Some(uv) = attrs.uvs1.get(f) {
                    out.second_uv = *uv;
                }
                if let Some(n) = attrs.normals.get(f) {
                    out.normal = n.map(encode_octahedral);
                    out.flags |= ATTR_NORMALS;
                }
                if let Some(c) = attrs.colors.get(f) {
                    out.color = c.map(encode_unorm8x4);
                    out.flags |= ATTR_COLORS;
                }
                out
            }
            _ => FlatTriangleAttrs::default(),
        })
        .collect()
}

/// A coordinate brought into [0, 1] by the wrap mode (exact: fract and the mirror's 2 − m are
/// exact in floating point).
#[inline]
fn wrap_coord(u: f32, mode: u32) -> f32 {
    if mode == Wrap::Clamp as u32 {
        u.clamp(0.0, 1.0)
    } else if mode == Wrap::Mirror as u32 {
        let m = u - 2.0 * (u * 0.5).floor();
        if m > 1.0 { 2.0 - m } else { m }
    } else {
        u - u.floor()
    }
}

/// A texel index one step outside [0, n) brought back by the wrap mode (mirror and clamp
/// agree there).
#[inline]
pub fn wrap_index(i: i32, n: i32, mode: u32) -> i32 {
    if mode == Wrap::Repeat as u32 {
        if i < 0 {
            i + n
        } else if i >= n {
            i - n
        } else {
            i
        }
    } else {
        i.clamp(0, n - 1)
    }
}

/// Texel (x, y) of texture `t`: linear RGB and alpha (1 for radiance maps).
#[inline(always)]
pub fn texel(texels: &[u32], t: &FlatTexture, x: i32, y: i32) -> [f32; 4] {
    let i = y as u32 * t.width + x as u32;
    if t.flags & TEXTURE_LINEAR_RGB != 0 {
        let k = (t.offset + 3 * i) as usize;
        return [f32::from_bits(texels[k]), f32::from_bits(texels[k + 1]), f32::from_bits(texels[k + 2]), 1.0];
    }
    let w = texels[(t.offset + i) as usize];
    let byte = |shift: u32| (w >> shift) & 255;
    let alpha = byte(24) as f32 / 255.0;
    if t.flags & TEXTURE_DATA != 0 {
        return [byte(0) as f32 / 255.0, byte(8) as f32 / 255.0, byte(16) as f32 / 255.0, alpha];
    }
    let code = |shift: u32| f32::from_bits(texels[byte(shift) as usize]);
    [code(0), code(8), code(16), alpha]
}

/// a·(1 − t) + b·t in each channel (on x86-64 the four channels in one register, which the
/// compiler does not do by itself in the lane tracer's loops; the same operations either way).
#[inline(always)]
pub fn lerp4(a: [f32; 4], b: [f32; 4], t: f32) -> [f32; 4] {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of x86-64; the loads and the store touch the four f32 of a, b and r.
    unsafe {
        use std::arch::x86_64::*;
        let (va, vb) = (_mm_loadu_ps(a.as_ptr()), _mm_loadu_ps(b.as_ptr()));
        let vt = _mm_set1_ps(t);
        let v = _mm_add_ps(_mm_mul_ps(va, _mm_sub_ps(_mm_set1_ps(1.0), vt)), _mm_mul_ps(vb, vt));
        let mut r = [0.0f32; 4];
        _mm_storeu_ps(r.as_mut_ptr(), v);
        r
    }
    #[cfg(not(target_arch = "x86_64"))]
    [0, 1, 2, 3].map(|k| a[k] * (1.0 - t) + b[k] * t)
}

/// Texture `t` at (u, v) (v = 0 is the image's top row; the use's transform is applied by the
/// caller, [`super::surface`]): bilinear between the four nearest texel centres, or the
/// nearest texel. RGB and alpha.
pub fn sample_rgba(texels: &[u32], t: &FlatTexture, u: f32, v: f32) -> [f32; 4] {
    let (w, h) = (t.width as i32, t.height as i32);
    let (wu, wv) = ((t.flags >> TEXTURE_WRAP_U_SHIFT) & 3, (t.flags >> TEXTURE_WRAP_V_SHIFT) & 3);
    let s = wrap_coord(u, wu) * t.width as f32 - 0.5;
    let r = wrap_coord(v, wv) * t.height as f32 - 0.5;
    if t.flags & TEXTURE_NEAREST != 0 {
        let x = ((s + 0.5).floor() as i32).clamp(0, w - 1);
        let y = ((r + 0.5).floor() as i32).clamp(0, h - 1);
        return texel(texels, t, x, y);
    }
    let (x0, y0) = (s.floor(), r.floor());
    let (fx, fy) = (s - x0, r - y0);
    let (xa, ya) = (x0 as i32, y0 as i32);
    let (xa, xb) = (wrap_index(xa, w, wu), wrap_index(xa + 1, w, wu));
    let (ya, yb) = (wrap_index(ya, h, wv), wrap_index(ya + 1, h, wv));
    let top = lerp4(texel(texels, t, xa, ya), texel(texels, t, xb, ya), fx);
    let bottom = lerp4(texel(texels, t, xa, yb), texel(texels, t, xb, yb), fx);
    lerp4(top, bottom, fy)
}

/// [`sample_rgba`] without alpha.
pub fn sample(texels: &[u32], t: &FlatTexture, u: f32, v: f32) -> V3<f32> {
    let [r, g, b, _] = sample_rgba(texels, t, u, v);
    V3::new(r, g, b)
}

/// Barycentric weights (of b and c) of point `p` in triangle (a, b, c), from the normal
/// equations of p − a = β(b − a) + γ(c − a) (Ericson, *Real-Time Collision Detection* 3.4);
/// (0, 0) for a degenerate triangle. p is a hit point, on the triangle up to rounding, so the
/// weights are within a few ULPs of the exact ones relative to the triangle's size.
#[inline]
pub fn barycentrics(a: V3<f32>, b: V3<f32>, c: V3<f32>, p: V3<f32>) -> (f32, f32) {
    let (e1, e2, q) = (b - a, c - a, p - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (dq1, dq2) = (q.dot(e1), q.dot(e2));
    let den = d11 * d22 - d12 * d12;
    if !(den > 0.0) {
        return (0.0, 0.0);
    }
    ((d22 * dq1 - d12 * dq2) / den, (d11 * dq2 - d12 * dq1) / den)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tex(w: u32, h: u32, px: Vec<[u8; 3]>, wrap: Wrap, nearest: bool) -> (Vec<FlatTexture>, Vec<u32>) {
        let px = px.into_iter().map(|[r, g, b]| [r, g, b, 255]).collect();
        let t = Texture { wrap: [wrap; 2], nearest, ..Texture::new("t", w, h, Texels::Rgba8(px)) };
        pack(std::iter::once(&t))
    }

    /// Two uses of one image share its texels; a data use reads codes as code / 255, alpha is
    /// linear in both.
    #[test]
    fn uses_of_one_image_share_texels_and_read_data_linearly() {
        let colour = Texture { nearest: true, ..Texture::new("t", 1, 1, Texels::Rgba8(vec![[128, 64, 255, 51]])) };
        let data = Texture { data: true, texcoord: 1, ..colour.clone() };
        let (t, px) = pack([&colour, &data].into_iter());
        assert_eq!(t[0].offset, t[1].offset);
        assert_eq!(px.len(), SRGB_TABLE_WORDS as usize + 1);
        assert_eq!(sample_rgba(&px, &t[0], 0.5, 0.5), [srgb_to_linear(128), srgb_to_linear(64), 1.0, 0.2]);
        assert_eq!(sample_rgba(&px, &t[1], 0.5, 0.5), [128.0 / 255.0, 64.0 / 255.0, 1.0, 0.2]);
        assert_ne!(t[1].flags & TEXTURE_UV1, 0);
    }

    #[test]
    fn texel_centres_return_their_texels_and_midpoints_average() {
        // 2 × 1: black, white (255 decodes to exactly 1).
        let (t, px) = tex(2, 1, vec![[0, 0, 0], [255, 255, 255]], Wrap::Clamp, false);
        assert_eq!(sample(&px, &t[0], 0.25, 0.5), V3::splat(0.0));
        assert_eq!(sample(&px, &t[0], 0.75, 0.5), V3::splat(1.0));
        assert_eq!(sample(&px, &t[0], 0.5, 0.5), V3::splat(0.5));
        // Clamp holds the edge texels beyond the centres.
        assert_eq!(sample(&px, &t[0], -3.0, 0.5), V3::splat(0.0));
        assert_eq!(sample(&px, &t[0], 0.99, 0.5), V3::splat(1.0));
        // Repeat: u = 0 is half way between the last and the first texel.
        let (t, px) = tex(2, 1, vec![[0, 0, 0], [255, 255, 255]], Wrap::Repeat, false);
        assert_eq!(sample(&px, &t[0], 0.0, 0.5), V3::splat(0.5));
        assert_eq!(sample(&px, &t[0], 3.25, 0.5), V3::splat(0.0));
        assert_eq!(sample(&px, &t[0], -0.25, 0.5), V3::splat(1.0));
        // Mirror: [1, 2] runs backwards, so u = 1.25 reads what u = 0.75 reads.
        let (t, px) = tex(2, 1, vec![[0, 0, 0], [255, 255, 255]], Wrap::Mirror, false);
        assert_eq!(sample(&px, &t[0], 1.25, 0.5), V3::splat(1.0));
        assert_eq!(sample(&px, &t[0], 1.75, 0.5), V3::splat(0.0));
        assert_eq!(sample(&px, &t[0], -0.25, 0.5), V3::splat(0.0));
        // Nearest: no blending.
        let (t, px) = tex(2, 1, vec![[0, 0, 0], [255, 255, 255]], Wrap::Clamp, true);
        assert_eq!(sample(&px, &t[0], 0.49, 0.5), V3::splat(0.0));
        assert_eq!(sample(&px, &t[0], 0.51, 0.5), V3::splat(1.0));
    }

    #[test]
    fn rows_run_top_down_and_channels_keep_their_order() {
        // 1 × 2: top red, bottom blue; sRGB 128 → 0.2158605 linear.
        let (t, px) = tex(1, 2, vec![[128, 0, 0], [0, 0, 255]], Wrap::Clamp, true);
        let top = sample(&px, &t[0], 0.5, 0.1);
        assert_eq!(top, V3::new(srgb_to_linear(128), 0.0, 0.0));
        assert!((top.x - 0.2158605).abs() < 1e-6);
        assert_eq!(sample(&px, &t[0], 0.5, 0.9), V3::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn barycentrics_recover_the_weights() {
        let (a, b, c) = (V3::new(1.0f32, 0.0, 2.0), V3::new(3.0, 1.0, 2.0), V3::new(0.0, 4.0, 2.5));
        for (beta, gamma) in [(0.0f32, 0.0f32), (1.0, 0.0), (0.0, 1.0), (0.25, 0.5), (0.1, 0.85)] {
            let p = a * (1.0 - beta - gamma) + b * beta + c * gamma;
            let (x, y) = barycentrics(a, b, c, p);
            assert!((x - beta).abs() < 1e-5 && (y - gamma).abs() < 1e-5, "{beta} {gamma}: {x} {y}");
        }
        assert_eq!(barycentrics(a, a, a, a), (0.0, 0.0));
    }
}
