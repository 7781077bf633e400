//! The GPU backend against the CPU reference (f32 mirror) on every shipped scene: ray queries
//! and images. Runs on lavapipe in CI.

mod common;

use common::{Rng, gpu, shipped_scenes};
use strahl::backend::cpu;
use strahl::backend::gpu::{GpuContext, SceneBuffers, render::render, trace::trace};
use strahl::math::V3;
use strahl::primitives::Hit;
use strahl::query::RayQuery;
use strahl::render::{Prepared, camera::primary_ray};
use strahl::scene::Scene;

/// Camera rays through random sub-pixel positions, and random rays from around the scene
/// towards random points of its bounds.
fn test_rays(prep: &Prepared, n: usize, seed: u64) -> Vec<RayQuery> {
    let mut rng = Rng(seed);
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
    let (lo, hi) = match prep.bvh.nodes.first() {
        Some(root) => (V3::from_array(root.bmin).cast::<f64>(), V3::from_array(root.bmax).cast::<f64>()),
        None => (V3::splat(-10.0), V3::splat(10.0)),
    };
    let size = (hi - lo).length().max(1.0);
    let centre = (lo + hi) * 0.5;
    (0..n)
        .map(|i| {
            let (origin, dir) = if i % 2 == 0 {
                let x = (rng.unit() * frame.width as f64) as u32;
                let y = (rng.unit() * frame.height as f64) as u32;
                let r = primary_ray(&frame, x, y, (rng.next_u64() % 64) as u32);
                (r.origin.to_f64(), r.dir.to_f64())
            } else {
                let mut u = || rng.range(-1.0, 1.0);
                let o = centre + V3::new(u(), u(), u()) * size;
                let target = V3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), rng.range(lo.z, hi.z));
                (o, (target - o).normalize())
            };
            RayQuery {
                origin: origin.cast::<f32>().cast(),
                dir: dir.cast::<f32>().cast(),
                tmin: 0.0,
                tmax: f64::INFINITY,
            }
        })
        .collect()
}

/// Same primitive, t within a relative 1e-4, normals within 0.3°, same enter flag.
fn same_hit(a: &Hit<f32>, b: &Hit<f32>) -> bool {
    a.prim == b.prim
        && a.tag.object == b.tag.object
        && a.tag.prim == b.tag.prim
        && (a.t - b.t).abs() <= 1e-4 * a.t.abs().max(1.0)
        && a.normal.dot(b.normal) > 0.99999
        && a.enter == b.enter
}

fn compare_traces(ctx: &GpuContext, path: &std::path::Path) {
    let scene = Scene::load(path).unwrap();
    let prep = Prepared::new(scene.clone());
    let buffers = SceneBuffers::upload(ctx, &prep.gpu).unwrap();
    let rays = test_rays(&prep, 4000, 17);
    for all in [false, true] {
        let want = cpu::trace::<f32>(&scene, &rays, all);
        let got = trace(ctx, &buffers, &rays, all).unwrap();
        assert_eq!(want.len(), got.len());
        let mut disagree = 0;
        let mut hits = 0;
        for (w, g) in want.iter().zip(&got) {
            hits += w.len();
            if w.len() != g.len() || !w.iter().zip(g).all(|(a, b)| same_hit(a, b)) {
                disagree += 1;
            }
        }
        // Rays within a rounding error of an edge or a tangent may legitimately differ: allow
        // 0.1 %, which a systematic error (a wrong normal, a missed primitive kind) exceeds.
        let allowed = rays.len() / 1000;
        assert!(
            disagree <= allowed,
            "{}: {disagree} of {} rays differ between GPU and CPU (all = {all}), {allowed} allowed",
            path.display(),
            rays.len()
        );
        assert!(hits > rays.len() / 10, "{}: too few hits ({hits}) to judge", path.display());
    }
}

#[test]
fn gpu_trace_matches_cpu_on_every_shipped_scene() {
    let Some(ctx) = gpu() else { return };
    for path in shipped_scenes() {
        compare_traces(&ctx, &path);
    }
}

