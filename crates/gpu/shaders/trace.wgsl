// Ray-query entry points (`strahl trace --backend gpu`): twin of crates/cpu/src/trace.rs (trace).
//
// trace_nearest: one QueryHit per ray. Every-hit mode runs two passes: trace_count writes
// each ray's hit count to `offsets`; the host turns the counts into exclusive offsets; then
// trace_all writes each ray's hits at its offset and sorts them like primitives::sort_hits.
#import strahl::types::{QueryRay, QueryHit, QUERY_FOUND, QUERY_ENTER, KIND_PLANE, KIND_TRIANGLE, INDEX_BITS, F32_MAX, LINK_SHAPES, LINK_EMPTY}
#import strahl::spawn::spawn_origin
#ifdef BVH
#import strahl::bindings::load_shape_ref
#ifdef TRIANGLES
#import strahl::traverse::fetch_leaf_triangle
#endif
#endif
#ifdef SPHERES
#import strahl::bindings::{load_sphere, sphere_count}
#endif
#ifdef CYLINDERS
#import strahl::bindings::{load_cylinder, cylinder_count}
#endif
#ifdef TRIANGLES
#import strahl::bindings::triangles
#endif
#ifdef PLANES
#import strahl::bindings::{load_plane, plane_count}
#endif
#import strahl::roots::Roots
#import strahl::traverse::{nearest_hit, prim_normal, prim_tag, prim_roots, prim_ref}
#ifdef BVH
#import strahl::traverse::{safe_inverse, Stack, stack_pop, visit_node, link_is_leaf, leaf_first, leaf_end}
#endif

@group(1) @binding(0) var<storage, read> rays: array<QueryRay>;
@group(1) @binding(1) var<storage, read_write> hits: array<QueryHit>;
@group(1) @binding(2) var<storage, read_write> offsets: array<u32>;

const WORKGROUP: u32 = #{TRACE_WORKGROUP};

fn make_hit(r: u32, o: vec3<f32>, d: vec3<f32>, t: f32, part: u32) -> QueryHit {
    let n = prim_normal(r, o, d, t, part);
    let tag = prim_tag(r);
    let enter = select(0u, QUERY_ENTER, dot(d, n) < 0.0);
    return QueryHit(n, t, tag.x, tag.y, r, QUERY_FOUND | enter | (part << 8u));
}

@compute @workgroup_size(WORKGROUP, 1, 1)
fn trace_nearest(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&rays) {
        return;
    }
    let q = rays[i];
    let best = nearest_hit(q.origin, q.dir, q.tmin, q.tmax);
    if best.found {
        hits[i] = make_hit(best.prim_ref, q.origin, q.dir, best.t, best.part);
    } else {
        hits[i] = QueryHit(vec3<f32>(0.0), 0.0, 0u, 0u, 0u, 0u);
    }
}

// Spawned rays (twin of backend::cpu::trace_spawn): rays come in pairs; ray 2i is traced to
// its nearest hit, from which a ray leaves in the direction of ray 2i+1 (its origin unused),
// starting at the hit point moved off the surface by spawn_origin to the side it
// leaves from. hits[2i] is the first hit, hits[2i+1] the spawned ray's nearest hit.
@compute @workgroup_size(WORKGROUP, 1, 1)
fn trace_spawn(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if 2u * i + 1u >= arrayLength(&rays) {
        return;
    }
    let q = rays[2u * i];
    let dir2 = rays[2u * i + 1u].dir;
    let none = QueryHit(vec3<f32>(0.0), 0.0, 0u, 0u, 0u, 0u);
    let first = nearest_hit(q.origin, q.dir, q.tmin, q.tmax);
    if !first.found {
        hits[2u * i] = none;
        hits[2u * i + 1u] = none;
        return;
    }
    let h = make_hit(first.prim_ref, q.origin, q.dir, first.t, first.part);
    hits[2u * i] = h;
    let side = select(-h.normal, h.normal, dot(dir2, h.normal) >= 0.0);
    let o2 = spawn_origin(q.origin, q.dir, first.t, side);
    let second = nearest_hit(o2, dir2, 0.0, F32_MAX);
    if second.found {
        hits[2u * i + 1u] = make_hit(second.prim_ref, o2, dir2, second.t, second.part);
    } else {
        hits[2u * i + 1u] = none;
    }
}

