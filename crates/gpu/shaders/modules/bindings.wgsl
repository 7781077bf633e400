// The scene's storage buffers (group 0), uploaded once per scene, and the per-dispatch frame.
// No CPU twin: the host binds them in crates/gpu/src/lib.rs (SceneBuffers).
// A binding is declared only in variants whose defs use it; empty arrays are bound to a
// one-element dummy buffer.
//
// An array larger than one binding (triangles, nodes, leaf triangles; crates/gpu/src/split.rs)
// is bound in parts: part 0 at its usual binding, parts 1, 2, 3 at 16 + 3 * array + part - 1.
// TRIANGLE_PARTS, NODE_PARTS and LEAF_TRIANGLE_PARTS (1: whole) say how many there are, and
// strahl::traverse reads an element from its part.
//
// The frame is a read-only storage buffer, not a uniform: lavapipe (Mesa 22.3) folds the values
// of uniforms that steer branches and loops into a new compiled copy of the shader every time
// the pipeline is bound, and never frees it: 1.4 MB and ~10 ms per sample pass of the seed
// scene (tests/gpu_memory.rs). Storage buffers are not folded.
#define_import_path strahl::bindings

#import strahl::types::{Frame, Material, Light, Emitter}
#ifdef BVH
#import strahl::types::Node
#endif
#ifdef SPHERES
#import strahl::types::Sphere
#endif
#ifdef CYLINDERS
#import strahl::types::Cylinder
#endif
#ifdef PLANES
#import strahl::types::Plane
#endif
#ifdef TRIANGLES
#import strahl::types::{Triangle, LeafTriangle}
#endif
#ifdef TEXELS
#import strahl::types::TextureInfo
#endif
#ifdef TEXTURES
#import strahl::types::TriangleAttrs
#endif
#ifdef ENVIRONMENT
#import strahl::types::Environment
#endif

@group(0) @binding(0) var<storage, read> frame: Frame;
#ifdef SPHERES
@group(0) @binding(1) var<storage, read> spheres: array<Sphere>;
#endif
#ifdef CYLINDERS
@group(0) @binding(2) var<storage, read> cylinders: array<Cylinder>;
#endif
#ifdef PLANES
@group(0) @binding(3) var<storage, read> planes: array<Plane>;
#endif
#ifdef TRIANGLES
@group(0) @binding(4) var<storage, read> triangles: array<Triangle>;
#if TRIANGLE_PARTS > 1
@group(0) @binding(16) var<storage, read> triangles_1: array<Triangle>;
#endif
#if TRIANGLE_PARTS > 2
@group(0) @binding(17) var<storage, read> triangles_2: array<Triangle>;
#endif
#if TRIANGLE_PARTS > 3
@group(0) @binding(18) var<storage, read> triangles_3: array<Triangle>;
#endif
#endif
#ifdef BVH
// With LOAD64 the nodes and leaf triangles are read as 64-bit words (strahl::traverse::fetch_node):
// a node as two 32-byte reads, a leaf triangle as three 16-byte reads.
#ifdef LOAD64
alias NodeElement = vec4<u64>;
#else
alias NodeElement = Node;
#endif
@group(0) @binding(5) var<storage, read> nodes: array<NodeElement>;
#if NODE_PARTS > 1
@group(0) @binding(19) var<storage, read> nodes_1: array<NodeElement>;
#endif
#if NODE_PARTS > 2
@group(0) @binding(20) var<storage, read> nodes_2: array<NodeElement>;
#endif
#if NODE_PARTS > 3
@group(0) @binding(21) var<storage, read> nodes_3: array<NodeElement>;
#endif
@group(0) @binding(6) var<storage, read> shape_refs: array<u32>;
#ifdef TRIANGLES
#ifdef LOAD64
alias LeafElement = vec2<u64>;
#else
alias LeafElement = LeafTriangle;
#endif
@group(0) @binding(10) var<storage, read> leaf_triangles: array<LeafElement>;
#if LEAF_TRIANGLE_PARTS > 1
@group(0) @binding(22) var<storage, read> leaf_triangles_1: array<LeafElement>;
#endif
#if LEAF_TRIANGLE_PARTS > 2
@group(0) @binding(23) var<storage, read> leaf_triangles_2: array<LeafElement>;
#endif
#if LEAF_TRIANGLE_PARTS > 3
@group(0) @binding(24) var<storage, read> leaf_triangles_3: array<LeafElement>;
#endif
#endif
#endif
@group(0) @binding(7) var<storage, read> materials: array<Material>;
@group(0) @binding(8) var<storage, read> lights: array<Light>;
@group(0) @binding(9) var<storage, read> emitters: array<Emitter>;
// Images (TEXELS: TEXTURES or ENV_MAP): the table and the packed texels (render::texture).
#ifdef TEXELS
@group(0) @binding(11) var<storage, read> textures: array<TextureInfo>;
@group(0) @binding(12) var<storage, read> texels: array<u32>;
#endif
#ifdef TEXTURES
@group(0) @binding(13) var<storage, read> triangle_attrs: array<TriangleAttrs>;
#endif
#ifdef ENVIRONMENT
@group(0) @binding(14) var<storage, read> environment: array<Environment>;
#endif
#ifdef ENV_MAP
@group(0) @binding(15) var<storage, read> env_distribution: array<f32>;
#endif
