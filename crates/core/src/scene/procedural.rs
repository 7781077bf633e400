//! Scenes made without a scene file: the bumpy torus at any size (millions of triangles,
//! nothing to download) seen by the camera of the Embree anchor benchmark
//! (`embree_bench.py`, the Embree 4 comparison), and a bare OBJ mesh with the camera file that script's
//! `--export-obj` writes beside it. Benchmarks and tests use these to work on big scenes.

use super::mesh::{self, Transform, bumpy_torus};
use super::{Camera, Geometry, ImageSize, Light, Object, Scene, SceneError};
use crate::geometry::Triangle;
use crate::math::V3;
use std::path::{Path, PathBuf};

/// The grid of nu × nv quads the anchor script uses for `ntris` triangles: 250 × 200 for
/// 100,000, else nu : nv = 2 : 1 (1000 × 500 for 1M, 2236 × 1118 = 4,999,696 triangles for 5M).
pub fn torus_grid(ntris: usize) -> (usize, usize) {
    if ntris == 100_000 {
        return (250, 200);
    }
    let nv = ((ntris as f64 / 4.0).sqrt().round() as usize).max(3);
    let nu = ((ntris as f64 / (2 * nv) as f64).round() as usize).max(3);
    (nu, nv)
}

/// The anchor's camera for a mesh with bounds `lo`–`hi`: at c + (0.3, 0.8, −1)·|hi − lo| from
/// the box centre c, looking at c, up +y, 30° horizontal field of view at aspect
/// `width / height`.
pub fn anchor_camera(lo: V3<f64>, hi: V3<f64>, aspect: f64) -> Camera {
    let c = (lo + hi) * 0.5;
    let eye = c + V3::new(0.3, 0.8, -1.0) * (hi - lo).length();
    Camera { eye, look_at: c, up: V3::new(0.0, 1.0, 0.0), fov_y: fov_y_of(30.0, aspect) }
}

/// The vertical field of view that goes with horizontal field `fov_x_deg` at `aspect`.
fn fov_y_of(fov_x_deg: f64, aspect: f64) -> f64 {
    2.0 * ((fov_x_deg.to_radians() * 0.5).tan() / aspect).atan().to_degrees()
}

fn bounds(tris: &[Triangle<f64>]) -> (V3<f64>, V3<f64>) {
    let mut lo = V3::splat(f64::INFINITY);
    let mut hi = V3::splat(f64::NEG_INFINITY);
    for v in tris.iter().flat_map(|t| t.v) {
        lo = lo.min_elem(v);
        hi = hi.max_elem(v);
    }
    (lo, hi)
}

/// A scene of one mesh: default grey material, one white directional light from above the
/// camera, `image` pixels.
fn mesh_scene(triangles: Vec<Triangle<f64>>, file: PathBuf, camera: Camera, image: ImageSize) -> Scene {
    let dir = (camera.look_at - camera.eye).normalize() + V3::new(0.0, -0.5, 0.0);
    Scene {
        objects: vec![Object {
            geometry: Geometry::Mesh { file, triangles, attrs: Default::default(), materials: Vec::new() },
            material: 0,
        }],
        lights: vec![Light::Directional { direction: dir.normalize(), intensity: [1.0; 3] }],
        ..Scene::empty(camera, image)
    }
}

/// The bumpy torus of about `ntris` triangles ([`torus_grid`]; R = 2, r = 0.8) as a scene
/// with the anchor's camera, 640 × 480 pixels.
pub fn torus_scene(ntris: usize) -> Scene {
    let (nu, nv) = torus_grid(ntris);
    let (verts, faces) = bumpy_torus(nu, nv, 2.0, 0.8);
    let triangles: Vec<Triangle<f64>> = faces.iter().map(|f| Triangle { v: f.map(|k| verts[k as usize]) }).collect();
    let (lo, hi) = bounds(&triangles);
    let image = ImageSize { width: 640, height: 480 };
    let camera = anchor_camera(lo, hi, 4.0 / 3.0);
    mesh_scene(triangles, PathBuf::from(format!("bumpy_torus_{}", 2 * nu * nv)), camera, image)
}

