//! The scene a `RaycastingScene` holds: strahl's [`Scene`], grown by `add_triangles`,
//! `add_spheres` and `add_cylinders` or read from a file, and what is built from it on the
//! first query after a change (the BVH and its 8-wide form, the f64 oracle's tree, the
//! winding numbers' far-field data, the buffers on the GPU), cached until the next change.

use crate::arrays::{Floats, Rows, read_points, read_radii, read_triangles, value_error};
use pyo3::exceptions::{PyMemoryError, PyOSError};
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use strahl_core::accel::Bvh;
use strahl_core::geometry::{Cylinder, Sphere, Triangle};
use strahl_core::math::V3;
use strahl_core::primitives::{Primitives, Tag};
use strahl_core::proximity::winding::WindingTree;
use strahl_core::render::{Prepared, available_memory, check_memory};
use strahl_core::scene::mesh::MAX_MESH_TRIANGLES;
use strahl_core::scene::{Camera, Geometry, ImageSize, Light, Object, Scene, SceneError, procedural};
use strahl_cpu::accel::WideBvh;
use strahl_gpu::{GpuContext, GpuError, SceneBuffers};

/// Open3D's `INVALID_ID`: the geometry and primitive id of a miss.
pub const INVALID_ID: u32 = u32::MAX;

/// Where each scene object's hits are reported: the geometry id `add_*` returned, and the
/// primitive id of its first primitive (a sphere of `add_spheres` is one object; the
/// triangles of `add_triangles` are the faces of one).
#[derive(Clone, Copy, Debug)]
struct Ids {
    geometry: u32,
    first_primitive: u32,
}

/// What a query needs, built once per change of the scene.
pub struct Built {
    pub prep: Prepared,
    /// The CPU's 8-wide tree of `prep`, which the CPU queries walk.
    pub wide: WideBvh,
    ids: Vec<Ids>,
    oracle: OnceLock<(Primitives<f64>, Bvh)>,
    /// The winding numbers' far-field data over `prep`'s tree, and over the oracle's.
    winding: OnceLock<WindingTree<f32>>,
    winding64: OnceLock<WindingTree<f64>>,
    gpu: OnceLock<Result<SceneBuffers, String>>,
}

impl Built {
    /// Geometry and primitive id of a hit's tag.
    #[inline]
    pub fn ids(&self, tag: Tag) -> (u32, u32) {
        let ids = self.ids[tag.object as usize];
        (ids.geometry, ids.first_primitive + tag.face)
    }

    /// The f64 primitives and their tree (the oracle), built at its first use.
    pub fn oracle(&self) -> &(Primitives<f64>, Bvh) {
        self.oracle.get_or_init(|| {
            let prims = Primitives::<f64>::from_scene(&self.prep.scene);
            let bvh = Bvh::build(&prims);
            (prims, bvh)
        })
    }

    /// The far-field data of the f32 tree, built at its first use.
    pub fn winding(&self) -> &WindingTree<f32> {
        self.winding.get_or_init(|| WindingTree::build(&self.prep.bvh, &self.prep.prims))
    }

    /// The far-field data of the oracle's tree, built at its first use.
    pub fn winding64(&self) -> &WindingTree<f64> {
        self.winding64.get_or_init(|| {
            let (p64, bvh) = self.oracle();
            WindingTree::build(bvh, p64)
        })
    }

    /// The scene's buffers on `ctx`, uploaded at their first use; the error says why they
    /// cannot be (too large for the adapter's limits, out of memory).
    pub fn buffers(&self, ctx: &GpuContext) -> Result<&SceneBuffers, GpuError> {
        self.gpu
            .get_or_init(|| SceneBuffers::upload(ctx, &self.prep.flat).map_err(|e| e.to_string()))
            .as_ref()
            .map_err(|e| GpuError::Wgpu(e.clone()))
    }

    pub fn is_empty(&self) -> bool {
        self.prep.prims.bounded_count() == 0 && self.prep.prims.planes.is_empty()
    }
}

/// The scene and the ids its objects report.
pub struct Contents {
    pub scene: Scene,
    ids: Vec<Ids>,
    /// Geometries added so far (the next `add_*` returns this id).
    geometries: u32,
    /// Whether the camera was given by a file (else it is fitted to the bounds at render time).
    has_camera: bool,
    built: Option<Arc<Built>>,
}

fn empty_scene() -> Scene {
    let camera = Camera { eye: V3::new(0.0, 0.0, -5.0), look_at: V3::zero(), up: V3::new(0.0, 1.0, 0.0), fov_y: 40.0 };
    Scene::empty(camera, ImageSize { width: 640, height: 480 })
}

/// Triangles that one scene may hold in all, as strahl's mesh loaders allow one mesh.
pub const MAX_TRIANGLES: usize = MAX_MESH_TRIANGLES;

impl Default for Contents {
    fn default() -> Self {
        Self { scene: empty_scene(), ids: Vec::new(), geometries: 0, has_camera: false, built: None }
    }
}

impl Contents {
    /// A scene read from a file: strahl's TOML, a glTF file (`.gltf`, `.glb`) with its first
    /// camera, or an OBJ mesh. Geometry id = the object's index in the file, primitive id =
    /// the triangle inside it, as `strahl trace` reports them.
    pub fn load(path: &Path) -> PyResult<Self> {
        let scene = procedural::scene_or_obj(path).map_err(scene_error)?;
        let ids = (0..scene.objects.len() as u32).map(|i| Ids { geometry: i, first_primitive: 0 }).collect();
        let geometries = scene.objects.len() as u32;
        Ok(Self { scene, ids, geometries, has_camera: true, built: None })
    }

