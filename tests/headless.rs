//! The headless build (`--no-default-features`: every subcommand but the viewer, without
//! eframe), which `.ci/run` builds beside the default one and runs this file against; in the
//! default build the file is empty. Every other test runs once, on the default build: the
//! crates' code is the same in both, and only the command line's `view` differs.
#![cfg(not(feature = "viewer"))]

use std::path::PathBuf;
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strahl"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("STRAHL_BACKEND")
        .args(args)
        .output()
        .expect("cannot run the strahl binary")
}

/// `strahl view` says how to get the viewer and fails (status 1) whatever its arguments,
/// opening nothing.
#[test]
fn view_in_a_build_without_the_viewer_says_how_to_get_it() {
    for args in [vec!["view", "assets/scenes/sphere.toml"], vec!["view", "assets/scenes/sphere.toml", "--scale", "2"]] {
        let out = run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("without the viewer") && err.contains("cargo build --release"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// The other subcommands work in the headless build: a render in bands, their merge, ray
/// queries.
#[test]
fn the_headless_build_renders_merges_and_traces() {
    let dir = tempfile::tempdir().unwrap();
    let at = |name: &str| -> PathBuf { dir.path().join(name) };
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    for k in 0..2 {
        let part = s(&at(&format!("part-{k}.exr")));
        let tile = format!("{k}/2");
        let args = ["render", "assets/scenes/seed.toml", "--backend", "cpu", "--width", "48", "--height", "32"];
        let out = run(&[&args[..], &["--tile", &tile, "-o", &part]].concat());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let out = run(&["merge", &s(&at("part-0.exr")), &s(&at("part-1.exr")), "-o", &s(&at("seed.png"))]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(image::open(at("seed.png")).unwrap().to_rgb8().dimensions(), (48, 32));
    std::fs::write(at("rays.csv"), "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,10\n").unwrap();
    let out = run(&["trace", "assets/scenes/lecture.toml", "--rays", &s(&at("rays.csv"))]);
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("\n0,3,0,0,3,"));
}
