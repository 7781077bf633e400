//! The TOML scene file → a validated [`Scene`].
//!
//! The file is deserialized into the serde structs below, whose fields are `Spanned` so that
//! every semantic check can point at the offending value. When `toml` itself fails (syntax,
//! wrong type, unknown or missing key), the document is parsed once more into `toml`'s
//! spanned tree to find the path of the key or value at the error's position.
//! Every error reads `FILE:LINE:COLUMN: FIELD: message` (line and column 1-based, the column
//! counted in characters), FIELD being a path such as `objects[2].radius`.

mod checks;
mod defs;
mod spans;

use defs::*;
use spans::*;

use super::mesh::{self, Transform};
use super::polygon;
use super::texture::{self, ImageKind, Texture};
use super::{
    Camera, Environment, Geometry, ImageSize, Light, Material, MaterialKind, Object, RenderMode, RenderSettings, Scene,
    SceneError,
};
use crate::geometry::{Cylinder, Plane, Sphere, Triangle};
use crate::math::V3;
use serde::Deserialize;
use std::collections::HashMap;
use std::fmt;
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: i64 = 16384;
/// Largest accepted image, in pixels (8192 × 8192).
pub const MAX_IMAGE_PIXELS: u64 = 67_108_864;
pub const MAX_OBJECTS: usize = 1_000_000;
pub const MAX_MATERIALS: usize = 4096;
pub const MAX_LIGHTS: usize = 1024;
/// Most triangles (triangles, polygons and meshes together) in one scene.
pub const MAX_SCENE_TRIANGLES: usize = 64_000_000;
/// Largest scene file read: a million small objects take about 70 MB of TOML (and parsing
/// needs some 40 bytes of memory per byte of it).
pub const MAX_SCENE_FILE_BYTES: u64 = 256 << 20;
pub const MAX_DEPTH: i64 = 64;
pub const MAX_SPP: i64 = 65536;
/// Most texels of an environment map as rendered (4096 × 2048): its linear RGB texels take 12
/// bytes each, 96 MiB, which fits one GPU storage buffer on lavapipe (128 MiB). Larger maps are
/// halved (2 × 2 box filter) until they fit, with a warning.
pub const MAX_ENVIRONMENT_TEXELS: u64 = 4096 * 2048;

/// What a glTF object adds to the scene besides its geometry.
pub(super) struct GltfLoaded<'a> {
    materials: &'a mut Vec<Material>,
    textures: &'a mut Vec<Texture>,
    lights: &'a mut Vec<Light>,
    warnings: &'a mut Vec<String>,
}

/// Reads and validates the scene file at `path`; relative mesh paths are resolved against
/// the file's directory.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let src = crate::input::read_text(path, MAX_SCENE_FILE_BYTES)
        .map_err(|e| SceneError::Io { path: path.to_path_buf(), message: e.to_string() })?;
    let base_dir = path.parent().unwrap_or(Path::new(""));
    parse(&src, path, base_dir)
}

