//! The point queries of a `RaycastingScene`: the nearest surface point, the distance to it,
//! and that distance signed by the generalized winding number (negative inside), on flat
//! arrays of points. On the CPU each chunk of points is read, answered and written by one
//! worker; on the GPU all points go in one dispatch series, and the winding numbers of signed
//! distances are summed on the CPU.
//!
//! Answers follow Open3D's `RaycastingScene`: `points`, `geometry_ids`, `primitive_ids`,
//! `primitive_uvs` and `primitive_normals` of the nearest point; on an empty scene the ids are
//! [`INVALID_ID`], the points, (u, v) and normals 0 and the distances infinity.

use crate::arrays::{CHUNK, Rows, value_error};
use crate::queries::{Engine, OutFloat};
use crate::scene::{Built, INVALID_ID};
use pyo3::PyResult;
use rayon::prelude::*;
use strahl_core::math::{Real, V3};
use strahl_core::primitives::Primitives;
use strahl_core::proximity::winding::inside;
use strahl_core::proximity::{Closest, closest};
use strahl_cpu::accel::wide_closest;
use strahl_gpu::GpuError;

/// Checks that every point is finite; the error names the first that is not.
pub fn check_points<T: Copy + Into<f64> + Sync>(values: &[T], rows: &Rows) -> PyResult<()> {
    match values.par_chunks(3).position_first(|r| !r.iter().all(|&x| x.into().is_finite())) {
        Some(k) => Err(value_error(format!("{}: NaN or infinity: all three values must be finite", rows.at(k)))),
        None => Ok(()),
    }
}

/// `compute_closest_points`' outputs, one entry (or 2, or 3) per point.
pub struct ClosestPoints<F> {
    pub points: Vec<F>,
    pub geometry_ids: Vec<u32>,
    pub primitive_ids: Vec<u32>,
    pub primitive_uvs: Vec<F>,
    pub primitive_normals: Vec<F>,
}

/// The point `k` of a flat array, in the scene's precision.
#[inline]
fn point<T: Copy + Into<f64>, R: Real>(values: &[T], k: usize) -> V3<R> {
    V3::new(values[3 * k].into(), values[3 * k + 1].into(), values[3 * k + 2].into()).cast()
}

/// The nearest surface point of `p` in the scene's precision: the 8-wide tree's walk in f32,
/// the oracle's binary tree in f64 (both return what testing every primitive returns).
trait Nearest: Real {
    fn prims(built: &Built) -> &Primitives<Self>;
    fn nearest(built: &Built, p: V3<Self>) -> Option<Closest<Self>>;
    fn inside(built: &Built, p: V3<Self>) -> bool;
}

impl Nearest for f32 {
    fn prims(built: &Built) -> &Primitives<f32> {
        &built.prep.prims
    }
    #[inline]
    fn nearest(built: &Built, p: V3<f32>) -> Option<Closest<f32>> {
        wide_closest::closest(&built.wide, &built.prep.prims, p)
    }
    #[inline]
    fn inside(built: &Built, p: V3<f32>) -> bool {
        inside(&built.prep.bvh, built.winding(), &built.prep.prims, p).inside()
    }
}

impl Nearest for f64 {
    fn prims(built: &Built) -> &Primitives<f64> {
        &built.oracle().0
    }
    #[inline]
    fn nearest(built: &Built, p: V3<f64>) -> Option<Closest<f64>> {
        let (p64, bvh) = built.oracle();
        closest(bvh, p64, p)
    }
    #[inline]
    fn inside(built: &Built, p: V3<f64>) -> bool {
        let (p64, bvh) = built.oracle();
        inside(bvh, built.winding64(), p64, p).inside()
    }
}

/// Runs `f` on each point's nearest surface point, a chunk of points at a time in parallel:
/// `f(the chunk's outputs, index in the chunk, answer)`. On the GPU all points go in one
/// [`strahl_gpu::closest::closest`].
fn each_closest<T, S: Send>(
    built: &Built,
    engine: &Engine,
    values: &[T],
    slices: Vec<S>,
    f: impl Fn(&mut S, usize, Option<Answer>) + Sync,
) -> Result<(), GpuError>
where
    T: Copy + Into<f64> + Sync,
{
    fn run<T: Copy + Into<f64> + Sync, R: Nearest, S: Send>(
        built: &Built,
        values: &[T],
        slices: Vec<S>,
        f: &(impl Fn(&mut S, usize, Option<Answer>) + Sync),
    ) {
        let prims = R::prims(built);
        values.par_chunks(3 * CHUNK).zip(slices).for_each(|(chunk, mut s)| {
            for k in 0..chunk.len() / 3 {
                let c = R::nearest(built, point::<T, R>(chunk, k));
                f(&mut s, k, c.map(|c| Answer::of(built, prims, &c)));
            }
        });
    }
    match engine {
        Engine::Cpu64 => run::<T, f64, S>(built, values, slices, &f),
        Engine::Cpu32 => run::<T, f32, S>(built, values, slices, &f),
        // A scene without geometry has no buffers to walk: every answer is none.
        Engine::Gpu(_) if built.is_empty() => {}
        Engine::Gpu(ctx) => {
            let points: Vec<V3<f32>> = values.par_chunks(3).map(|r| point::<T, f32>(r, 0)).collect();
            let answers = strahl_gpu::closest::closest(ctx, built.buffers(ctx)?, &points)?;
            let prims = &built.prep.prims;
            answers.par_chunks(CHUNK).zip(slices).for_each(|(chunk, mut s)| {
                for (k, c) in chunk.iter().enumerate() {
                    f(&mut s, k, c.map(|c| Answer::of(built, prims, &c)));
                }
            });
        }
    }
    Ok(())
}

