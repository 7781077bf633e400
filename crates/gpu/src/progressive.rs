//! The GPU's progressive path tracer as `strahl converge` drives it ([`strahl_core::Progressive`]),
//! with its images denoised as `strahl render --denoise` would at the same sample count.

use crate::tiles::PathAccumulator;
use strahl_core::image::{Image, Region};
use strahl_core::layout::FrameParams;
use strahl_core::render::aov::Aov;
use web_time::Instant;

/// The GPU backend's progressive path tracer.
impl strahl_core::Progressive for PathAccumulator {
    fn label(&self) -> String {
        format!("gpu ({})", self.context().adapter_info.name)
    }
    fn backend(&self) -> &'static str {
        "gpu"
    }
    fn add_samples(&mut self, n: u32) -> anyhow::Result<()> {
        Ok(PathAccumulator::add_samples(self, n)?)
    }
    fn samples(&self) -> u32 {
        PathAccumulator::samples(self)
    }
    fn image(&mut self) -> anyhow::Result<Image> {
        Ok(PathAccumulator::image(self)?)
    }
    fn denoised(&mut self) -> anyhow::Result<(Image, f64)> {
        let start = Instant::now();
        let image = PathAccumulator::image(self)?;
        let frame = FrameParams { spp: self.samples().max(1), ..*self.frame() };
        let whole = Region::whole(frame.width, frame.height);
        let ctx = self.context();
        let guides = crate::aov::render_aovs(ctx, self.scene(), &frame, whole, &[Aov::Albedo, Aov::Normal])?;
        let denoiser = crate::denoise::Denoiser::new(ctx)?;
        let (out, _) = denoiser.denoise(ctx, &image, &guides.guides().expect("both guides were computed"))?;
        Ok((out, start.elapsed().as_secs_f64()))
    }
}
