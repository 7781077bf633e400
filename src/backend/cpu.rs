//! The CPU backend: the f32 mirror of the GPU, run with rayon over image rows.

use crate::gpu_types::GpuFrame;
use crate::image::Image;
use crate::render::Prepared;
use crate::render::shade::{ShadeInputs, shade_pixel};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Renders the image described by `frame` (its `width`, `height`, `spp`, `sample_base`).
/// `progress` is called with the number of rows finished so far, from worker threads.
pub fn render(prep: &Prepared, frame: &GpuFrame, progress: &(dyn Fn(u64) + Sync)) -> Image {
    let inputs = ShadeInputs { prims: &prep.prims, bvh: &prep.bvh, gpu: &prep.gpu, frame };
    let mut img = Image::new(frame.width, frame.height);
    let done = AtomicU64::new(0);
    img.pixels.par_chunks_mut(frame.width as usize).enumerate().for_each(|(y, row)| {
        for (x, px) in row.iter_mut().enumerate() {
            *px = shade_pixel(&inputs, x as u32, y as u32);
        }
        progress(done.fetch_add(1, Ordering::Relaxed) + 1);
    });
    img
}

/// Answers ray queries in precision `R` (f32: the GPU's mirror; f64: the oracle): the
/// nearest hit per ray, or with `all` every hit sorted by `t`.
pub fn trace<R: crate::math::Real>(
    scene: &crate::scene::Scene,
    rays: &[crate::query::RayQuery],
    all: bool,
) -> Vec<Vec<crate::primitives::Hit<R>>> {
    use crate::accel::{Bvh, traverse};
    let prims = crate::primitives::Primitives::<R>::from_scene(scene);
    let bvh = Bvh::build(&prims);
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
