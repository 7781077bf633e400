// Buffer layouts shared by every stage: the twins of the #[repr(C)] structs in
// crates/core/src/layout.rs and crates/core/src/accel/gpu_bvh.rs (a test checks sizes and offsets through naga).
#define_import_path strahl::types

struct Frame {
    eye: vec3<f32>,
    width: u32,
    forward: vec3<f32>,
    height: u32,
    right: vec3<f32>,
    spp: u32,
    up: vec3<f32>,
    max_depth: u32,
    background: vec3<f32>,
    pad: u32,
    ambient: vec3<f32>,
    num_lights: u32,
    tile_origin: vec2<u32>,
    tile_size: vec2<u32>,
    sample_base: u32,
    out_pitch: u32,
    out_first_row: u32,
    flags: u32,
    num_emitters: u32,
    emitter_norm: f32,
    rr_depth: u32,
    seed: u32,
}

struct Sphere {
    center: vec3<f32>,
    radius: f32,
    object: u32,
    face: u32,
    material: u32,
    pad: u32,
}

struct Cylinder {
    // p1 and p2 of the lecture (naga renames members that end in a digit).
    pa: vec3<f32>,
    radius: f32,
    pb: vec3<f32>,
    caps: u32,
    object: u32,
    face: u32,
    material: u32,
    pad: u32,
}

struct Plane {
    point: vec3<f32>,
    object: u32,
    normal: vec3<f32>,
    material: u32,
}

struct Triangle {
    va: vec3<f32>,
    object: u32,
    vb: vec3<f32>,
    face: u32,
    vc: vec3<f32>,
    material: u32,
}

// A node of the BVH as the GPU walks it (accel::gpu_bvh::GpuNode): the boxes and links of
// its two children.
struct Node {
    lo_a: vec3<f32>,
    link_a: u32,
    hi_a: vec3<f32>,
    link_b: u32,
    lo_b: vec3<f32>,
    pad_a: u32,
    hi_b: vec3<f32>,
    pad_b: u32,
}

// A triangle in leaf order (accel::gpu_bvh::GpuLeafTriangle): vertices, its index in the
// scene-order triangle array, its material.
struct LeafTriangle {
    va: vec3<f32>,
    index: u32,
    vb: vec3<f32>,
    material: u32,
    vc: vec3<f32>,
    pad: u32,
}

struct Material {
    color: vec3<f32>,
    kind: u32,
    radiance: vec3<f32>,
    ior: f32,
    roughness: f32,
    flags: u32,
    // 1 + index in `textures` of the image multiplying color / radiance; 0: none.
    color_texture: u32,
    radiance_texture: u32,
    // pbr: metalness (roughness is then perceptual), the metallic-roughness and normal maps.
    metallic: f32,
    metal_rough_texture: u32,
    normal_texture: u32,
    normal_scale: f32,
    // Alpha factor and the MASK cut-off.
    alpha: f32,
    alpha_cutoff: f32,
    // pbr: KHR_materials_clearcoat's factor and perceptual roughness (render::layers).
    clearcoat: f32,
    clearcoat_roughness: f32,
    // Absorption per unit length inside (Beer-Lambert, on the segment that ends on a back face).
    absorption: vec3<f32>,
    // pbr: KHR_materials_transmission's factor (render::bsdf::glass_share).
    transmission: f32,
    // pbr: the dielectric's reflectance at normal and grazing incidence (ior, KHR_materials_specular).
    spec_at_normal: vec3<f32>,
    spec_at_grazing: f32,
    // pbr: KHR_materials_sheen's colour (black: none) and roughness.
    sheen_color: vec3<f32>,
    sheen_roughness: f32,
}

// A use of an image in `texels` (gpu_types::FlatTexture): the texture-coordinate transform
// (a, b, d, e) and offset (c, f) of (a u + b v + c, d u + e v + f).
struct TextureInfo {
    width: u32,
    height: u32,
    offset: u32,
    flags: u32,
    linear: vec4<f32>,
    offset_uv: vec2<f32>,
    pad: vec2<u32>,
}

// What a triangle's vertices carry besides positions (gpu_types::FlatTriangleAttrs): two sets
// of texture coordinates, octahedral normals (two snorm16), RGBA8 colours, ATTR_* flags.
struct TriangleAttrs {
    uv: array<vec2<f32>, 3>,
    second_uv: array<vec2<f32>, 3>,
    normal: array<u32, 3>,
    color: array<u32, 3>,
    flags: u32,
    pad: u32,
}

// The environment (gpu_types::FlatEnvironment).
struct Environment {
    radiance: vec3<f32>,
    flags: u32,
    rot_cos: f32,
    rot_sin: f32,
    texture: u32,
    select_prob: f32,
    width: u32,
    height: u32,
    pad: vec2<u32>,
    sh: array<vec4<f32>, 9>,
}

struct Light {
    vector: vec3<f32>,
    kind: u32,
    intensity: vec3<f32>,
    flags: u32,
    // A spot light's axis and cone (render::emitters::spot_factor), its range (0: unlimited).
    axis: vec3<f32>,
    cone_scale: f32,
    cone_offset: f32,
    range: f32,
    pad: vec2<u32>,
}

struct Emitter {
    source: u32,
    kind: u32,
    cdf: f32,
    pdf: f32,
}

struct QueryRay {
    origin: vec3<f32>,
    tmin: f32,
    dir: vec3<f32>,
    tmax: f32,
}