// Counts (write = false) or writes at hits[base..] (write = true) every root of r.
fn emit_roots(r: u32, q: QueryRay, write: bool, base: u32, count: ptr<function, u32>) {
    let roots = prim_roots(r, q.origin, q.dir, q.tmin, q.tmax);
    for (var j = 0u; j < roots.len; j += 1u) {
        if write {
            hits[base + *count] = make_hit(r, q.origin, q.dir, roots.t[j], roots.part[j]);
        }
        *count += 1u;
    }
}

// Every hit of ray q in (tmin, tmax): the walk of accel::traverse::all.
fn visit_all(q: QueryRay, write: bool, base: u32) -> u32 {
    var count = 0u;
#ifdef PLANES
    for (var i = 0u; i < plane_count(); i += 1u) {
        emit_roots(prim_ref(KIND_PLANE, i), q, write, base, &count);
    }
#endif
#ifdef BVH
    // The walk of nearest_hit with a fixed bound: every leaf the ray enters within tmax.
    let inv = safe_inverse(q.dir);
    var stack: Stack;
    var cur = 0u;
    while cur != LINK_EMPTY {
        if !link_is_leaf(cur) {
            cur = visit_node(&stack, cur, q.origin, inv, q.tmin, q.tmax);
        } else {
            let end = leaf_end(cur);
            if (cur & LINK_SHAPES) != 0u {
                for (var k = leaf_first(cur); k < end; k += 1u) {
                    emit_roots(load_shape_ref(k), q, write, base, &count);
                }
            } else {
#ifdef TRIANGLES
                for (var k = leaf_first(cur); k < end; k += 1u) {
                    emit_roots(prim_ref(KIND_TRIANGLE, fetch_leaf_triangle(k).index), q, write, base, &count);
                }
#endif
            }
            cur = stack_pop(&stack, q.tmax);
        }
    }
#else
#ifdef SPHERES
    for (var i = 0u; i < sphere_count(); i += 1u) {
        emit_roots(prim_ref(0u, i), q, write, base, &count);
    }
#endif
#ifdef CYLINDERS
    for (var i = 0u; i < cylinder_count(); i += 1u) {
        emit_roots(prim_ref(1u, i), q, write, base, &count);
    }
#endif
#ifdef TRIANGLES
    for (var i = 0u; i < arrayLength(&triangles); i += 1u) {
        emit_roots(prim_ref(2u, i), q, write, base, &count);
    }
#endif
#endif
    return count;
}

@compute @workgroup_size(WORKGROUP, 1, 1)
fn trace_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&rays) {
        return;
    }
    offsets[i] = visit_all(rays[i], false, 0u);
}

// Hit a sorts before hit b: by t, then PrimRef, then part (primitives::sort_hits).
fn hit_less(a: QueryHit, b: QueryHit) -> bool {
    if a.t != b.t {
        return a.t < b.t;
    }
    if a.prim_ref != b.prim_ref {
        return a.prim_ref < b.prim_ref;
    }
    return (a.flags >> 8u) < (b.flags >> 8u);
}

@compute @workgroup_size(WORKGROUP, 1, 1)
fn trace_all(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&rays) {
        return;
    }
    let base = offsets[i];
    let count = visit_all(rays[i], true, base);
    // Insertion sort of this ray's hits (a ray crosses few surfaces).
    for (var a = 1u; a < count; a += 1u) {
        let h = hits[base + a];
        var b = a;
        while b > 0u && hit_less(h, hits[base + b - 1u]) {
            hits[base + b] = hits[base + b - 1u];
            b -= 1u;
        }
        hits[base + b] = h;
    }
}
