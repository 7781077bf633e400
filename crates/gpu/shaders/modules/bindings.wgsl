// The scene's storage buffers (group 0), uploaded once per scene, and the per-dispatch frame.
// No CPU twin: the host packs and binds them in crates/gpu/src/objects.rs and
// crates/gpu/src/scene_buffers.rs (SceneBuffers).
//
// Seven bindings at most, so that with a program's own (the trace program's three, the render
// programs' one) no pipeline binds more than the 8 storage buffers per stage that WebGPU
// guarantees: the frame; `objects`, one buffer of 16-byte words holding every small array
// (spheres, cylinders, planes, shape references, materials, lights, emitters, the texture
// table, the environment) behind a header that says where each starts (objects.rs,
// ObjectsHeader), read through the load_* functions below; the three arrays that grow with the
// triangle count (scene-order triangles, BVH nodes, leaf-order triangles), each in its own
// typed binding so that it can be split; the texels, with the environment map's distribution
// after them; the triangle attributes. A binding is declared only in variants whose defs use
// it; empty arrays are bound to a one-element dummy buffer.
//
// An array larger than one binding (triangles, nodes, leaf triangles; crates/gpu/src/split.rs)
// is bound in parts: part 0 at its usual binding, parts 1, 2, 3 at 7 + 3 * array + part - 1.
// TRIANGLE_PARTS, NODE_PARTS and LEAF_TRIANGLE_PARTS (1: whole) say how many there are, and
// strahl::traverse reads an element from its part.
//
// The frame is a read-only storage buffer, not a uniform: lavapipe (Mesa 22.3) folds the values
// of uniforms that steer branches and loops into a new compiled copy of the shader every time
// the pipeline is bound, and never frees it: 1.4 MB and ~10 ms per sample pass of the seed
// scene (tests/gpu_memory.rs). Storage buffers are not folded.
#define_import_path strahl::bindings

#import strahl::types::{Frame, Material, Light, Emitter}
#ifdef SPHERES
#import strahl::types::Sphere
#endif
#ifdef CYLINDERS
#import strahl::types::Cylinder
#endif
#ifdef PLANES
#import strahl::types::Plane
#endif
#ifdef TEXELS
#import strahl::types::TextureInfo
#endif
#ifdef ENVIRONMENT
#import strahl::types::Environment
#endif
#ifdef BVH
#import strahl::types::Node
#endif
#ifdef TRIANGLES
#import strahl::types::{Triangle, LeafTriangle}
#endif
#ifdef TEXTURES
#import strahl::types::TriangleAttrs
#endif

@group(0) @binding(0) var<storage, read> frame: Frame;
@group(0) @binding(1) var<storage, read> objects: array<vec4<u32>>;
#ifdef TRIANGLES
@group(0) @binding(2) var<storage, read> triangles: array<Triangle>;
#if TRIANGLE_PARTS > 1
@group(0) @binding(7) var<storage, read> triangles_1: array<Triangle>;
#endif
#if TRIANGLE_PARTS > 2
@group(0) @binding(8) var<storage, read> triangles_2: array<Triangle>;
#endif
#if TRIANGLE_PARTS > 3
@group(0) @binding(9) var<storage, read> triangles_3: array<Triangle>;
#endif
#endif
#ifdef BVH
// With LOAD64 the nodes and leaf triangles are read as 64-bit words (strahl::traverse::fetch_node):
// a node as two 32-byte reads, a leaf triangle as three 16-byte reads. The element types are
// written out, not through an alias: naga_oil declares a binding of an alias type once per
// module that imports it.
#ifdef LOAD64
@group(0) @binding(3) var<storage, read> nodes: array<vec4<u64>>;
#else
@group(0) @binding(3) var<storage, read> nodes: array<Node>;
#endif
#if NODE_PARTS > 1
#ifdef LOAD64
@group(0) @binding(10) var<storage, read> nodes_1: array<vec4<u64>>;
#else
@group(0) @binding(10) var<storage, read> nodes_1: array<Node>;
#endif
#endif
#if NODE_PARTS > 2
#ifdef LOAD64
@group(0) @binding(11) var<storage, read> nodes_2: array<vec4<u64>>;
#else
@group(0) @binding(11) var<storage, read> nodes_2: array<Node>;
#endif
#endif
#if NODE_PARTS > 3
#ifdef LOAD64
@group(0) @binding(12) var<storage, read> nodes_3: array<vec4<u64>>;
#else
@group(0) @binding(12) var<storage, read> nodes_3: array<Node>;
#endif
#endif
#ifdef TRIANGLES
#ifdef LOAD64
@group(0) @binding(4) var<storage, read> leaf_triangles: array<vec2<u64>>;
#else
@group(0) @binding(4) var<storage, read> leaf_triangles: array<LeafTriangle>;
#endif
#if LEAF_TRIANGLE_PARTS > 1
#ifdef LOAD64
@group(0) @binding(13) var<storage, read> leaf_triangles_1: array<vec2<u64>>;
#else
@group(0) @binding(13) var<storage, read> leaf_triangles_1: array<LeafTriangle>;
#endif
#endif
#if LEAF_TRIANGLE_PARTS > 2
#ifdef LOAD64
@group(0) @binding(14) var<storage, read> leaf_triangles_2: array<vec2<u64>>;
#else
@group(0) @binding(14) var<storage, read> leaf_triangles_2: array<LeafTriangle>;
#endif
#endif
#if LEAF_TRIANGLE_PARTS > 3
#ifdef LOAD64
@group(0) @binding(15) var<storage, read> leaf_triangles_3: array<vec2<u64>>;
#else
@group(0) @binding(15) var<storage, read> leaf_triangles_3: array<LeafTriangle>;
#endif
#endif
#endif
#endif
// Images (TEXELS: TEXTURES or ENV_MAP): the packed texels (render::texture), then the
// environment map's distribution as f32 bits.
#ifdef TEXELS
@group(0) @binding(5) var<storage, read> texels: array<u32>;
#endif
#ifdef TEXTURES
@group(0) @binding(6) var<storage, read> triangle_attrs: array<TriangleAttrs>;
#endif

