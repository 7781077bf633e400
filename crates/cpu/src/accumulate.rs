//! Progressive path tracing on the CPU: per-pixel sums that grow by whole sample passes, as
//! `strahl converge`, the viewer's comparison and the benchmarks drive it.

use crate::accel::WideBvh;
use crate::lanes;
use crate::path;
use crate::render::PathTracer;
use crate::shade::ShadeInputs;
use rayon::prelude::*;
use std::sync::Arc;
use strahl_core::image::Image;
use strahl_core::layout::FrameParams;
use strahl_core::render::Prepared;
use strahl_core::render::aov::Aov;

/// PathAccumulator path tracing on the CPU: per-pixel sums that grow by whole sample passes, in
/// the order the GPU's passes add them.
pub struct PathAccumulator {
    prep: Arc<Prepared>,
    /// The CPU's 8-wide tree of `prep`, built once for every pass.
    wide: WideBvh,
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
        let wide = WideBvh::new(&prep.bvh, &prep.prims);
        Self { prep, wide, frame, sums: vec![[0.0; 3]; n], samples: 0, tracer }
    }

    /// Adds samples `samples() .. samples() + n` to every pixel.
    pub fn add_samples(&mut self, n: u32) {
        let frame = FrameParams { spp: 1, ..self.frame };
        let prep = &self.prep;
        let inputs = ShadeInputs { prims: &prep.prims, wide: &self.wide, flat: &prep.flat, frame: &frame };
        let first = self.samples;
        let rows = self.sums.par_chunks_mut(frame.width as usize).enumerate();
        match self.tracer.lanes() {
            Some((isa, walk)) => {
                let facts = lanes::Facts::new(&prep.flat, frame.num_lights, walk);
                rows.for_each_init(
                    || lanes::Tracer::new(isa, &facts, false),
                    |tracer, (y, row)| {
                        let width = row.len() as u32;
                        let span = lanes::Span { y: y as u32, x0: 0, width, samples: first..first + n };
                        tracer.row(&inputs, span, &mut |x, c| {
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
impl strahl_core::Progressive for PathAccumulator {
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
    fn denoised(&mut self) -> anyhow::Result<(Image, f64)> {
        let start = std::time::Instant::now();
        let image = PathAccumulator::image(self);
        let frame = FrameParams { spp: self.samples.max(1), ..self.frame };
        let prep = &self.prep;
        let inputs = ShadeInputs { prims: &prep.prims, wide: &self.wide, flat: &prep.flat, frame: &frame };
        let whole = strahl_core::image::Region::whole(frame.width, frame.height);
        let guides = crate::aov::render_aovs(&inputs, whole, &[Aov::Albedo, Aov::Normal]);
        let out = strahl_core::denoise::denoise(&image, &guides.guides().expect("both guides were computed"));
        Ok((out, start.elapsed().as_secs_f64()))
    }
}
