// Image textures: twin of src/render/texture.rs (texture coordinates at a triangle hit,
// bilinear lookups with glTF's wrap modes on the packed texels, the same f32 operations).
//
// Shader defs: TEXELS (textures and texels bound: TEXTURES or ENV_MAP), TEXTURES (materials
// have textures: per-triangle texture coordinates bound).
#define_import_path strahl::texture

#ifdef TEXELS
#import strahl::types::{TextureInfo, TEXTURE_WRAP_U_SHIFT, TEXTURE_WRAP_V_SHIFT, TEXTURE_NEAREST, TEXTURE_LINEAR_RGB, WRAP_REPEAT, WRAP_CLAMP, WRAP_MIRROR}
#import strahl::bindings::{textures, texels}
#ifdef TEXTURES
#import strahl::types::{Material, KIND_TRIANGLE, INDEX_BITS, INDEX_MASK}
#import strahl::bindings::triangle_uvs
#ifdef TRIANGLES
#import strahl::bindings::triangles
#if TRIANGLE_PARTS > 1
#import strahl::traverse::scene_triangle
#endif
#endif
#endif

// A coordinate brought into [0, 1] by the wrap mode.
fn wrap_coord(u: f32, mode: u32) -> f32 {
    if mode == WRAP_CLAMP {
        return clamp(u, 0.0, 1.0);
    }
    if mode == WRAP_MIRROR {
        let m = u - 2.0 * floor(u * 0.5);
        return select(m, 2.0 - m, m > 1.0);
    }
    return u - floor(u);
}

// A texel index one step outside [0, n) brought back by the wrap mode.
fn wrap_index(i: i32, n: i32, mode: u32) -> i32 {
    if mode == WRAP_REPEAT {
        if i < 0 {
            return i + n;
        }
        if i >= n {
            return i - n;
        }
        return i;
    }
    return clamp(i, 0, n - 1);
}

// Texel (x, y) of t, linear: 8-bit sRGB codes read through the table at the buffer's start.
fn texel(t: TextureInfo, x: i32, y: i32) -> vec3<f32> {
    let i = u32(y) * t.width + u32(x);
    if (t.flags & TEXTURE_LINEAR_RGB) != 0u {
        let k = t.offset + 3u * i;
        return vec3<f32>(bitcast<f32>(texels[k]), bitcast<f32>(texels[k + 1u]), bitcast<f32>(texels[k + 2u]));
    }
    let w = texels[t.offset + i];
    return vec3<f32>(bitcast<f32>(texels[w & 255u]), bitcast<f32>(texels[(w >> 8u) & 255u]), bitcast<f32>(texels[(w >> 16u) & 255u]));
}

// t at (u, v), v = 0 the top row: bilinear between the four nearest texel centres, or the
// nearest texel.
fn texture_sample(t: TextureInfo, uv: vec2<f32>) -> vec3<f32> {
    let w = i32(t.width);
    let h = i32(t.height);
    let wu = (t.flags >> TEXTURE_WRAP_U_SHIFT) & 3u;
    let wv = (t.flags >> TEXTURE_WRAP_V_SHIFT) & 3u;
    let s = wrap_coord(uv.x, wu) * f32(t.width) - 0.5;
    let r = wrap_coord(uv.y, wv) * f32(t.height) - 0.5;
    if (t.flags & TEXTURE_NEAREST) != 0u {
        let x = clamp(i32(floor(s + 0.5)), 0, w - 1);
        let y = clamp(i32(floor(r + 0.5)), 0, h - 1);
        return texel(t, x, y);
    }
    let x0 = floor(s);
    let y0 = floor(r);
    let fx = s - x0;
    let fy = r - y0;
    let xa = wrap_index(i32(x0), w, wu);
    let xb = wrap_index(i32(x0) + 1, w, wu);
    let ya = wrap_index(i32(y0), h, wv);
    let yb = wrap_index(i32(y0) + 1, h, wv);
    let top = texel(t, xa, ya) * (1.0 - fx) + texel(t, xb, ya) * fx;
    let bottom = texel(t, xa, yb) * (1.0 - fx) + texel(t, xb, yb) * fx;
    return top * (1.0 - fy) + bottom * fy;
}

#ifdef TEXTURES
// Barycentric weights (of b and c) of p in triangle (a, b, c) (render::texture::barycentrics).
fn barycentrics(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, p: vec3<f32>) -> vec2<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let q = p - a;
    let d11 = dot(e1, e1);
    let d12 = dot(e1, e2);
    let d22 = dot(e2, e2);
    let dq1 = dot(q, e1);
    let dq2 = dot(q, e2);
    let den = d11 * d22 - d12 * d12;
    if !(den > 0.0) {
        return vec2<f32>(0.0);
    }
    return vec2<f32>((d22 * dq1 - d12 * dq2) / den, (d11 * dq2 - d12 * dq1) / den);
}

// Texture `texture` (1 + index; 0: none) at barycentric weights bc of scene triangle tri, else 1.
fn factor_at(texture: u32, tri: u32, bc: vec2<f32>) -> vec3<f32> {
    if texture == 0u {
        return vec3<f32>(1.0);
    }
    let t = triangle_uvs[tri];
    let alpha = 1.0 - bc.x - bc.y;
    let uv = vec2<f32>(t.a.x * alpha + t.b.x * bc.x + t.c.x * bc.y, t.a.y * alpha + t.b.y * bc.x + t.c.y * bc.y);
    return texture_sample(textures[texture - 1u], uv);
}

// Material m as seen at hit point p on primitive prim: colour and radiance times its textures
// there (triangles only).
fn textured(m: Material, prim: u32, p: vec3<f32>) -> Material {
    var out = m;
#ifdef TRIANGLES
    if (m.color_texture != 0u || m.radiance_texture != 0u) && (prim >> INDEX_BITS) == KIND_TRIANGLE {
        let i = prim & INDEX_MASK;
#if TRIANGLE_PARTS > 1
        let t = scene_triangle(i);
#else
        let t = triangles[i];
#endif
        let bc = barycentrics(t.va, t.vb, t.vc, p);
        out.color = m.color * factor_at(m.color_texture, i, bc);
        out.radiance = m.radiance * factor_at(m.radiance_texture, i, bc);
    }
#endif
    return out;
}
#endif
#endif