// The slots of the objects header (objects.rs, ObjectsHeader).
const OBJ_SPHERES: u32 = #{OBJ_SPHERES};
const OBJ_CYLINDERS: u32 = #{OBJ_CYLINDERS};
const OBJ_PLANES: u32 = #{OBJ_PLANES};
const OBJ_SHAPE_REFS: u32 = #{OBJ_SHAPE_REFS};
const OBJ_MATERIALS: u32 = #{OBJ_MATERIALS};
const OBJ_LIGHTS: u32 = #{OBJ_LIGHTS};
const OBJ_EMITTERS: u32 = #{OBJ_EMITTERS};
const OBJ_TEXTURES: u32 = #{OBJ_TEXTURES};
const OBJ_ENVIRONMENT: u32 = #{OBJ_ENVIRONMENT};
const OBJ_ENV_DISTRIBUTION: u32 = #{OBJ_ENV_DISTRIBUTION};
const OBJ_SPHERE_COUNT: u32 = #{OBJ_SPHERE_COUNT};
const OBJ_CYLINDER_COUNT: u32 = #{OBJ_CYLINDER_COUNT};
const OBJ_PLANE_COUNT: u32 = #{OBJ_PLANE_COUNT};
const OBJ_GLASS_TABLE: u32 = #{OBJ_GLASS_TABLE};

// Word `slot` of the objects header (OBJ_*: where an array starts, in 16-byte words, or a
// count).
fn object_slot(slot: u32) -> u32 {
    return objects[slot >> 2u][slot & 3u];
}

fn f3(w: vec4<u32>) -> vec3<f32> {
    return bitcast<vec3<f32>>(w.xyz);
}

fn f4(w: vec4<u32>) -> vec4<f32> {
    return bitcast<vec4<f32>>(w);
}

// Each load_* reads element i of its array, field by field in the order of its struct in
// strahl::types (the host writes the Rust twin's bytes, crates/core/src/layout.rs).
#ifdef SPHERES
fn sphere_count() -> u32 {
    return object_slot(OBJ_SPHERE_COUNT);
}

fn load_sphere(i: u32) -> Sphere {
    let b = object_slot(OBJ_SPHERES) + 2u * i;
    let w0 = objects[b];
    let w1 = objects[b + 1u];
    return Sphere(f3(w0), bitcast<f32>(w0.w), w1.x, w1.y, w1.z, w1.w);
}
#endif

#ifdef CYLINDERS
fn cylinder_count() -> u32 {
    return object_slot(OBJ_CYLINDER_COUNT);
}

fn load_cylinder(i: u32) -> Cylinder {
    let b = object_slot(OBJ_CYLINDERS) + 3u * i;
    let w0 = objects[b];
    let w1 = objects[b + 1u];
    let w2 = objects[b + 2u];
    return Cylinder(f3(w0), bitcast<f32>(w0.w), f3(w1), w1.w, w2.x, w2.y, w2.z, w2.w);
}
#endif

