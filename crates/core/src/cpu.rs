//! The CPU backend: the f32 mirror of the GPU, run with rayon over image rows.

use crate::accel::bundle::Isa;
use crate::image::{Image, Region};
use crate::layout::FrameParams;
use crate::math::V3;
use crate::render::shade::ShadeInputs;
use crate::render::{Prepared, lanes, path, shade};
use crate::scene::RenderMode;
use rayon::prelude::*;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Which CPU tracer renders: path mode many paths at a time or one at a time, and Whitted mode
/// with its camera rays in bundles of the same lanes ([`lanes::whitted`]) or one ray at a
/// time. Each pair gives the same image, bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathTracer {
    /// Many paths at a time, their rays in bundles of SIMD lanes ([`crate::render::lanes`]):
    /// the default, with the widest lanes this processor has. The rays after the camera's
    /// take the walk measured faster.
    Lanes(Isa),
    /// [`PathTracer::Lanes`] with every ray after the camera's taking `Walk` (for tests and
    /// comparisons).
    LanesWalking(Isa, lanes::Walk),
    /// One path at a time ([`crate::render::path`], the WGSL megakernel's mirror): the
    /// reference the lane tracer is tested against.
    OneByOne,
}

impl PathTracer {
    /// The lane tracer's lanes and the walk forced on the rays after the camera's, if any;
    /// `None` for one path at a time.
    fn lanes(self) -> Option<(Isa, Option<lanes::Walk>)> {
        match self {
            PathTracer::Lanes(isa) => Some((isa, None)),
            PathTracer::LanesWalking(isa, w) => Some((isa, Some(w))),
            PathTracer::OneByOne => None,
        }
    }
}

impl Default for PathTracer {
    /// The widest lanes this processor runs; one path at a time on an x86-64 without AVX2,
    /// where the portable lanes' fused multiply-adds are library calls (measured twice as slow
    /// as one path at a time on the Cornell box). STRAHL_CPU_TRACER = `one-by-one`, `avx2`,
    /// `portable`, or `bundles` / `one-ray` (the widest lanes, every ray after the camera's
    /// walking that way) chooses, for comparisons from the command line.
    fn default() -> Self {
        match std::env::var("STRAHL_CPU_TRACER").as_deref() {
            Ok("one-by-one") => return PathTracer::OneByOne,
            Ok("avx2") if Isa::Avx2.runs_here() => return PathTracer::Lanes(Isa::Avx2),
            Ok("portable") => return PathTracer::Lanes(Isa::Portable),
            Ok("bundles") => return PathTracer::LanesWalking(Isa::detect(), lanes::Walk::Bundles),
            Ok("one-ray") => return PathTracer::LanesWalking(Isa::detect(), lanes::Walk::OneRay),
            _ => {}
        }
        match Isa::detect() {
            Isa::Portable if cfg!(target_arch = "x86_64") => PathTracer::OneByOne,
            isa => PathTracer::Lanes(isa),
        }
    }
}

/// Renders the image described by `frame` (its `width`, `height`, `spp`, `sample_base`) in
/// `mode`. `progress` is called with the number of rows finished so far, from worker threads.
pub fn render(prep: &Prepared, frame: &FrameParams, mode: RenderMode, progress: &(dyn Fn(u64) + Sync)) -> Image {
    render_region(prep, frame, mode, Region::whole(frame.width, frame.height), progress)
}

/// Renders the pixels of `region` of the image described by `frame`, each exactly as a
/// render of the whole image computes it (its rays and random numbers depend on the pixel's
/// place in the whole image only). `progress` is called with the number of the region's rows
/// finished so far, from worker threads.
pub fn render_region(
    prep: &Prepared,
    frame: &FrameParams,
    mode: RenderMode,
    region: Region,
    progress: &(dyn Fn(u64) + Sync),
) -> Image {
    render_region_with(prep, frame, mode, region, PathTracer::default(), progress)
}

/// [`render_region`] with path mode traced by `tracer`.
pub fn render_region_with(
    prep: &Prepared,
    frame: &FrameParams,
    mode: RenderMode,
    region: Region,
    tracer: PathTracer,
    progress: &(dyn Fn(u64) + Sync),
) -> Image {
    render_region_timed(prep, frame, mode, region, tracer, None, progress)
}

/// The whole image in path mode by the lane tracer with `isa`'s lanes, and where its time
/// went (summed over the threads).
pub fn render_path_timed(prep: &Prepared, frame: &FrameParams, isa: Isa) -> (Image, lanes::StageTimes) {
    let times = std::sync::Mutex::new(lanes::StageTimes::default());
    let whole = Region::whole(frame.width, frame.height);
    let img = render_region_timed(prep, frame, RenderMode::Path, whole, PathTracer::Lanes(isa), Some(&times), &|_| {});
    (img, times.into_inner().unwrap_or_else(|e| e.into_inner()))
}