/// A pathological input for BVH builders: a chain of `chain` triangles in the plane z = 1,
/// `(0, 0) (2^−60 · 17^k, 0) (0, 1)` (at most 43: the widest 2^111.7, so that an area times
/// a count stays finite in f32, the narrowest with a normal whose square does too), each 17
/// times as wide as the one before, and `cluster` more
/// copies of the narrowest. Their boxes are nested, and the SAH's 16 bins tell their centroids
/// apart only for the widest, which it peels off one at every level; the copies cannot be told
/// apart at all. Without a bound on its depth the tree grows as deep as the chain is long and
/// ends in one leaf holding the copies. A ray in the plane x = 0 enters both children at every
/// level.
pub fn deep_chain_triangles(chain: usize, cluster: usize) -> Vec<Triangle<f64>> {
    assert!((1..=43).contains(&chain), "the chain's widest triangle is 2^−60 · 17^(chain − 1) wide, at most 2^111.7");
    let width = |k: usize| 2f64.powi(-60) * 17f64.powi(k as i32);
    let tri = |x: f64| Triangle { v: [V3::new(0.0, 0.0, 1.0), V3::new(x, 0.0, 1.0), V3::new(0.0, 1.0, 1.0)] };
    let mut tris = vec![tri(width(0)); cluster];
    tris.extend((0..chain).map(|k| tri(width(k))));
    tris
}

/// [`deep_chain_triangles`] as a scene seen from (0.3, 0.4, −1), looking along +z, `width` ×
/// `height` pixels.
pub fn deep_chain_scene(chain: usize, cluster: usize, width: u32, height: u32) -> Scene {
    let camera = Camera {
        eye: V3::new(0.3, 0.4, -1.0),
        look_at: V3::new(0.3, 0.4, 1.0),
        up: V3::new(0.0, 1.0, 0.0),
        fov_y: 60.0,
    };
    let tris = deep_chain_triangles(chain, cluster);
    mesh_scene(tris, PathBuf::from("deep_chain"), camera, ImageSize { width, height })
}

/// The camera file `embree_bench.py --export-obj` writes as `NAME_camera.json` beside
/// `NAME.obj`.
#[derive(serde::Deserialize)]
struct CameraFile {
    eye: [f64; 3],
    look_at: [f64; 3],
    up: [f64; 3],
    fov_x_deg: f64,
    aspect_w_over_h: f64,
}

/// Width of the image an OBJ scene gets; the height follows from the camera's aspect.
const OBJ_IMAGE_WIDTH: u32 = 1024;

/// An OBJ mesh as a scene (default material, one directional light). The camera is read from
/// `NAME_camera.json` beside `NAME.obj` when that file exists (eye, look_at, up, fov_x_deg,
/// aspect_w_over_h), else it is [`anchor_camera`] at 4 : 3 for the mesh's bounds. The image
/// is 1024 pixels wide.
pub fn obj_scene(path: &Path) -> Result<Scene, SceneError> {
    let mesh_err = |message: String| SceneError::Mesh {
        path: path.to_path_buf(),
        line: 0,
        column: 0,
        field: "mesh".into(),
        mesh: path.to_path_buf(),
        message,
    };
    let triangles = mesh::load_obj(path, &Transform::default(), mesh::MAX_MESH_TRIANGLES).map_err(mesh_err)?;
    let (lo, hi) = bounds(&triangles);
    let cam_path = camera_file(path);
    let (camera, aspect) =
        if cam_path.exists() { read_camera(&cam_path)? } else { (anchor_camera(lo, hi, 4.0 / 3.0), 4.0 / 3.0) };
    let height = ((OBJ_IMAGE_WIDTH as f64 / aspect).round() as u32).clamp(1, super::file::MAX_IMAGE_SIDE as u32);
    Ok(mesh_scene(triangles, path.to_path_buf(), camera, ImageSize { width: OBJ_IMAGE_WIDTH, height }))
}

/// A scene file (strahl's TOML, glTF), or an OBJ mesh as [`obj_scene`] makes it a scene: what
/// the ray and point queries and `strahl bench rays` take.
pub fn scene_or_obj(path: &Path) -> Result<Scene, SceneError> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")) { obj_scene(path) } else { Scene::load(path) }
}

/// `dir/NAME_camera.json` for `dir/NAME.obj`.
pub fn camera_file(obj: &Path) -> PathBuf {
    let stem = obj.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    obj.with_file_name(format!("{stem}_camera.json"))
}

