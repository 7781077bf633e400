//! Ray queries on the CPU, the twin of `shaders/trace.wgsl`: the nearest or every hit of each
//! ray, in f32 (the GPU's mirror, by the 8-wide walks) or f64 (the oracle, by the binary
//! tree's walk), and spawned rays.

use rayon::prelude::*;

/// Answers ray queries in precision `R` (f32: the GPU's mirror; f64: the oracle): the
/// nearest hit per ray, or with `all` every hit sorted by `t`.
pub fn trace<R: strahl_core::math::Real>(
    scene: &strahl_core::scene::Scene,
    rays: &[strahl_core::query::RayQuery],
    all: bool,
) -> Vec<Vec<strahl_core::primitives::Hit<R>>> {
    use crate::accel::{WideBvh, binary as traverse, wide_all, wide_traverse};
    use std::any::Any;
    use strahl_core::accel::Bvh;
    use strahl_core::primitives::{Hit, Primitives};
    let prims = Primitives::<R>::from_scene(scene);
    let bvh = Bvh::build(&prims);
    // Queries in f32 take the CPU's 8-wide walks (the same answers, faster).
    if let Some(p32) = (&prims as &dyn Any).downcast_ref::<Primitives<f32>>() {
        let wide = WideBvh::new(&bvh, p32);
        let hits: Vec<Vec<Hit<f32>>> = rays
            .par_iter()
            .map(|q| {
                let (ray, tmin, tmax) = (q.ray(), q.tmin as f32, q.tmax as f32);
                if all {
                    let mut hits = Vec::new();
                    wide_all::all(&wide, p32, &ray, tmin, tmax, &mut hits);
                    hits
                } else {
                    wide_traverse::nearest(&wide, p32, &ray, tmin, tmax).into_iter().collect()
                }
            })
            .collect();
        let hits: Box<dyn Any> = Box::new(hits);
        return *hits.downcast::<Vec<Vec<Hit<R>>>>().expect("R is f32 here");
    }
    rays.par_iter()
        .map(|q| {
            let ray = q.ray::<R>();
            let (tmin, tmax) = (R::from_f64(q.tmin), R::from_f64(q.tmax));
            if all {
                traverse::all(&bvh, &prims, &ray, tmin, tmax)
            } else {
                traverse::nearest(&bvh, &prims, &ray, tmin, tmax).into_iter().collect()
            }
        })
        .collect()
}

/// Spawned rays, the twin of `trace_spawn` in `shaders/trace.wgsl`: `pairs[i].0` is traced to
/// its nearest hit; from there a ray leaves along `pairs[i].1` (unit), starting at the hit
/// point moved off the surface by [`strahl_core::render::spawn::spawn_origin`] to the side it
/// leaves from. Returns (first hit, spawned ray's nearest hit) per pair.
pub fn trace_spawn(
    prims: &strahl_core::primitives::Primitives<f32>,
    bvh: &strahl_core::accel::Bvh,
    pairs: &[(strahl_core::math::Ray<f32>, strahl_core::math::V3<f32>)],
) -> Vec<strahl_core::SpawnHits> {
    use strahl_core::math::Ray;
    let wide = crate::accel::WideBvh::new(bvh, prims);
    let nearest = |ray: &Ray<f32>| crate::accel::wide_traverse::nearest(&wide, prims, ray, 0.0, f32::INFINITY);
    pairs
        .par_iter()
        .map(|(ray, dir2)| {
            let Some(first) = nearest(ray) else {
                return (None, None);
            };
            let side = if dir2.dot(first.normal) >= 0.0 { first.normal } else { -first.normal };
            let o2 = strahl_core::render::spawn::spawn_origin(ray, first.t, side);
            (Some(first), nearest(&Ray::new(o2, *dir2)))
        })
        .collect()
}