fn render_region_timed(
    prep: &Prepared,
    frame: &FrameParams,
    mode: RenderMode,
    region: Region,
    tracer: PathTracer,
    times: Option<&std::sync::Mutex<lanes::StageTimes>>,
    progress: &(dyn Fn(u64) + Sync),
) -> Image {
    assert!(region.fits(frame.width, frame.height), "region {region} of a {}x{} image", frame.width, frame.height);
    let inputs = ShadeInputs { prims: &prep.prims, wide: &prep.wide, gpu: &prep.gpu, frame };
    let mut img = Image::new(region.width(), region.height());
    if img.pixels.is_empty() {
        return img;
    }
    let done = AtomicU64::new(0);
    let rows = img.pixels.par_chunks_mut(region.width() as usize).enumerate();
    match (mode, tracer.lanes()) {
        (RenderMode::Path, Some((isa, walk))) => {
            let samples = frame.sample_base..frame.sample_base + frame.spp;
            let facts = lanes::Facts::new(&prep.gpu, frame.num_lights, walk);
            // Each worker's tracer, its time added to `times` when the worker is done.
            struct Worker<'f, 't> {
                tracer: lanes::Tracer<'f>,
                sums: Vec<V3<f32>>,
                times: Option<&'t std::sync::Mutex<lanes::StageTimes>>,
            }
            impl Drop for Worker<'_, '_> {
                fn drop(&mut self) {
                    if let Some(t) = self.times {
                        t.lock().unwrap_or_else(|e| e.into_inner()).add(&self.tracer.times);
                    }
                }
            }
            rows.for_each_init(
                || Worker { tracer: lanes::Tracer::new(isa, &facts, times.is_some()), sums: Vec::new(), times },
                |w, (dy, row)| {
                    w.sums.clear();
                    w.sums.resize(row.len(), V3::zero());
                    let y = region.y0 + dy as u32;
                    let sums = &mut w.sums;
                    w.tracer.row(&inputs, y, region.x0, row.len() as u32, samples.clone(), &mut |x, c| sums[x] += c);
                    for (px, sum) in row.iter_mut().zip(sums.iter()) {
                        *px = (*sum / frame.spp as f32).to_array();
                    }
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                },
            );
        }
        (RenderMode::Whitted, Some((isa, _))) => {
            rows.for_each(|(dy, row)| {
                lanes::whitted::row(isa, &inputs, region.y0 + dy as u32, region.x0, row);
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            });
        }
        _ => {
            let shade_pixel = match mode {
                RenderMode::Whitted => shade::shade_pixel,
                RenderMode::Path => path::shade_pixel,
            };
            rows.for_each(|(dy, row)| {
                let y = region.y0 + dy as u32;
                for (dx, px) in row.iter_mut().enumerate() {
                    *px = shade_pixel(&inputs, region.x0 + dx as u32, y);
                }
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            });
        }
    }
    img
}

/// PathAccumulator path tracing on the CPU: per-pixel sums that grow by whole sample passes, in
/// the order the GPU's passes add them.
pub struct PathAccumulator {
    prep: Arc<Prepared>,
    frame: FrameParams,
    sums: Vec<[f32; 3]>,
    samples: u32,
    tracer: PathTracer,
}

impl PathAccumulator {
    /// An empty accumulation for `frame` (whole image; its `spp` and `sample_base` are ignored).
    pub fn new(prep: Arc<Prepared>, frame: FrameParams) -> Self {
        Self::with_tracer(prep, frame, PathTracer::default())
    }

    /// [`PathAccumulator::new`] traced by `tracer`.
    pub fn with_tracer(prep: Arc<Prepared>, frame: FrameParams, tracer: PathTracer) -> Self {
        let n = frame.width as usize * frame.height as usize;
        Self { prep, frame, sums: vec![[0.0; 3]; n], samples: 0, tracer }
    }

    /// Adds samples `samples() .. samples() + n` to every pixel.
    pub fn add_samples(&mut self, n: u32) {
        let frame = FrameParams { spp: 1, ..self.frame };
        let prep = &self.prep;
        let inputs = ShadeInputs { prims: &prep.prims, wide: &prep.wide, gpu: &prep.gpu, frame: &frame };
        let first = self.samples;
        let rows = self.sums.par_chunks_mut(frame.width as usize).enumerate();
        match self.tracer.lanes() {
            Some((isa, walk)) => {
                let facts = lanes::Facts::new(&prep.gpu, frame.num_lights, walk);
                rows.for_each_init(
                    || lanes::Tracer::new(isa, &facts, false),
                    |tracer, (y, row)| {
                        let width = row.len() as u32;
                        tracer.row(&inputs, y as u32, 0, width, first..first + n, &mut |x, c| {
                            let px = &mut row[x];
                            *px = [px[0] + c.x, px[1] + c.y, px[2] + c.z];
                        });
                    },
                );
            }
            None => rows.for_each(|(y, row)| {
                for (x, px) in row.iter_mut().enumerate() {
                    for s in first..first + n {
                        let c = path::sample_pixel(&inputs, x as u32, y as u32, s);
                        *px = [px[0] + c.x, px[1] + c.y, px[2] + c.z];
                    }
                }
            }),
        }
        self.samples += n;
    }

    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// Starts over from zero samples.
    pub fn reset(&mut self) {
        self.sums.iter_mut().for_each(|s| *s = [0.0; 3]);
        self.samples = 0;
    }

