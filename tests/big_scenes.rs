//! Million-triangle scenes from the procedural bumpy torus: the CPU's walk finds exactly the
//! brute-force hits at 5M triangles and renders them; on the GPU the scene renders as on the
//! CPU where its arrays fit one storage binding each, and is otherwise refused before
//! allocation with an error naming the buffer, its size and the adapter's limit; then the
//! largest torus that fits renders as on the CPU.

mod common;

use common::gpu;
use rayon::prelude::*;
use strahl::accel::wide_traverse;
use strahl::backend::cpu;
use strahl::backend::gpu::{GpuContext, GpuError, SceneBuffers, render::render};
use strahl::image::Image;
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
    let limit = ctx.max_binding_bytes();
    let triangle_bytes = std::mem::size_of_val(prep.gpu.triangles.as_slice()) as u64;
    if triangle_bytes <= limit {
        assert_gpu_renders_as_cpu(&ctx, &prep, &cpu_image);
        return;
    }
    // The 240 MB triangle array exceeds one storage binding (lavapipe: 128 MiB): refused before
    // anything is allocated on the device, naming the buffer and both sizes.
    let e = SceneBuffers::upload(&ctx, &prep.gpu).err().expect("an upload over the binding limit must fail");
    let GpuError::TooLarge { what, need, limit: named } = &e else { panic!("unexpected error: {e}") };
    assert_eq!((what.as_str(), *need, *named), ("triangles", triangle_bytes, limit), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("triangles") && msg.contains(&need.to_string()) && msg.contains(&limit.to_string()), "{msg}");
    drop(prep);

    // The largest torus this adapter's bindings hold (with a tenth to spare) renders on the GPU
    // as on the CPU.
    let fits = (limit / size_of::<strahl::gpu_types::GpuTriangle>() as u64) * 9 / 10;
    let mut scene = torus_scene(fits as usize);
    scene.image.width = 96;
    scene.image.height = 72;
    let prep = Prepared::new(scene);
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
    let cpu_image = cpu::render(&prep, &frame, RenderMode::Whitted, &|_| {});
    assert_gpu_renders_as_cpu(&ctx, &prep, &cpu_image);
}

/// The GPU's Whitted render of `prep` at the frame of its scene's image matches `cpu_image`.
fn assert_gpu_renders_as_cpu(ctx: &GpuContext, prep: &Prepared, cpu_image: &Image) {
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
    let buffers = SceneBuffers::upload(ctx, &prep.gpu).unwrap();
    let (gpu_image, _) = render(ctx, &buffers, &frame, RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
    let a = strahl::metrics::agreement(cpu_image, &gpu_image, 1);
    assert!(a.within_tolerance >= 0.999 && a.mean_flip < 0.005, "{} triangles: {a:?}", prep.prims.triangles.len());
}
