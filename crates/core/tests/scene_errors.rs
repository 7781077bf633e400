//! The bad-input corpus: every file in tests/bad_scenes/*.toml must fail to load with the
//! error its first line announces (`# expect: LINE:COL: FIELD: message`), and every scene
//! shipped in assets/scenes/ must load.

use std::path::{Path, PathBuf};
use strahl_core::scene::{Geometry, Scene, SceneError};

/// Paths relative to the package root (the working directory of `cargo test`), so that the
/// paths inside messages are short and predictable.
fn files_in(dir: &str, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{dir}: {e}"))
        .map(|e| Path::new(dir).join(e.unwrap().file_name()))
        .filter(|p| p.extension().is_some_and(|x| x == ext))
        .collect();
    v.sort();
    v
}

#[test]
fn every_bad_scene_fails_with_its_expected_error() {
    let files = files_in("tests/bad_scenes", "toml");
    assert!(files.len() >= 40, "corpus has only {} files", files.len());
    let mut failures = Vec::new();
    for path in &files {
        let src = std::fs::read_to_string(path).unwrap();
        let first = src.lines().next().unwrap_or("");
        let expect = first
            .strip_prefix("# expect: ")
            .unwrap_or_else(|| panic!("{}: first line must be `# expect: ...`", path.display()));
        match Scene::load(path) {
            Ok(_) => failures.push(format!("{}: loaded, expected error {expect:?}", path.display())),
            Err(e) => {
                let msg = e.to_string();
                eprintln!("{msg}"); // the whole corpus's messages, with --nocapture
                let want = format!("{}:{expect}", path.display());
                if !msg.starts_with(&want) || !msg.contains(&path.display().to_string()) {
                    failures.push(format!("{}:\n  got  {msg}\n  want {want}...", path.display()));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{} of {} failed:\n{}", failures.len(), files.len(), failures.join("\n"));
}

#[test]
fn mesh_errors_name_the_mesh_file() {
    let e = Scene::load("tests/bad_scenes/mesh_missing_file.toml").unwrap_err();
    let SceneError::Mesh { mesh, field, line, column, .. } = &e else { panic!("{e}") };
    assert_eq!(mesh, Path::new("tests/bad_scenes/no_such_mesh.obj"));
    assert_eq!((field.as_str(), *line, *column), ("objects[0].file", 12, 8));
}

#[test]
fn missing_scene_file_is_an_io_error() {
    let e = Scene::load("tests/bad_scenes/does_not_exist.toml").unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }), "{e}");
    assert!(e.to_string().starts_with("tests/bad_scenes/does_not_exist.toml: cannot read scene file"));
}

const HEAD: &str = "[camera]\neye = [0, 0, -10]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nfov_y = 45\n\
                    [image]\nwidth = 64\nheight = 48\n";

#[test]
fn too_many_lights_and_materials() {
    let p = Path::new("big.toml");
    let lights = "[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\n".repeat(1025);
    let e = strahl_core::scene::file::parse(&format!("{HEAD}{lights}"), p, Path::new(".")).unwrap_err();
    assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
    assert_eq!(
        e.to_string(),
        "big.toml: too many lights: more than 1024 ([[lights]] table number 1025 is on line 4105)"
    );

    let mats: String = (0..4097).map(|i| format!("[[materials]]\nname = \"m{i}\"\ntype = \"diffuse\"\n")).collect();
    let e = strahl_core::scene::file::parse(&format!("{HEAD}{mats}"), p, Path::new(".")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "big.toml: too many materials: more than 4096 ([[materials]] table number 4097 is on line 12297)"
    );
}

/// A million and one `[[objects]]` tables are counted and refused before the document is
/// parsed (which took 8 s and 3.4 GB); the message names the line of the first one too many.
#[test]
fn too_many_object_tables_are_refused_before_parsing() {
    let p = Path::new("big.toml");
    let objs = "[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n".repeat(1_000_001);
    let e = strahl_core::scene::file::parse(&format!("{HEAD}{objs}"), p, Path::new(".")).unwrap_err();
    assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
    assert_eq!(
        e.to_string(),
        "big.toml: too many objects: more than 1000000 ([[objects]] table number 1000001 is on line 4000009)"
    );
}

/// Objects written as one inline array, which the count before parsing does not see: the
/// count after parsing refuses them (about 2.4 GB while `toml` holds a million parsed tables).
#[test]
fn too_many_objects() {
    let p = Path::new("big.toml");
    let objs = "objects = [".to_string() + &"{type=\"sphere\",center=[0,0,0],radius=1},".repeat(1_000_001) + "]\n";
    let e = strahl_core::scene::file::parse(&format!("{objs}{HEAD}"), p, Path::new(".")).unwrap_err();
    assert_eq!(e.to_string(), "big.toml: too many objects: 1000001 (at most 1000000)");
}

#[test]
fn all_shipped_scenes_load() {
    let files = files_in("../../assets/scenes", "toml");
    assert!(files.len() >= 8);
    for path in &files {
        let s = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
        assert!(!s.objects.is_empty(), "{}", path.display());
        // Lit by a light or by an emissive material (an area light).
        let emissive = s.materials.iter().any(|m| m.kind == strahl_core::scene::MaterialKind::Emissive);
        assert!(!s.lights.is_empty() || emissive, "{}", path.display());
        let name = path.file_stem().unwrap().to_str().unwrap();
        // The lecture, the seed and the benchmark scenes keep the full 640x480 frame.
        if !matches!(name, "lecture" | "seed" | "spheres") {
            assert!(s.image.width <= 320 && s.image.height <= 240, "{}", path.display());
        }
    }
}

#[test]
fn lecture_scene_is_the_problem_time() {
    let s = Scene::load("../../assets/scenes/lecture.toml").unwrap();
    let spheres: Vec<_> = s
        .objects
        .iter()
        .map(|o| match &o.geometry {
            Geometry::Sphere(sp) => (sp.center.to_array(), sp.radius),
            g => panic!("{g:?}"),
        })
        .collect();
    assert_eq!(spheres, [([0.0, 0.0, 8.0], 5.0), ([0.0, 0.0, 9.0], 3.0), ([0.0, -3.0, 8.0], 2.0)]);
    assert_eq!(s.camera.eye.to_array(), [0.0, 0.0, -10.0]);
    assert_eq!((s.image.width, s.image.height), (640, 480));
    let mats: Vec<u32> = s.objects.iter().map(|o| o.material).collect();
    assert_eq!(mats, [0, 1, 2]);
}

#[test]
fn seed_scene_matches_the_anchor() {
    let s = Scene::load("../../assets/scenes/seed.toml").unwrap();
    let want_fov = 2.0 * (28f64.to_radians().tan() * 480.0 / 640.0).atan().to_degrees();
    assert!((s.camera.fov_y - want_fov).abs() < 1e-12, "{}", s.camera.fov_y);
    assert_eq!(s.render.max_depth, 5);
    let kinds: Vec<&str> = s.objects.iter().map(|o| o.geometry.kind().name()).collect();
    assert_eq!(kinds, ["sphere", "sphere", "sphere", "cylinder", "polygon", "mesh", "polygon"]);
    let Geometry::Polygon { triangles: ground, .. } = &s.objects[4].geometry else { panic!() };
    assert!(ground.iter().all(|t| t.face_normal().y > 0.0));
    let Geometry::Polygon { triangles: quad, .. } = &s.objects[6].geometry else { panic!() };
    assert!(quad.iter().all(|t| t.face_normal().y < 0.0));
    let Geometry::Mesh { triangles, .. } = &s.objects[5].geometry else { panic!() };
    assert_eq!(triangles.len(), 100_000);
    assert_eq!(s.triangle_count(), 100_004);
    // The tilted torus stays centred on (8.5, -2.4, 15).
    let n = (triangles.len() * 3) as f64;
    let c = triangles.iter().flat_map(|t| t.v).fold([0.0; 3], |a, v| [a[0] + v.x / n, a[1] + v.y / n, a[2] + v.z / n]);
    assert!((c[0] - 8.5).abs() < 1e-3 && (c[1] + 2.4).abs() < 1e-3 && (c[2] - 15.0).abs() < 1e-3, "{c:?}");
}

#[test]
fn shipped_cube_faces_outward() {
    let s = Scene::load("../../assets/scenes/mesh.toml").unwrap();
    let Geometry::Mesh { triangles, .. } = &s.objects[0].geometry else { panic!() };
    assert_eq!(triangles.len(), 12);
    let n = 36.0;
    let c = triangles.iter().flat_map(|t| t.v).fold(strahl_core::math::V3::zero(), |a, v| a + v / n);
    for t in triangles {
        let centroid = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
        assert!(t.face_normal().dot(centroid - c) > 0.0, "{t:?}");
    }
}
