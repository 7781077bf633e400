//! `strahl._strahl`, the extension module under the `strahl` Python package: strahl's ray
//! queries and renders on numpy arrays. The package's Python layer (`strahl/__init__.py`)
//! checks dtypes and shapes and hands over flat contiguous arrays; this module checks values,
//! runs strahl without the GIL and hands back flat arrays for the Python layer to shape.

// `!(x > 0.0)` is used on purpose, as in strahl-core: unlike `x <= 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod arrays;
mod device;
mod points;
mod queries;
mod render;
mod scene;

use arrays::{FloatArray, Floats, RayChunks, Rows, contiguous};
use numpy::IntoPyArray;
use pyo3::exceptions::{PyRuntimeWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use queries::Engine;
use scene::{Built, Contents};
use std::sync::Mutex;
use strahl_gpu::GpuError;
use strahl_gpu::select::{Choice, Workload};

/// Runs `$body` with `$chunks` bound to the rays as [`RayChunks`] of their own float type.
macro_rules! with_rays {
    ($floats:expr, $chunks:ident => $body:expr) => {
        match &$floats.array {
            FloatArray::F32(a) => {
                let values = contiguous(a)?;
                let $chunks = RayChunks::new(values);
                $body
            }
            FloatArray::F64(a) => {
                let values = contiguous(a)?;
                let $chunks = RayChunks::new(values);
                $body
            }
        }
    };
}

/// Runs `queries::$query` (generic over the rays' and the outputs' float types) on `$rays` in
/// the scene's precision: its outputs as a dict of numpy arrays ([`Outputs`]).
macro_rules! dict_query {
    ($self:ident, $py:ident, $rays:ident, $lead:ident, $query:ident) => {{
        let rows = Rows::new("rays", $lead);
        let floats = Floats::extract($rays, &rows, 6)?;
        let d = PyDict::new($py);
        if $self.f64 {
            dict_query!(@run $self, $py, floats, rows, $query, f64).put(&d)?;
        } else {
            dict_query!(@run $self, $py, floats, rows, $query, f32).put(&d)?;
        }
        Ok(d)
    }};
    (@run $self:ident, $py:ident, $floats:ident, $rows:ident, $query:ident, $f:ty) => {
        with_rays!($floats, chunks => {
            let out = $self.run($py, |b, e| queries::$query::<_, $f>(b, e, &chunks))?;
            chunks.check(&$rows)?;
            out
        })
    };
}

/// A query's outputs, put into a dict of numpy arrays under Open3D's names.
trait Outputs {
    fn put(self, d: &Bound<'_, PyDict>) -> PyResult<()>;
}

impl<F: queries::OutFloat> Outputs for queries::Nearest<F> {
    fn put(self, d: &Bound<'_, PyDict>) -> PyResult<()> {
        set(d, "t_hit", self.t_hit)?;
        set(d, "geometry_ids", self.geometry_ids)?;
        set(d, "primitive_ids", self.primitive_ids)?;
        set(d, "primitive_uvs", self.primitive_uvs)?;
        set(d, "primitive_normals", self.primitive_normals)
    }
}

impl<F: queries::OutFloat> Outputs for points::ClosestPoints<F> {
    fn put(self, d: &Bound<'_, PyDict>) -> PyResult<()> {
        set(d, "points", self.points)?;
        set(d, "geometry_ids", self.geometry_ids)?;
        set(d, "primitive_ids", self.primitive_ids)?;
        set(d, "primitive_uvs", self.primitive_uvs)?;
        set(d, "primitive_normals", self.primitive_normals)
    }
}

impl<F: queries::OutFloat> Outputs for queries::AllHits<F> {
    fn put(self, d: &Bound<'_, PyDict>) -> PyResult<()> {
        set(d, "ray_splits", self.splits)?;
        set(d, "ray_ids", self.ray_ids)?;
        set(d, "t_hit", self.t_hit)?;
        set(d, "geometry_ids", self.geometry_ids)?;
        set(d, "primitive_ids", self.primitive_ids)?;
        set(d, "primitive_uvs", self.primitive_uvs)?;
        set(d, "primitive_normals", self.primitive_normals)
    }
}

/// A scene to query: triangles, spheres and cylinders, or a scene file.
#[pyclass(module = "strahl._strahl", name = "Scene", frozen)]
struct PyScene {
    contents: Mutex<Contents>,
    choice: Choice,
    f64: bool,
    /// Where queries run, decided at the first one: with the reason `auto` chose.
    engine: Mutex<Option<(Engine, String)>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl PyScene {
    fn new(contents: Contents, device: &str, precision: &str) -> PyResult<Self> {
        let choice = device::parse_choice(device, "device")?;
        let f64 = match precision.trim().to_ascii_lowercase().as_str() {
            "f32" | "float32" => false,
            "f64" | "float64" => true,
            _ => return Err(PyValueError::new_err(format!("precision={precision:?}: use \"f32\" or \"f64\""))),
        };
        if f64 && choice == Choice::Gpu {
            return Err(PyValueError::new_err(
                "precision=\"f64\" runs on the CPU (the GPU traces in f32): use device=\"cpu\" or \"auto\"",
            ));
        }
        Ok(Self { contents: Mutex::new(contents), choice, f64, engine: Mutex::new(None) })
    }

    fn engine(&self) -> Result<(Engine, String), GpuError> {
        let mut slot = lock(&self.engine);
        if let Some(e) = slot.as_ref() {
            return Ok(e.clone());
        }
        let e = if self.f64 {
            (Engine::Cpu64, "cpu (f64)".to_string())
        } else {
            match device::open(self.choice, Workload::Trace)? {
                (Some(ctx), note) => {
                    let name = ctx.adapter_name();
                    (Engine::Gpu(ctx), note.unwrap_or_else(|| format!("gpu ({name})")))
                }
                (None, note) => (Engine::Cpu32, note.unwrap_or_else(|| "cpu".into())),
            }
        };
        *slot = Some(e.clone());
        Ok(e)
    }

    /// Runs query `f` without the GIL on the scene as built now. Where `auto` chose a GPU
    /// that then fails (a scene over its limits, out of memory), the query runs on the CPU,
    /// and so do later ones, with a warning; a forced GPU's failure is the error.
    fn run<'py, T: Send>(
        &self,
        py: Python<'py>,
        f: impl Fn(&Built, &Engine) -> Result<T, GpuError> + Send + Sync,
    ) -> PyResult<T> {
        let (result, warning) = py.detach(|| -> PyResult<(T, Option<String>)> {
            let built = lock(&self.contents).built()?;
            let (engine, _) = self.engine().map_err(device::gpu_error)?;
            match f(&built, &engine) {
                Ok(v) => Ok((v, None)),
                Err(e) if matches!(engine, Engine::Gpu(_)) && self.choice == Choice::Auto => {
                    let why = format!("strahl: the GPU failed ({e}); this scene's queries run on the CPU");
                    *lock(&self.engine) = Some((Engine::Cpu32, format!("cpu ({why})")));
                    let v = f(&built, &Engine::Cpu32).map_err(device::gpu_error)?;
                    Ok((v, Some(why)))
                }
                Err(e) => Err(device::gpu_error(e)),
            }
        })?;
        if let Some(w) = warning {
            let message = std::ffi::CString::new(w).unwrap_or_default();
            PyErr::warn(py, &py.get_type::<PyRuntimeWarning>(), &message, 2)?;
        }
        Ok(result)
    }
}

/// Runs point query `$query` (generic over the points' and the outputs' float types) on the
/// flat `$values`, in the scene's precision, with `$rest` after the points.
macro_rules! point_query {
    ($self:ident, $py:ident, $floats:ident, $query:ident $(, $rest:expr)*) => {{
        match (&$floats.array, $self.f64) {
            (FloatArray::F32(a), false) => {
                let v = contiguous(a)?;
                Either::F32($self.run($py, |b, e| points::$query::<_, f32>(b, e, v $(, $rest)*))?)
            }
            (FloatArray::F64(a), false) => {
                let v = contiguous(a)?;
                Either::F32($self.run($py, |b, e| points::$query::<_, f32>(b, e, v $(, $rest)*))?)
            }
            (FloatArray::F32(a), true) => {
                let v = contiguous(a)?;
                Either::F64($self.run($py, |b, e| points::$query::<_, f64>(b, e, v $(, $rest)*))?)
            }
            (FloatArray::F64(a), true) => {
                let v = contiguous(a)?;
                Either::F64($self.run($py, |b, e| points::$query::<_, f64>(b, e, v $(, $rest)*))?)
            }
        }
    }};
}

/// A query's answer in float32 (the f32 scene) or float64 (the oracle).
enum Either<A, B> {
    F32(A),
    F64(B),
}

impl PyScene {
    /// The points of a point query, checked: finite, as many as `lead` says.
    fn points<'py>(&self, points: &Bound<'py, PyAny>, lead: Vec<usize>) -> PyResult<Floats<'py>> {
        let rows = Rows::new("query_points", lead);
        let floats = Floats::extract(points, &rows, 3)?;
        match &floats.array {
            FloatArray::F32(a) => points::check_points(contiguous(a)?, &rows)?,
            FloatArray::F64(a) => points::check_points(contiguous(a)?, &rows)?,
        }
        Ok(floats)
    }
}

