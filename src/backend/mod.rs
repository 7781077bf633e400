//! Backends turn a [`crate::render::Prepared`] scene into images and answer ray queries:
//! [`cpu`] (the reference) and `gpu` (WGSL compute through wgpu).

pub mod cpu;
pub mod select;

/// A spawned-ray query's answer: the first hit, and the nearest hit of the ray spawned from it.
pub type SpawnHits = (Option<crate::primitives::Hit<f32>>, Option<crate::primitives::Hit<f32>>);
pub mod gpu;

/// A renderer that adds samples to a running per-pixel mean: each backend's progressive path
/// tracer, as `strahl converge` and the benchmarks drive it.
pub trait Progressive {
    /// Name for tables and plots, e.g. "gpu (llvmpipe (LLVM 15.0.6, 256 bits))" or "cpu (2 threads)".
    fn label(&self) -> String;
    /// Short backend id for CSV: "gpu" or "cpu".
    fn backend(&self) -> &'static str;
    /// Adds `n` samples per pixel (sample indices samples()..samples()+n) and returns when they are done.
    fn add_samples(&mut self, n: u32) -> anyhow::Result<()>;
    /// Samples per pixel accumulated so far.
    fn samples(&self) -> u32;
    /// The current mean image (reading it back is not timed).
    fn image(&mut self) -> anyhow::Result<crate::image::Image>;
}
