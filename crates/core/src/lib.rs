//! strahl-core: what both backends share: the scene read from its files, the primitives and
//! their intersections (f32, the GPU's mirror, and f64, the oracle), the BVH and its GPU
//! layout, the render stages' formulas (the f32 twins of the shaders), the buffer layouts, and
//! images, their files, the view transforms that display them and the denoiser (the CPU twin
//! of the GPU's).
//!
//! Data flows one way: scene file → [`scene::Scene`] → [`primitives::Primitives`] →
//! [`accel::Bvh`] → [`render::Prepared`] → a backend (`strahl-cpu`, or `strahl-gpu` on a
//! device) → [`image::Image`] → output. [`parts`] assembles images rendered a region at a time.

// `!(x >= 0.0)` is used on purpose throughout: unlike `x < 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod accel;
pub mod denoise;
pub mod display;
pub mod errors;
pub mod geometry;
pub mod image;
pub mod input;
pub mod layout;
pub mod math;
pub mod output;
pub mod parts;
pub mod primitives;
pub mod proximity;
pub mod query;
pub mod raysets;
pub mod render;
pub mod rng;
pub mod scene;
#[doc(hidden)]
pub mod testutil;

/// A spawned-ray query's answer: the first hit, and the nearest hit of the ray spawned from it.
pub type SpawnHits = (Option<crate::primitives::Hit<f32>>, Option<crate::primitives::Hit<f32>>);

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
    /// The current mean image denoised as `strahl render --denoise` would at this sample count
    /// (the guides of [`render::aov`], then [`denoise`]), with the seconds both took.
    fn denoised(&mut self) -> anyhow::Result<(crate::image::Image, f64)> {
        anyhow::bail!("the {} renderer has no denoiser", self.backend())
    }
}
