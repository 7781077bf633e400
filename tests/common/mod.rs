//! Shared helpers of the integration tests.
#![allow(dead_code)]

use strahl_gpu::GpuContext;

/// Records that the running test skipped (all or part of) its checks, and why: a line
/// `SKIPPED <test>: <why>` on standard error (shown with the test's output), and the same line
/// appended to the file `STRAHL_SKIP_LOG` names, where set. `.ci/run` sets it, counts the
/// lines and fails when any test it expects to run skipped.
pub fn skip(why: &str) {
    let test = std::thread::current().name().unwrap_or("a test").to_string();
    let line = format!("SKIPPED {test}: {why}");
    eprintln!("{line}");
    if let Some(log) = std::env::var_os("STRAHL_SKIP_LOG") {
        use std::io::Write;
        let appended =
            std::fs::OpenOptions::new().create(true).append(true).open(&log).and_then(|mut f| writeln!(f, "{line}"));
        if let Err(e) = appended {
            panic!("cannot record the skip in {}: {e}", std::path::Path::new(&log).display());
        }
    }
}

/// Whether GPU tests may skip where their device or tools are missing (STRAHL_SKIP_GPU_TESTS=1).
pub fn gpu_tests_may_skip() -> bool {
    std::env::var("STRAHL_SKIP_GPU_TESTS").is_ok_and(|v| v == "1")
}

/// The variable naming (part of) the adapter the GPU tests must run on, in any case: where it
/// is set and the adapter strahl takes has another name, [`gpu`] fails the test. `.ci/run`
/// sets it beside `WGPU_BACKEND` or `VK_DRIVER_FILES` when it runs the GPU tests on another
/// driver, so that a driver that cannot be found fails there instead of leaving the tests on
/// lavapipe. The CLI tests' `strahl` processes inherit the same variables and choose the same
/// way.
pub const EXPECT_ADAPTER_VAR: &str = "STRAHL_EXPECT_ADAPTER";

/// The GPU context for GPU tests: lavapipe in CI. Without any adapter the test fails with the
/// install hint, unless STRAHL_SKIP_GPU_TESTS=1 asks to skip (returns None, the skip recorded
/// by [`skip`]); with an adapter other than [`EXPECT_ADAPTER_VAR`] names, it fails.
pub fn gpu() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => {
            if let Ok(want) = std::env::var(EXPECT_ADAPTER_VAR) {
                let info = &ctx.adapter_info;
                assert!(
                    info.name.to_lowercase().contains(&want.to_lowercase()),
                    "{EXPECT_ADAPTER_VAR}={want}, but the tests got {}",
                    strahl_gpu::instance::describe(info)
                );
            }
            Some(ctx)
        }
        Err(e) if gpu_tests_may_skip() => {
            skip(&format!("no GPU: {e}"));
            None
        }
        Err(e) => panic!("{e} (set STRAHL_SKIP_GPU_TESTS=1 to skip GPU tests)"),
    }
}

#[allow(unused_imports)] // not every test binary reads the shipped scenes or makes images
pub use strahl_core::testutil::{png, shipped_scenes};

/// Deterministic test randomness: the crate's SplitMix64.
#[allow(unused_imports)] // not every test binary draws random rays
pub use strahl_core::rng::SplitMix64 as Rng;

/// The mean of `spp` path-traced samples per pixel of `frame` on the CPU.
pub fn cpu_path_image(
    prep: &std::sync::Arc<strahl_core::render::Prepared>,
    frame: strahl_core::layout::FrameParams,
    spp: u32,
) -> strahl_core::image::Image {
    let mut p = strahl_cpu::PathAccumulator::new(prep.clone(), frame);
    p.add_samples(spp);
    p.image()
}

/// The mean of `spp` path-traced samples per pixel of `frame` on the GPU.
pub fn gpu_path_image(
    ctx: &std::sync::Arc<GpuContext>,
    prep: &strahl_core::render::Prepared,
    frame: strahl_core::layout::FrameParams,
    spp: u32,
) -> strahl_core::image::Image {
    let buffers = strahl_gpu::SceneBuffers::upload(ctx, &prep.flat).unwrap();
    let mut p = strahl_gpu::tiles::PathAccumulator::new(ctx.clone(), buffers, frame).unwrap();
    p.add_samples(spp).unwrap();
    p.image().unwrap()
}

