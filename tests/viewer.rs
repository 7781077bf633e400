//! `strahl view` under Xvfb on lavapipe: the window's screenshot must show the rendered scene
//! (its image area matching a GPU render of the same view and samples) beside the side panel.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use strahl_core::render::Prepared;
use strahl_core::scene::Scene;
use strahl_gpu::{SceneBuffers, render};

const TIMEOUT: Duration = Duration::from_secs(120);

fn on_path(program: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|paths| std::env::split_paths(&paths).any(|dir| dir.join(program).is_file()))
}

/// The numbers after `key` on its line of the viewer's standard output.
fn numbers(stdout: &str, key: &str) -> Vec<u32> {
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix(key).filter(|rest| rest.starts_with(' ')))
        .unwrap_or_else(|| panic!("the viewer printed no `{key}` line:\n{stdout}"));
    line.split_whitespace().map(|v| v.parse().unwrap()).collect()
}

/// Runs the viewer under xvfb-run, killing the whole process group after TIMEOUT.
fn run_viewer(dir: &Path, args: &[&str]) -> (bool, String, String) {
    use std::os::unix::process::CommandExt;
    let runtime = dir.join("runtime");
    std::fs::create_dir_all(&runtime).unwrap();
    std::fs::set_permissions(&runtime, std::os::unix::fs::PermissionsExt::from_mode(0o700)).unwrap();
    let (out, err) = (dir.join("stdout.txt"), dir.join("stderr.txt"));
    let mut child = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x720x24", env!("CARGO_BIN_EXE_strahl"), "view"])
        .args(args)
        .env("XDG_RUNTIME_DIR", &runtime)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .process_group(0)
        .spawn()
        .expect("starting xvfb-run");
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if start.elapsed() > TIMEOUT {
            let _ = Command::new("kill").args(["-KILL", &format!("-{}", child.id())]).status();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let read = |p: &PathBuf| std::fs::read_to_string(p).unwrap_or_default();
    let (stdout, stderr) = (read(&out), read(&err));
    assert!(status.is_some(), "the viewer did not finish within {TIMEOUT:?}\nstdout:\n{stdout}\nstderr:\n{stderr}");
    (status.unwrap().success(), stdout, stderr)
}

#[test]
fn the_window_shows_the_rendered_scene_beside_the_side_panel() {
    window_matches_the_library(strahl_core::scene::RenderMode::Whitted);
}

#[test]
fn the_path_mode_window_shows_the_path_traced_samples_of_the_library() {
    window_matches_the_library(strahl_core::scene::RenderMode::Path);
}

/// Runs the viewer for three frames in `mode` and compares its screenshot with the library's
/// render of the same samples; checks the side panel too.
fn window_matches_the_library(mode: strahl_core::scene::RenderMode) {
    if !on_path("xvfb-run") {
        if common::gpu_tests_may_skip() {
            common::skip("xvfb-run not found");
            return;
        }
        panic!("xvfb-run not found: install xvfb and xauth (.ci/run does), or set STRAHL_SKIP_GPU_TESTS=1 to skip");
    }
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("shot.png");
    let scene_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/sphere.toml");
    let (ok, stdout, stderr) = run_viewer(
        dir.path(),
        &[
            scene_path.to_str().unwrap(),
            "--mode",
            mode.name(),
            "--frames",
            "3",
            "--scale",
            "1",
            "--screenshot",
            shot.to_str().unwrap(),
        ],
    );
    assert!(ok, "the viewer failed\nstdout:\n{stdout}\nstderr:\n{stderr}");
    let [x, y, w, h] = numbers(&stdout, "image_rect")[..] else { panic!("image_rect: {stdout}") };
    let [rw, rh] = numbers(&stdout, "render_size")[..] else { panic!("render_size: {stdout}") };
    let samples = numbers(&stdout, "samples")[0];
    assert_eq!((rw, rh), (w, h), "at scale 1 one texel is one window pixel");
    assert_eq!(samples, 3, "three frames, one whole sample pass each");

    let shot = image::open(&shot).expect("the screenshot is a PNG").to_rgb8();
    let (sw, sh) = shot.dimensions();
    assert!(
        x >= 100 && x + w <= sw && y + h <= sh,
        "image {x},{y} {w}x{h} inside the {sw}x{sh} window, right of the panel"
    );

    // The same view rendered by the library with the same samples.
    let prep = Prepared::new(Scene::load(&scene_path).unwrap());
    let buffers = SceneBuffers::upload(&ctx, &prep.flat).unwrap();
    let mut frame = prep.frame(w, h);
    frame.spp = samples;
    let (reference, _) = render(&ctx, &buffers, &frame, mode, buffers.key, &|_, _| {}).unwrap();
    let reference = reference.to_srgb8();
    let mut close = 0usize;
    for py in 0..h {
        for px in 0..w {
            let got = shot.get_pixel(x + px, y + py).0;
            let i = 3 * (py * w + px) as usize;
            if (0..3).all(|c| got[c].abs_diff(reference[i + c]) <= 2) {
                close += 1;
            }
        }
    }
    let share = close as f64 / (w * h) as f64;
    eprintln!("{:.3} % of {w}x{h} image pixels within 2 codes of the library render", share * 100.0);
    assert!(
        share >= 0.99,
        "{mode:?}: only {:.3} % of the image pixels match the GPU render within 2 codes",
        share * 100.0
    );

    // The side panel: its own background, with text on it, unlike the image.
    let most_common = |x0: u32, x1: u32| {
        let mut counts = std::collections::HashMap::new();
        for py in 0..sh {
            for px in x0..x1 {
                *counts.entry(shot.get_pixel(px, py).0).or_insert(0usize) += 1;
            }
        }
        let (colour, n) = counts.iter().max_by_key(|(_, n)| **n).map(|(c, n)| (*c, *n)).unwrap();
        (colour, n, counts.len())
    };
    let (panel_bg, panel_bg_count, panel_colours) = most_common(0, x);
    let (image_bg, _, _) = most_common(x, x + w);
    assert_ne!(panel_bg, image_bg, "the panel looks like the image");
    let panel_pixels = (x * sh) as usize;
    let light = (0..sh)
        .flat_map(|py| (0..x).map(move |px| (px, py)))
        .filter(|&(px, py)| {
            let p = shot.get_pixel(px, py).0;
            (0..3).map(|c| p[c] as i32 - panel_bg[c] as i32).sum::<i32>() > 150
        })
        .count();
    assert!(
        panel_colours >= 8 && panel_bg_count < panel_pixels && light >= 300,
        "the side panel shows no text: {panel_colours} colours, {light} light pixels"
    );
}
