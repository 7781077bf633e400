//! The GPU backend under the adapter's limits: over-limit buffers fail with a clear error
//! before allocation, and images taller than one output binding are rendered in bands that
//! join seamlessly. Also the command line without any Vulkan driver.

mod common;

use common::gpu;
use strahl::backend::gpu::{GpuError, SceneBuffers, render::render};
use strahl::render::Prepared;
use strahl::scene::Scene;

fn scene(name: &str) -> Prepared {
    Prepared::new(Scene::load(format!("{}/assets/scenes/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap())
}

#[test]
fn a_buffer_over_the_binding_limit_is_refused_by_name() {
    let Some(mut ctx) = gpu() else { return };
    // Pretend the adapter allows 1 MiB per binding: the seed's 100k triangles need 4.8 MB.
    ctx.limits.max_storage_buffer_binding_size = 1 << 20;
    let prep = scene("seed.toml");
    match SceneBuffers::upload(&ctx, &prep.gpu) {
        Err(e @ GpuError::TooLarge { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("triangles") && msg.contains("1048576"), "{msg}");
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("an over-limit upload was accepted"),
    }
}

#[test]
fn images_taller_than_one_binding_render_in_seamless_bands() {
    let Some(mut ctx) = gpu() else { return };
    let prep = scene("cylinder.toml");
    let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
    let buffers = SceneBuffers::upload(&ctx, &prep.gpu).unwrap();
    let (whole, one) =
        render(&ctx, &buffers, &frame, strahl::scene::RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
    // Room for 37 rows per output binding: the image needs several bands, none tile-aligned.
    ctx.limits.max_storage_buffer_binding_size = frame.width as u64 * 16 * 37;
    let (banded, many) =
        render(&ctx, &buffers, &frame, strahl::scene::RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
    assert!(many.dispatches > one.dispatches, "{} vs {} dispatches", many.dispatches, one.dispatches);
    assert_eq!(whole, banded, "bands must join into the same image");
    // One row that does not fit is a clear error, not a crash.
    ctx.limits.max_storage_buffer_binding_size = 64;
    let err = render(&ctx, &buffers, &frame, strahl::scene::RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap_err();
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
            .output()
            .unwrap()
    };
    let auto = run(&[]);
    let stderr = String::from_utf8_lossy(&auto.stderr);
    assert!(auto.status.success(), "{stderr}");
    let notes: Vec<&str> = stderr.lines().filter(|l| l.starts_with("backend: ")).collect();
    assert_eq!(notes, ["backend: cpu (no Vulkan adapter found)"], "{stderr}");
    assert!(out.exists());
    let explicit = run(&["--backend", "gpu"]);
    let stderr = String::from_utf8_lossy(&explicit.stderr);
    assert!(!explicit.status.success());
    assert!(stderr.contains("no Vulkan adapter") && stderr.contains("mesa-vulkan-drivers"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}
