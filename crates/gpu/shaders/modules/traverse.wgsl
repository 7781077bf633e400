// Nearest-hit search over the BVH (or every primitive, for tiny scenes): twin of
// crates/core/src/accel/gpu_bvh.rs (the walk) and the tie rule of crates/core/src/primitives.rs (`Nearest`).
//
// Shader defs: SPHERES, CYLINDERS, TRIANGLES, PLANES (which primitive kinds exist), BVH (walk
// the tree; without it every bounded primitive is tested), LOAD64 (the device reads 64-bit
// words: nodes and leaf triangles are fetched as such, see fetch_node) and TRIANGLE_PARTS,
// NODE_PARTS, LEAF_TRIANGLE_PARTS (arrays larger than one binding, bound in parts: see
// scene_triangle; 1 for every scene whose arrays fit). The accessors scene_triangle,
// fetch_node and fetch_leaf_triangle exist in every variant that has the array and make
// those choices inside, so their callers read the same whatever the variant.
//
// What this is shaped for: on a device that runs invocations as the lanes of one SIMD program
// (lavapipe: 8 lanes on the CPU), a storage-buffer read whose address differs per lane costs
// a scalar load, a bounds check and an insert per lane and per component, which makes bytes
// fetched the main cost of a traversal; so a node step fetches both child boxes in one 64-byte
// node, a leaf's triangles are fetched once, in leaf order, with their material, and a hit
// keeps what shading needs (normal, material) instead of fetching the triangle again.
#define_import_path strahl::traverse

#import strahl::types::{INDEX_BITS, INDEX_MASK, KIND_SPHERE, KIND_CYLINDER, KIND_TRIANGLE, KIND_PLANE, PART_SURFACE}
#ifdef BVH
#import strahl::types::{Node, F32_MAX, LINK_LEAF, LINK_SHAPES, LINK_COUNT_SHIFT, LINK_FIRST_MASK, LINK_EMPTY}
// The parts after the first of a split array exist in split variants only, and only code of
// those uses them (an imported item that no code uses is not looked up).
#import strahl::bindings::{nodes, nodes_1, nodes_2, nodes_3, load_shape_ref}
#ifdef TRIANGLES
#import strahl::types::LeafTriangle
#import strahl::bindings::{leaf_triangles, leaf_triangles_1, leaf_triangles_2, leaf_triangles_3}
#endif
#endif
#import strahl::roots::{Roots, roots_empty}
#ifdef SPHERES
#import strahl::bindings::{load_sphere, sphere_count}
#import strahl::sphere::{sphere_roots, sphere_first, sphere_normal}
#endif
#ifdef CYLINDERS
#import strahl::bindings::{load_cylinder, cylinder_count}
#import strahl::cylinder::{cylinder_roots, cylinder_first, cylinder_normal}
#endif
#ifdef TRIANGLES
#import strahl::types::Triangle
#import strahl::bindings::{triangles, triangles_1, triangles_2, triangles_3}
#import strahl::triangle::{triangle_roots, triangle_intersect, vertices_intersect, shear_new, Shear, triangle_normal}
#endif
#ifdef PLANES
#import strahl::bindings::{load_plane, plane_count}
#import strahl::plane::{plane_roots, plane_first}
#endif

// Entries of the traversal stack: the deepest tree the host collapses (accel::gpu_bvh::MAX_DEPTH).
const GPU_STACK: u32 = #{GPU_STACK};
// 1 + 2 gamma(3) in f32, the far-distance growth of the slab test (pbrt-v3 3.9.2).
const SLAB_GROW: f32 = #{SLAB_GROW};

struct Nearest {
    t: f32,
    prim_ref: u32,
    part: u32,
    found: bool,
    // Set by the BVH walk for a triangle hit: its front normal (v1 - v0) x (v2 - v0), not
    // normalised, and its material, kept from the leaf triangle when it became the best hit
    // (hit_normal and hit_material then fetch nothing).
    kept: bool,
    normal: vec3<f32>,
    material: u32,
}

fn nearest_none(tmax: f32) -> Nearest {
    return Nearest(tmax, 0xffffffffu, 0u, false, false, vec3<f32>(0.0), 0u);
}

#ifdef COUNT_VISITS
// Work of the traversals since the caller last zeroed them: BVH nodes visited and primitives
// tested (the viewer's BVH-cost heat map, shaders/view.wgsl).
var<private> visited_nodes: u32;
var<private> tested_prims: u32;
#endif

fn prim_ref(kind: u32, index: u32) -> u32 {
    return (kind << INDEX_BITS) | index;
}

