//! The CPU backend: the f32 mirror of the GPU, run with rayon over image rows.

use crate::CpuScene;
use crate::accel::bundle::Isa;
use crate::{lanes, path, shade};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use strahl_core::image::{Image, Region};
use strahl_core::layout::FrameParams;
use strahl_core::math::V3;
use strahl_core::scene::RenderMode;

/// Which CPU tracer renders: path mode many paths at a time or one at a time, and Whitted mode
/// with its camera rays in bundles of the same lanes ([`lanes::whitted`]) or one ray at a
/// time. Each pair gives the same image, bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathTracer {
    /// Many paths at a time, their rays in bundles of SIMD lanes ([`crate::lanes`]):
    /// the default, with the widest lanes this processor has. The rays after the camera's
    /// take the walk measured faster.
    Lanes(Isa),
    /// [`PathTracer::Lanes`] with every ray after the camera's taking `Walk` (for tests and
    /// comparisons).
    LanesWalking(Isa, lanes::Walk),
    /// One path at a time ([`crate::path`], the WGSL megakernel's mirror): the
    /// reference the lane tracer is tested against.
    OneByOne,
}

impl PathTracer {
    /// The lane tracer's lanes and the walk forced on the rays after the camera's, if any;
    /// `None` for one path at a time.
    pub(crate) fn lanes(self) -> Option<(Isa, Option<lanes::Walk>)> {
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
pub fn render(scene: &CpuScene, frame: &FrameParams, mode: RenderMode, progress: &(dyn Fn(u64) + Sync)) -> Image {
    render_region(scene, frame, mode, Region::whole(frame.width, frame.height), progress)
}

/// Renders the pixels of `region` of the image described by `frame`, each exactly as a
/// render of the whole image computes it (its rays and random numbers depend on the pixel's
/// place in the whole image only). `progress` is called with the number of the region's rows
/// finished so far, from worker threads.
pub fn render_region(
    scene: &CpuScene,
    frame: &FrameParams,
    mode: RenderMode,
    region: Region,
    progress: &(dyn Fn(u64) + Sync),
) -> Image {
    render_region_with(scene, frame, mode, region, PathTracer::default(), progress)
}

/// [`render_region`] with path mode traced by `tracer`.
pub fn render_region_with(
    scene: &CpuScene,
    frame: &FrameParams,
    mode: RenderMode,
    region: Region,
    tracer: PathTracer,
    progress: &(dyn Fn(u64) + Sync),
) -> Image {
    render_region_reported(scene, frame, mode, region, tracer, false, progress).0
}

/// The whole image in path mode by the lane tracer with `isa`'s lanes, and where its time
/// went (summed over the threads).
pub fn render_path_timed(scene: &CpuScene, frame: &FrameParams, isa: Isa) -> (Image, lanes::StageTimes) {
    let whole = Region::whole(frame.width, frame.height);
    let (img, report) =
        render_region_reported(scene, frame, RenderMode::Path, whole, PathTracer::Lanes(isa), true, &|_| {});
    (img, report.times)
}

/// What a render did besides its image, summed over the threads: where the lane tracer's
/// time went (when timed), and the path vertices it shaded in lanes and those it left to the
/// one-path code.
#[derive(Clone, Debug, Default)]
pub struct Report {
    pub times: lanes::StageTimes,
    pub fallbacks: lanes::Fallbacks,
}

/// [`render_region_with`], and its [`Report`] (`timed`: with the lane tracer's stage times).
pub fn render_region_reported(
    scene: &CpuScene,
    frame: &FrameParams,
    mode: RenderMode,
    region: Region,
    tracer: PathTracer,
    timed: bool,
    progress: &(dyn Fn(u64) + Sync),
) -> (Image, Report) {
    assert!(region.fits(frame.width, frame.height), "region {region} of a {}x{} image", frame.width, frame.height);
    let inputs = scene.inputs(frame);
    let mut img = Image::new(region.width(), region.height());
    let report = std::sync::Mutex::new(Report::default());
    if img.pixels.is_empty() {
        return (img, Report::default());
    }
    let done = AtomicU64::new(0);
    let rows = img.pixels.par_chunks_mut(region.width() as usize).enumerate();
    match (mode, tracer.lanes()) {
        (RenderMode::Path, Some((isa, walk))) => {
            let samples = frame.sample_base..frame.sample_base + frame.spp;
            let facts = lanes::Facts::new(&scene.prep.flat, frame.num_lights, walk);
            // Each worker's tracer, its report added to the render's when the worker is done.
            struct Worker<'f, 't> {
                tracer: lanes::Tracer<'f>,
                sums: Vec<V3<f32>>,
                report: &'t std::sync::Mutex<Report>,
            }
            impl Drop for Worker<'_, '_> {
                fn drop(&mut self) {
                    let mut r = self.report.lock().unwrap_or_else(|e| e.into_inner());
                    r.times.add(&self.tracer.times);
                    r.fallbacks.add(&self.tracer.fallbacks);
                }
            }
            rows.for_each_init(
                || Worker { tracer: lanes::Tracer::new(isa, &facts, timed), sums: Vec::new(), report: &report },
                |w, (dy, row)| {
                    w.sums.clear();
                    w.sums.resize(row.len(), V3::zero());
                    let y = region.y0 + dy as u32;
                    let sums = &mut w.sums;
                    let span = lanes::Span { y, x0: region.x0, width: row.len() as u32, samples: samples.clone() };
                    w.tracer.row(&inputs, span, &mut |x, c| sums[x] += c);
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
    (img, report.into_inner().unwrap_or_else(|e| e.into_inner()))
}
