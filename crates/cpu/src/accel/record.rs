//! The hit record of a wide walk's result, shared by the one-ray walk ([`super::wide_traverse`])
//! and the packet walk ([`super::packet`]).

use super::simd;
use super::wide::{LeafBlock, WideBvh};
use strahl_core::geometry::{Shape, Triangle};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{Hit, Nearest, Primitives};

/// The hit record of a search's result `best` for `ray`; `from_block`: the leaf block of the
/// best triangle hit, if the walk kept it (its copy of the triangle gives the normal without
/// loading the triangle again).
#[inline(always)]
pub(super) fn hit_record(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    best: &Nearest<f32>,
    from_block: Option<&LeafBlock>,
) -> Option<Hit<f32>> {
    // A sphere or cylinder found later may have won, even in the same block.
    let in_block = from_block
        .filter(|_| best.found && simd::is_triangle(best.prim_ref.0))
        .and_then(|b| b.prim_ref.iter().position(|&p| p == best.prim_ref.0).map(|lane| (b, lane)));
    match in_block {
        // The record prims.hit makes, from the copy of the triangle in the block, written
        // field by field into the result (a record built aside and copied out cost a
        // store-forwarding stall per ray).
        Some((block, lane)) => {
            let v = |k: usize| V3::new(block.v[k][0][lane], block.v[k][1][lane], block.v[k][2][lane]);
            let normal = Triangle { v: [v(0), v(1), v(2)] }.normal(ray, best.t, best.part);
            Some(Hit {
                t: best.t,
                normal,
                prim_ref: best.prim_ref,
                part: best.part,
                tag: w.triangle_tag(best.prim_ref.index()),
                enter: ray.dir.dot(normal) < 0.0,
            })
        }
        None if best.found => Some(prims.hit(best.prim_ref, ray, best.t, best.part)),
        None => None,
    }
}