// Reading a split array (crates/gpu/src/split.rs): element e lies in part e / PER_PART at
// e % PER_PART (PER_PART a value of the variant: TRIANGLES_PER_PART and the like). A binding
// cannot be indexed by a value, so branches pick the part, part 0 last. Where the array is
// whole, its accessor reads it directly.
#ifdef TRIANGLES
// Triangle i of the scene order.
fn scene_triangle(i: u32) -> Triangle {
#if TRIANGLE_PARTS > 1
    let p = i / #{TRIANGLES_PER_PART};
    let j = i - p * #{TRIANGLES_PER_PART};
    if p == 1u {
        return triangles_1[j];
    }
#if TRIANGLE_PARTS > 2
    if p == 2u {
        return triangles_2[j];
    }
#endif
#if TRIANGLE_PARTS > 3
    if p == 3u {
        return triangles_3[j];
    }
#endif
    return triangles[j];
#else
    return triangles[i];
#endif
}
#endif

// Every root of primitive r in (tmin, tmax).
fn prim_roots(r: u32, o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Roots {
    let kind = r >> INDEX_BITS;
    let i = r & INDEX_MASK;
#ifdef SPHERES
    if kind == KIND_SPHERE {
        return sphere_roots(load_sphere(i), o, d, tmin, tmax);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        return cylinder_roots(load_cylinder(i), o, d, tmin, tmax);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        return triangle_roots(scene_triangle(i), o, d, tmin, tmax);
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        return plane_roots(load_plane(i), o, d, tmin, tmax);
    }
#endif
    return roots_empty();
}

// The first root of primitive r in (tmin, tmax) as (t, part), or t = -1: the same root as
// prim_roots(..).t[0] (what Primitives::offer_nearest uses), without building the list.
fn prim_first(r: u32, o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> vec2<f32> {
    let kind = r >> INDEX_BITS;
    let i = r & INDEX_MASK;
#ifdef SPHERES
    if kind == KIND_SPHERE {
        return sphere_first(load_sphere(i), o, d, tmin, tmax);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        return cylinder_first(load_cylinder(i), o, d, tmin, tmax);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        return vec2<f32>(triangle_intersect(scene_triangle(i), o, shear_new(d), tmin, tmax), 0.0);
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        return plane_first(load_plane(i), o, d, tmin, tmax);
    }
#endif
    return vec2<f32>(-1.0, 0.0);
}

// Unit front-face normal of primitive r at root t on part.
fn prim_normal(r: u32, o: vec3<f32>, d: vec3<f32>, t: f32, part: u32) -> vec3<f32> {
    let kind = r >> INDEX_BITS;
    let i = r & INDEX_MASK;
#ifdef SPHERES
    if kind == KIND_SPHERE {
        return sphere_normal(load_sphere(i), o, d, t);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        return cylinder_normal(load_cylinder(i), o, d, t, part);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        return triangle_normal(scene_triangle(i));
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        return load_plane(i).normal;
    }
#endif
    return vec3<f32>(0.0, 0.0, 1.0);
}

// (object, prim, material) of primitive r.
fn prim_tag(r: u32) -> vec3<u32> {
    let kind = r >> INDEX_BITS;
    let i = r & INDEX_MASK;
#ifdef SPHERES
    if kind == KIND_SPHERE {
        let s = load_sphere(i);
        return vec3<u32>(s.object, s.face, s.material);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        let c = load_cylinder(i);
        return vec3<u32>(c.object, c.face, c.material);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        let t = scene_triangle(i);
        return vec3<u32>(t.object, t.face, t.material);
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        let p = load_plane(i);
        return vec3<u32>(p.object, 0u, p.material);
    }
#endif
    return vec3<u32>(0u);
}

// Bound for the next roots search: the next float above the best t once something was found,
// so that roots at exactly that t are still seen by the tie rule (t > 0 here).
fn search_bound(best: Nearest) -> f32 {
    if best.found {
        return bitcast<f32>(bitcast<u32>(best.t) + 1u);
    }
    return best.t;
}

fn offer_nearest(best: ptr<function, Nearest>, r: u32, o: vec3<f32>, d: vec3<f32>, tmin: f32) {
#ifdef COUNT_VISITS
    tested_prims += 1u;
#endif
    let first = prim_first(r, o, d, tmin, search_bound(*best));
    let t = first.x;
    if t >= 0.0 && (t < (*best).t || (t == (*best).t && r < (*best).prim_ref)) {
        (*best).t = t;
        (*best).prim_ref = r;
        (*best).part = u32(first.y);
        (*best).found = true;
        (*best).kept = false;
    }
}

// Unit front-face normal at the nearest hit of the ray (o, d).
fn hit_normal(hit: Nearest, o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    if hit.kept {
        return normalize(hit.normal);
    }
    return prim_normal(hit.prim_ref, o, d, hit.t, hit.part);
}

// Material of the nearest hit.
fn hit_material(hit: Nearest) -> u32 {
    if hit.kept {
        return hit.material;
    }
    return prim_tag(hit.prim_ref).z;
}

#ifdef BVH
// 1/d, with components below 1e-30 in magnitude (the ray runs parallel to that axis) set to 0,
// which slab() takes apart (see accel::traverse::safe_inverse).
fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(1.0) / d, vec3<f32>(0.0), abs(d) < vec3<f32>(1e-30));
}