#ifdef PLANES
fn plane_count() -> u32 {
    return object_slot(OBJ_PLANE_COUNT);
}

fn load_plane(i: u32) -> Plane {
    let b = object_slot(OBJ_PLANES) + 2u * i;
    let w0 = objects[b];
    let w1 = objects[b + 1u];
    return Plane(f3(w0), w0.w, f3(w1), w1.w);
}
#endif

#ifdef BVH
// Shape reference k of the leaf order, four to a word.
fn load_shape_ref(k: u32) -> u32 {
    return objects[object_slot(OBJ_SHAPE_REFS) + (k >> 2u)][k & 3u];
}
#endif

fn load_material(i: u32) -> Material {
    let b = object_slot(OBJ_MATERIALS) + 8u * i;
    let w0 = objects[b];
    let w1 = objects[b + 1u];
    let w2 = objects[b + 2u];
    let w3 = objects[b + 3u];
    let w4 = objects[b + 4u];
    let w5 = objects[b + 5u];
    let w6 = objects[b + 6u];
    let w7 = objects[b + 7u];
    return Material(
        f3(w0), w0.w,
        f3(w1), bitcast<f32>(w1.w),
        bitcast<f32>(w2.x), w2.y, w2.z, w2.w,
        bitcast<f32>(w3.x), w3.y, w3.z, bitcast<f32>(w3.w),
        bitcast<f32>(w4.x), bitcast<f32>(w4.y), bitcast<f32>(w4.z), bitcast<f32>(w4.w),
        f3(w5), bitcast<f32>(w5.w),
        f3(w6), bitcast<f32>(w6.w),
        f3(w7), bitcast<f32>(w7.w),
    );
}

fn load_light(i: u32) -> Light {
    let b = object_slot(OBJ_LIGHTS) + 4u * i;
    let w0 = objects[b];
    let w1 = objects[b + 1u];
    let w2 = objects[b + 2u];
    let w3 = objects[b + 3u];
    return Light(f3(w0), w0.w, f3(w1), w1.w, f3(w2), bitcast<f32>(w2.w), bitcast<f32>(w3.x), bitcast<f32>(w3.y), w3.zw);
}

#ifdef ROUGH_GLASS
// Entry i of the rough dielectric's albedo table (render::dielectric::table).
fn load_glass_table(i: u32) -> f32 {
    let k = object_slot(OBJ_GLASS_TABLE) + (i >> 2u);
    return bitcast<f32>(objects[k][i & 3u]);
}
#endif

fn load_emitter(i: u32) -> Emitter {
    let w = objects[object_slot(OBJ_EMITTERS) + i];
    return Emitter(w.x, w.y, bitcast<f32>(w.z), bitcast<f32>(w.w));
}

#ifdef TEXELS
fn load_texture(i: u32) -> TextureInfo {
    let b = object_slot(OBJ_TEXTURES) + 3u * i;
    let w0 = objects[b];
    let w2 = objects[b + 2u];
    return TextureInfo(w0.x, w0.y, w0.z, w0.w, f4(objects[b + 1u]), bitcast<vec2<f32>>(w2.xy), w2.zw);
}
#endif

#ifdef ENVIRONMENT
// The environment (one element; ENV_MAP scenes only).
fn load_environment() -> Environment {
    let b = object_slot(OBJ_ENVIRONMENT);
    let w0 = objects[b];
    let w1 = objects[b + 1u];
    let w2 = objects[b + 2u];
    let sh = array<vec4<f32>, 9>(
        f4(objects[b + 3u]), f4(objects[b + 4u]), f4(objects[b + 5u]),
        f4(objects[b + 6u]), f4(objects[b + 7u]), f4(objects[b + 8u]),
        f4(objects[b + 9u]), f4(objects[b + 10u]), f4(objects[b + 11u]),
    );
    return Environment(
        f3(w0), w0.w,
        bitcast<f32>(w1.x), bitcast<f32>(w1.y), w1.z, bitcast<f32>(w1.w),
        w2.x, w2.y, w2.zw,
        sh,
    );
}
#endif

#ifdef TEXELS
// Entry k of the environment map's distribution (render::environment).
fn env_distribution(k: u32) -> f32 {
    return bitcast<f32>(texels[object_slot(OBJ_ENV_DISTRIBUTION) + k]);
}
#endif
