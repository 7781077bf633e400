//! Million-triangle scenes from the procedural bumpy torus: the CPU's walk finds exactly the
//! brute-force hits at 5M triangles and renders them; on the GPU the scene either renders as
//! on the CPU or is refused before allocation with an error naming the buffer, its size and
//! the adapter's limit.

mod common;

use common::gpu;
use rayon::prelude::*;
use strahl::accel::wide_traverse;
use strahl::backend::cpu;
use strahl::backend::gpu::{GpuError, SceneBuffers, render::render};
use strahl::render::Prepared;
use strahl::render::camera::primary_ray;
use strahl::scene::RenderMode;
use strahl::scene::procedural::torus_scene;

#[test]
fn five_million_triangles_hit_as_brute_force_and_render_on_cpu_and_gpu() {
    let mut scene = torus_scene(5_000_000);
    scene.image.width = 96;
    scene.image.height = 72;
    let prep = Prepared::new(scene);
    assert_eq!(prep.prims.triangles.len(), 2 * 2236 * 1118);
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);

    // Camera rays through a grid of pixels: the wide walk against all 5M triangles.
    let rays: Vec<_> = (0..12).flat_map(|j| (0..16).map(move |i| (6 * i + 3, 6 * j + 3))).collect();
    let hits: usize = rays
        .par_iter()
        .map(|&(x, y)| {
            let ray = primary_ray(&frame, x, y, 0);
            let want = prep.prims.nearest_brute(&ray, 0.0, f32::INFINITY);
            assert_eq!(
                wide_traverse::nearest(&prep.wide, &prep.prims, &ray, 0.0, f32::INFINITY),
                want,
                "pixel {x},{y}"
            );
            want.is_some() as usize
        })
        .sum();
    assert!(
        hits > rays.len() / 4 && hits < rays.len(),
        "{hits} of {} rays hit: the view must show torus and sky",
        rays.len()
    );

    let cpu_image = cpu::render(&prep, &frame, RenderMode::Whitted, &|_| {});
    assert_eq!(cpu_image.non_finite_count(), 0);
    let background = prep.scene.render.background.map(|c| c as f32);
    let lit = cpu_image.pixels.iter().filter(|p| **p != background).count();
    assert!(lit > cpu_image.pixels.len() / 4, "only {lit} pixels show the torus");

    let Some(ctx) = gpu() else { return };
    match SceneBuffers::upload(&ctx, &prep.gpu) {
        Ok(buffers) => {
            let (gpu_image, _) = render(&ctx, &buffers, &frame, RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
            let a = strahl::metrics::agreement(&cpu_image, &gpu_image, 1);
            assert!(a.within_tolerance >= 0.999 && a.mean_flip < 0.005, "{a:?}");
        }
        // The 240 MB triangle array exceeds a 128 MiB storage binding (lavapipe): refused
        // before anything is allocated on the device, naming the buffer and both sizes.
        Err(e @ GpuError::TooLarge { .. }) => {
            let GpuError::TooLarge { need, limit, .. } = &e else { unreachable!() };
            assert!(need > limit && *limit == ctx.max_binding_bytes(), "{e}");
            let msg = e.to_string();
            assert!(msg.contains(&need.to_string()) && msg.contains(&limit.to_string()), "{msg}");
        }
        Err(e) => panic!("unexpected error: {e}"),
    }
}
