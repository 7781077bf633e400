//! What rays see where they hit triangles with attributes, in lanes: the barycentric weights,
//! image texture lookups (bilinear, glTF's wrap modes) and interpolated vertex normals of
//! [`crate::render::surface::surface`], by its operations in its order, so each lane computes
//! what the scalar routine computes, bit for bit. Texels are fetched lane after lane; the
//! arithmetic runs over the lanes.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::lane::{F, M, U, V};
use super::pbr::clamp01;
use crate::layout::{ATTR_NORMALS, FlatScene, TEXTURE_UV1, TEXTURE_WRAP_U_SHIFT, TEXTURE_WRAP_V_SHIFT};
use crate::render::texture::{texel, wrap_index};
use crate::scene::texture::Wrap;

/// [`crate::render::texture::barycentrics`]: the weights of b and c at `p` in triangles
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
    // lerp_uv, then the use's transform.
    let at = |k: usize| F(uv[0][k]) * w[0] + F(uv[1][k]) * w[1] + F(uv[2][k]) * w[2];
    let (u0, v0) = (at(0), at(1));
    let u = F(lin[0]) * u0 + F(lin[1]) * v0 + F(off[0]);
    let v = F(lin[2]) * u0 + F(lin[3]) * v0 + F(off[1]);
    sample_rgba(g, index, u, v)
}

/// [`crate::render::texture::sample_rgba`], bilinear, in the lanes with a texture
/// (`texture[l]`: its index in the scene's table) at (u, v); 1 in the others.
#[inline(always)]
pub(super) fn sample_rgba<const N: usize>(g: &FlatScene, texture: [Option<u32>; N], u: F<N>, v: F<N>) -> [F<N>; 4] {
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
    // Lane after lane: the four texels.
    let mut px = [[[0.0f32; N]; 4]; 4];
    for l in 0..N {
        let Some(i) = texture[l] else { continue };
        let t = &g.textures[i as usize];
        let (w, h) = (t.width as i32, t.height as i32);
        let (xa, ya) = (x0.0[l] as i32, y0.0[l] as i32);
        let (xa, xb) = (wrap_index(xa, w, wraps[0][l]), wrap_index(xa + 1, w, wraps[0][l]));
        let (ya, yb) = (wrap_index(ya, h, wraps[1][l]), wrap_index(ya + 1, h, wraps[1][l]));
        for (j, (x, y)) in [(xa, ya), (xb, ya), (xa, yb), (xb, yb)].into_iter().enumerate() {
            let c = texel(&g.texels, t, x, y);
            for k in 0..4 {
                px[j][k][l] = c[k];
            }
        }
    }
    let one = F::splat(1.0);
    let lerp = |a: F<N>, b: F<N>, t: F<N>| a * (one - t) + b * t;
    let mut has = [false; N];
    for l in 0..N {
        has[l] = texture[l].is_some();
    }
    let has = M::from_bools(&has);
    let mut out = [one; 4];
    for (k, c) in out.iter_mut().enumerate() {
        let top = lerp(F(px[0][k]), F(px[1][k]), fx);
        let bottom = lerp(F(px[2][k]), F(px[3][k]), fx);
        *c = has.select(lerp(top, bottom, fy), one);
    }
    out
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
    let vert = |j: usize| decode_octahedral(U(code[j]));
    let v = (vert(0).scale(w[0]) + vert(1).scale(w[1]) + vert(2).scale(w[2])).normalize();
    let one = F::splat(1.0);
    let unit = v.x.abs().le(one) & v.y.abs().le(one) & v.z.abs().le(one);
    let flipped = v.dot(n).lt(F::splat(0.0)).select_v(-v, v);
    (M::from_bools(&smooth) & unit).select_v(flipped, n)
}

/// [`crate::render::surface::decode_octahedral`] in every lane, by its operations.
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
    use super::*;
    use crate::render::sampler::Sampler;
    use crate::render::surface;

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
