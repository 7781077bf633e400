// Image textures: twin of crates/core/src/render/texture.rs (bilinear lookups with glTF's wrap modes on
// the packed texels, the same f32 operations).
//
// Shader def: TEXELS (textures and texels bound: TEXTURES or ENV_MAP).
#define_import_path strahl::texture

#ifdef TEXELS
#import strahl::types::{TextureInfo, TEXTURE_WRAP_U_SHIFT, TEXTURE_WRAP_V_SHIFT, TEXTURE_NEAREST, TEXTURE_LINEAR_RGB, TEXTURE_DATA, WRAP_REPEAT, WRAP_CLAMP, WRAP_MIRROR}
#import strahl::bindings::{load_texture, texels}

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

// Texel (x, y) of t, linear RGB and alpha: 8-bit colour codes read through the sRGB table at
// the buffer's start, data codes as code / 255, alpha linear.
fn texel(t: TextureInfo, x: i32, y: i32) -> vec4<f32> {
    let i = u32(y) * t.width + u32(x);
    if (t.flags & TEXTURE_LINEAR_RGB) != 0u {
        let k = t.offset + 3u * i;
        return vec4<f32>(bitcast<f32>(texels[k]), bitcast<f32>(texels[k + 1u]), bitcast<f32>(texels[k + 2u]), 1.0);
    }
    let w = texels[t.offset + i];
    let alpha = f32(w >> 24u) / 255.0;
    if (t.flags & TEXTURE_DATA) != 0u {
        return vec4<f32>(f32(w & 255u) / 255.0, f32((w >> 8u) & 255u) / 255.0, f32((w >> 16u) & 255u) / 255.0, alpha);
    }
    return vec4<f32>(bitcast<f32>(texels[w & 255u]), bitcast<f32>(texels[(w >> 8u) & 255u]), bitcast<f32>(texels[(w >> 16u) & 255u]), alpha);
}

// t at (u, v), v = 0 the top row: bilinear between the four nearest texel centres, or the
// nearest texel (RGB and alpha).
fn texture_sample(t: TextureInfo, uv: vec2<f32>) -> vec4<f32> {
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

#endif
