// What a ray sees where it hits a triangle: twin of crates/core/src/render/surface.rs (in lanes crates/cpu/src/lanes/surface.rs; the material with
// its textures and vertex colours applied, the shading normal from vertex normals and the
// normal map, the shading frame the integrators use).
//
// Shader defs: TEXTURES (per-triangle attributes bound: a material has a texture or a mesh
// has normals or colours).
#define_import_path strahl::surface

#import strahl::types::{Material, MAT_DIELECTRIC, MAT_MIRROR, MAT_PBR, MATERIAL_ALPHA_MASK, MATERIAL_ALPHA_BLEND}
#ifdef TEXTURES
#import strahl::types::{TextureInfo, KIND_TRIANGLE, INDEX_BITS, INDEX_MASK, ATTR_NORMALS, ATTR_COLORS, TEXTURE_UV1, MATERIAL_UNLIT}
#import strahl::bindings::{triangle_attrs, load_texture}
#import strahl::texture::texture_sample
#ifdef TRIANGLES
#import strahl::traverse::scene_triangle
#endif
#endif

struct Surface {
    m: Material,
    // Unit shading normal, on the side of the geometric normal given.
    normal: vec3<f32>,
    // The material's alpha times its colour texture's and the vertex colours'.
    alpha: f32,
}

// How much of a ray the surface stops (render::surface::coverage).
fn coverage(m: Material, alpha: f32) -> f32 {
    if (m.flags & MATERIAL_ALPHA_MASK) != 0u {
        return select(0.0, 1.0, alpha >= m.alpha_cutoff);
    }
    if (m.flags & MATERIAL_ALPHA_BLEND) != 0u {
        return clamp(alpha, 0.0, 1.0);
    }
    return 1.0;
}

// The face normal and the shading normal on wo's side (render::surface::shading_frame).
struct Frame2 {
    ng: vec3<f32>,
    ns: vec3<f32>,
}

fn shading_frame(m: Material, front: bool, n: vec3<f32>, shading: vec3<f32>, wo: vec3<f32>) -> Frame2 {
    let ng = select(-n, n, front);
    let ns = select(-shading, shading, front);
    if m.kind == MAT_DIELECTRIC || dot(ns, wo) <= 0.0 {
        return Frame2(ng, ng);
    }
    if m.kind == MAT_MIRROR || m.kind == MAT_PBR {
        return Frame2(ng, reflecting_normal(ng, wo, ns));
    }
    return Frame2(ng, ns);
}

