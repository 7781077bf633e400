//! The GPU backend under the adapter's limits: arrays larger than one storage binding are
//! split across several and read as if whole, what no split holds fails with a clear error
//! before allocation, and images taller than one output binding are rendered in bands that
//! join seamlessly. Also the command line without any Vulkan driver.

mod common;

use common::{Rng, gpu};
use std::sync::Arc;
use strahl_core::math::V3;
use strahl_core::query::RayQuery;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene};
use strahl_gpu::split::SplitArray;
use strahl_gpu::tiles::{PathAccumulator, render};
use strahl_gpu::trace::trace;
use strahl_gpu::{GpuContext, GpuError, PathKernels, SceneBuffers};

fn scene(name: &str) -> Prepared {
    Prepared::new(Scene::load(format!("{}/assets/scenes/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap())
}

#[test]
fn arrays_over_what_strahl_splits_or_the_bindings_allow_are_refused_by_name() {
    let Some(mut ctx) = gpu() else { return };
    let prep = scene("seed.toml");
    // Pretend the adapter allows 1 MiB per binding: the seed's 100k triangles (4.8 MB) would
    // need five parts of 21845 triangles, one more than strahl splits an array into.
    ctx.limits.max_storage_buffer_binding_size = 1 << 20;
    let e = SceneBuffers::upload(&ctx, &prep.flat).err().expect("an upload over the limits must fail");
    let msg = e.to_string();
    assert!(matches!(e, GpuError::TooManyParts { what: "triangles", parts: 5, .. }), "{msg}");
    for part in ["triangles", "5 storage bindings of 1048560 bytes", "max_storage_buffer_binding_size", "the 4"] {
        assert!(msg.contains(part), "{part} missing from: {msg}");
    }
    // At 2 MiB the arrays fit in 3 + 2 + 3 parts, five bindings more than the 8 storage buffers
    // per stage a pipeline binds for a scene whose arrays fit: more than 12.
    ctx.limits.max_storage_buffer_binding_size = 2 << 20;
    ctx.limits.max_storage_buffers_per_shader_stage = 12;
    let e = SceneBuffers::upload(&ctx, &prep.flat).err().expect("an upload over the bindings must fail");
    assert!(matches!(e, GpuError::TooManyBindings { need: 13, extra: 5, limit: 12 }), "{e}");
    assert!(e.to_string().contains("max_storage_buffers_per_shader_stage"), "{e}");
    // The buffer that is never split over one binding: the packed objects of the lecture's
    // three spheres (a header, 96 bytes of spheres, the materials; too few for a BVH).
    ctx.limits.max_storage_buffer_binding_size = 64;
    let lecture = scene("lecture.toml");
    let objects = strahl_gpu::objects::objects_bytes(&lecture.flat);
    assert!(objects > 64 + 96, "{objects}");
    let e = SceneBuffers::upload(&ctx, &lecture.flat).err().expect("64-byte bindings hold no scene");
    let GpuError::TooLarge { what, need, limit: 64, limit_name: "max_storage_buffer_binding_size" } = &e else {
        panic!("wrong error: {e}")
    };
    assert_eq!(*need, objects, "{e}");
    assert!(what.starts_with("the scene's objects (spheres,"), "{e}");
    // Where max_buffer_size is the smaller limit, the error names it.
    ctx.limits.max_buffer_size = 32;
    let e = SceneBuffers::upload(&ctx, &scene("lecture.toml").flat).err().expect("32-byte buffers hold no scene");
    assert!(e.to_string().contains("32 bytes, its max_buffer_size"), "{e}");
}

/// Rays at the scene's objects: one through every 9th pixel of a 160 × 120 image, and 1000
/// from around the BVH's box to points in it.
fn rays(prep: &Prepared) -> Vec<RayQuery> {
    let frame = prep.frame(160, 120);
    let mut rays: Vec<RayQuery> = (0..120 * 160)
        .step_by(9)
        .map(|i| {
            let r = strahl_core::render::camera::primary_ray(&frame, i % 160, i / 160, 0);
            RayQuery { origin: r.origin.to_f64(), dir: r.dir.to_f64(), tmin: 0.0, tmax: f64::INFINITY }
        })
        .collect();
    let root = prep.bvh.nodes[0];
    let (lo, hi) = (V3::from_array(root.bmin).to_f64(), V3::from_array(root.bmax).to_f64());
    let mut rng = Rng(3);
    rays.extend((0..1000).map(|_| {
        let mut u = || rng.range(-1.0, 1.0);
        let o = (lo + hi) * 0.5 + V3::new(u(), u(), u()).normalize() * (hi - lo).length();
        let target = V3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), rng.range(lo.z, hi.z));
        RayQuery { origin: o, dir: (target - o).normalize(), tmin: 0.0, tmax: f64::INFINITY }
    }));
    rays
}

/// A scene whose arrays exceed the (pretended) binding limit is uploaded in parts and renders,
/// path-traces (both path kernels: emitters are read from the split triangles) and traces
/// (hits' tags and normals too) exactly as when each array is whole: the same numbers from the
/// same elements. The seed at 2 MiB per binding splits triangles, nodes and leaf triangles in 3,
/// 2 and 3; a 80k-triangle torus at 1 MiB in 4, 3 and 4, the most strahl splits into.
#[test]
fn arrays_split_across_bindings_are_read_as_if_whole() {
    let Some(whole_ctx) = gpu() else { return };
    let whole_ctx = Arc::new(whole_ctx);
    let torus = {
        let mut s = strahl_core::scene::procedural::torus_scene(80_000);
        s.image.width = 160;
        s.image.height = 120;
        Prepared::new(s)
    };
    for (name, prep, limit, parts, path) in
        [("seed", scene("seed.toml"), 2 << 20, [3, 2, 3], true), ("torus", torus, 1 << 20, [4, 3, 4], false)]
    {
        let mut split_ctx = GpuContext::new().unwrap();
        split_ctx.limits.max_storage_buffer_binding_size = limit;
        let split_ctx = Arc::new(split_ctx);
        let whole = SceneBuffers::upload(&whole_ctx, &prep.flat).unwrap();
        let split = SceneBuffers::upload(&split_ctx, &prep.flat).unwrap();
        assert!(!whole.split().is_split(), "{name}");
        assert_eq!(SplitArray::ALL.map(|a| split.split().parts(a)), parts, "{name}: {}", split.key.label());
        assert_eq!(split.bytes, whole.bytes, "{name}: every byte uploaded once");
        assert!(!split.runs_with(whole.key) && !whole.runs_with(split.key), "{name}: the variants differ");

        let frame = prep.frame(160, 120);
        let draw = |ctx: &GpuContext, b: &SceneBuffers| {
            render(ctx, b, &frame, RenderMode::Whitted, b.key, &|_, _| {}).unwrap().0
        };
        assert_eq!(draw(&split_ctx, &split).pixels, draw(&whole_ctx, &whole).pixels, "{name}: Whitted");
        if path {
            for kernels in [PathKernels::Megakernel, PathKernels::Wavefront] {
                let trace_path = |ctx: &Arc<GpuContext>, b: &SceneBuffers| {
                    let mut p = PathAccumulator::with_kernels(ctx.clone(), b.clone(), frame, kernels).unwrap();
                    p.add_samples(2).unwrap();
                    p.image().unwrap().pixels
                };
                assert_eq!(trace_path(&split_ctx, &split), trace_path(&whole_ctx, &whole), "{name}: {kernels:?}");
            }
        }
        let rays = rays(&prep);
        for all in [false, true] {
            let got = trace(&split_ctx, &split, &rays, all).unwrap();
            assert_eq!(got, trace(&whole_ctx, &whole, &rays, all).unwrap(), "{name}: trace, all = {all}");
            assert!(got.iter().filter(|h| !h.is_empty()).count() > rays.len() / 4, "{name}: too few hits to judge");
        }
    }
}

#[test]
fn images_taller_than_one_binding_render_in_seamless_bands() {
    let Some(mut ctx) = gpu() else { return };
    let prep = scene("cylinder.toml");
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
    let buffers = SceneBuffers::upload(&ctx, &prep.flat).unwrap();
    let (whole, one) =
        render(&ctx, &buffers, &frame, strahl_core::scene::RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
    // Room for 37 rows per output binding: the image needs several bands, none tile-aligned.
    ctx.limits.max_storage_buffer_binding_size = frame.width as u64 * 16 * 37;
    let (banded, many) =
        render(&ctx, &buffers, &frame, strahl_core::scene::RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
    assert!(many.dispatches > one.dispatches, "{} vs {} dispatches", many.dispatches, one.dispatches);
    assert_eq!(whole, banded, "bands must join into the same image");
    // One row that does not fit is a clear error, not a crash.
    ctx.limits.max_storage_buffer_binding_size = 64;
    let err =
        render(&ctx, &buffers, &frame, strahl_core::scene::RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap_err();
    assert!(matches!(err, GpuError::TooLarge { .. }), "{err}");
}

/// Without any Vulkan driver, `render` (backend auto) says in one line that it renders on the
/// CPU, while `--backend gpu` fails with the hint to install lavapipe.
#[test]
fn without_a_vulkan_driver_render_falls_back_and_explicit_gpu_explains() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let scene = format!("{}/assets/scenes/sphere.toml", env!("CARGO_MANIFEST_DIR"));
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_strahl"))
            .args(["render", &scene, "-o", out.to_str().unwrap(), "--width", "32", "--height", "24"])
            .args(extra)
            // Point the Vulkan loader at no driver at all.
            .env("VK_DRIVER_FILES", dir.path().join("none.json"))
            .env("VK_ICD_FILENAMES", dir.path().join("none.json"))
            // and search Vulkan only: GL would find llvmpipe.
            .env("WGPU_BACKEND", "vulkan")
            .output()
            .unwrap()
    };
    let auto = run(&[]);
    let stderr = String::from_utf8_lossy(&auto.stderr);
    assert!(auto.status.success(), "{stderr}");
    let notes: Vec<&str> = stderr.lines().filter(|l| l.starts_with("backend: ")).collect();
    assert_eq!(notes, ["backend: cpu (no GPU adapter found)"], "{stderr}");
    assert!(out.exists());
    let explicit = run(&["--backend", "gpu"]);
    let stderr = String::from_utf8_lossy(&explicit.stderr);
    assert!(!explicit.status.success());
    assert!(stderr.contains("no GPU adapter") && stderr.contains("mesa-vulkan-drivers"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}