/// The lecture's worked example, through the GPU trace kernel: exactly the analytic values.
#[test]
fn lecture_example_is_bit_exact_on_gpu() {
    let Some(ctx) = gpu() else { return };
    let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/lecture.toml")).unwrap();
    let prep = Prepared::new(scene);
    let buffers = SceneBuffers::upload(&ctx, &prep.gpu).unwrap();
    let ray = RayQuery { origin: V3::zero(), dir: V3::new(0.0, 0.0, 1.0), tmin: 0.0, tmax: f64::INFINITY };
    let all = trace(&ctx, &buffers, &[ray], true).unwrap();
    let rows: Vec<(f32, u32, bool, [f32; 3])> =
        all[0].iter().map(|h| (h.t, h.tag.object, h.enter, h.normal.to_array())).collect();
    assert_eq!(
        rows,
        vec![
            (3.0, 0, true, [0.0, 0.0, -1.0]),
            (6.0, 1, true, [0.0, 0.0, -1.0]),
            (12.0, 1, false, [0.0, 0.0, 1.0]),
            (13.0, 0, false, [0.0, 0.0, 1.0]),
        ]
    );
    let nearest = trace(&ctx, &buffers, &[ray], false).unwrap();
    assert_eq!((nearest[0][0].t, nearest[0][0].tag.object), (3.0, 0));
}

/// Empty results read back cleanly from every trace kernel: no rays at all, a batch in which
/// no ray hits anything (zero hit records in --all mode), and spawned-ray pairs of none.
#[test]
fn zero_size_results_read_back_from_every_kernel() {
    let Some(ctx) = gpu() else { return };
    let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/lecture.toml")).unwrap();
    let prep = Prepared::new(scene.clone());
    let buffers = SceneBuffers::upload(&ctx, &prep.gpu).unwrap();
    let miss =
        RayQuery { origin: V3::new(0.0, 20.0, 0.0), dir: V3::new(0.0, 0.0, 1.0), tmin: 0.0, tmax: f64::INFINITY };
    for all in [false, true] {
        assert!(trace(&ctx, &buffers, &[], all).unwrap().is_empty(), "no rays, all = {all}");
        let got = trace(&ctx, &buffers, &[miss, miss], all).unwrap();
        assert_eq!(got, cpu::trace::<f32>(&scene, &[miss, miss], all), "all = {all}");
        assert_eq!(got, vec![Vec::new(), Vec::new()]);
    }
    let spawn = strahl::backend::gpu::trace::trace_spawn(&ctx, &buffers, &[]).unwrap();
    assert!(spawn.is_empty());
}

/// Images: at least 99.9 % of pixels within one 8-bit code per channel, and a mean FLIP
/// below 0.005. FLIP is about 0.05 where a difference first becomes noticeable at a glance
/// (Andersson et al. 2020); a handful of edge pixels flipping between two surfaces gives a
/// mean of the order of 1e-4, while a wrong shading term gives well over 0.01.
#[test]
fn gpu_images_match_cpu_on_every_shipped_scene() {
    let Some(ctx) = gpu() else { return };
    for path in shipped_scenes() {
        let prep = Prepared::new(Scene::load(&path).unwrap());
        let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
        let want = cpu::render(&prep, &frame, strahl::scene::RenderMode::Whitted, &|_| {});
        let buffers = SceneBuffers::upload(&ctx, &prep.gpu).unwrap();
        let (got, _) =
            render(&ctx, &buffers, &frame, strahl::scene::RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
        assert_eq!(got.non_finite_count(), 0, "{}", path.display());
        let a = strahl::metrics::agreement(&want, &got, 1);
        eprintln!("{}: {:?}", path.display(), a);
        assert!(a.within_tolerance >= 0.999, "{}: {a:?}", path.display());
        assert!(a.mean_flip < 0.005, "{}: {a:?}", path.display());
    }
}

/// The all-features shader renders a scene exactly as its specialised shader does, up to
/// rounding: leaving code out changes nothing else.
#[test]
fn all_features_shader_agrees_with_the_specialised_one() {
    use strahl::backend::gpu::FeatureKey;
    let Some(ctx) = gpu() else { return };
    for name in ["sphere.toml", "polygon.toml"] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes").join(name);
        let prep = Prepared::new(Scene::load(&path).unwrap());
        let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
        let buffers = SceneBuffers::upload(&ctx, &prep.gpu).unwrap();
        assert_ne!(buffers.key, FeatureKey::ALL);
        let (a, _) =
            render(&ctx, &buffers, &frame, strahl::scene::RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
        let (b, _) =
            render(&ctx, &buffers, &frame, strahl::scene::RenderMode::Whitted, FeatureKey::ALL, &|_, _| {}).unwrap();
        let agree = strahl::metrics::agreement(&a, &b, 1);
        assert!(agree.within_tolerance >= 0.999, "{name}: {agree:?}");
    }
}
