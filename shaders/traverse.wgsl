// Nearest-hit search over the BVH (or every primitive, for tiny scenes): twin of
// src/accel/traverse.rs and the tie rule of src/primitives.rs (`Nearest`).
//
// Shader defs: SPHERES, CYLINDERS, TRIANGLES, PLANES (which primitive kinds exist) and
// BVH (walk the tree; without it every bounded primitive is tested).
#define_import_path strahl::traverse

#import strahl::types::{INDEX_BITS, INDEX_MASK, KIND_SPHERE, KIND_CYLINDER, KIND_TRIANGLE, KIND_PLANE}
#ifdef BVH
#import strahl::types::{BvhNode, F32_MAX}
#endif
#ifdef BVH
#import strahl::bindings::{nodes, prim_refs}
#endif
#import strahl::roots::{Roots, roots_empty}
#ifdef SPHERES
#import strahl::bindings::spheres
#import strahl::sphere::{sphere_roots, sphere_first, sphere_normal}
#endif
#ifdef CYLINDERS
#import strahl::bindings::cylinders
#import strahl::cylinder::{cylinder_roots, cylinder_first, cylinder_normal}
#endif
#ifdef TRIANGLES
#import strahl::bindings::triangles
#import strahl::triangle::{triangle_roots, triangle_intersect, shear_new, Shear, triangle_normal}
#endif
#ifdef PLANES
#import strahl::bindings::planes
#import strahl::plane::{plane_roots, plane_first}
#endif

// Deepest BVH the host builds (accel::bvh::MAX_DEPTH) + 1.
const TRAVERSAL_STACK: u32 = 49u;
// 1 + 2 gamma(3) in f32, the far-distance growth of the slab test (pbrt-v3 3.9.2).
const SLAB_GROW: f32 = 1.00000036;

