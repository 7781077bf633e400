//! The ray queries of a `RaycastingScene`, on flat arrays: the nearest hit, occlusion, the
//! number of hits and every hit. On the CPU each chunk of rays is parsed, traced and written
//! by one worker ([`RayChunks`]), so that a ray's values are read and its answers written
//! while they are in the caches; on the GPU all rays go in one [`strahl_gpu::trace::trace`].
//!
//! Answers follow Open3D's `RaycastingScene`: distances in units of the caller's direction
//! (`t_hit`), ids [`INVALID_ID`] and distance infinity on a miss.

use crate::arrays::{CHUNK, RayChunks, RayIn};
use crate::scene::{Built, INVALID_ID};
use rayon::prelude::*;
use std::sync::Arc;
use strahl_core::geometry::Triangle;
use strahl_core::math::{Ray, Real, V3};
use strahl_core::primitives::{Hit, PrimKind, Primitives};
use strahl_core::query::RayQuery;
use strahl_cpu::accel::wide::prefetch;
use strahl_cpu::accel::{binary as traverse, wide_all, wide_traverse};
use strahl_gpu::{GpuContext, GpuError};

/// Where a query runs.
#[derive(Clone)]
pub enum Engine {
    /// The CPU in f32: the GPU's mirror, the 8-wide tree for nearest hits and occlusion.
    Cpu32,
    /// The CPU in f64: the oracle.
    Cpu64,
    Gpu(Arc<GpuContext>),
}