// The smaller and the larger of two floats that are not NaN, as one comparison and one select:
// the min and max builtins also order NaN, which lavapipe pays for with a second comparison
// and a blend per call (the book's performance chapter has what it saved).
fn min_of(a: f32, b: f32) -> f32 {
    return select(b, a, a < b);
}
fn max_of(a: f32, b: f32) -> f32 {
    return select(b, a, a > b);
}

// Entry distance of the ray into the box (lo, hi) within [tmin, tmax], or -1 (twin of
// accel::gpu_bvh::slab, which computes what accel::traverse::slab does). A parallel axis (inv 0)
// bounds nothing while the origin lies within the box on it and rules the box out otherwise;
// its lanes of t0 and t1 (0, or NaN from an overflowed gap) are replaced before the minima and
// maxima, so no operand of those is NaN and they choose what the comparisons there choose (up
// to the sign of a zero, which no comparison sees).
fn slab(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, inv: vec3<f32>, tmin: f32, tmax: f32) -> f32 {
    let t0 = (lo - o) * inv;
    let t1 = (hi - o) * inv;
    let parallel = inv == vec3<f32>(0.0);
    let swap = t1 < t0;
    let near = select(select(t0, t1, swap), vec3<f32>(-F32_MAX), parallel);
    let far = select(select(t1, t0, swap) * SLAB_GROW, vec3<f32>(F32_MAX), parallel);
    let outside = parallel & ((o < lo) | (o > hi));
    let tnear = max_of(tmin, max_of(near.x, max_of(near.y, near.z)));
    let tfar = min_of(tmax, min_of(far.x, min_of(far.y, far.z)));
    if tnear <= tfar && !any(outside) {
        return tnear;
    }
    return -1.0;
}

// The elements of the nodes binding (strahl::bindings): with LOAD64 a node is two 32-byte
// halves of four 64-bit words (see fetch_node), else one element.
#ifdef LOAD64
alias NodeElement = vec4<u64>;
const NODE_ELEMENTS: u32 = 2u;

// The two 32-bit halves of a 64-bit word (little-endian, as the host wrote the 32-bit fields).
fn low_u32(v: u64) -> u32 {
    return u32(v & 0xfffffffflu);
}
fn high_u32(v: u64) -> u32 {
    return u32(v >> 32u);
}
// The 16 bytes w as (x, y, z) floats and a u32 in the last word.
fn vec3_word(w: vec2<u64>) -> vec3<f32> {
    return vec3<f32>(bitcast<f32>(low_u32(w.x)), bitcast<f32>(high_u32(w.x)), bitcast<f32>(low_u32(w.y)));
}
#else
alias NodeElement = Node;
const NODE_ELEMENTS: u32 = 1u;
#endif

// Element e of the nodes binding, NODE_ELEMENTS per node (a split array: see scene_triangle).
fn node_element(e: u32) -> NodeElement {
#if NODE_PARTS > 1
    let per_part = NODE_ELEMENTS * #{NODES_PER_PART};
    let p = e / per_part;
    let j = e - p * per_part;
    if p == 1u {
        return nodes_1[j];
    }
#if NODE_PARTS > 2
    if p == 2u {
        return nodes_2[j];
    }
#endif
#if NODE_PARTS > 3
    if p == 3u {
        return nodes_3[j];
    }
#endif
    return nodes[j];
#else
    return nodes[e];
#endif
}

// Inner node i. With LOAD64 as two 32-byte reads of four 64-bit words each: a SIMD device
// that reads storage lane by lane (lavapipe) pays a mask test, a bounds check and a scalar
// load per lane and per read, and a few instructions per further word of the same read, so
// fewer, wider reads cost less.
fn fetch_node(i: u32) -> Node {
#ifdef LOAD64
    let h0 = node_element(2u * i);
    let h1 = node_element(2u * i + 1u);
    let a = h0.xy;
    let b = h0.zw;
    let c = h1.xy;
    let e = h1.zw;
    return Node(vec3_word(a), high_u32(a.y), vec3_word(b), high_u32(b.y), vec3_word(c), 0u, vec3_word(e), 0u);
#else
    return node_element(i);
#endif
}