struct Nearest {
    t: f32,
    prim: u32,
    part: u32,
    found: bool,
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

// Every root of primitive r in (tmin, tmax).
fn prim_roots(r: u32, o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Roots {
    let kind = r >> INDEX_BITS;
    let i = r & INDEX_MASK;
#ifdef SPHERES
    if kind == KIND_SPHERE {
        return sphere_roots(spheres[i], o, d, tmin, tmax);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        return cylinder_roots(cylinders[i], o, d, tmin, tmax);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        return triangle_roots(triangles[i], o, d, tmin, tmax);
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        return plane_roots(planes[i], o, d, tmin, tmax);
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
        return sphere_first(spheres[i], o, d, tmin, tmax);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        return cylinder_first(cylinders[i], o, d, tmin, tmax);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        return vec2<f32>(triangle_intersect(triangles[i], o, shear_new(d), tmin, tmax), 0.0);
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        return plane_first(planes[i], o, d, tmin, tmax);
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
        return sphere_normal(spheres[i], o, d, t);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        return cylinder_normal(cylinders[i], o, d, t, part);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        return triangle_normal(triangles[i]);
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        return planes[i].normal;
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
        let s = spheres[i];
        return vec3<u32>(s.object, s.prim, s.material);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        let c = cylinders[i];
        return vec3<u32>(c.object, c.prim, c.material);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        let t = triangles[i];
        return vec3<u32>(t.object, t.prim, t.material);
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        let p = planes[i];
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
    if t >= 0.0 && (t < (*best).t || (t == (*best).t && r < (*best).prim)) {
        (*best).t = t;
        (*best).prim = r;
        (*best).part = u32(first.y);
        (*best).found = true;
    }
}

#ifdef BVH
// 1/d, with components below 1e-30 in magnitude (the ray runs parallel to that axis) set to 0,
// which slab() takes apart (see accel::traverse::safe_inverse).
fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(1.0) / d, vec3<f32>(0.0), abs(d) < vec3<f32>(1e-30));
}

// Entry distance of the ray into the node's box within [tmin, tmax], or -1.
fn slab(n: BvhNode, o: vec3<f32>, inv: vec3<f32>, tmin: f32, tmax: f32) -> f32 {
    // Per axis as accel::traverse::slab. A parallel axis (inv 0) bounds nothing while the
    // origin lies within the box on it and rules the box out otherwise; its lanes of t0 and t1
    // (0, or NaN from an overflowed gap) are replaced before min/max, so no operand of those is
    // NaN and they choose exactly what the comparisons there choose.
    let t0 = (n.bmin - o) * inv;
    let t1 = (n.bmax - o) * inv;
    let parallel = inv == vec3<f32>(0.0);
    let lo = select(min(t0, t1), vec3<f32>(-F32_MAX), parallel);
    let hi = select(max(t0, t1) * SLAB_GROW, vec3<f32>(F32_MAX), parallel);
    let outside = parallel & ((o < n.bmin) | (o > n.bmax));
    let tnear = max(tmin, max(lo.x, max(lo.y, lo.z)));
    let tfar = min(tmax, min(hi.x, min(hi.y, hi.z)));
    if tnear <= tfar && !any(outside) {
        return tnear;
    }
    return -1.0;
}
#endif

// The nearest hit in (tmin, tmax): identical choice to accel::traverse::nearest.
fn nearest_hit(o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Nearest {
    var best = Nearest(tmax, 0xffffffffu, 0u, false);
#ifdef PLANES
    let np = arrayLength(&planes);
    for (var i = 0u; i < np; i += 1u) {
        offer_nearest(&best, prim_ref(KIND_PLANE, i), o, d, tmin);
    }
#endif
#ifdef BVH
    let inv = safe_inverse(d);
    var stack_node: array<u32, TRAVERSAL_STACK>;
    var stack_t: array<f32, TRAVERSAL_STACK>;
    var sp = 0u;
    var node = 0u;
    var walking = slab(nodes[0], o, inv, tmin, search_bound(best)) >= 0.0;
    while walking {
        let n = nodes[node];
#ifdef COUNT_VISITS
        visited_nodes += 1u;
#endif
        var next = 0xffffffffu;
        if n.count > 0u {
            let end = n.left_or_first + n.count;
            for (var k = n.left_or_first; k < end; k += 1u) {
                offer_nearest(&best, prim_refs[k], o, d, tmin);
            }
        } else {
            let l = node + 1u;
            let r = n.left_or_first;
            let tb = search_bound(best);
            let hl = slab(nodes[l], o, inv, tmin, tb);
            let hr = slab(nodes[r], o, inv, tmin, tb);
            if hl >= 0.0 && hr >= 0.0 {
                if hr < hl {
                    stack_node[sp] = l;
                    stack_t[sp] = hl;
                    next = r;
                } else {
                    stack_node[sp] = r;
                    stack_t[sp] = hr;
                    next = l;
                }
                sp += 1u;
            } else if hl >= 0.0 {
                next = l;
            } else if hr >= 0.0 {
                next = r;
            }
        }
        while next == 0xffffffffu {
            if sp == 0u {
                walking = false;
                break;
            }
            sp -= 1u;
            if stack_t[sp] <= search_bound(best) {
                next = stack_node[sp];
            }
        }
        node = next;
    }
#else
#ifdef SPHERES
    for (var i = 0u; i < arrayLength(&spheres); i += 1u) {
        offer_nearest(&best, prim_ref(KIND_SPHERE, i), o, d, tmin);
    }
#endif
#ifdef CYLINDERS
    for (var i = 0u; i < arrayLength(&cylinders); i += 1u) {
        offer_nearest(&best, prim_ref(KIND_CYLINDER, i), o, d, tmin);
    }
#endif
#ifdef TRIANGLES
    for (var i = 0u; i < arrayLength(&triangles); i += 1u) {
        offer_nearest(&best, prim_ref(KIND_TRIANGLE, i), o, d, tmin);
    }
#endif
#endif
    return best;
}