    /// The mean of the samples so far (black before the first).
    pub fn image(&self) -> Image {
        let mut img = Image::new(self.frame.width, self.frame.height);
        let k = 1.0 / self.samples.max(1) as f32;
        for (p, s) in img.pixels.iter_mut().zip(&self.sums) {
            *p = s.map(|c| c * k);
        }
        img
    }
}

/// The CPU backend's progressive path tracer.
impl crate::Progressive for PathAccumulator {
    fn label(&self) -> String {
        format!("cpu ({} threads)", rayon::current_num_threads())
    }
    fn backend(&self) -> &'static str {
        "cpu"
    }
    fn add_samples(&mut self, n: u32) -> anyhow::Result<()> {
        PathAccumulator::add_samples(self, n);
        Ok(())
    }
    fn samples(&self) -> u32 {
        PathAccumulator::samples(self)
    }
    fn image(&mut self) -> anyhow::Result<Image> {
        Ok(PathAccumulator::image(self))
    }
}

/// Answers ray queries in precision `R` (f32: the GPU's mirror; f64: the oracle): the
/// nearest hit per ray, or with `all` every hit sorted by `t`.
pub fn trace<R: crate::math::Real>(
    scene: &crate::scene::Scene,
    rays: &[crate::query::RayQuery],
    all: bool,
) -> Vec<Vec<crate::primitives::Hit<R>>> {
    use crate::accel::{Bvh, WideBvh, traverse, wide_all, wide_traverse};
    use crate::primitives::{Hit, Primitives};
    use std::any::Any;
    let prims = Primitives::<R>::from_scene(scene);
    let bvh = Bvh::build(&prims);
    // Queries in f32 take the CPU's 8-wide walks (the same answers, faster).
    if let Some(p32) = (&prims as &dyn Any).downcast_ref::<Primitives<f32>>() {
        let wide = WideBvh::new(&bvh, p32);
        let hits: Vec<Vec<Hit<f32>>> = rays
            .par_iter()
            .map(|q| {
                let (ray, tmin, tmax) = (q.ray(), q.tmin as f32, q.tmax as f32);
                if all {
                    let mut hits = Vec::new();
                    wide_all::all(&wide, p32, &ray, tmin, tmax, &mut hits);
                    hits
                } else {
                    wide_traverse::nearest(&wide, p32, &ray, tmin, tmax).into_iter().collect()
                }
            })
            .collect();
        let hits: Box<dyn Any> = Box::new(hits);
        return *hits.downcast::<Vec<Vec<Hit<R>>>>().expect("R is f32 here");
    }
    rays.par_iter()
        .map(|q| {
            let ray = q.ray::<R>();
            let (tmin, tmax) = (R::from_f64(q.tmin), R::from_f64(q.tmax));
            if all {
                traverse::all(&bvh, &prims, &ray, tmin, tmax)
            } else {
                traverse::nearest(&bvh, &prims, &ray, tmin, tmax).into_iter().collect()
            }
        })
        .collect()
}

/// Spawned rays, the twin of `trace_spawn` in `shaders/trace.wgsl`: `pairs[i].0` is traced to
/// its nearest hit; from there a ray leaves along `pairs[i].1` (unit), starting at the hit
/// point moved off the surface by [`crate::render::spawn::spawn_origin`] to the side it
/// leaves from. Returns (first hit, spawned ray's nearest hit) per pair.
pub fn trace_spawn(
    prims: &crate::primitives::Primitives<f32>,
    bvh: &crate::accel::Bvh,
    pairs: &[(crate::math::Ray<f32>, crate::math::V3<f32>)],
) -> Vec<crate::SpawnHits> {
    use crate::math::Ray;
    let wide = crate::accel::WideBvh::new(bvh, prims);
    let nearest = |ray: &Ray<f32>| crate::accel::wide_traverse::nearest(&wide, prims, ray, 0.0, f32::INFINITY);
    pairs
        .par_iter()
        .map(|(ray, dir2)| {
            let Some(first) = nearest(ray) else {
                return (None, None);
            };
            let side = if dir2.dot(first.normal) >= 0.0 { first.normal } else { -first.normal };
            let o2 = crate::render::spawn::spawn_origin(ray, first.t, side);
            (Some(first), nearest(&Ray::new(o2, *dir2)))
        })
        .collect()
}
