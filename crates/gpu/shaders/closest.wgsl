// Closest-point queries, one invocation per query point: twin of crates/core/src/accel/gpu_bvh.rs
// (closest, the same walk of the same nodes), which returns what crates/core/src/proximity/mod.rs
// (closest_brute, closest) returns (host: crates/gpu/src/closest.rs).
//
// closest_points writes per point the nearest surface point of the scene: its PrimRef
// (CLOSEST_NONE for an empty scene), the foot, its squared distance, uv and part. Planes are
// tested for every point; then the BVH is walked depth first, nearer child first, skipping a
// child whose box lies farther than the best squared distance grown by 1 + 2 gamma(4) (the box
// distance's own rounding, so that no box holding an equally near foot is skipped); without a
// BVH (tiny scenes) every bounded primitive is tested. Equal squared distances go to the
// smaller PrimRef (proximity::Closest::offer), so the order of the tests does not matter.
#import strahl::types::{F32_MAX, INDEX_BITS, INDEX_MASK, KIND_SPHERE, KIND_CYLINDER, KIND_TRIANGLE, KIND_PLANE}
#import strahl::closest::{Foot, ClosestPoint, triangle_closest}
#import strahl::traverse::prim_ref
#ifdef SPHERES
#import strahl::bindings::{load_sphere, sphere_count}
#import strahl::closest::sphere_closest
#endif
#ifdef CYLINDERS
#import strahl::bindings::{load_cylinder, cylinder_count}
#import strahl::closest::cylinder_closest
#endif
#ifdef TRIANGLES
#import strahl::bindings::triangles
#import strahl::traverse::scene_triangle
#endif
#ifdef PLANES
#import strahl::bindings::{load_plane, plane_count}
#import strahl::closest::plane_closest
#endif
#ifdef BVH
#import strahl::types::{LINK_SHAPES, LINK_EMPTY}
#import strahl::bindings::load_shape_ref
#import strahl::traverse::{Stack, stack_push, stack_pop, fetch_node, link_is_leaf, leaf_first, leaf_end}
#ifdef TRIANGLES
#import strahl::traverse::fetch_leaf_triangle
#endif
#endif

// One query point per element (w unused).
@group(1) @binding(0) var<storage, read> points: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read_write> answers: array<ClosestPoint>;

const WORKGROUP: u32 = #{CLOSEST_WORKGROUP};
// 1 + 2 gamma(4) in f32 (accel::gpu_bvh::closest_grow).
const CLOSEST_GROW: f32 = #{CLOSEST_GROW};
// The PrimRef of no primitive (u32::MAX): the answer of an empty scene.
const CLOSEST_NONE: u32 = #{CLOSEST_NONE};

// The best foot so far and whose it is (proximity::Closest; found: Some). Not named prim_ref:
// naga_oil renames this file's uses of an imported name, a member's declaration among them.
struct Best {
    foot: Foot,
    prim: u32,
    found: bool,
}

// Keeps the nearer foot, at equal squared distance the smaller PrimRef (proximity::Closest::offer).
// A NaN distance is never kept (a computed squared distance is >= 0 or NaN).
fn offer(best: ptr<function, Best>, r: u32, f: Foot) {
    let d = (*best).foot.dist_sq;
    let nearer = f.dist_sq < d || (f.dist_sq == d && r < (*best).prim);
    if f.dist_sq >= 0.0 && (!(*best).found || nearer) {
        (*best).foot = f;
        (*best).prim = r;
        (*best).found = true;
    }
}

// The foot of p on primitive r (Primitives::closest_of).
fn prim_foot(r: u32, p: vec3<f32>) -> Foot {
    let kind = r >> INDEX_BITS;
    let i = r & INDEX_MASK;
#ifdef SPHERES
    if kind == KIND_SPHERE {
        return sphere_closest(load_sphere(i), p);
    }
#endif
#ifdef CYLINDERS
    if kind == KIND_CYLINDER {
        return cylinder_closest(load_cylinder(i), p);
    }
#endif
#ifdef TRIANGLES
    if kind == KIND_TRIANGLE {
        let t = scene_triangle(i);
        return triangle_closest(t.va, t.vb, t.vc, p);
    }
#endif
#ifdef PLANES
    if kind == KIND_PLANE {
        return plane_closest(load_plane(i), p);
    }
#endif
    // No such kind in this variant: a NaN-free foot that offer refuses.
    return Foot(p, -1.0, vec2<f32>(0.0), 0u);
}

