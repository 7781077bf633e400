//! The hit record of a wide walk's result, shared by the one-ray walk ([`super::wide_traverse`])
//! and the packet walk ([`super::packet`]).

use super::simd;
use super::wide::{LeafBlock, WideBvh};
use crate::geometry::{Shape, Triangle};
use crate::math::{Ray, V3};
use crate::primitives::{Hit, Nearest, PrimKind, Primitives};

/// What a nearest-hit walk writes for each ray ([`super::wide_traverse::nearest_many`]): the
/// hit record alone, or the record with its triangle ([`HitTriangle`]).
pub trait NearestRecord: Sized {
    /// The record of a search's result `best` for `ray`; `from_block`: the leaf block of the
    /// best triangle hit, if the walk kept it.
    fn record(
        w: &WideBvh,
        prims: &Primitives<f32>,
        ray: &Ray<f32>,
        best: &Nearest<f32>,
        from_block: Option<&LeafBlock>,
    ) -> Self;
}

impl NearestRecord for Option<Hit<f32>> {
    #[inline(always)]
    fn record(
        w: &WideBvh,
        prims: &Primitives<f32>,
        ray: &Ray<f32>,
        best: &Nearest<f32>,
        from_block: Option<&LeafBlock>,
    ) -> Self {
        hit_record::<false>(w, prims, ray, best, from_block).0
    }
}

/// A nearest hit with the vertices of its triangle (`None` for a sphere, a cylinder, a plane
/// or a miss), the same values as the scene's triangle, taken from the walk's copy in the
/// leaf block where it has one: for callers that need more of the triangle than the record
/// (barycentric coordinates) without loading it from the scene again, a cache miss per ray in
/// a large mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HitTriangle {
    pub hit: Option<Hit<f32>>,
    pub triangle: Option<Triangle<f32>>,
}

impl NearestRecord for HitTriangle {
    #[inline(always)]
    fn record(
        w: &WideBvh,
        prims: &Primitives<f32>,
        ray: &Ray<f32>,
        best: &Nearest<f32>,
        from_block: Option<&LeafBlock>,
    ) -> Self {
        let (hit, triangle) = hit_record::<true>(w, prims, ray, best, from_block);
        Self { hit, triangle }
    }
}

/// The hit record of a search's result `best` for `ray`, and (with `TRIANGLE`) the hit
/// triangle; `from_block`: the leaf block of the best triangle hit, if the walk kept it (its
/// copy of the triangle gives the normal without loading the triangle again).
#[inline(always)]
pub(super) fn hit_record<const TRIANGLE: bool>(
    w: &WideBvh,
    prims: &Primitives<f32>,
    ray: &Ray<f32>,
    best: &Nearest<f32>,
    from_block: Option<&LeafBlock>,
) -> (Option<Hit<f32>>, Option<Triangle<f32>>) {
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
            let triangle = Triangle { v: [v(0), v(1), v(2)] };
            let normal = triangle.normal(ray, best.t, best.part);
            let hit = Hit {
                t: best.t,
                normal,
                prim_ref: best.prim_ref,
                part: best.part,
                tag: w.triangle_tag(best.prim_ref.index()),
                enter: ray.dir.dot(normal) < 0.0,
            };
            (Some(hit), TRIANGLE.then_some(triangle))
        }
        None if best.found => {
            let triangle = (TRIANGLE && best.prim_ref.kind() == PrimKind::Triangle)
                .then(|| prims.triangles[best.prim_ref.index()].shape);
            (Some(prims.hit(best.prim_ref, ray, best.t, best.part)), triangle)
        }
        None => (None, None),
    }
}