    fn push(&mut self, geometry: Geometry, first_primitive: u32) {
        self.scene.objects.push(Object { geometry, material: 0 });
        self.ids.push(Ids { geometry: self.geometries, first_primitive });
    }

    /// Ends an `add_*`: the next id, and what was built is stale.
    fn added(&mut self) -> u32 {
        self.built = None;
        self.geometries += 1;
        self.geometries - 1
    }

    fn check_total(&self, more: usize) -> PyResult<()> {
        let have: usize = self.scene.objects.iter().map(|o| o.geometry.primitive_count()).sum();
        if have.saturating_add(more) > MAX_TRIANGLES {
            return Err(value_error(format!(
                "the scene would hold {} primitives; strahl takes at most {MAX_TRIANGLES}",
                have.saturating_add(more)
            )));
        }
        Ok(())
    }

    pub fn add_triangles(&mut self, vertices: &Floats, triangles: &Bound<'_, PyAny>, count: usize) -> PyResult<u32> {
        self.check_total(count)?;
        let vertices = read_points(&vertices.to_f64()?, &Rows::new("vertices", vec![vertices.rows()]))?;
        let faces = read_triangles(triangles, &Rows::new("triangles", vec![count]), vertices.len())?;
        let triangles: Vec<Triangle<f64>> = faces.iter().map(|f| Triangle { v: f.map(|k| vertices[k]) }).collect();
        self.push(
            Geometry::Mesh {
                file: PathBuf::from("add_triangles"),
                triangles,
                attrs: Default::default(),
                materials: Vec::new(),
            },
            0,
        );
        Ok(self.added())
    }

    pub fn add_spheres(&mut self, centers: &Floats, radii: &Floats) -> PyResult<u32> {
        let n = centers.rows();
        self.check_total(n)?;
        let c = read_points(&centers.to_f64()?, &Rows::new("centers", vec![n]))?;
        let r = read_radii(&radii.to_f64()?, &Rows::new("radii", vec![n]))?;
        for (k, (center, radius)) in c.into_iter().zip(r).enumerate() {
            self.push(Geometry::Sphere(Sphere { center, radius }), k as u32);
        }
        Ok(self.added())
    }

    pub fn add_cylinders(&mut self, p0: &Floats, p1: &Floats, radii: &Floats) -> PyResult<u32> {
        let n = p0.rows();
        self.check_total(n)?;
        let a = read_points(&p0.to_f64()?, &Rows::new("p0", vec![n]))?;
        let b = read_points(&p1.to_f64()?, &Rows::new("p1", vec![n]))?;
        let r = read_radii(&radii.to_f64()?, &Rows::new("radii", vec![n]))?;
        for (k, (p1, p2)) in a.iter().zip(&b).enumerate() {
            if p1 == p2 {
                return Err(value_error(format!("p0[{k}] and p1[{k}]: the axis has zero length")));
            }
        }
        for (k, ((p1, p2), radius)) in a.into_iter().zip(b).zip(r).enumerate() {
            self.push(Geometry::Cylinder(Cylinder { p1, p2, radius, caps: true }), k as u32);
        }
        Ok(self.added())
    }

    /// What queries need, built now if the scene changed. Runs without the GIL.
    pub fn built(&mut self) -> PyResult<Arc<Built>> {
        if let Some(b) = &self.built {
            return Ok(b.clone());
        }
        check_memory(&self.scene, available_memory()).map_err(|e| PyMemoryError::new_err(e.to_string()))?;
        let prep = Prepared::new(self.scene.clone());
        let wide = WideBvh::new(&prep.bvh, &prep.prims);
        let built = Arc::new(Built {
            prep,
            wide,
            ids: self.ids.clone(),
            oracle: OnceLock::new(),
            winding: OnceLock::new(),
            winding64: OnceLock::new(),
            gpu: OnceLock::new(),
        });
        self.built = Some(built.clone());
        Ok(built)
    }

    /// The scene as `render` draws it: a file's camera and lights as given; a scene built
    /// by `add_*` seen as strahl's OBJ scenes are (the anchors' camera over its bounds, a
    /// directional light from above the camera), unless `camera` is given.
    pub fn for_render(&self, camera: Option<Camera>) -> Scene {
        let mut scene = self.scene.clone();
        if !self.has_camera {
            let prims = Primitives::<f64>::from_scene(&scene);
            let (mut lo, mut hi) = (V3::splat(f64::INFINITY), V3::splat(f64::NEG_INFINITY));
            for r in prims.bounded_refs() {
                let (a, b) = prims.bounds_f64(r);
                (lo, hi) = (lo.min_elem(a), hi.max_elem(b));
            }
            if lo.x <= hi.x {
                let aspect = scene.image.width as f64 / scene.image.height as f64;
                scene.camera = procedural::anchor_camera(lo, hi, aspect);
            }
            let c = &scene.camera;
            let dir = (c.look_at - c.eye).normalize() + V3::new(0.0, -0.5, 0.0);
            scene.lights = vec![Light::Directional { direction: dir.normalize(), intensity: [1.0; 3] }];
        }
        if let Some(c) = camera {
            scene.camera = c;
        }
        scene
    }
}

fn scene_error(e: SceneError) -> PyErr {
    match e {
        SceneError::Io { .. } => PyOSError::new_err(e.to_string()),
        e => value_error(e.to_string()),
    }
}