#ifdef BVH
// Squared distance from p to the box (lo, hi), 0 inside it, capped at F32_MAX
// (accel::gpu_bvh::box_dist2: the per-axis gaps of proximity::box_dist2, summed in order).
fn box_dist2(lo: vec3<f32>, hi: vec3<f32>, p: vec3<f32>) -> f32 {
    let d = max(max(lo - p, p - hi), vec3<f32>(0.0));
    return min(d.x * d.x + d.y * d.y + d.z * d.z, F32_MAX);
}

// The squared distance a box must not exceed to be visited: the best grown by CLOSEST_GROW,
// F32_MAX before any foot (box distances are capped there).
fn search_bound(best: Best) -> f32 {
    if best.found {
        return best.foot.dist_sq * CLOSEST_GROW;
    }
    return F32_MAX;
}

// One step from inner node `node`: the nearer child whose box lies within bound (the other
// pushed with its box distance), else the next link on the stack within bound.
fn visit_node(s: ptr<function, Stack>, node: u32, p: vec3<f32>, bound: f32) -> u32 {
    let n = fetch_node(node);
    let da = box_dist2(n.lo_a, n.hi_a, p);
    let db = box_dist2(n.lo_b, n.hi_b, p);
    let ha = da <= bound;
    // Only a root that is a leaf has an absent child (b).
    let hb = n.link_b != LINK_EMPTY && db <= bound;
    if ha && hb {
        if db < da {
            stack_push(s, n.link_a, da);
            return n.link_b;
        }
        stack_push(s, n.link_b, db);
        return n.link_a;
    }
    if ha {
        return n.link_a;
    }
    if hb {
        return n.link_b;
    }
    return stack_pop(s, bound);
}
#endif

// The nearest surface point of the scene to p: accel::gpu_bvh::closest.
fn closest_point(p: vec3<f32>) -> Best {
    var best = Best(Foot(vec3<f32>(0.0), 0.0, vec2<f32>(0.0), 0u), CLOSEST_NONE, false);
#ifdef PLANES
    for (var i = 0u; i < plane_count(); i += 1u) {
        offer(&best, prim_ref(KIND_PLANE, i), plane_closest(load_plane(i), p));
    }
#endif
#ifdef BVH
    var stack: Stack;
    stack.size = 0u;
    stack.top_held = false;
    var cur = 0u;
    while cur != LINK_EMPTY {
        if !link_is_leaf(cur) {
            cur = visit_node(&stack, cur, p, search_bound(best));
        } else {
            let end = leaf_end(cur);
            if (cur & LINK_SHAPES) != 0u {
                for (var k = leaf_first(cur); k < end; k += 1u) {
                    let r = load_shape_ref(k);
                    offer(&best, r, prim_foot(r, p));
                }
            } else {
#ifdef TRIANGLES
                for (var k = leaf_first(cur); k < end; k += 1u) {
                    let t = fetch_leaf_triangle(k);
                    offer(&best, prim_ref(KIND_TRIANGLE, t.index), triangle_closest(t.va, t.vb, t.vc, p));
                }
#endif
            }
            cur = stack_pop(&stack, search_bound(best));
        }
    }
#else
#ifdef SPHERES
    for (var i = 0u; i < sphere_count(); i += 1u) {
        offer(&best, prim_ref(KIND_SPHERE, i), prim_foot(prim_ref(KIND_SPHERE, i), p));
    }
#endif
#ifdef CYLINDERS
    for (var i = 0u; i < cylinder_count(); i += 1u) {
        offer(&best, prim_ref(KIND_CYLINDER, i), prim_foot(prim_ref(KIND_CYLINDER, i), p));
    }
#endif
#ifdef TRIANGLES
    for (var i = 0u; i < arrayLength(&triangles); i += 1u) {
        offer(&best, prim_ref(KIND_TRIANGLE, i), prim_foot(prim_ref(KIND_TRIANGLE, i), p));
    }
#endif
#endif
    return best;
}

@compute @workgroup_size(WORKGROUP, 1, 1)
fn closest_points(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&points) {
        return;
    }
    let best = closest_point(points[i].xyz);
    if best.found {
        answers[i] = ClosestPoint(best.foot.point, best.foot.dist_sq, best.foot.uv, best.prim, best.foot.part);
    } else {
        answers[i] = ClosestPoint(vec3<f32>(0.0), 0.0, vec2<f32>(0.0), CLOSEST_NONE, 0u);
    }
}