#ifdef TRIANGLES
// The elements of the leaf-triangle binding: with LOAD64 a triangle is three 16-byte words of
// two 64-bit words each, else one element.
#ifdef LOAD64
alias LeafElement = vec2<u64>;
const LEAF_ELEMENTS: u32 = 3u;
#else
alias LeafElement = LeafTriangle;
const LEAF_ELEMENTS: u32 = 1u;
#endif

// Element e of the leaf-triangle binding, LEAF_ELEMENTS per triangle (a split array: see
// scene_triangle).
fn leaf_element(e: u32) -> LeafElement {
#if LEAF_TRIANGLE_PARTS > 1
    let per_part = LEAF_ELEMENTS * #{LEAF_TRIANGLES_PER_PART};
    let p = e / per_part;
    let j = e - p * per_part;
    if p == 1u {
        return leaf_triangles_1[j];
    }
#if LEAF_TRIANGLE_PARTS > 2
    if p == 2u {
        return leaf_triangles_2[j];
    }
#endif
#if LEAF_TRIANGLE_PARTS > 3
    if p == 3u {
        return leaf_triangles_3[j];
    }
#endif
    return leaf_triangles[j];
#else
    return leaf_triangles[e];
#endif
}

// Triangle k of the leaf order (see fetch_node for LOAD64).
fn fetch_leaf_triangle(k: u32) -> LeafTriangle {
#ifdef LOAD64
    let a = leaf_element(3u * k);
    let b = leaf_element(3u * k + 1u);
    let c = leaf_element(3u * k + 2u);
    return LeafTriangle(vec3_word(a), high_u32(a.y), vec3_word(b), high_u32(b.y), vec3_word(c), 0u);
#else
    return leaf_element(k);
#endif
}
#endif

// The traversal stack: child links and the distances at which the ray enters their boxes. The
// most recent entry is held in `top` (link, entry distance bits) while `top_held`, out of the
// array, which a SIMD device indexes lane by lane (lavapipe: a scalar store or load per lane and
// word); the next pop usually takes it. The order of entries is that of a plain stack.
struct Stack {
    entries: array<vec2<u32>, GPU_STACK>,
    size: u32,
    top: vec2<u32>,
    top_held: bool,
}

fn stack_push(s: ptr<function, Stack>, link: u32, t: f32) {
    if (*s).top_held {
        (*s).entries[(*s).size] = (*s).top;
        (*s).size += 1u;
    }
    (*s).top = vec2<u32>(link, bitcast<u32>(t));
    (*s).top_held = true;
}

// The most recently pushed link whose box the ray enters within bound (entries beyond bound
// are dropped), or LINK_EMPTY when none is left.
fn stack_pop(s: ptr<function, Stack>, bound: f32) -> u32 {
    if (*s).top_held {
        (*s).top_held = false;
        if bitcast<f32>((*s).top.y) <= bound {
            return (*s).top.x;
        }
    }
    while (*s).size > 0u {
        (*s).size -= 1u;
        let e = (*s).entries[(*s).size];
        if bitcast<f32>(e.y) <= bound {
            return e.x;
        }
    }
    return LINK_EMPTY;
}

// One step from inner node `node`: the nearer child whose box the ray enters within
// [tmin, tb] (the farther one pushed), else the next link on the stack.
fn visit_node(s: ptr<function, Stack>, node: u32, o: vec3<f32>, inv: vec3<f32>, tmin: f32, tb: f32) -> u32 {
#ifdef COUNT_VISITS
    visited_nodes += 1u;
#endif
    let n = fetch_node(node);
    let ha = slab(n.lo_a, n.hi_a, o, inv, tmin, tb);
    // Only a root that is a leaf has an absent child (b).
    let hb = select(-1.0, slab(n.lo_b, n.hi_b, o, inv, tmin, tb), n.link_b != LINK_EMPTY);
    if ha >= 0.0 && hb >= 0.0 {
        if hb < ha {
            stack_push(s, n.link_a, ha);
            return n.link_b;
        }
        stack_push(s, n.link_b, hb);
        return n.link_a;
    }
    if ha >= 0.0 {
        return n.link_a;
    }
    if hb >= 0.0 {
        return n.link_b;
    }
    return stack_pop(s, tb);
}

