//! `strahl adapters`: what it lists is what wgpu reports, lavapipe among it, and wgpu's own
//! variables choose as the book says, a bad value failing with a message that names it.

mod common;

use std::process::{Command, Output};

fn strahl(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_strahl"));
    c.args(args).env_remove("WGPU_BACKEND").env_remove("WGPU_ADAPTER_NAME");
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("cannot run the strahl binary")
}

/// The block `strahl adapters` prints for the adapter whose first line is `name` and whose
/// backend is `backend`.
fn block<'a>(out: &'a str, name: &str, backend: &str) -> Option<&'a str> {
    out.split("\n\n").find(|b| {
        b.lines().next().is_some_and(|l| l.split_once(": ").is_some_and(|(_, n)| n == name))
            && b.lines().any(|l| l == format!("  backend: {backend}"))
    })
}

#[test]
fn adapters_lists_lavapipe_with_the_limits_wgpu_reports() {
    if common::gpu().is_none() {
        return;
    }
    let lavapipe = strahl_gpu::instance::adapters()
        .unwrap()
        .into_iter()
        .find(|a| a.get_info().backend == wgpu::Backend::Vulkan && a.get_info().driver == "llvmpipe");
    let Some(lavapipe) = lavapipe else {
        if common::gpu_tests_may_skip() {
            return common::skip("no lavapipe here");
        }
        panic!("no lavapipe (Mesa's llvmpipe Vulkan driver) among the adapters: install mesa-vulkan-drivers");
    };
    let run = strahl(&["adapters"], &[]);
    let out = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let info = lavapipe.get_info();
    let b = block(&out, &info.name, "vulkan").unwrap_or_else(|| panic!("no block for {} on vulkan:\n{out}", info.name));
    let l = lavapipe.limits();
    let want = [
        "  device type: Cpu".to_string(),
        "  driver: llvmpipe".to_string(),
        format!("  driver info: {}", info.driver_info),
        format!("  max_storage_buffers_per_shader_stage: {}", l.max_storage_buffers_per_shader_stage),
        format!("  max_storage_buffer_binding_size: {}", l.max_storage_buffer_binding_size),
        format!("  max_buffer_size: {}", l.max_buffer_size),
        format!("  max_compute_invocations_per_workgroup: {}", l.max_compute_invocations_per_workgroup),
        format!("  max_bind_groups: {}", l.max_bind_groups),
        format!(
            "  SHADER_INT64: {}",
            if lavapipe.features().contains(wgpu::Features::SHADER_INT64) { "yes" } else { "no" }
        ),
        "  strahl runs on it: yes".to_string(),
    ];
    for line in want {
        assert!(b.lines().any(|l| l == line), "missing {line:?} in\n{b}");
    }
    // lavapipe's own figures, not only whatever wgpu says: enough storage buffers for the
    // wavefront tracer beside every scene binding, and 128 MiB bindings, which the other tests
    // (the wavefront tests, the split bands) rely on.
    let wavefront = strahl_gpu::SCENE_BINDINGS + strahl_gpu::wavefront::BINDINGS;
    assert!(l.max_storage_buffers_per_shader_stage >= wavefront && l.max_storage_buffer_binding_size >= 1 << 27, "{b}");
    assert!(out.contains("--backend gpu takes "), "{out}");

    // Vulkan only: every block says so.
    let run = strahl(&["adapters"], &[("WGPU_BACKEND", "vulkan")]);
    let out = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{out}");
    let backends: Vec<&str> = out.lines().filter(|l| l.starts_with("  backend: ")).collect();
    assert!(!backends.is_empty() && backends.iter().all(|l| *l == "  backend: vulkan"), "{out}");
}

#[test]
fn a_bad_backend_or_adapter_name_fails_naming_the_variable_and_its_value() {
    for args in [&["adapters"][..], &["render", "assets/scenes/sphere.toml", "-o", "never.png", "--backend", "gpu"]] {
        let run = strahl(args, &[("WGPU_BACKEND", "nonsense")]);
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("WGPU_BACKEND=nonsense: `nonsense` is not a backend; use vulkan, metal, dx12 or gl"),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
    // auto, too: a misspelt variable is not a reason to take the CPU quietly.
    let run = strahl(&["render", "assets/scenes/sphere.toml", "-o", "never.png"], &[("WGPU_BACKEND", "vulkan,metl")]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && err.contains("WGPU_BACKEND=vulkan,metl: `metl` is not a backend"), "{err}");
    assert!(!std::path::Path::new("never.png").exists());

    if common::gpu().is_none() {
        return;
    }
    let run = strahl(
        &["render", "assets/scenes/sphere.toml", "-o", "never.png", "--backend", "gpu"],
        &[("WGPU_ADAPTER_NAME", "no-such-adapter")],
    );
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{err}");
    assert!(
        err.contains("WGPU_ADAPTER_NAME=no-such-adapter: no adapter's name contains it; the adapters here: "),
        "{err}"
    );
}