// ns turned towards ng just far enough that wo's mirror direction leaves the face
// (render::surface::reflecting_normal).
fn reflecting_normal(ng: vec3<f32>, wo: vec3<f32>, ns: vec3<f32>) -> vec3<f32> {
    let wz = dot(wo, ng);
    let t = min(0.9 * wz, 0.01);
    let c0 = dot(ns, ng);
    if 2.0 * dot(wo, ns) * c0 - wz >= t {
        return ns;
    }
    let tangential = ns - ng * c0;
    let s0 = length(tangential);
    if !(s0 > 0.0) {
        return ns;
    }
    let x = tangential / s0;
    let wx = dot(wo, x);
    let a = sqrt(wx * wx + wz * wz);
    let phi = clamp(0.5 * (atan2(wx, wz) + acos(clamp(t / a, -1.0, 1.0))), 0.0, atan2(s0, c0));
    return normalize(ng * cos(phi) + x * sin(phi));
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

// render::surface::decode_octahedral.
fn decode_octahedral(w: u32) -> vec3<f32> {
    let xy = unpack2x16snorm(w);
    let z = 1.0 - abs(xy.x) - abs(xy.y);
    let t = max(-z, 0.0);
    let sx = select(t, -t, xy.x >= 0.0);
    let sy = select(t, -t, xy.y >= 0.0);
    return vec3<f32>(xy.x + sx, xy.y + sy, z);
}

fn transformed(t: TextureInfo, uv: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(t.linear.x * uv.x + t.linear.y * uv.y + t.offset_uv.x, t.linear.z * uv.x + t.linear.w * uv.y + t.offset_uv.y);
}

// The vertex texture coordinates of the set texture t reads, transformed.
fn corner_uvs(t: TextureInfo, tri: u32) -> array<vec2<f32>, 3> {
    let a = triangle_attrs[tri];
    var uv = a.uv;
    if (t.flags & TEXTURE_UV1) != 0u {
        uv = a.second_uv;
    }
    return array<vec2<f32>, 3>(transformed(t, uv[0]), transformed(t, uv[1]), transformed(t, uv[2]));
}

// Texture `texture` (1 + index; 0: none) at weights w of triangle tri, else 1.
fn look(texture: u32, tri: u32, w: vec3<f32>) -> vec4<f32> {
    if texture == 0u {
        return vec4<f32>(1.0);
    }
    let t = load_texture(texture - 1u);
    let a = triangle_attrs[tri];
    var c = a.uv;
    if (t.flags & TEXTURE_UV1) != 0u {
        c = a.second_uv;
    }
    let uv = vec2<f32>(c[0].x * w.x + c[1].x * w.y + c[2].x * w.z, c[0].y * w.x + c[1].y * w.y + c[2].y * w.z);
    return texture_sample(t, transformed(t, uv));
}
#endif

// The radiance an area light of material m gives off at point p of primitive prim
// (render::surface::emission).
fn emission(m: Material, prim: u32, p: vec3<f32>) -> vec3<f32> {
#ifdef TEXTURES
#ifdef TRIANGLES
    if m.radiance_texture != 0u && (prim >> INDEX_BITS) == KIND_TRIANGLE {
        let i = prim & INDEX_MASK;
        let tri = scene_triangle(i);
        let bc = barycentrics(tri.va, tri.vb, tri.vc, p);
        return m.radiance * look(m.radiance_texture, i, vec3<f32>(1.0 - bc.x - bc.y, bc.x, bc.y)).xyz;
    }
#endif
#endif
    return m.radiance;
}

// Material m at point p of primitive prim, geometric normal n there (render::surface::surface).
fn surface(m: Material, prim: u32, p: vec3<f32>, n: vec3<f32>) -> Surface {
    var s = Surface(m, n, m.alpha);
#ifdef TEXTURES
#ifdef TRIANGLES
    if (prim >> INDEX_BITS) != KIND_TRIANGLE {
        return s;
    }
    let i = prim & INDEX_MASK;
    let tri = scene_triangle(i);
    let bc = barycentrics(tri.va, tri.vb, tri.vc, p);
    let w = vec3<f32>(1.0 - bc.x - bc.y, bc.x, bc.y);
    let a = triangle_attrs[i];
    var vertex = vec3<f32>(1.0);
    var vertex_alpha = 1.0;
    if (a.flags & ATTR_COLORS) != 0u {
        let ka = unpack4x8unorm(a.color[0]);
        let kb = unpack4x8unorm(a.color[1]);
        let kc = unpack4x8unorm(a.color[2]);
        vertex = vec3<f32>(
            ka.x * w.x + kb.x * w.y + kc.x * w.z,
            ka.y * w.x + kb.y * w.y + kc.y * w.z,
            ka.z * w.x + kb.z * w.y + kc.z * w.z,
        );
        vertex_alpha = ka.w * w.x + kb.w * w.y + kc.w * w.z;
    }
    let c = look(m.color_texture, i, w);
    s.m.color = m.color * c.xyz * vertex;
    s.alpha = m.alpha * c.w * vertex_alpha;
    var radiance = m.radiance * look(m.radiance_texture, i, w).xyz;
    if (m.flags & MATERIAL_UNLIT) != 0u {
        // An unlit material shows its base colour, vertex colours included.
        radiance = radiance * vertex;
    }
    s.m.radiance = radiance;
    if m.metal_rough_texture != 0u {
        let mr = look(m.metal_rough_texture, i, w);
        s.m.roughness = m.roughness * mr.y;
        s.m.metallic = m.metallic * mr.z;
    }
    var ns = n;
    if (a.flags & ATTR_NORMALS) != 0u {
        let v = normalize(decode_octahedral(a.normal[0]) * w.x + decode_octahedral(a.normal[1]) * w.y + decode_octahedral(a.normal[2]) * w.z);
        if all(abs(v) <= vec3<f32>(1.0)) {
            ns = select(v, -v, dot(v, n) < 0.0);
        }
    }
    if m.normal_texture != 0u {
        let t = load_texture(m.normal_texture - 1u);
        let uv = corner_uvs(t, i);
        let d1 = uv[1] - uv[0];
        let d2 = uv[2] - uv[0];
        let det = d1.x * d2.y - d1.y * d2.x;
        let e1 = tri.vb - tri.va;
        let e2 = tri.vc - tri.va;
        if det != 0.0 {
            let dpdu = (e1 * d2.y - e2 * d1.y) / det;
            let dpdv = (e2 * d1.x - e1 * d2.x) / det;
            let tangent = normalize(dpdu - ns * dot(ns, dpdu));
            let b0 = cross(ns, tangent);
            let bitangent = select(b0, -b0, dot(b0, dpdv) > 0.0);
            let c = look(m.normal_texture, i, w);
            let x = (2.0 * c.x - 1.0) * m.normal_scale;
            let y = (2.0 * c.y - 1.0) * m.normal_scale;
            let z = 2.0 * c.z - 1.0;
            let mapped = normalize(tangent * x + bitangent * y + ns * z);
            if all(abs(mapped) <= vec3<f32>(1.0)) && dot(mapped, n) > 0.0 {
                ns = mapped;
            }
        }
    }
    s.normal = ns;
#endif
#endif
    return s;
}