fn link_is_leaf(link: u32) -> bool {
    return (link & LINK_LEAF) != 0u;
}

fn leaf_first(link: u32) -> u32 {
    return link & LINK_FIRST_MASK;
}

fn leaf_end(link: u32) -> u32 {
    return (link & LINK_FIRST_MASK) + ((link & ~(LINK_LEAF | LINK_SHAPES)) >> LINK_COUNT_SHIFT) + 1u;
}

#ifdef TRIANGLES
// Offers triangles first .. end of the leaf order to best (the leaf loop of nearest_hit).
fn offer_triangles(best: ptr<function, Nearest>, first: u32, end: u32, o: vec3<f32>, sh: Shear, tmin: f32) {
    for (var k = first; k < end; k += 1u) {
#ifdef COUNT_VISITS
        tested_prims += 1u;
#endif
        let tri = fetch_leaf_triangle(k);
        let r = prim_ref(KIND_TRIANGLE, tri.index);
        let t = vertices_intersect(tri.va, tri.vb, tri.vc, o, sh, tmin, search_bound(*best));
        if t >= 0.0 && (t < (*best).t || (t == (*best).t && r < (*best).prim_ref)) {
            (*best).t = t;
            (*best).prim_ref = r;
            (*best).part = PART_SURFACE;
            (*best).found = true;
            (*best).kept = true;
            (*best).normal = cross(tri.vb - tri.va, tri.vc - tri.va);
            (*best).material = tri.material;
        }
    }
}
#endif
#endif

// The nearest hit in (tmin, tmax): identical choice to accel::traverse::nearest (and to
// accel::gpu_bvh::nearest, whose walk this is).
fn nearest_hit(o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Nearest {
    return walk(o, d, tmin, tmax, false);
}

// Whether anything lies in (tmin, tmax) along the ray: the walk of nearest_hit, ended at the
// first hit it meets (accel::gpu_bvh::occluded), for shadow rays.
fn occluded(o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> bool {
    return walk(o, d, tmin, tmax, true).found;
}

// The nearest hit in (tmin, tmax) or, with any_hit, some hit (each caller passes a constant,
// and the driver's inlining leaves a walk specialised to it).
fn walk(o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32, any_hit: bool) -> Nearest {
    var best = nearest_none(tmax);
#ifdef PLANES
    let np = plane_count();
    for (var i = 0u; i < np && !(any_hit && best.found); i += 1u) {
        offer_nearest(&best, prim_ref(KIND_PLANE, i), o, d, tmin);
    }
#endif
#ifdef BVH
    let inv = safe_inverse(d);
#ifdef TRIANGLES
    let sh = shear_new(d);
#endif
    var stack: Stack;
    stack.size = 0u;
    stack.top_held = false;
    var cur = 0u;
    if any_hit && best.found {
        cur = LINK_EMPTY;
    }
    // One loop whose iterations take one node step or one leaf: SIMD lanes at leaves and
    // lanes at inner nodes advance together (cheaper on lavapipe than separate loops for node
    // steps and leaves, which make lanes wait for each other).
    while cur != LINK_EMPTY {
        if !link_is_leaf(cur) {
            cur = visit_node(&stack, cur, o, inv, tmin, search_bound(best));
        } else {
            let first = leaf_first(cur);
            let end = leaf_end(cur);
            if (cur & LINK_SHAPES) != 0u {
                for (var k = first; k < end; k += 1u) {
                    offer_nearest(&best, load_shape_ref(k), o, d, tmin);
                }
            } else {
#ifdef TRIANGLES
                offer_triangles(&best, first, end, o, sh, tmin);
#endif
            }
            cur = select(stack_pop(&stack, search_bound(best)), LINK_EMPTY, any_hit && best.found);
        }
    }
#else
#ifdef SPHERES
    for (var i = 0u; i < sphere_count() && !(any_hit && best.found); i += 1u) {
        offer_nearest(&best, prim_ref(KIND_SPHERE, i), o, d, tmin);
    }
#endif
#ifdef CYLINDERS
    for (var i = 0u; i < cylinder_count() && !(any_hit && best.found); i += 1u) {
        offer_nearest(&best, prim_ref(KIND_CYLINDER, i), o, d, tmin);
    }
#endif
#ifdef TRIANGLES
    for (var i = 0u; i < arrayLength(&triangles) && !(any_hit && best.found); i += 1u) {
        offer_nearest(&best, prim_ref(KIND_TRIANGLE, i), o, d, tmin);
    }
#endif
#endif
    return best;
}
