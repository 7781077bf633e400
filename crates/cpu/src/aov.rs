//! Output variables besides radiance on the CPU (`aov.wgsl` is the twin): the passes of
//! [`strahl_core::render::aov`] over a region's pixels, rows spread over rayon's threads. A
//! pixel's value is the sum of its camera rays' values in sample order divided by their
//! number, as the GPU's passes add them; the albedo and normal passes share one walk per ray.

use crate::accel::wide_traverse;
use crate::shade::ShadeInputs;
use rayon::prelude::*;
use strahl_core::image::Region;
use strahl_core::math::Ray;
use strahl_core::render::aov::{self, AOV_PASS_ALBEDO, AOV_PASS_NORMAL, Aov, AovImages};
use strahl_core::render::camera::primary_ray;

/// The AOVs `aovs` of the pixels of `region` of the image `inp.frame` describes.
pub fn render_aovs(inp: &ShadeInputs, region: Region, aovs: &[Aov]) -> AovImages {
    let pass_ids = aov::passes(aovs);
    let (f, g) = (inp.frame, inp.flat);
    let nearest = |r: &Ray<f32>| wide_traverse::nearest(inp.wide, inp.prims, r, 0.0, f32::INFINITY);
    let counts: Vec<u32> = pass_ids.iter().map(|&p| aov::aov_samples(p, f.spp)).collect();
    let w = region.width() as usize;
    let n = w * region.height() as usize;
    // Each pixel's values of every pass, pass after pass.
    let mut values = vec![[0.0f32; 3]; n * pass_ids.len()];
    values.par_chunks_mut(w * pass_ids.len()).enumerate().for_each(|(row, out)| {
        let y = region.y0 + row as u32;
        for (i, px) in out.chunks_mut(pass_ids.len()).enumerate() {
            let x = region.x0 + i as u32;
            let most = counts.iter().copied().max().unwrap_or(0);
            for s in 0..most {
                let ray = primary_ray(f, x, y, s);
                let mut guides = None;
                for (k, &pass) in pass_ids.iter().enumerate() {
                    if s >= counts[k] {
                        continue;
                    }
                    let v = match pass {
                        AOV_PASS_ALBEDO | AOV_PASS_NORMAL => {
                            let (albedo, normal) = *guides.get_or_insert_with(|| aov::guides(g, f, ray, nearest));
                            if pass == AOV_PASS_ALBEDO { albedo } else { normal }
                        }
                        _ => aov::first_hit(g, pass, ray, nearest),
                    };
                    for (sum, v) in px[k].iter_mut().zip(v) {
                        *sum += v;
                    }
                }
            }
            for (k, v) in px.iter_mut().enumerate() {
                *v = v.map(|c| c / counts[k] as f32);
            }
        }
    });
    let passes: Vec<Vec<[f32; 3]>> =
        (0..pass_ids.len()).map(|k| values.iter().skip(k).step_by(pass_ids.len()).copied().collect()).collect();
    AovImages::from_passes(region.width(), region.height(), aovs, &pass_ids, &passes)
}