/// One nearest point as the caller sees it.
#[derive(Clone, Copy, Debug)]
pub struct Answer {
    pub point: [f64; 3],
    pub distance: f64,
    pub geometry: u32,
    pub primitive: u32,
    pub uv: [f64; 2],
    pub normal: [f64; 3],
}

impl Answer {
    fn of<R: Real>(built: &Built, prims: &Primitives<R>, c: &Closest<R>) -> Self {
        let (geometry, primitive) = built.ids(prims.tag(c.prim_ref));
        let n = prims.foot_normal(c.prim_ref, &c.foot).to_f64();
        let p = c.foot.point.to_f64();
        Answer {
            point: [p.x, p.y, p.z],
            distance: c.distance().to_f64(),
            geometry,
            primitive,
            uv: c.foot.uv.map(|u| u.to_f64()),
            normal: [n.x, n.y, n.z],
        }
    }
}

/// The nearest surface point of each point.
pub fn closest_points<T: Copy + Into<f64> + Sync, F: OutFloat>(
    built: &Built,
    engine: &Engine,
    values: &[T],
) -> Result<ClosestPoints<F>, GpuError> {
    let n = values.len() / 3;
    let zero = F::of(0.0);
    let mut out = ClosestPoints {
        points: vec![zero; 3 * n],
        geometry_ids: vec![INVALID_ID; n],
        primitive_ids: vec![INVALID_ID; n],
        primitive_uvs: vec![zero; 2 * n],
        primitive_normals: vec![zero; 3 * n],
    };
    let slices: Vec<_> = out
        .points
        .chunks_mut(3 * CHUNK)
        .zip(out.geometry_ids.chunks_mut(CHUNK))
        .zip(out.primitive_ids.chunks_mut(CHUNK))
        .zip(out.primitive_uvs.chunks_mut(2 * CHUNK))
        .zip(out.primitive_normals.chunks_mut(3 * CHUNK))
        .collect();
    each_closest(built, engine, values, slices, |s, k, a| {
        let ((((p, g), pr), uv), nrm) = s;
        if let Some(a) = a {
            p[3 * k..3 * k + 3].copy_from_slice(&a.point.map(F::of));
            g[k] = a.geometry;
            pr[k] = a.primitive;
            uv[2 * k..2 * k + 2].copy_from_slice(&a.uv.map(F::of));
            nrm[3 * k..3 * k + 3].copy_from_slice(&a.normal.map(F::of));
        }
    })?;
    Ok(out)
}

/// The distance from each point to the nearest surface, signed by the winding number
/// (negative inside) when `signed`; infinity on an empty scene. The winding number is summed
/// on the CPU, in the scene's precision, also where the distances come from the GPU.
pub fn distances<T: Copy + Into<f64> + Sync, F: OutFloat>(
    built: &Built,
    engine: &Engine,
    values: &[T],
    signed: bool,
) -> Result<Vec<F>, GpuError> {
    fn sign<T: Copy + Into<f64> + Sync, R: Nearest, F: OutFloat>(built: &Built, values: &[T], out: &mut [F]) {
        out.par_chunks_mut(CHUNK).zip(values.par_chunks(3 * CHUNK)).for_each(|(s, chunk)| {
            for (k, d) in s.iter_mut().enumerate() {
                if R::inside(built, point::<T, R>(chunk, k)) {
                    *d = F::of(-d.to_f64());
                }
            }
        });
    }
    let mut out = vec![F::of(f64::INFINITY); values.len() / 3];
    let slices: Vec<&mut [F]> = out.chunks_mut(CHUNK).collect();
    each_closest(built, engine, values, slices, |s, k, a| {
        if let Some(a) = a {
            s[k] = F::of(a.distance);
        }
    })?;
    if signed && !built.is_empty() {
        match engine {
            Engine::Cpu64 => sign::<T, f64, F>(built, values, &mut out),
            Engine::Cpu32 | Engine::Gpu(_) => sign::<T, f32, F>(built, values, &mut out),
        }
    }
    Ok(out)
}
