//! numpy arrays in: the checks on values that the Python layer (`strahl/__init__.py`) cannot
//! make cheaply, each naming the first bad row as the caller indexes it.
//!
//! The Python layer has already checked dtypes and shapes and flattened each array to one
//! contiguous dimension; `lead` is the caller's shape without its last axis, so that row `k`
//! of the flat array is named `rays[i, j]` as the caller would index it.

use numpy::{PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use strahl_core::math::{Ray, V3};
use strahl_core::query::{RayQuery, unit_and_length};

/// How the caller names an array and indexes its rows.
#[derive(Clone, Debug)]
pub struct Rows {
    pub name: String,
    pub lead: Vec<usize>,
}

impl Rows {
    pub fn new(name: &str, lead: Vec<usize>) -> Self {
        Self { name: name.to_string(), lead }
    }

    /// `name[i, j]` for flat row `k` (`name` for the one row of an array without leading axes).
    pub fn at(&self, k: usize) -> String {
        if self.lead.is_empty() {
            return self.name.clone();
        }
        let mut idx = vec![0; self.lead.len()];
        let mut rest = k;
        for (i, &n) in self.lead.iter().enumerate().rev() {
            idx[i] = rest % n.max(1);
            rest /= n.max(1);
        }
        let parts: Vec<String> = idx.iter().map(|i| i.to_string()).collect();
        format!("{}[{}]", self.name, parts.join(", "))
    }

    pub fn count(&self) -> usize {
        self.lead.iter().product()
    }
}

pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// A flat float array as numpy passed it: float32 or float64, never converted here.
pub enum FloatArray<'py> {
    F32(PyReadonlyArray1<'py, f32>),
    F64(PyReadonlyArray1<'py, f64>),
}

/// Rows of `width` floats.
pub struct Floats<'py> {
    pub array: FloatArray<'py>,
    pub width: usize,
}

impl<'py> Floats<'py> {
    pub fn extract(array: &Bound<'py, PyAny>, rows: &Rows, width: usize) -> PyResult<Self> {
        let floats = if let Ok(a) = array.extract::<PyReadonlyArray1<'py, f32>>() {
            FloatArray::F32(a)
        } else if let Ok(a) = array.extract::<PyReadonlyArray1<'py, f64>>() {
            FloatArray::F64(a)
        } else {
            return Err(value_error(format!("{}: expected a float32 or float64 array", rows.name)));
        };
        let len = match &floats {
            FloatArray::F32(a) => a.len(),
            FloatArray::F64(a) => a.len(),
        };
        if len != rows.count() * width {
            return Err(value_error(format!("{}: {len} values for {} rows of {width}", rows.name, rows.count())));
        }
        Ok(Self { array: floats, width })
    }

    /// Rows of `width` values.
    pub fn rows(&self) -> usize {
        let len = match &self.array {
            FloatArray::F32(a) => a.len(),
            FloatArray::F64(a) => a.len(),
        };
        len / self.width.max(1)
    }

    /// The values, widened to f64 (exact for float32).
    pub fn to_f64(&self) -> PyResult<Vec<f64>> {
        Ok(match &self.array {
            FloatArray::F32(a) => contiguous(a)?.iter().map(|&x| x as f64).collect(),
            FloatArray::F64(a) => contiguous(a)?.to_vec(),
        })
    }
}

/// The values of a contiguous array (the Python layer makes every array contiguous).
pub fn contiguous<'a, T: numpy::Element>(a: &'a PyReadonlyArray1<'_, T>) -> PyResult<&'a [T]> {
    a.as_slice().map_err(|_| value_error("internal error: an array reached strahl not contiguous"))
}

/// One ray as strahl traces it, from a row `ox, oy, oz, dx, dy, dz` in any units: the
/// direction normalised in f64 as `strahl trace` does ([`unit_and_length`]), and its length
/// kept, so that distances go back to the caller in units of its direction (Open3D's `t_hit`).
#[derive(Clone, Copy, Debug)]
pub struct RayIn {
    pub origin: V3<f64>,
    /// Unit length.
    pub dir: V3<f64>,
    /// |d| of the caller's direction.
    pub length: f64,
}

impl RayIn {
    /// Parses one row; the error says what is wrong with it.
    #[inline]
    pub fn parse(r: [f64; 6]) -> Result<Self, &'static str> {
        if !r.iter().all(|x| x.is_finite()) {
            return Err("NaN or infinity in a ray: all six values (ox, oy, oz, dx, dy, dz) must be finite");
        }
        // As `strahl trace` normalises it (bit for bit), keeping the length.
        let (dir, length) = unit_and_length(V3::new(r[3], r[4], r[5])).ok_or("the direction (dx, dy, dz) is zero")?;
        Ok(Self { origin: V3::new(r[0], r[1], r[2]), dir, length })
    }

    /// Rounded to f32, exactly as `RayQuery::ray::<f32>` rounds it.
    #[inline]
    pub fn ray32(&self) -> Ray<f32> {
        Ray::new(self.origin.cast(), self.dir.cast())
    }

    #[inline]
    pub fn ray64(&self) -> Ray<f64> {
        Ray::new(self.origin, self.dir)
    }

    /// As a batch query, with the caller's (tnear, tfar) scaled from units of its direction to
    /// distances along the unit one.
    pub fn query(&self, tnear: f64, tfar: f64) -> RayQuery {
        RayQuery { origin: self.origin, dir: self.dir, tmin: tnear * self.length, tmax: tfar * self.length }
    }
}

