//! `strahl bench rays` end to end: an OBJ with its camera file as `embree_bench.py
//! --export-obj` writes them, a scene file, the JSON report, and bad input.

use std::path::Path;
use std::process::{Command, Output};

fn strahl(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strahl")).args(args).output().unwrap()
}

/// Writes the bumpy torus of 2·nu·nv triangles and a camera file as the anchor script does.
fn export(dir: &Path, nu: usize, nv: usize) -> std::path::PathBuf {
    let (v, f) = strahl_core::scene::mesh::bumpy_torus(nu, nv, 2.0, 0.8);
    let obj = dir.join(format!("bumpy_torus_{}.obj", 2 * nu * nv));
    let mut buf = Vec::new();
    strahl_core::scene::mesh::write_obj(&mut buf, &v, &f).unwrap();
    std::fs::write(&obj, buf).unwrap();
    let camera = r#"{"eye": [1.7, 4.5, -5.7], "look_at": [0.0, 0.0, 0.0], "up": [0, 1, 0],
        "fov_x_deg": 30.0, "aspect_w_over_h": 1.3333333333333333, "note": "pinhole"}"#;
    std::fs::write(strahl_core::scene::procedural::camera_file(&obj), camera).unwrap();
    obj
}

fn json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn obj_with_camera_file_reports_camera_and_random_rays() {
    let dir = tempfile::tempdir().unwrap();
    let obj = export(dir.path(), 50, 40);
    let obj = obj.to_str().unwrap();
    let camera = json(&strahl(&["bench", "rays", obj, "--json", "--count", "20000", "--reps", "1", "--threads", "1"]));
    assert_eq!(camera["triangles"], 4000);
    assert_eq!(camera["ray_set"], "camera");
    // The image for 20,000 rays at 4:3, as the anchor script sizes it: 163 × 122.
    assert_eq!(camera["rays"], 163 * 122);
    let hit = camera["hit_fraction"].as_f64().unwrap();
    assert!(hit > 0.3 && hit < 0.95, "{hit}");
    for key in ["build_s", "mrays_per_s", "bytes_per_triangle", "sah_cost"] {
        assert!(camera[key].as_f64().unwrap() > 0.0, "{key}: {camera}");
    }
    let random = json(&strahl(&["bench", "rays", obj, "--json", "--rays", "random", "--count", "5000", "--reps", "1"]));
    assert_eq!(random["rays"], 5000);
    let hit = random["hit_fraction"].as_f64().unwrap();
    assert!(hit > 0.5 && hit < 1.0, "{hit}");
    // One ray at a time answers the same rays the same way.
    let single = json(&strahl(&[
        "bench",
        "rays",
        obj,
        "--json",
        "--rays",
        "random",
        "--count",
        "5000",
        "--reps",
        "1",
        "--one-at-a-time",
    ]));
    assert_eq!(single["hit_fraction"], random["hit_fraction"]);
    assert_eq!(single["walk"], "one at a time");
}

#[test]
fn scene_files_use_their_camera_and_image() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/seed.toml");
    let r = json(&strahl(&["bench", "rays", scene, "--json", "--reps", "1"]));
    let s = strahl_core::scene::Scene::load(scene).unwrap();
    assert_eq!(r["rays"].as_u64().unwrap(), s.image.width as u64 * s.image.height as u64);
    assert_eq!(r["triangles"].as_u64().unwrap(), s.triangle_count() as u64);
    let text = strahl(&["bench", "rays", scene, "--reps", "1", "--count", "1000"]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("BVH build") && text.contains("M rays/s") && text.contains("bytes per triangle"), "{text}");
}

#[test]
fn bad_input_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.obj");
    let out = strahl(&["bench", "rays", missing.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("nope.obj") && err.contains("cannot open"), "{err}");
    let obj = export(dir.path(), 8, 6);
    std::fs::write(strahl_core::scene::procedural::camera_file(&obj), "{\"eye\": [0, 0]}").unwrap();
    let out = strahl(&["bench", "rays", obj.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("_camera.json") && err.contains("camera file"), "{err}");
    for bad in [&["--count", "0"][..], &["--rays", "sideways"], &["--threads", "0"], &["--reps", "0"]] {
        let out = strahl(&[&["bench", "rays", obj.to_str().unwrap()][..], bad].concat());
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
    // A scene of planes only gives rays nothing to aim at.
    let planes = dir.path().join("planes.toml");
    std::fs::write(
        &planes,
        "[camera]\neye = [0, 1, -5]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nfov_y = 40\n[image]\nwidth = 8\nheight = 8\n\
         [[objects]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n",
    )
    .unwrap();
    let out = strahl(&["bench", "rays", planes.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no bounded primitive"));
}

#[test]
fn bench_without_a_subcommand_keeps_its_scene_arguments() {
    let out = strahl(&["bench", "--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(help.contains("rays") && help.contains("[SCENES]..."), "{help}");
    // A scene argument is still a scene of the shader benchmark (a runtime error for a
    // missing file, or for a machine without Vulkan; not a command-line error).
    let out = strahl(&["bench", "no-such-scene.toml", "--frames", "1"]);
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no-such-scene.toml") || err.contains("Vulkan"), "{err}");
}