fn set<'py, T: numpy::Element>(d: &Bound<'py, PyDict>, key: &str, v: Vec<T>) -> PyResult<()> {
    d.set_item(key, v.into_pyarray(d.py()))
}

#[pymethods]
impl PyScene {
    #[new]
    #[pyo3(signature = (device = "auto", precision = "f32"))]
    fn py_new(device: &str, precision: &str) -> PyResult<Self> {
        Self::new(Contents::default(), device, precision)
    }

    /// A scene read from a file (strahl's TOML, glTF, OBJ).
    #[staticmethod]
    #[pyo3(signature = (path, device = "auto", precision = "f32"))]
    fn from_file(py: Python<'_>, path: std::path::PathBuf, device: &str, precision: &str) -> PyResult<Self> {
        let contents = py.detach(|| Contents::load(&path))?;
        Self::new(contents, device, precision)
    }

    /// Where queries run ("gpu (...)" or "cpu (...)", with the reason where auto chose);
    /// decided at the first query, or now.
    fn device(&self, py: Python<'_>) -> PyResult<String> {
        py.detach(|| self.engine().map(|e| e.1)).map_err(device::gpu_error)
    }

    fn add_triangles(
        &self,
        vertices: &Bound<'_, PyAny>,
        nvertices: usize,
        triangles: &Bound<'_, PyAny>,
        ntriangles: usize,
    ) -> PyResult<u32> {
        let v = Floats::extract(vertices, &Rows::new("vertices", vec![nvertices]), 3)?;
        lock(&self.contents).add_triangles(&v, triangles, ntriangles)
    }