/// Rays parsed a chunk at a time on worker threads, remembering the first bad row of all.
pub struct RayChunks<'a, T> {
    values: &'a [T],
    first_bad: AtomicUsize,
    why: std::sync::Mutex<&'static str>,
}

/// Rays per chunk of work: enough to amortise a task, few enough to stay in the caches.
pub const CHUNK: usize = 4096;

impl<'a, T: Copy + Into<f64> + Sync> RayChunks<'a, T> {
    pub fn new(values: &'a [T]) -> Self {
        Self { values, first_bad: AtomicUsize::new(usize::MAX), why: std::sync::Mutex::new("") }
    }

    pub fn len(&self) -> usize {
        self.values.len() / 6
    }

    /// The values of chunk `c` ([`CHUNK`] rays, the last one shorter), as parallel work items.
    pub fn chunks(&self) -> rayon::slice::Chunks<'a, T> {
        self.values.par_chunks(6 * CHUNK)
    }

    /// The rays of chunk `c`, or None where one of them is bad (recorded) or an earlier bad
    /// row was already found (no work is wasted on it).
    pub fn parse(&self, c: usize, values: &[T]) -> Option<Vec<RayIn>> {
        let first = c * CHUNK;
        if self.first_bad.load(Ordering::Relaxed) < first {
            return None;
        }
        let mut rays = Vec::with_capacity(values.len() / 6);
        for (k, r) in values.chunks_exact(6).enumerate() {
            match RayIn::parse([r[0].into(), r[1].into(), r[2].into(), r[3].into(), r[4].into(), r[5].into()]) {
                Ok(ray) => rays.push(ray),
                Err(why) => {
                    let mut w = self.why.lock().unwrap_or_else(|e| e.into_inner());
                    if first + k < self.first_bad.load(Ordering::Relaxed) {
                        self.first_bad.store(first + k, Ordering::Relaxed);
                        *w = why;
                    }
                    return None;
                }
            }
        }
        Some(rays)
    }

    /// The error for the first bad row, if there was one.
    pub fn check(&self, rows: &Rows) -> PyResult<()> {
        let k = self.first_bad.load(Ordering::Relaxed);
        if k == usize::MAX {
            return Ok(());
        }
        let why = *self.why.lock().unwrap_or_else(|e| e.into_inner());
        Err(value_error(format!("{}: {why}", rows.at(k))))
    }
}

/// Points or vectors of three finite values.
pub fn read_points(values: &[f64], rows: &Rows) -> PyResult<Vec<V3<f64>>> {
    values
        .chunks(3)
        .enumerate()
        .map(|(k, r)| {
            if r.iter().all(|x| x.is_finite()) {
                Ok(V3::new(r[0], r[1], r[2]))
            } else {
                Err(value_error(format!("{}: NaN or infinity: all three values must be finite", rows.at(k))))
            }
        })
        .collect()
}

/// Radii: finite and positive.
pub fn read_radii(values: &[f64], rows: &Rows) -> PyResult<Vec<f64>> {
    for (k, &r) in values.iter().enumerate() {
        if !(r.is_finite() && r > 0.0) {
            return Err(value_error(format!("{}: a radius must be finite and positive, got {r}", rows.at(k))));
        }
    }
    Ok(values.to_vec())
}

/// Triangle vertex indices (int64 from the Python layer): each in 0..vertex_count.
pub fn read_triangles(array: &Bound<'_, PyAny>, rows: &Rows, vertex_count: usize) -> PyResult<Vec<[usize; 3]>> {
    let a = array
        .extract::<PyReadonlyArray1<'_, i64>>()
        .map_err(|_| value_error(format!("{}: expected an integer array", rows.name)))?;
    let v = contiguous(&a)?;
    if v.len() != rows.count() * 3 {
        return Err(value_error(format!("{}: {} values for {} rows of 3", rows.name, v.len(), rows.count())));
    }
    v.chunks(3)
        .enumerate()
        .map(|(k, t)| {
            let mut out = [0usize; 3];
            for (o, &i) in out.iter_mut().zip(t) {
                if i < 0 || i as u64 >= vertex_count as u64 {
                    return Err(value_error(format!(
                        "{}: vertex index {i} is out of range: there are {vertex_count} vertices",
                        rows.at(k)
                    )));
                }
                *o = i as usize;
            }
            Ok(out)
        })
        .collect()
}