fn read_camera(path: &Path) -> Result<(Camera, f64), SceneError> {
    let too_bad = |message: String| SceneError::File { path: path.to_path_buf(), message };
    // A camera file is a few hundred bytes; a larger one is not one.
    let text = crate::input::read_text(path, 1 << 16).map_err(|e| too_bad(format!("cannot read camera file: {e}")))?;
    let c: CameraFile = serde_json::from_str(&text).map_err(|e| too_bad(format!("camera file: {e}")))?;
    let v = |a: [f64; 3]| V3::new(a[0], a[1], a[2]);
    let (eye, look_at, up) = (v(c.eye), v(c.look_at), v(c.up));
    if ![eye, look_at, up].iter().all(|p| p.is_finite()) {
        return Err(too_bad("camera file: eye, look_at and up must be finite".into()));
    }
    if (look_at - eye).length() == 0.0 || (look_at - eye).cross(up).length() == 0.0 {
        return Err(too_bad(
            "camera file: look_at must differ from eye, and up must not be parallel to the view".into(),
        ));
    }
    if !(c.fov_x_deg > 0.0 && c.fov_x_deg < 180.0) {
        return Err(too_bad(format!("camera file: fov_x_deg {} is not in (0, 180)", c.fov_x_deg)));
    }
    if !(c.aspect_w_over_h > 1e-3 && c.aspect_w_over_h < 1e3) {
        return Err(too_bad(format!("camera file: aspect_w_over_h {} is not in (0.001, 1000)", c.aspect_w_over_h)));
    }
    let fov_y = fov_y_of(c.fov_x_deg, c.aspect_w_over_h);
    Ok((Camera { eye, look_at, up, fov_y }, c.aspect_w_over_h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids_match_the_anchor_script() {
        assert_eq!(torus_grid(100_000), (250, 200));
        assert_eq!(torus_grid(1_000_000), (1000, 500));
        assert_eq!(torus_grid(5_000_000), (2236, 1118));
    }

    #[test]
    fn torus_scene_has_the_asked_size_and_sees_the_torus() {
        let s = torus_scene(20_000);
        assert_eq!(torus_grid(20_000), (141, 71));
        assert_eq!(s.triangle_count(), 2 * 141 * 71);
        let frame = crate::render::camera::frame(&s.camera, s.image.width, s.image.height);
        let centre = crate::render::camera::primary_ray(&frame, 320, 240, 0);
        let to_centre = (s.camera.look_at - s.camera.eye).normalize().cast::<f32>();
        assert!(centre.dir.dot(to_centre) > 0.9999);
        // 30° horizontally: the ray through the right edge is 15° off the axis.
        let edge = crate::render::camera::ray_through(&frame, 640, 240, 0.0, 0.5);
        assert!((edge.dir.dot(to_centre) - 15f32.to_radians().cos()).abs() < 1e-4);
    }

    #[test]
    fn obj_with_camera_file_loads_and_bad_camera_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let obj = dir.path().join("m.obj");
        std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        // Without a camera file: the anchor camera at 4:3.
        let s = obj_scene(&obj).unwrap();
        assert_eq!((s.image.width, s.image.height), (1024, 768));
        let cam = dir.path().join("m_camera.json");
        std::fs::write(
            &cam,
            r#"{"eye": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_x_deg": 90.0,
            "aspect_w_over_h": 2.0, "note": "ignored"}"#,
        )
        .unwrap();
        let s = obj_scene(&obj).unwrap();
        assert_eq!((s.image.width, s.image.height), (1024, 512));
        assert_eq!(s.camera.eye, V3::new(0.0, 0.0, -5.0));
        assert!((s.camera.fov_y - 2.0 * 0.5f64.atan().to_degrees()).abs() < 1e-12);
        std::fs::write(
            &cam,
            r#"{"eye": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_x_deg": 190.0,
            "aspect_w_over_h": 2.0}"#,
        )
        .unwrap();
        let e = obj_scene(&obj).unwrap_err().to_string();
        assert!(e.contains("m_camera.json") && e.contains("fov_x_deg"), "{e}");
        std::fs::write(&cam, r#"{"eye": [0, 0, -5]}"#).unwrap();
        let e = obj_scene(&obj).unwrap_err().to_string();
        assert!(e.contains("m_camera.json") && e.contains("missing field"), "{e}");
    }
}