    fn add_spheres(&self, centers: &Bound<'_, PyAny>, radii: &Bound<'_, PyAny>, n: usize) -> PyResult<u32> {
        let c = Floats::extract(centers, &Rows::new("centers", vec![n]), 3)?;
        let r = Floats::extract(radii, &Rows::new("radii", vec![n]), 1)?;
        lock(&self.contents).add_spheres(&c, &r)
    }

    fn add_cylinders(
        &self,
        p0: &Bound<'_, PyAny>,
        p1: &Bound<'_, PyAny>,
        radii: &Bound<'_, PyAny>,
        n: usize,
    ) -> PyResult<u32> {
        let a = Floats::extract(p0, &Rows::new("p0", vec![n]), 3)?;
        let b = Floats::extract(p1, &Rows::new("p1", vec![n]), 3)?;
        let r = Floats::extract(radii, &Rows::new("radii", vec![n]), 1)?;
        lock(&self.contents).add_cylinders(&a, &b, &r)
    }

    /// Nearest hits: a dict of flat arrays (t_hit, geometry_ids, primitive_ids,
    /// primitive_uvs, primitive_normals).
    fn cast_rays<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        lead: Vec<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        dict_query!(self, py, rays, lead, cast_rays)
    }

    fn test_occlusions<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        lead: Vec<usize>,
        tnear: f64,
        tfar: f64,
    ) -> PyResult<Bound<'py, numpy::PyArray1<bool>>> {
        if !(tnear.is_finite() && tnear >= 0.0) || tfar.is_nan() || tfar < tnear {
            return Err(PyValueError::new_err(format!(
                "tnear={tnear:?}, tfar={tfar:?}: need 0 <= tnear <= tfar, with tnear finite"
            )));
        }
        let rows = Rows::new("rays", lead);
        let floats = Floats::extract(rays, &rows, 6)?;
        let out = with_rays!(floats, chunks => {
            let out = self.run(py, |b, e| queries::test_occlusions(b, e, &chunks, tnear, tfar))?;
            chunks.check(&rows)?;
            out
        });
        Ok(out.into_pyarray(py))
    }

    fn count_intersections<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        lead: Vec<usize>,
    ) -> PyResult<Bound<'py, numpy::PyArray1<u32>>> {
        let rows = Rows::new("rays", lead);
        let floats = Floats::extract(rays, &rows, 6)?;
        let out = with_rays!(floats, chunks => {
            let out = self.run(py, |b, e| queries::count_intersections(b, e, &chunks))?;
            chunks.check(&rows)?;
            out
        });
        Ok(out.into_pyarray(py))
    }

    /// Every hit: a dict of flat arrays (ray_splits, ray_ids, t_hit, geometry_ids,
    /// primitive_ids, primitive_uvs, primitive_normals).
    fn list_intersections<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        lead: Vec<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        dict_query!(self, py, rays, lead, list_intersections)
    }

    /// The nearest surface point of each point: a dict of flat arrays (points, geometry_ids,
    /// primitive_ids, primitive_uvs, primitive_normals).
    fn compute_closest_points<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        lead: Vec<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let floats = self.points(points, lead)?;
        let d = PyDict::new(py);
        match point_query!(self, py, floats, closest_points) {
            Either::F32(out) => out.put(&d)?,
            Either::F64(out) => out.put(&d)?,
        }
        Ok(d)
    }

    /// The distance from each point to the nearest surface; `signed`: negative inside, by
    /// the winding number.
    fn compute_distance<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        lead: Vec<usize>,
        signed: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let floats = self.points(points, lead)?;
        Ok(match point_query!(self, py, floats, distances, signed) {
            Either::F32(v) => v.into_pyarray(py).into_any(),
            Either::F64(v) => v.into_pyarray(py).into_any(),
        })
    }

    /// Renders the scene: (flat float32 pixels, where it rendered).
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (mode, spp, width, height, max_depth, seed, device, camera, denoise = false))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        mode: &str,
        spp: u32,
        width: Option<u32>,
        height: Option<u32>,
        max_depth: Option<u32>,
        seed: u32,
        device: &str,
        camera: Option<render::CameraArgs>,
        denoise: bool,
    ) -> PyResult<(Bound<'py, numpy::PyArray1<f32>>, String, u32, u32)> {
        let camera = camera.map(|(e, l, u, f)| render::camera(e, l, u, f)).transpose()?;
        let scene = lock(&self.contents).for_render(camera);
        let req = render::Request {
            mode: render::parse_mode(mode)?,
            spp,
            width: width.unwrap_or(scene.image.width),
            height: height.unwrap_or(scene.image.height),
            max_depth,
            seed,
            device: device::parse_choice(device, "device")?,
            denoise,
        };
        req.check()?;
        let (pixels, on) = py.detach(|| req.run(scene))?;
        Ok((pixels.into_pyarray(py), on, req.width, req.height))
    }
}

#[pymodule]
fn _strahl(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene>()?;
    m.add("INVALID_ID", scene::INVALID_ID)?;
    m.add("MAX_TRIANGLES", scene::MAX_TRIANGLES)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