struct QueryHit {
    normal: vec3<f32>,
    t: f32,
    object: u32,
    face: u32,
    prim_ref: u32,
    flags: u32,
}

// Child links of Node (accel::gpu_bvh): an inner node's index, or a leaf: LINK_LEAF, LINK_SHAPES
// for spheres and cylinders (shape_refs) else triangles (leaf_triangles), count - 1 from bit
// LINK_COUNT_SHIFT, first primitive in the low bits. LINK_EMPTY: no child / no node.
const LINK_LEAF: u32 = #{LINK_LEAF};
const LINK_SHAPES: u32 = #{LINK_SHAPES};
const LINK_COUNT_SHIFT: u32 = #{LINK_COUNT_SHIFT};
const LINK_FIRST_MASK: u32 = #{LINK_FIRST_MASK};
const LINK_EMPTY: u32 = #{LINK_EMPTY};

// PrimRef: kind in bits 30-31 (crates/core/src/primitives.rs).
const KIND_SPHERE: u32 = #{KIND_SPHERE};
const KIND_CYLINDER: u32 = #{KIND_CYLINDER};
const KIND_TRIANGLE: u32 = #{KIND_TRIANGLE};
const KIND_PLANE: u32 = #{KIND_PLANE};
const INDEX_BITS: u32 = #{INDEX_BITS};
const INDEX_MASK: u32 = #{INDEX_MASK};

// Part of a surface (geometry::Part).
const PART_SURFACE: u32 = #{PART_SURFACE};
const PART_CAP_P1: u32 = #{PART_CAP_P1};
const PART_CAP_P2: u32 = #{PART_CAP_P2};

// MaterialKind (every other kind is diffuse).
const MAT_MIRROR: u32 = #{MAT_MIRROR};
const MAT_DIELECTRIC: u32 = #{MAT_DIELECTRIC};
const MAT_EMISSIVE: u32 = #{MAT_EMISSIVE};
const MAT_PBR: u32 = #{MAT_PBR};

const LIGHT_POINT: u32 = #{LIGHT_POINT};
const LIGHT_STAND_IN: u32 = #{LIGHT_STAND_IN};
const LIGHT_SPOT: u32 = #{LIGHT_SPOT};
const MATERIAL_TWO_SIDED: u32 = #{MATERIAL_TWO_SIDED};
const MATERIAL_UNLIT: u32 = #{MATERIAL_UNLIT};
const MATERIAL_ALPHA_MASK: u32 = #{MATERIAL_ALPHA_MASK};
const MATERIAL_ALPHA_BLEND: u32 = #{MATERIAL_ALPHA_BLEND};
const MATERIAL_SINGLE_SCATTERING: u32 = #{MATERIAL_SINGLE_SCATTERING};
const MATERIAL_ALPHA: u32 = #{MATERIAL_ALPHA};

const FRAME_ACCUMULATE: u32 = #{FRAME_ACCUMULATE};
const FRAME_ENVIRONMENT: u32 = #{FRAME_ENVIRONMENT};
const QUERY_FOUND: u32 = #{QUERY_FOUND};
const QUERY_ENTER: u32 = #{QUERY_ENTER};

// Texture flags and wrap modes (gpu_types, scene::texture::Wrap).
const TEXTURE_WRAP_U_SHIFT: u32 = #{TEXTURE_WRAP_U_SHIFT};
const TEXTURE_WRAP_V_SHIFT: u32 = #{TEXTURE_WRAP_V_SHIFT};
const TEXTURE_NEAREST: u32 = #{TEXTURE_NEAREST};
const TEXTURE_LINEAR_RGB: u32 = #{TEXTURE_LINEAR_RGB};
const TEXTURE_DATA: u32 = #{TEXTURE_DATA};
const TEXTURE_UV1: u32 = #{TEXTURE_UV1};
const ATTR_NORMALS: u32 = #{ATTR_NORMALS};
const ATTR_COLORS: u32 = #{ATTR_COLORS};
const WRAP_REPEAT: u32 = #{WRAP_REPEAT};
const WRAP_CLAMP: u32 = #{WRAP_CLAMP};
const WRAP_MIRROR: u32 = #{WRAP_MIRROR};
// Environment flags (gpu_types::ENV_MAP, ENV_UNIFORM; ENV_MAP names a feature's shader def).
const ENV_FLAG_MAP: u32 = #{ENV_FLAG_MAP};
const ENV_FLAG_UNIFORM: u32 = #{ENV_FLAG_UNIFORM};

// The largest f32: stands for "no upper bound" (WGSL cannot spell infinity). Roots are
// compared with `t < tmax`, so FLT_MAX and +inf reject exactly the same values.
const F32_MAX: f32 = #{F32_MAX};

// A point light's share of its intensity towards -dir at dist: a spot light's cone, a range's
// window (render::emitters::spot_factor).
fn spot_factor(l: Light, dir: vec3<f32>, dist: f32) -> f32 {
    var f = 1.0;
    if (l.flags & LIGHT_SPOT) != 0u {
        let c = -dot(dir, l.axis);
        let a = clamp(c * l.cone_scale + l.cone_offset, 0.0, 1.0);
        f = a * a;
    }
    if l.range > 0.0 {
        let r = dist / l.range;
        let w = clamp(1.0 - r * r * r * r, 0.0, 1.0);
        f *= w * w;
    }
    return f;
}
