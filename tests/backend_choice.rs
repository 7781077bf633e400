//! `--backend auto` (the default) and `STRAHL_BACKEND` through the binary.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use strahl_gpu::instance;
use strahl_gpu::select::Workload;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn strahl() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_strahl"));
    c.current_dir(root()).env_remove("STRAHL_BACKEND");
    c
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn ok(out: &Output) -> String {
    let err = stderr(out);
    assert!(out.status.success(), "stderr:\n{err}");
    err
}

fn render(out: &Path, mode: &str) -> Command {
    let mut c = strahl();
    c.args(["render", "assets/scenes/sphere.toml", "-o", out.to_str().unwrap(), "--mode", mode]);
    c.args(["--width", "32", "--height", "24", "--spp", "2"]);
    c
}

/// Files under `dir`, recursively.
fn file_count(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .map(|rd| rd.map(|e| e.unwrap().path()).map(|p| if p.is_dir() { file_count(&p) } else { 1 }).sum())
        .unwrap_or(0)
}

/// What `auto` must do here, stated apart from `select::on_software_device` (the book,
/// "Choosing the backend"): the GPU on hardware; where the only device is a software one, the
/// CPU for every workload, as measured. None without any Vulkan adapter.
fn expected(w: Workload) -> Option<&'static str> {
    let adapter = instance::request_adapter().ok()?;
    if !instance::is_software(&adapter.get_info()) {
        return Some("gpu");
    }
    Some(match w {
        Workload::Whitted | Workload::Path | Workload::Trace => "cpu",
    })
}

#[test]
fn auto_takes_the_backend_the_table_names_and_says_so() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.png");
    for (mode, w) in [("whitted", Workload::Whitted), ("path", Workload::Path)] {
        let want = expected(w).unwrap();
        // An empty Mesa shader cache of its own: a CPU choice must compile no shader at all.
        let cache = dir.path().join(format!("cache-{mode}"));
        std::fs::create_dir(&cache).unwrap();
        let run = render(&out, mode).env("MESA_SHADER_CACHE_DIR", &cache).output().unwrap();
        let err = ok(&run);
        let notes: Vec<&str> = err.lines().filter(|l| l.starts_with("backend: ")).collect();
        assert_eq!(notes.len(), 1, "one line says which backend: {err}");
        assert!(notes[0].starts_with(&format!("backend: {want} (")), "{mode}: {err}");
        let said = String::from_utf8_lossy(&run.stdout).into_owned();
        if want == "cpu" {
            assert!(said.contains("on the cpu") && notes[0].contains("software"), "{said}{err}");
            assert_eq!(file_count(&cache), 0, "{mode}: choosing the cpu compiled a shader");
        } else {
            assert!(!said.contains("on the cpu"), "{said}");
        }
    }
    // The trace workload too.
    let rays = dir.path().join("rays.csv");
    std::fs::write(&rays, "ox,oy,oz,dx,dy,dz\n0,0,-5,0,0,1\n").unwrap();
    let run = strahl().args(["trace", "assets/scenes/sphere.toml", "--rays", rays.to_str().unwrap()]).output().unwrap();
    let err = ok(&run);
    let want = expected(Workload::Trace).unwrap();
    assert!(err.lines().any(|l| l.starts_with(&format!("backend: {want} ("))), "{err}");
}

#[test]
fn strahl_backend_sets_the_default_and_the_flag_wins() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.png");
    let run = render(&out, "whitted").env("STRAHL_BACKEND", "gpu").output().unwrap();
    let err = ok(&run);
    assert!(err.contains("backend: gpu (STRAHL_BACKEND=gpu)"), "{err}");
    assert!(!String::from_utf8_lossy(&run.stdout).contains("on the cpu"));

    let run = render(&out, "whitted").env("STRAHL_BACKEND", "gpu").args(["--backend", "cpu"]).output().unwrap();
    let err = ok(&run);
    assert!(!err.contains("backend: "), "a forced backend needs no note: {err}");
    assert!(String::from_utf8_lossy(&run.stdout).contains("on the cpu"));

    let run = render(&out, "whitted").env("STRAHL_BACKEND", " CPU ").output().unwrap();
    ok(&run);
    assert!(String::from_utf8_lossy(&run.stdout).contains("on the cpu"));
}

#[test]
fn a_bad_strahl_backend_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.png");
    let run = render(&out, "whitted").env("STRAHL_BACKEND", "fast").output().unwrap();
    let err = stderr(&run);
    assert_eq!(run.status.code(), Some(2), "{err}");
    assert!(err.contains("STRAHL_BACKEND=\"fast\": use auto, gpu or cpu"), "{err}");
    assert!(!out.exists());
}
