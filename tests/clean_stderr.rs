//! A quiet standard error: a successful render prints only strahl's own lines, even without a
//! desktop session (no driver or display-server noise).

mod common;

use std::path::PathBuf;
use std::process::Command;

/// A render in an environment without a desktop session (no XDG_RUNTIME_DIR, as on a server
/// or in a container) prints only strahl's lines on standard error, on the GPU and by default.
/// `WAYLAND_DISPLAY` is set to make Mesa's device-selection layer look for a compositor where
/// the surface extensions ask it to (Mesa 22.3's layer does even without it): it used to print
/// `error: XDG_RUNTIME_DIR is invalid or not set in the environment.` twice.
#[test]
fn a_render_prints_only_its_own_lines() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.png");
    for backend in [&["--backend", "gpu"][..], &[]] {
        let mut c = Command::new(env!("CARGO_BIN_EXE_strahl"));
        c.current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")));
        c.args(["render", "assets/scenes/sphere.toml", "-o", out.to_str().unwrap(), "--width", "32", "--height", "24"]);
        c.env_clear().env("PATH", std::env::var_os("PATH").unwrap_or_default());
        c.env("HOME", dir.path()).env("WAYLAND_DISPLAY", "wayland-strahl-test");
        // The driver under test, where the environment chooses one (tests run on Mesa 22 and 25).
        for var in ["VK_DRIVER_FILES", "VK_ICD_FILENAMES", "VK_IMPLICIT_LAYER_PATH", "LD_LIBRARY_PATH"] {
            if let Some(v) = std::env::var_os(var) {
                c.env(var, v);
            }
        }
        let run = c.args(backend).output().unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{err}");
        let foreign: Vec<&str> =
            err.lines().filter(|l| !(l.starts_with("scene: ") || l.starts_with("backend: "))).collect();
        assert!(foreign.is_empty(), "{backend:?}: lines that are not strahl's: {foreign:?}\n{err}");
    }
}
