//! The GPU context as a device's owner: its pipeline cache under concurrent requests, and
//! device errors (validation, out of memory) turned into errors rather than wgpu's panics.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Barrier};
use strahl_core::render::Prepared;
use strahl_core::scene::Scene;
use strahl_gpu::{FeatureKey, Program, SceneBuffers};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Threads asking at once for a variant nobody compiled yet get one pipeline, compiled once:
/// the others wait for it instead of compiling it again.
#[test]
fn concurrent_requests_for_one_variant_compile_it_once() {
    let Some(ctx) = common::gpu() else { return };
    let ctx = Arc::new(ctx);
    let key = FeatureKey::SPHERES | FeatureKey::PLANES;
    let threads = 4;
    let barrier = Arc::new(Barrier::new(threads));
    let handles: Vec<_> = (0..threads)
        .map(|_| {
            let (ctx, barrier) = (ctx.clone(), barrier.clone());
            std::thread::spawn(move || {
                barrier.wait();
                ctx.pipeline(Program::Trace, key, "trace_nearest").unwrap()
            })
        })
        .collect();
    let pipelines: Vec<_> = handles.into_iter().map(|h| h.join().unwrap()).collect();
    assert_eq!(ctx.pipelines_compiled(), 1, "one variant, compiled {} times", ctx.pipelines_compiled());
    assert!(pipelines.windows(2).all(|w| Arc::ptr_eq(&w[0], &w[1])), "every thread got the one pipeline");
    assert!(ctx.cached_pipeline(Program::Trace, key, "trace_nearest").is_some());
}

/// A buffer larger than the device can allocate, asked for past strahl's size checks, is an
/// out-of-memory or validation error of the call that asked, not a panic; the context stays
/// usable.
#[test]
fn a_device_error_is_returned_and_the_context_stays_usable() {
    let Some(ctx) = common::gpu() else { return };
    let huge = ctx.limits.max_buffer_size.saturating_add(4);
    let made = ctx.scoped("a test buffer", || {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("too large"),
            size: huge,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    });
    let e = made.expect_err("a buffer over max_buffer_size is refused");
    assert!(e.to_string().contains("a test buffer"), "{e}");
    let prep = Prepared::new(Scene::load(root().join("assets/scenes/sphere.toml")).unwrap());
    SceneBuffers::upload(&ctx, &prep.flat).expect("the context works after the error");
    ctx.check().expect("the error was reported once, where it happened");
}

/// A copy of `shaders/` in `dir`.
fn copy_shaders(dir: &Path) -> PathBuf {
    let copy = dir.join("shaders");
    std::fs::create_dir_all(copy.join("modules")).unwrap();
    for sub in ["", "modules"] {
        for e in std::fs::read_dir(root().join("crates/gpu/shaders").join(sub)).unwrap() {
            let p = e.unwrap().path();
            if p.is_file() {
                std::fs::copy(&p, copy.join(sub).join(p.file_name().unwrap())).unwrap();
            }
        }
    }
    copy
}

/// A copy of `shaders/` whose Whitted program binds a buffer its pipeline layout lacks: naga
/// accepts the module, the device refuses the pipeline.
fn shaders_with_an_unbound_buffer(dir: &Path) -> PathBuf {
    let copy = copy_shaders(dir);
    let render = copy.join("whitted.wgsl");
    let text = std::fs::read_to_string(&render).unwrap();
    let text = text
        .replace(
            "@group(1) @binding(0) var<storage, read_write> output",
            "@group(1) @binding(7) var<storage, read_write> stray: array<u32>;\n\
             @group(1) @binding(0) var<storage, read_write> output",
        )
        .replace(
            "    let sum = shade_pixel_sum(px.x, px.y);",
            "    stray[0] = 1u;\n    let sum = shade_pixel_sum(px.x, px.y);",
        );
    assert!(text.contains("stray[0]"), "whitted.wgsl changed: update this test");
    std::fs::write(&render, text).unwrap();
    copy
}

/// Standard error of a small GPU render with the shaders of `shaders`, which must fail (exit
/// status 1) without writing its image (into `dir`).
fn failing_render(dir: &Path, shaders: &Path) -> String {
    let out = dir.join("a.png");
    let run = Command::new(env!("CARGO_BIN_EXE_strahl"))
        .current_dir(root())
        .args(["render", "assets/scenes/sphere.toml", "--backend", "gpu", "--width", "16", "--height", "12", "-o"])
        .arg(&out)
        .env("STRAHL_SHADER_DIR", shaders)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr).into_owned();
    assert_eq!(run.status.code(), Some(1), "{err}");
    assert!(!out.exists(), "an image was written");
    err
}

/// The command line reports a pipeline the device refuses as an error naming the shader
/// (exit status 1) and writes nothing; before error scopes, wgpu's default handler panicked.
#[test]
fn a_pipeline_the_device_refuses_is_an_error_message() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let shaders = shaders_with_an_unbound_buffer(dir.path());
    let err = failing_render(dir.path(), &shaders);
    assert!(!err.contains("panicked"), "{err}");
    let line = err.lines().find(|l| l.starts_with("error: ")).unwrap_or_else(|| panic!("no error line: {err}"));
    assert!(line.contains("pipeline") && line.contains("Whitted"), "{line}");
}

/// A shader that does not compose is reported where it is wrong: the file, line and column,
/// and the source line, as naga_oil prints them (not its error's debug form).
#[test]
fn a_composition_error_names_its_file_and_line() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let shaders = copy_shaders(dir.path());
    let module = shaders.join("modules/sphere.wgsl");
    let text = std::fs::read_to_string(&module).unwrap();
    std::fs::write(&module, text + "\nfn broken( -> f32 { return 1.0; }\n").unwrap();
    let err = failing_render(dir.path(), &shaders);
    assert!(err.contains("modules/sphere.wgsl") && err.contains("fn broken( -> f32"), "{err}");
    assert!(!err.contains("ComposerError") && !err.contains("panicked"), "{err}");
}
