//! What rays see where they hit triangles with attributes, in lanes: the barycentric weights,
//! image texture lookups (bilinear, glTF's wrap modes) and interpolated vertex normals of
//! [`strahl_core::render::surface::surface`], by its operations in its order, so each lane computes
//! what the scalar routine computes, bit for bit. Texels are fetched lane after lane (from
//! their decoded copies where there are, [`super::texels`]) and each lane's four channels
//! interpolated together; the other arithmetic runs over the lanes.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::texels::Texels;
use strahl_core::layout::{
    ATTR_NORMALS, FlatScene, FlatTexture, TEXTURE_UV1, TEXTURE_WRAP_U_SHIFT, TEXTURE_WRAP_V_SHIFT,
};
use strahl_core::math::lanes::{F, M, U, V, clamp01};
use strahl_core::render::texture::{lerp4, texel, wrap_index};
use strahl_core::scene::texture::Wrap;

/// [`strahl_core::render::texture::barycentrics`]: the weights of b and c at `p` in triangles
/// (a, b, c), (0, 0) where a triangle is degenerate.
#[inline(always)]
pub(super) fn barycentrics<const N: usize>(a: V<N>, b: V<N>, c: V<N>, p: V<N>) -> (F<N>, F<N>) {
    let (e1, e2, q) = (b - a, c - a, p - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (dq1, dq2) = (q.dot(e1), q.dot(e2));
    let den = d11 * d22 - d12 * d12;
    let ok = den.gt(F::splat(0.0));
    let zero = F::splat(0.0);
    (ok.select((d22 * dq1 - d12 * dq2) / den, zero), ok.select((d11 * dq2 - d12 * dq1) / den, zero))
}

/// `texture::wrap_coord` for each lane's mode.
#[inline(always)]
fn wrap_coord<const N: usize>(u: F<N>, mode: U<N>) -> F<N> {
    let clamp = clamp01(u);
    let m = u - F::splat(2.0) * (u * F::splat(0.5)).map(f32::floor);
    let mirror = m.gt(F::splat(1.0)).select(F::splat(2.0) - m, m);
    let repeat = u - u.map(f32::floor);
    let is = |w: Wrap| mode.eq(U::splat(w as u32));
    is(Wrap::Clamp).select(clamp, is(Wrap::Mirror).select(mirror, repeat))
}

/// `surface::texture_at` in lanes `on`: texture `texture[l]` (1 + index into the scene's
/// table, 0: none, which reads 1; none with nearest filtering) of triangle `tri[l]` at weights
/// `w`, RGB and alpha.
#[inline(always)]
pub(super) fn texture<const N: usize>(
    g: &FlatScene,
    texels: &Texels,
    on: [bool; N],
    texture: [u32; N],
    tri: [u32; N],
    w: [F<N>; 3],
) -> [F<N>; 4] {
    let (mut uv, mut lin, mut off) = ([[[0.0f32; N]; 2]; 3], [[0.0f32; N]; 4], [[0.0f32; N]; 2]);
    let mut index = [None; N];
    for l in 0..N {
        if !on[l] || texture[l] == 0 {
            continue;
        }
        index[l] = Some(texture[l] - 1);
        let t = &g.textures[texture[l] as usize - 1];
        let a = &g.triangle_attrs[tri[l] as usize];
        let set = if t.flags & TEXTURE_UV1 != 0 { &a.second_uv } else { &a.uv };
        for (j, c) in set.iter().enumerate() {
            (uv[j][0][l], uv[j][1][l]) = (c[0], c[1]);
        }
        for k in 0..4 {
            lin[k][l] = t.linear[k];
        }
        (off[0][l], off[1][l]) = (t.offset_uv[0], t.offset_uv[1]);
    }
    if index.iter().all(Option::is_none) {
        return [F::splat(1.0); 4];
    }
    // lerp_uv, then the use's transform. (Written out: the compiler left a closure for it out
    // of line, in code without the ISA's instructions.)
    let u0 = F(uv[0][0]) * w[0] + F(uv[1][0]) * w[1] + F(uv[2][0]) * w[2];
    let v0 = F(uv[0][1]) * w[0] + F(uv[1][1]) * w[1] + F(uv[2][1]) * w[2];
    let u = F(lin[0]) * u0 + F(lin[1]) * v0 + F(off[0]);
    let v = F(lin[2]) * u0 + F(lin[3]) * v0 + F(off[1]);
    sample_rgba(g, texels, index, u, v)
}

/// [`strahl_core::render::texture::sample_rgba`], bilinear, in the lanes with a texture
/// (`texture[l]`: its index in the scene's table) at (u, v); 1 in the others. The texel
/// coordinates and weights are computed in lanes; then each lane reads its four texels (from
/// the decoded copy, [`Texels`], where there is one) and interpolates their four channels at
/// once, by [`lerp4`]'s operations.
#[inline(always)]
pub(super) fn sample_rgba<const N: usize>(
    g: &FlatScene,
    texels: &Texels,
    texture: [Option<u32>; N],
    u: F<N>,
    v: F<N>,
) -> [F<N>; 4] {
    // Where every lane with a texture reads one (an environment map, or a bundle's rays on one
    // surface), its copy: the texel indices are then computed in lanes too.
    // (1 + the index, 0 for none: the largest is the one texture where there is one.)
    let mut code = [0u32; N];
    for l in 0..N {
        code[l] = texture[l].map_or(0, |i| i.wrapping_add(1));
    }
    let top = code.iter().fold(0, |a, &c| a.max(c));
    let mut others = 0;
    for l in 0..N {
        others |= (code[l] != 0 && code[l] != top) as u32;
    }
    if let (0, Some(rgba)) = (others, texels.get(top.wrapping_sub(1) as usize)) {
        let mut has = [false; N];
        for l in 0..N {
            has[l] = code[l] != 0;
        }
        return sample_one(&g.textures[top as usize - 1], rgba, M::from_bools(&has), u, v);
    }
    let (mut size, mut wraps) = ([[0.0f32; N]; 2], [[0u32; N]; 2]);
    for l in 0..N {
        let Some(i) = texture[l] else { continue };
        let t = &g.textures[i as usize];
        (size[0][l], size[1][l]) = (t.width as f32, t.height as f32);
        wraps[0][l] = (t.flags >> TEXTURE_WRAP_U_SHIFT) & 3;
        wraps[1][l] = (t.flags >> TEXTURE_WRAP_V_SHIFT) & 3;
    }
    let s = wrap_coord(u, U(wraps[0])) * F(size[0]) - F::splat(0.5);
    let r = wrap_coord(v, U(wraps[1])) * F(size[1]) - F::splat(0.5);
    let (x0, y0) = (s.map(f32::floor), r.map(f32::floor));
    let (fx, fy) = (s - x0, r - y0);
    let mut out = [[1.0f32; N]; 4];
    for l in 0..N {
        let Some(i) = texture[l] else { continue };
        let t = &g.textures[i as usize];
        let (w, h) = (t.width as i32, t.height as i32);
        let (xa, ya) = (x0.0[l] as i32, y0.0[l] as i32);
        let (xa, xb) = (wrap_index(xa, w, wraps[0][l]), wrap_index(xa + 1, w, wraps[0][l]));
        let (ya, yb) = (wrap_index(ya, h, wraps[1][l]), wrap_index(ya + 1, h, wraps[1][l]));
        let px = match texels.get(i as usize) {
            Some(rgba) => {
                let at = |x: i32, y: i32| rgba[(y as u32 * t.width + x as u32) as usize];
                [at(xa, ya), at(xb, ya), at(xa, yb), at(xb, yb)]
            }
            None => [(xa, ya), (xb, ya), (xa, yb), (xb, yb)].map(|(x, y)| texel(&g.texels, t, x, y)),
        };
        let c = lerp4(lerp4(px[0], px[1], fx.0[l]), lerp4(px[2], px[3], fx.0[l]), fy.0[l]);
        for k in 0..4 {
            out[k][l] = c[k];
        }
    }
    out.map(F)
}

/// [`sample_rgba`] in the lanes `on`, which all read texture `t`, whose decoded copy is
/// `rgba`, by the same operations; 1 in the others.
#[inline(always)]
pub(super) fn sample_one<const N: usize>(t: &FlatTexture, rgba: &[[f32; 4]], on: M<N>, u: F<N>, v: F<N>) -> [F<N>; 4] {
    let (wu, wv) = ((t.flags >> TEXTURE_WRAP_U_SHIFT) & 3, (t.flags >> TEXTURE_WRAP_V_SHIFT) & 3);
    let s = wrap_coord(u, U::splat(wu)) * F::splat(t.width as f32) - F::splat(0.5);
    let r = wrap_coord(v, U::splat(wv)) * F::splat(t.height as f32) - F::splat(0.5);
    let (x0, y0) = (s.map(f32::floor), r.map(f32::floor));
    let (fx, fy) = (s - x0, r - y0);
    let (w, h) = (t.width as i32, t.height as i32);
    let mut at = [[0u32; N]; 4];
    for l in 0..N {
        let (xa, ya) = (x0.0[l] as i32, y0.0[l] as i32);
        let (xa, xb) = (wrap_index(xa, w, wu), wrap_index(xa + 1, w, wu));
        let (ya, yb) = (wrap_index(ya, h, wv), wrap_index(ya + 1, h, wv));
        let (xa, xb, ya, yb) = (xa as u32, xb as u32, ya as u32 * t.width, yb as u32 * t.width);
        (at[0][l], at[1][l], at[2][l], at[3][l]) = (ya + xa, ya + xb, yb + xa, yb + xb);
    }
    // Every lane reads (the others' indices are in range too, whatever their coordinates);
    // the lanes off take 1 after.
    let mut out = [[1.0f32; N]; 4];
    for l in 0..N {
        let px = |j: usize| rgba[at[j][l] as usize];
        let c = lerp4(lerp4(px(0), px(1), fx.0[l]), lerp4(px(2), px(3), fx.0[l]), fy.0[l]);
        for k in 0..4 {
            out[k][l] = c[k];
        }
    }
    let one = F::splat(1.0);
    [on.select(F(out[0]), one), on.select(F(out[1]), one), on.select(F(out[2]), one), on.select(F(out[3]), one)]
}

/// The shading normals of `surface::surface` from the vertex normals, in lanes `on` whose
/// triangle `tri[l]` has them, at weights `w`; `n` (the face normal) elsewhere. The normals'
/// codes are read lane after lane and decoded in lanes.
#[inline(always)]
pub(super) fn normals<const N: usize>(g: &FlatScene, on: [bool; N], tri: [u32; N], w: [F<N>; 3], n: V<N>) -> V<N> {
    let mut code = [[0u32; N]; 3];
    let mut smooth = [false; N];
    for l in 0..N {
        if !on[l] {
            continue;
        }
        let a = &g.triangle_attrs[tri[l] as usize];
        if a.flags & ATTR_NORMALS == 0 {
            continue;
        }
        smooth[l] = true;
        for j in 0..3 {
            code[j][l] = a.normal[j];
        }
    }
    let (v0, v1, v2) = (decode_octahedral(U(code[0])), decode_octahedral(U(code[1])), decode_octahedral(U(code[2])));
    let v = (v0.scale(w[0]) + v1.scale(w[1]) + v2.scale(w[2])).normalize();
    let one = F::splat(1.0);
    let unit = v.x.abs().le(one) & v.y.abs().le(one) & v.z.abs().le(one);
    let flipped = v.dot(n).lt(F::splat(0.0)).select_v(-v, v);
    (M::from_bools(&smooth) & unit).select_v(flipped, n)
}

/// [`strahl_core::render::surface::decode_octahedral`] in every lane, by its operations.
#[inline(always)]
fn decode_octahedral<const N: usize>(w: U<N>) -> V<N> {
    let snorm = |h: U<N>| {
        let mut r = [0.0f32; N];
        for l in 0..N {
            r[l] = (h.0[l] as u16 as i16) as f32;
        }
        (F(r) / F::splat(32767.0)).max(F::splat(-1.0))
    };
    let (x, y) = (snorm(w), snorm(w >> U::splat(16)));
    let zero = F::splat(0.0);
    let z = F::splat(1.0) - x.abs() - y.abs();
    let t = (-z).max(zero);
    let sx = x.ge(zero).select(-t, t);
    let sy = y.ge(zero).select(-t, t);
    V::new(x + sx, y + sy, z)
}

#[cfg(test)]
mod tests {
    use super::super::texels;
    use super::*;
    use strahl_core::render::sampler::Sampler;
    use strahl_core::render::{surface, texture};
    use strahl_core::scene::texture::{Texels as Image, Texture};

    /// Four textures of every kind of texel and wrap mode: sRGB colour, data, linear RGB,
    /// and a single texel.
    fn textures() -> FlatScene {
        let mut rng = Sampler::new(3, 4, 5);
        let mut code = || (rng.next_f32() * 256.0) as u8;
        let rgba = |n: usize, code: &mut dyn FnMut() -> u8| (0..n).map(|_| [code(), code(), code(), code()]).collect();
        let colour = Texture {
            wrap: [Wrap::Repeat, Wrap::Mirror],
            ..Texture::new("colour", 5, 3, Image::Rgba8(rgba(15, &mut code)))
        };
        let data = Texture {
            wrap: [Wrap::Clamp, Wrap::Repeat],
            data: true,
            ..Texture::new("data", 4, 4, Image::Rgba8(rgba(16, &mut code)))
        };
        let linear = (0..6).map(|i| [i as f32 * 0.7, 1.0 / (i + 1) as f32, 100.0 - i as f32]).collect();
        let linear =
            Texture { wrap: [Wrap::Mirror, Wrap::Clamp], ..Texture::new("linear", 3, 2, Image::Linear(linear)) };
        let single = Texture::new("one", 1, 1, Image::Rgba8(vec![[200, 10, 99, 7]]));
        let mut g = FlatScene::default();
        (g.textures, g.texels) = texture::pack([colour, data, linear, single].iter());
        g
    }

    /// The lanes' bilinear lookups equal `texture::sample_rgba`'s bit for bit: every kind of
    /// texel and wrap, coordinates inside, outside, on texel centres and edges, infinite and
    /// NaN; lanes reading one texture (through its indices in lanes) and several, some none;
    /// from the decoded copies, from the packed texels, and from a mix of both.
    #[test]
    fn lanes_sample_textures_as_the_scalar_routine() {
        const N: usize = 16;
        let g = textures();
        let all = Texels::new(&g, 0..4, texels::BUDGET);
        // 15 + 16 texels fit, the linear map's 6 do not, the single texel does.
        let some = Texels::new(&g, 0..4, 15 + 16 + 1);
        assert!(some.get(0).is_some() && some.get(1).is_some() && some.get(2).is_none() && some.get(3).is_some());
        let none = Texels::default();
        let mut rng = Sampler::new(6, 7, 8);
        let special = [0.0, 1.0, -1.0, 0.5, 0.1, 1.0 / 3.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.0, 1e30];
        for round in 0..3000 {
            let mut coord = || match rng.next_f32() {
                x if x < 0.2 => special[(rng.next_f32() * special.len() as f32) as usize % special.len()],
                _ => rng.next_f32() * 6.0 - 3.0,
            };
            let (u, v): ([f32; N], [f32; N]) = (std::array::from_fn(|_| coord()), std::array::from_fn(|_| coord()));
            let one = (round / 3 % 5) as u32;
            let texture: [Option<u32>; N] = std::array::from_fn(|l| match round / 3 % 3 {
                // One texture (or none, one = 4) in most lanes.
                0 => (l % 7 != 3 && one < 4).then_some(one),
                1 => (one < 4).then_some(one),
                // Several.
                _ => Some((l as u32 + round as u32) % 5).filter(|&i| i < 4),
            });
            let copies = [&all, &some, &none][round % 3];
            let got = sample_rgba(&g, copies, texture, F(u), F(v));
            for l in 0..N {
                let want = texture[l]
                    .map_or([1.0; 4], |i| texture::sample_rgba(&g.texels, &g.textures[i as usize], u[l], v[l]));
                let got = [got[0].0[l], got[1].0[l], got[2].0[l], got[3].0[l]];
                // (Any NaN as one: IEEE leaves a NaN's sign and payload to the implementation,
                // and the compiler may swap a product's operands.)
                let bits = |c: [f32; 4]| c.map(|x| if x.is_nan() { f32::NAN.to_bits() } else { x.to_bits() });
                assert_eq!(bits(got), bits(want), "texture {:?} at ({}, {})", texture[l], u[l], v[l]);
            }
        }
    }

    /// A decoded copy holds what `texture::texel` reads, texel for texel; a table past the
    /// scene's and a repeated number are passed over.
    #[test]
    fn copies_hold_the_texels() {
        let g = textures();
        let copies = Texels::new(&g, [2, 0, 2, 9, 1, 3], texels::BUDGET);
        for (i, t) in g.textures.iter().enumerate() {
            let copy = copies.get(i).expect("a copy");
            assert_eq!(copy.len(), (t.width * t.height) as usize);
            for y in 0..t.height as i32 {
                for x in 0..t.width as i32 {
                    let want = texture::texel(&g.texels, t, x, y);
                    assert_eq!(
                        copy[(y as u32 * t.width + x as u32) as usize].map(f32::to_bits),
                        want.map(f32::to_bits)
                    );
                }
            }
        }
        assert!(copies.get(9).is_none());
    }

    /// The lanes decode every normal code as the scalar routine does, bit for bit: random
    /// codes, and halves at the ends of the range (−32768 clamps to −1) and at zero.
    #[test]
    fn lanes_decode_normals_as_the_scalar_routine() {
        const N: usize = 16;
        let mut rng = Sampler::new(8, 9, 10);
        let ends = [0u32, 1, 0x7fff, 0x8000, 0x8001, 0xffff];
        let mut codes: Vec<u32> = ends.iter().flat_map(|&a| ends.iter().map(move |&b| a | b << 16)).collect();
        codes
            .extend((0..20_000).map(|_| (rng.next_f32() * 65536.0) as u32 | ((rng.next_f32() * 65536.0) as u32) << 16));
        for chunk in codes.chunks(N) {
            let mut c = [0u32; N];
            c[..chunk.len()].copy_from_slice(chunk);
            let got = decode_octahedral(U(c)).rows();
            for (l, &code) in c.iter().enumerate() {
                let want = surface::decode_octahedral(code).to_array().map(f32::to_bits);
                assert_eq!([got[0][l], got[1][l], got[2][l]].map(f32::to_bits), want, "code {code:#x}");
            }
        }
    }
}