/// Parses and validates scene source `src`. `path` names the file in error messages only;
/// mesh files are looked up relative to `base_dir`.
pub fn parse(src: &str, path: &Path, base_dir: &Path) -> Result<Scene, SceneError> {
    let cx = Cx { src, path, base_dir };
    cx.prescan_counts()?;
    let def: SceneDef = toml::from_str(src).map_err(|e| {
        // Only on error is the document parsed again, to name the field at the error's span
        // (a syntax error fails this parse too and is reported as such).
        match toml::de::DeTable::parse(src) {
            Ok(doc) => cx.toml_error(&e, Some(&doc)),
            Err(syntax) => cx.toml_error(&syntax, None),
        }
    })?;
    cx.build(def)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    const HEAD: &str = "[camera]\neye = [0, 0, -10]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nfov_y = 45\n\
                        [image]\nwidth = 64\nheight = 48\n";

    fn parse_str(src: &str) -> Result<Scene, SceneError> {
        parse(src, Path::new("t.toml"), Path::new("."))
    }

    fn err(src: &str) -> String {
        match parse_str(src) {
            Ok(_) => panic!("expected an error for\n{src}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn minimal_scene_with_defaults() {
        let s = parse_str(HEAD).unwrap();
        assert_eq!(s.image, ImageSize { width: 64, height: 48 });
        assert_eq!(s.render, RenderSettings::default());
        assert!(s.objects.is_empty() && s.materials.is_empty() && s.lights.is_empty());
        assert_eq!(s.camera.fov_y, 45.0);
    }

    #[test]
    fn integers_are_accepted_as_floats_and_default_material_appended() {
        let src = format!(
            "{HEAD}[[materials]]\nname = \"red\"\ntype = \"diffuse\"\ncolor = [1, 0, 0]\n\
             [[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 8]\nradius = 5\n\
             [[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 8]\nradius = 1\nmaterial = \"red\"\n\
             [[lights]]\ntype = \"directional\"\ndirection = [0, -2, 0]\nintensity = [1, 1, 1]\n"
        );
        let s = parse_str(&src).unwrap();
        assert_eq!(s.materials.len(), 2);
        assert_eq!(s.materials[1], Material::default_grey());
        assert_eq!(s.objects[0].material, 1);
        assert_eq!(s.objects[1].material, 0);
        assert_eq!(s.objects[0].geometry, Geometry::Sphere(Sphere { center: V3::new(0.0, 0.0, 8.0), radius: 5.0 }));
        assert_eq!(s.lights[0], Light::Directional { direction: V3::new(0.0, -1.0, 0.0), intensity: [1.0; 3] });
    }

    #[test]
    fn errors_point_at_the_value() {
        let src = format!("{HEAD}[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 8]\nradius = -1\n");
        let e = err(&src);
        assert_eq!(e, "t.toml:12:10: objects[0].radius: must be > 0 and finite, got -1");
        let src = format!("{HEAD}[[objects]]\ntype = \"sphere\"\ncenter = [0, inf, 8]\nradius = 1\n");
        assert_eq!(err(&src), "t.toml:11:14: objects[0].center[1]: must be finite, got inf");
    }

    #[test]
    fn toml_errors_name_the_field() {
        let e = err(&format!("{HEAD}[[objects]]\ntype = \"sphere\"\nradiuss = 1\n"));
        assert_eq!(
            e,
            "t.toml:11:1: objects[0].radiuss: unknown key `radiuss` for a sphere; it takes `type`, `center`, `radius`, \
             `material`"
        );
        let e = err(&format!("{HEAD}[[lights]]\ntype = \"directional\"\ndirecton = [0, -1, 0]\n"));
        assert!(
            e.ends_with("unknown key `directon` for a directional light; it takes `type`, `direction`, `intensity`")
        );
        let e = err(&format!("{HEAD}[[objects]]\ntype = \"sphere\"\nradius = \"big\"\n"));
        assert!(e.starts_with("t.toml:11:10: objects[0].radius: invalid type"), "{e}");
        assert!(e.contains("expected a number"), "{e}");
        let e = err("[image]\nwidth = 1\nheight = 1\n");
        assert!(e.starts_with("t.toml:1:1: camera: missing field `camera`"), "{e}");
        let e = err(&format!("{HEAD}[[objects]]\nradius = 1\n"));
        assert!(e.starts_with("t.toml:9:1: objects[0].type: missing field `type`"), "{e}");
        let e = err("[camera\n");
        assert!(e.starts_with("t.toml:1:"), "{e}");
        assert!(e.contains(": toml: "), "{e}");
        let e = err(&format!("{HEAD}[camera]\n"));
        assert!(e.contains("t.toml:9:"), "{e}");
    }

    #[test]
    fn column_counts_characters() {
        let src = format!("# äöü\n{HEAD}[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 8]\nradius = 0 # ü\n");
        assert!(err(&src).starts_with("t.toml:13:10: objects[0].radius"));
        let src = format!("{HEAD}[[materials]]\nname = \"ü\"\ntype = \"glass\"\n");
        assert!(err(&src).starts_with("t.toml:11:8: materials[0].type: unknown material type"));
    }

    /// A pbr material's clear coat, sheen and specular keys: values read, defaults, and bad
    /// ones named.
    #[test]
    fn layer_keys() {
        let src = format!(
            "{HEAD}[[materials]]\nname = \"p\"\ntype = \"pbr\"\nclearcoat = 0.5\nclearcoat_roughness = 0.1\n\
             sheen_color = [1, 0.5, 0]\nsheen_roughness = 0.3\nspecular = 0.7\nspecular_color = [2, 1, 1]\n\
             [[materials]]\nname = \"q\"\ntype = \"pbr\"\n"
        );
        let s = parse_str(&src).unwrap();
        let (p, q) = (&s.materials[0], &s.materials[1]);
        assert_eq!((p.clearcoat, p.clearcoat_roughness, p.sheen_roughness, p.specular), (0.5, 0.1, 0.3, 0.7));
        assert_eq!((p.sheen_color, p.specular_color), ([1.0, 0.5, 0.0], [2.0, 1.0, 1.0]));
        assert_eq!((q.clearcoat, q.sheen_color, q.specular, q.specular_color), (0.0, [0.0; 3], 1.0, [1.0; 3]));
        let material = |body: &str| err(&format!("{HEAD}[[materials]]\nname = \"m\"\n{body}\n"));
        assert!(
            material("type = \"pbr\"\nclearcoat = 1.5").contains("materials[0].clearcoat: must be in [0, 1], got 1.5")
        );
        assert!(
            material("type = \"pbr\"\nsheen_color = [1, 2, 0]").contains("materials[0].sheen_color[1]: must be <= 1")
        );
        assert!(
            material("type = \"pbr\"\nspecular_color = [1, -1, 0]")
                .contains("materials[0].specular_color[1]: must be >= 0")
        );
        assert!(
            material("type = \"diffuse\"\nsheen_roughness = 0.5")
                .contains("materials[0].sheen_roughness: not a field of a diffuse")
        );
    }

    /// Glass and spot lights: values read, and bad ones named.
    #[test]
    fn glass_and_spot_keys() {
        let src = format!(
            "{HEAD}[[materials]]\nname = \"g\"\ntype = \"dielectric\"\nroughness = 0.3\nabsorption = [1, 0.5, 0]\n\
             single_scattering = true\n[[materials]]\nname = \"p\"\ntype = \"pbr\"\ntransmission = 0.25\nior = 1.4\n\
             [[lights]]\ntype = \"spot\"\nposition = [0, 2, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n\
             inner_angle = 10\nouter_angle = 30\nrange = 5\n"
        );
        let s = parse_str(&src).unwrap();
        let (g, p) = (&s.materials[0], &s.materials[1]);
        assert_eq!((g.roughness, g.absorption, g.single_scattering), (0.3, [1.0, 0.5, 0.0], true));
        assert_eq!((p.transmission, p.ior, p.single_scattering), (0.25, 1.4, false));
        let Light::Spot { inner, outer, range, direction, .. } = s.lights[0] else { panic!("{:?}", s.lights[0]) };
        assert_eq!((inner, outer, range), (10f64.to_radians(), 30f64.to_radians(), 5.0));
        assert_eq!(direction, V3::new(0.0, -1.0, 0.0));
        let material = |body: &str| err(&format!("{HEAD}[[materials]]\nname = \"m\"\n{body}\n"));
        assert!(
            material("type = \"dielectric\"\nabsorption = [1, -1, 0]")
                .contains("materials[0].absorption[1]: must be >= 0")
        );
        assert!(
            material("type = \"pbr\"\ntransmission = 1.5")
                .contains("materials[0].transmission: must be in [0, 1], got 1.5")
        );
        assert!(material("type = \"dielectric\"\nroughness = 2").contains("materials[0].roughness: must be in [0, 1]"));
        assert!(
            material("type = \"dielectric\"\ntransmission = 1")
                .contains("materials[0].transmission: not a field of a dielectric")
        );
        assert!(
            material("type = \"diffuse\"\nabsorption = [1, 1, 1]")
                .contains("materials[0].absorption: not a field of a diffuse")
        );
        let spot = |extra: &str| {
            err(&format!(
                "{HEAD}[[lights]]\ntype = \"spot\"\nposition = [0, 2, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n{extra}\n"
            ))
        };
        assert!(
            spot("inner_angle = 30\nouter_angle = 20")
                .contains("lights[0].inner_angle: must be less than outer_angle (20), got 30")
        );
        assert!(spot("outer_angle = 95").contains("lights[0].outer_angle: must be in [0, 90] degrees, got 95"));
        assert!(spot("range = 0").contains("lights[0].range: must be > 0, got 0"));
        let point = parse_str(&format!(
            "{HEAD}[[lights]]\ntype = \"point\"\nposition = [0, 2, 0]\nintensity = [1, 1, 1]\nrange = 3\n"
        ))
        .unwrap();
        assert!(matches!(point.lights[0], Light::Point { range: 3.0, .. }), "{:?}", point.lights[0]);
        let e = err(&format!(
            "{HEAD}[[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\nrange = 3\n"
        ));
        assert!(e.contains("lights[0].range: not a field of a directional light"), "{e}");
    }

    #[test]
    fn field_not_of_the_type() {
        let e =
            err(&format!("{HEAD}[[objects]]\ntype = \"triangle\"\nvertices = [[0,0,0],[1,0,0],[0,1,0]]\nradius = 1\n"));
        assert!(e.contains("objects[0].radius: not a field of a triangle"), "{e}");
        let e = err(&format!("{HEAD}[[materials]]\nname = \"m\"\ntype = \"diffuse\"\nior = 1.3\n"));
        assert!(e.contains("materials[0].ior: not a field of a diffuse material"), "{e}");
    }

    #[test]
    fn mesh_scale_forms() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let go = |scale: &str| {
            let src = format!("{HEAD}[[objects]]\ntype = \"mesh\"\nfile = \"t.obj\"\nscale = {scale}\n");
            parse(&src, Path::new("t.toml"), dir.path())
        };
        let s = go("2").unwrap();
        let Geometry::Mesh { triangles, file, .. } = &s.objects[0].geometry else { panic!() };
        assert_eq!(triangles[0].v[1], V3::new(2.0, 0.0, 0.0));
        assert_eq!(file, &dir.path().join("t.obj"));
        let s = go("[1, 3, 1.5]").unwrap();
        let Geometry::Mesh { triangles, .. } = &s.objects[0].geometry else { panic!() };
        assert_eq!(triangles[0].v[2], V3::new(0.0, 3.0, 0.0));
        assert!(go("0").unwrap_err().to_string().contains("objects[0].scale: must be non-zero"));
        assert!(go("[1, 0, 1]").unwrap_err().to_string().contains("objects[0].scale[1]: must be non-zero"));
        assert!(go("[1, 1]").unwrap_err().to_string().contains("objects[0].scale: must be a number or have 3"));
        assert!(go("\"x\"").unwrap_err().to_string().contains("objects[0].scale: invalid type"));
    }

    fn manifest() -> PathBuf {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
    }

    /// Every prefix of the seed scene parses to Ok or Err, never a panic. The mesh is swapped
    /// for a small one so the successful prefixes stay quick.
    #[test]
    fn truncated_seed_scene_never_panics() {
        let src = std::fs::read_to_string(manifest().join("assets/scenes/seed.toml")).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let scenes = dir.path().join("scenes");
        let meshes = dir.path().join("meshes");
        std::fs::create_dir_all(&scenes).unwrap();
        std::fs::create_dir_all(&meshes).unwrap();
        std::fs::copy(manifest().join("assets/meshes/cube.obj"), meshes.join("bumpy_torus.obj")).unwrap();
        let path = scenes.join("seed.toml");
        let mut ok = 0;
        for end in 0..=src.len() {
            if !src.is_char_boundary(end) {
                continue;
            }
            match parse(&src[..end], &path, &scenes) {
                Ok(_) => ok += 1,
                Err(e) => assert!(e.to_string().starts_with(&path.display().to_string())),
            }
        }
        assert!(parse(&src, &path, &scenes).is_ok());
        assert!(ok >= 1);
    }

    /// Junk in place of each line, and each byte replaced by a few others: no panics either.
    #[test]
    fn mangled_seed_scene_never_panics() {
        let src = std::fs::read_to_string(manifest().join("assets/scenes/seed.toml")).unwrap();
        let nowhere = Path::new("/nonexistent");
        let junk = ["", "=", "[", "]]", "\"", "x = 1", "nan", "-inf", "[[objects]]", "1e400", "{", "'''"];
        let lines: Vec<&str> = src.lines().collect();
        for i in 0..lines.len() {
            for j in junk {
                let mut l = lines.clone();
                l[i] = j;
                let _ = parse(&l.join("\n"), Path::new("m.toml"), nowhere);
            }
        }
        let bytes = src.as_bytes();
        for i in 0..bytes.len() {
            for b in [b'0', b'-', b'"', b']', b'n', b'\n', b'.'] {
                let mut m = bytes.to_vec();
                m[i] = b;
                if let Ok(m) = std::str::from_utf8(&m) {
                    let _ = parse(m, Path::new("m.toml"), nowhere);
                }
            }
        }
    }
}