/// Camera rays through random sub-pixel positions, and random rays from around the scene
/// towards random points of its bounds.
pub fn test_rays(prep: &strahl_core::render::Prepared, n: usize, seed: u64) -> Vec<strahl_core::query::RayQuery> {
    let mut rng = Rng(seed);
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
    let (lo, hi) = match prep.bvh.nodes.first() {
        Some(root) => (
            strahl_core::math::V3::from_array(root.bmin).cast::<f64>(),
            strahl_core::math::V3::from_array(root.bmax).cast::<f64>(),
        ),
        None => (strahl_core::math::V3::splat(-10.0), strahl_core::math::V3::splat(10.0)),
    };
    let size = (hi - lo).length().max(1.0);
    let centre = (lo + hi) * 0.5;
    (0..n)
        .map(|i| {
            let (origin, dir) = if i % 2 == 0 {
                let x = (rng.unit() * frame.width as f64) as u32;
                let y = (rng.unit() * frame.height as f64) as u32;
                let r = strahl_core::render::camera::primary_ray(&frame, x, y, (rng.next_u64() % 64) as u32);
                (r.origin.to_f64(), r.dir.to_f64())
            } else {
                let mut u = || rng.range(-1.0, 1.0);
                let o = centre + strahl_core::math::V3::new(u(), u(), u()) * size;
                let target =
                    strahl_core::math::V3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), rng.range(lo.z, hi.z));
                (o, (target - o).normalize())
            };
            strahl_core::query::RayQuery {
                origin: origin.cast::<f32>().cast(),
                dir: dir.cast::<f32>().cast(),
                tmin: 0.0,
                tmax: f64::INFINITY,
            }
        })
        .collect()
}

/// Same primitive, t within a relative 1e-4, normals within 0.3°, same enter flag.
pub fn same_hit(a: &strahl_core::primitives::Hit<f32>, b: &strahl_core::primitives::Hit<f32>) -> bool {
    a.prim_ref == b.prim_ref
        && a.tag.object == b.tag.object
        && a.tag.face == b.tag.face
        && (a.t - b.t).abs() <= 1e-4 * a.t.abs().max(1.0)
        && a.normal.dot(b.normal) > 0.99999
        && a.enter == b.enter
}

/// `n` rays at points of the seed floor's diagonal, the edge its two triangles share (its
/// corners (-30, -5, -20)-(30, -5, 40) and (-30, -5, 40)-(30, -5, -20), alternately), from
/// random points above it, every coordinate an f32.
pub fn shared_edge_rays(n: usize, seed: u64) -> Vec<strahl_core::query::RayQuery> {
    use strahl_core::math::V3;
    let mut rng = Rng(seed);
    let (a, b) = (V3::new(-30.0, -5.0, -20.0), V3::new(30.0, -5.0, 40.0));
    let (c, d) = (V3::new(-30.0, -5.0, 40.0), V3::new(30.0, -5.0, -20.0));
    (0..n)
        .map(|i| {
            let (p, q) = if i % 2 == 0 { (a, b) } else { (c, d) };
            let target: V3<f64> = (p + (q - p) * rng.unit()).cast::<f32>().cast();
            let o: V3<f64> =
                V3::new(rng.range(-40.0, 40.0), rng.range(-4.0, 30.0), rng.range(-30.0, 50.0)).cast::<f32>().cast();
            let dir = (target - o).normalize().cast::<f32>().cast();
            strahl_core::query::RayQuery { origin: o, dir, tmin: 0.0, tmax: f64::INFINITY }
        })
        .collect()
}

/// The share of pixels of two images rendered from the same samples (the GPU's and the
/// CPU's) whose channels agree to 1e-3·(1 + |x|): the same paths except where f32 rounding
/// flips a branch (a Fresnel or roulette draw on the edge).
pub fn agreeing_fraction(a: &strahl_core::image::Image, b: &strahl_core::image::Image) -> f64 {
    let close = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(p, q)| p.iter().zip(q.iter()).all(|(x, y)| (x - y).abs() <= 1e-3 * (1.0 + x.abs())))
        .count();
    close as f64 / a.pixels.len() as f64
}

/// Mean over the given pixels (channels averaged) and its standard error from their spread
/// (pixels are independent estimates).
pub fn mean_and_error(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// An EXR file's pixels, each channel as its bits, so that -0.0 and 0.0 are told apart.
pub fn exr_bits(p: &std::path::Path) -> Vec<[u32; 3]> {
    strahl_core::image::read_exr(p).unwrap().image.pixels.iter().map(|px| px.map(f32::to_bits)).collect()
}

/// The seed scene rendered whole by the built `strahl` with `flags` (no backend from the
/// caller's environment) into `dir/whole.exr`, as [`exr_bits`]: what a split render's merged
/// image must equal.
pub fn seed_whole_bits(dir: &std::path::Path, flags: &[&str]) -> Vec<[u32; 3]> {
    let whole = dir.join("whole.exr");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_strahl"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("STRAHL_BACKEND")
        .args(["render", "assets/scenes/seed.toml", "-o", whole.to_str().unwrap()])
        .args(flags)
        .output()
        .unwrap();
    assert!(out.status.success(), "the whole render failed: {}", String::from_utf8_lossy(&out.stderr));
    exr_bits(&whole)
}