/// An output float: float32, or float64 for the f64 oracle.
pub trait OutFloat: numpy::Element + Copy + Send + Sync {
    fn of(x: f64) -> Self;
    fn to_f64(self) -> f64;
}
impl OutFloat for f32 {
    #[inline]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
}
impl OutFloat for f64 {
    #[inline]
    fn of(x: f64) -> Self {
        x
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
}

/// One hit as the caller sees it.
#[derive(Clone, Copy, Debug)]
pub struct Answer {
    /// In units of the caller's direction.
    pub t: f64,
    pub geometry: u32,
    pub primitive: u32,
    pub uv: [f64; 2],
    pub normal: [f64; 3],
}

/// Barycentric coordinates (u, v) of `p` in `tri`, where p = (1 − u − v)·v0 + u·v1 + v·v2
/// (Embree's and Open3D's convention), from the point's projection onto the triangle's plane
/// (Ericson, Real-Time Collision Detection, §3.4), clamped to the triangle. The hit point is
/// o + t·d in f64 from the f32 distance, so u and v carry the error of t (a few ulps of the
/// distance, relative to the triangle's size) and that of the projection (|e1|²|e2|² / the
/// Gram determinant, large only for slivers).
#[inline(always)]
pub fn barycentric(tri: &Triangle<f64>, p: V3<f64>) -> [f64; 2] {
    let (e1, e2, w) = (tri.v[1] - tri.v[0], tri.v[2] - tri.v[0], p - tri.v[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (dw1, dw2) = (w.dot(e1), w.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if !(det > 0.0) {
        return [0.0, 0.0];
    }
    let inv = 1.0 / det;
    let u = ((d22 * dw1 - d12 * dw2) * inv).clamp(0.0, 1.0);
    let v = ((d11 * dw2 - d12 * dw1) * inv).clamp(0.0, 1.0 - u);
    [u, v]
}

/// A strahl hit as an [`Answer`] for `ray`; `prims` gives the triangle for its (u, v).
#[inline(always)]
pub fn answer<R: Real>(built: &Built, prims: &Primitives<R>, ray: &RayIn, hit: &Hit<R>) -> Answer {
    let t = hit.t.to_f64();
    let (geometry, primitive) = built.ids(hit.tag);
    let uv = match hit.prim_ref.kind() {
        PrimKind::Triangle => {
            let tri = prims.triangles[hit.prim_ref.index()].shape.cast::<f64>();
            barycentric(&tri, ray.origin + ray.dir * t)
        }
        _ => [0.0, 0.0],
    };
    let n = hit.normal.to_f64();
    Answer { t: t / ray.length, geometry, primitive, uv, normal: [n.x, n.y, n.z] }
}

/// How many hits ahead [`prefetch_triangle`] asks for the triangle: enough to overlap the
/// misses, few enough to keep them in L1. Measured in the book's Python chapter.
const PREFETCH_AHEAD: usize = 16;

/// Asks for the cache lines of the triangle `hit` names, if it is one.
#[inline(always)]
fn prefetch_triangle(prims: &Primitives<f32>, hit: &Hit<f32>) {
    if hit.prim_ref.kind() == PrimKind::Triangle {
        let t = &prims.triangles[hit.prim_ref.index()];
        prefetch(t);
        prefetch(&t.tag);
    }
}

/// `cast_rays`' outputs, one entry (or 2, or 3) per ray.
pub struct Nearest<F> {
    pub t_hit: Vec<F>,
    pub geometry_ids: Vec<u32>,
    pub primitive_ids: Vec<u32>,
    pub primitive_uvs: Vec<F>,
    pub primitive_normals: Vec<F>,
}

struct NearestSlice<'a, F> {
    t: &'a mut [F],
    geometry: &'a mut [u32],
    primitive: &'a mut [u32],
    uv: &'a mut [F],
    normal: &'a mut [F],
}

impl<F: OutFloat> NearestSlice<'_, F> {
    #[inline]
    fn set(&mut self, k: usize, a: Option<Answer>) {
        match a {
            Some(a) => {
                self.t[k] = F::of(a.t);
                self.geometry[k] = a.geometry;
                self.primitive[k] = a.primitive;
                self.uv[2 * k..2 * k + 2].copy_from_slice(&a.uv.map(F::of));
                self.normal[3 * k..3 * k + 3].copy_from_slice(&a.normal.map(F::of));
            }
            None => {
                self.t[k] = F::of(f64::INFINITY);
                self.geometry[k] = INVALID_ID;
                self.primitive[k] = INVALID_ID;
                self.uv[2 * k..2 * k + 2].fill(F::of(0.0));
                self.normal[3 * k..3 * k + 3].fill(F::of(0.0));
            }
        }
    }
}

impl<F: OutFloat> Nearest<F> {
    fn new(n: usize) -> Self {
        let zero = F::of(0.0);
        Self {
            t_hit: vec![zero; n],
            geometry_ids: vec![0; n],
            primitive_ids: vec![0; n],
            primitive_uvs: vec![zero; 2 * n],
            primitive_normals: vec![zero; 3 * n],
        }
    }

    /// The outputs cut into the chunks of [`RayChunks::chunks`].
    fn slices(&mut self) -> Vec<NearestSlice<'_, F>> {
        self.t_hit
            .chunks_mut(CHUNK)
            .zip(self.geometry_ids.chunks_mut(CHUNK))
            .zip(self.primitive_ids.chunks_mut(CHUNK))
            .zip(self.primitive_uvs.chunks_mut(2 * CHUNK))
            .zip(self.primitive_normals.chunks_mut(3 * CHUNK))
            .map(|((((t, geometry), primitive), uv), normal)| NearestSlice { t, geometry, primitive, uv, normal })
            .collect()
    }
}

/// Runs `f` on each chunk of rays with its outputs `slices`, in parallel, skipping chunks
/// that hold a bad ray (which `rays` records).
fn for_chunks<T, S: Send>(rays: &RayChunks<'_, T>, slices: Vec<S>, f: impl Fn(&[RayIn], S) + Sync)
where
    T: Copy + Into<f64> + Sync,
{
    rays.chunks().zip(slices).enumerate().for_each(|(c, (values, s))| {
        if let Some(parsed) = rays.parse(c, values) {
            f(&parsed, s)
        }
    });
}

/// Every ray of `rays`, parsed (for the GPU, which takes them all at once).
fn parse_all<T: Copy + Into<f64> + Sync>(rays: &RayChunks<'_, T>) -> Option<Vec<RayIn>> {
    let parts: Vec<Option<Vec<RayIn>>> = rays.chunks().enumerate().map(|(c, v)| rays.parse(c, v)).collect();
    parts.into_iter().collect::<Option<Vec<Vec<RayIn>>>>().map(|v| v.concat())
}

fn queries(rays: &[RayIn], tnear: f64, tfar: f64) -> Vec<RayQuery> {
    rays.par_iter().map(|r| r.query(tnear, tfar)).collect()
}

/// The nearest hit of each ray in [tnear, tfar)·|d| (all of it: 0 to infinity for `cast_rays`).
pub fn cast_rays<T, F>(built: &Built, engine: &Engine, rays: &RayChunks<'_, T>) -> Result<Nearest<F>, GpuError>
where
    T: Copy + Into<f64> + Sync,
    F: OutFloat,
{
    let mut out = Nearest::<F>::new(rays.len());
    if built.is_empty() {
        for_chunks(rays, out.slices(), |r, mut s| (0..r.len()).for_each(|k| s.set(k, None)));
        return Ok(out);
    }
    let prims = &built.prep.prims;
    match engine {
        Engine::Cpu32 => for_chunks(rays, out.slices(), |r, mut s| {
            let rays32: Vec<Ray<f32>> = r.iter().map(RayIn::ray32).collect();
            let mut hits = vec![None; r.len()];
            wide_traverse::nearest_many(&built.wide, prims, &rays32, 0.0, f32::INFINITY, &mut hits);
            for (k, h) in hits.iter().enumerate() {
                // The walk took the triangle from its copy in a leaf; (u, v) needs it from
                // the scene's array, a cache miss in a large mesh: asked for ahead.
                if let Some(Some(ahead)) = hits.get(k + PREFETCH_AHEAD) {
                    prefetch_triangle(prims, ahead);
                }
                s.set(k, h.as_ref().map(|h| answer(built, prims, &r[k], h)));
            }
        }),
        Engine::Cpu64 => {
            let (p64, bvh) = built.oracle();
            for_chunks(rays, out.slices(), |r, mut s| {
                for (k, ray) in r.iter().enumerate() {
                    let h = traverse::nearest(bvh, p64, &ray.ray64(), 0.0, f64::INFINITY);
                    s.set(k, h.as_ref().map(|h| answer(built, p64, ray, h)));
                }
            })
        }
        Engine::Gpu(ctx) => {
            let Some(parsed) = parse_all(rays) else { return Ok(out) };
            let hits =
                strahl_gpu::trace::trace(ctx, built.buffers(ctx)?, &queries(&parsed, 0.0, f64::INFINITY), false)?;
            let mut slices = out.slices();
            slices.par_iter_mut().enumerate().for_each(|(c, s)| {
                for k in 0..s.t.len() {
                    let i = c * CHUNK + k;
                    s.set(k, hits[i].first().map(|h| answer(built, prims, &parsed[i], h)));
                }
            });
        }
    }
    Ok(out)
}

/// Whether each ray meets anything in [tnear, tfar]·|d|.
pub fn test_occlusions<T>(
    built: &Built,
    engine: &Engine,
    rays: &RayChunks<'_, T>,
    tnear: f64,
    tfar: f64,
) -> Result<Vec<bool>, GpuError>
where
    T: Copy + Into<f64> + Sync,
{
    let mut out = vec![false; rays.len()];
    if built.is_empty() {
        for_chunks(rays, out.chunks_mut(CHUNK).collect(), |_, _| ());
        return Ok(out);
    }
    let prims = &built.prep.prims;
    match engine {
        Engine::Cpu32 => for_chunks(rays, out.chunks_mut(CHUNK).collect(), |r, s: &mut [bool]| {
            for (o, ray) in s.iter_mut().zip(r) {
                let q = ray.query(tnear, tfar);
                *o = wide_traverse::occluded(&built.wide, prims, &ray.ray32(), q.tmin as f32, q.tmax as f32);
            }
        }),
        Engine::Cpu64 => {
            let (p64, bvh) = built.oracle();
            for_chunks(rays, out.chunks_mut(CHUNK).collect(), |r, s: &mut [bool]| {
                for (o, ray) in s.iter_mut().zip(r) {
                    let q = ray.query(tnear, tfar);
                    *o = traverse::nearest(bvh, p64, &ray.ray64(), q.tmin, q.tmax).is_some();
                }
            })
        }
        Engine::Gpu(ctx) => {
            let Some(parsed) = parse_all(rays) else { return Ok(out) };
            let hits = strahl_gpu::trace::trace(ctx, built.buffers(ctx)?, &queries(&parsed, tnear, tfar), false)?;
            out.par_iter_mut().zip(&hits).for_each(|(o, h)| *o = !h.is_empty());
        }
    }
    Ok(out)
}

/// Every hit of each ray (0 to infinity), sorted by distance: the hits of ray `i` are
/// `hits[splits[i]..splits[i + 1]]`.
pub struct AllHits<F> {
    pub splits: Vec<u32>,
    pub ray_ids: Vec<u32>,
    pub t_hit: Vec<F>,
    pub geometry_ids: Vec<u32>,
    pub primitive_ids: Vec<u32>,
    pub primitive_uvs: Vec<F>,
    pub primitive_normals: Vec<F>,
}

/// Every hit of every ray, per chunk: (hits per ray, the hits in order).
fn all_hits<T>(built: &Built, engine: &Engine, rays: &RayChunks<'_, T>) -> Result<Vec<Vec<Vec<Answer>>>, GpuError>
where
    T: Copy + Into<f64> + Sync,
{
    let chunks = rays.len().div_ceil(CHUNK);
    if built.is_empty() {
        let mut empty: Vec<Vec<Vec<Answer>>> = (0..chunks).map(|_| Vec::new()).collect();
        for_chunks(rays, empty.iter_mut().collect(), |r, s: &mut Vec<Vec<Answer>>| s.resize(r.len(), Vec::new()));
        return Ok(empty);
    }
    let prims = &built.prep.prims;
    let mut out: Vec<Vec<Vec<Answer>>> = (0..chunks).map(|_| Vec::new()).collect();
    match engine {
        Engine::Cpu32 => for_chunks(rays, out.iter_mut().collect(), |r, s: &mut Vec<Vec<Answer>>| {
            let mut hits = Vec::new();
            *s = r
                .iter()
                .map(|ray| {
                    wide_all::all(&built.wide, prims, &ray.ray32(), 0.0, f32::INFINITY, &mut hits);
                    hits.iter().map(|h| answer(built, prims, ray, h)).collect()
                })
                .collect();
        }),
        Engine::Cpu64 => {
            let (p64, bvh) = built.oracle();
            for_chunks(rays, out.iter_mut().collect(), |r, s: &mut Vec<Vec<Answer>>| {
                *s = r
                    .iter()
                    .map(|ray| {
                        let hits = traverse::all(bvh, p64, &ray.ray64(), 0.0, f64::INFINITY);
                        hits.iter().map(|h| answer(built, p64, ray, h)).collect()
                    })
                    .collect();
            })
        }
        Engine::Gpu(ctx) => {
            let Some(parsed) = parse_all(rays) else { return Ok(out) };
            let hits = strahl_gpu::trace::trace(ctx, built.buffers(ctx)?, &queries(&parsed, 0.0, f64::INFINITY), true)?;
            out.par_iter_mut().enumerate().for_each(|(c, s)| {
                let range = c * CHUNK..((c + 1) * CHUNK).min(parsed.len());
                *s = range.map(|i| hits[i].iter().map(|h| answer(built, prims, &parsed[i], h)).collect()).collect();
            });
        }
    }
    Ok(out)
}

/// How many hits each ray has (0 to infinity), as `list_intersections` lists them.
pub fn count_intersections<T>(built: &Built, engine: &Engine, rays: &RayChunks<'_, T>) -> Result<Vec<u32>, GpuError>
where
    T: Copy + Into<f64> + Sync,
{
    let mut out = vec![0u32; rays.len()];
    match engine {
        // Counting needs no records and no order: the wide walk's count alone.
        Engine::Cpu32 if !built.is_empty() => {
            let prims = &built.prep.prims;
            for_chunks(rays, out.chunks_mut(CHUNK).collect(), |r, s: &mut [u32]| {
                for (o, ray) in s.iter_mut().zip(r) {
                    *o = wide_all::count(&built.wide, prims, &ray.ray32(), 0.0, f32::INFINITY) as u32;
                }
            })
        }
        _ => {
            let all = all_hits(built, engine, rays)?;
            let counts = all.iter().flat_map(|c| c.iter().map(|h| h.len() as u32));
            out.iter_mut().zip(counts).for_each(|(o, n)| *o = n);
        }
    }
    Ok(out)
}

pub fn list_intersections<T, F>(built: &Built, engine: &Engine, rays: &RayChunks<'_, T>) -> Result<AllHits<F>, GpuError>
where
    T: Copy + Into<f64> + Sync,
    F: OutFloat,
{
    let chunks = all_hits(built, engine, rays)?;
    let total: usize = chunks.iter().flatten().map(Vec::len).sum();
    let mut out = AllHits {
        splits: Vec::with_capacity(rays.len() + 1),
        ray_ids: Vec::with_capacity(total),
        t_hit: Vec::with_capacity(total),
        geometry_ids: Vec::with_capacity(total),
        primitive_ids: Vec::with_capacity(total),
        primitive_uvs: Vec::with_capacity(2 * total),
        primitive_normals: Vec::with_capacity(3 * total),
    };
    out.splits.push(0);
    for (i, hits) in chunks.iter().flatten().enumerate() {
        for a in hits {
            out.ray_ids.push(i as u32);
            out.t_hit.push(F::of(a.t));
            out.geometry_ids.push(a.geometry);
            out.primitive_ids.push(a.primitive);
            out.primitive_uvs.extend(a.uv.map(F::of));
            out.primitive_normals.extend(a.normal.map(F::of));
        }
        out.splits.push(out.ray_ids.len() as u32);
    }
    Ok(out)
}
