//! Million-triangle scenes from the procedural bumpy torus: the CPU's walk finds exactly the
//! brute-force hits at 5M triangles and renders them; the GPU renders and traces the scene as
//! the CPU does, its arrays split across storage bindings where they exceed one (lavapipe:
//! 128 MiB). What no split holds is refused before allocation: tests/gpu_limits.rs and
//! crates/gpu/src/split.rs.

mod common;

use common::gpu;
use rayon::prelude::*;
use strahl_core::image::Image;
use strahl_core::primitives::Hit;
use strahl_core::query::RayQuery;
use strahl_core::render::Prepared;
use strahl_core::render::camera::primary_ray;
use strahl_core::scene::RenderMode;
use strahl_core::scene::procedural::torus_scene;
use strahl_cpu as cpu;
use strahl_cpu::accel::wide_traverse;
use strahl_gpu::split::SplitArray;
use strahl_gpu::{GpuContext, SceneBuffers, render, trace::trace};

#[test]
fn five_million_triangles_hit_as_brute_force_and_render_on_cpu_and_gpu() {
    let mut scene = torus_scene(5_000_000);
    scene.image.width = 96;
    scene.image.height = 72;
    let prep = Prepared::new(scene);
    assert_eq!(prep.prims.triangles.len(), 2 * 2236 * 1118);
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
    let on_cpu = cpu::CpuScene::new(&prep);

    // Camera rays through a grid of pixels: the wide walk against all 5M triangles.
    let rays: Vec<_> = (0..12).flat_map(|j| (0..16).map(move |i| (6 * i + 3, 6 * j + 3))).collect();
    let hits: usize = rays
        .par_iter()
        .map(|&(x, y)| {
            let ray = primary_ray(&frame, x, y, 0);
            let want = prep.prims.nearest_brute(&ray, 0.0, f32::INFINITY);
            assert_eq!(
                wide_traverse::nearest(&on_cpu.wide, &prep.prims, &ray, 0.0, f32::INFINITY),
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

    let cpu_image = cpu::render(&on_cpu, &frame, RenderMode::Whitted, &|_| {});
    assert_eq!(cpu_image.non_finite_count(), 0);
    let background = prep.scene.render.background.map(|c| c as f32);
    let lit = cpu_image.pixels.iter().filter(|p| **p != background).count();
    assert!(lit > cpu_image.pixels.len() / 4, "only {lit} pixels show the torus");

    let Some(ctx) = gpu() else { return };
    // On an adapter whose bindings hold less than the 240 MB of triangles (lavapipe: 128 MiB)
    // the triangles, nodes and leaf triangles are uploaded in parts, and the variant reads them
    // so.
    let start = std::time::Instant::now();
    let buffers = SceneBuffers::upload(&ctx, &prep.flat).unwrap();
    let triangle_bytes = std::mem::size_of_val(prep.flat.triangles.as_slice()) as u64;
    let over = triangle_bytes > ctx.max_binding_bytes();
    assert_eq!(buffers.split().parts(SplitArray::Triangles) > 1, over, "{}", buffers.key.label());
    assert_gpu_renders_as_cpu(&ctx, &prep, &buffers, &cpu_image);
    // Hits' tags and normals come from the scene-order triangles: the GPU finds the CPU's.
    let queries: Vec<RayQuery> = rays
        .iter()
        .map(|&(x, y)| {
            let r = primary_ray(&frame, x, y, 0);
            RayQuery { origin: r.origin.to_f64(), dir: r.dir.to_f64(), tmin: 0.0, tmax: f64::INFINITY }
        })
        .collect();
    let got = trace(&ctx, &buffers, &queries, false).unwrap();
    let want = cpu::trace::<f32>(&prep.scene, &queries, false);
    let same = |a: &[Hit<f32>], b: &[Hit<f32>]| match (a, b) {
        ([], []) => true,
        ([a], [b]) => {
            a.prim_ref == b.prim_ref
                && (a.tag.object, a.tag.face) == (b.tag.object, b.tag.face)
                && (a.t - b.t).abs() <= 1e-4 * a.t
        }
        _ => false,
    };
    let differ = got.iter().zip(&want).filter(|(g, w)| !same(g, w)).count();
    assert!(differ <= 2, "{differ} of {} rays differ between GPU and CPU", queries.len());
    eprintln!(
        "5M triangles on {}: {} ({}), uploaded, rendered and traced in {:.1} s",
        ctx.adapter_name(),
        buffers.key.label(),
        if over { "split" } else { "whole" },
        start.elapsed().as_secs_f64()
    );
}

/// The GPU's Whitted render of `prep` (uploaded as `buffers`) at the frame of its scene's
/// image matches `cpu_image`.
fn assert_gpu_renders_as_cpu(ctx: &GpuContext, prep: &Prepared, buffers: &SceneBuffers, cpu_image: &Image) {
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
    let (gpu_image, _) = render(ctx, buffers, &frame, RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
    let a = strahl_metrics::agreement(cpu_image, &gpu_image, 1);
    assert!(a.within_tolerance >= 0.999 && a.mean_flip < 0.005, "{} triangles: {a:?}", prep.prims.triangles.len());
}
