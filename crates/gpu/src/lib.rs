//! The GPU backend: WGSL compute shaders through wgpu (Vulkan, Metal, DX12, GL, or WebGPU in
//! a browser).
//!
//! [`GpuContext`] owns the device (`context.rs`, its errors in `error.rs`) and caches one
//! pipeline per (program, [`FeatureKey`]) (`pipelines.rs`); [`SceneBuffers`] holds a scene's
//! storage buffers (`scene_buffers.rs`); [`render`], [`trace`] and [`closest`] dispatch.
//!
//! Every readback has an async form for web pages, which cannot block (`readback.rs`):
//! [`GpuContext::read_buffer_async`], [`tiles::render_region_async`],
//! [`PathAccumulator::image_async`].

pub mod aov;
pub mod bsdf_probe;
pub mod closest;
mod context;
pub mod denoise;
mod error;
pub mod instance;
pub mod objects;
mod pipelines;
mod progressive;
mod readback;
mod scene_buffers;
pub mod select;
pub mod shaders;
pub mod shared;
pub mod split;
pub mod tiles;
pub mod timing;
pub mod trace;
pub mod wavefront;

pub use context::{GpuContext, MIN_STORAGE_BUFFERS, unmet_requirement};
pub use error::{GpuError, NO_ADAPTER_HINT};
pub use pipelines::{CachedPipeline, PATH_KERNELS_VAR, PathKernels, SceneBindings};
pub use readback::{IN_BROWSER, block_on};
pub use scene_buffers::{SCENE_BINDINGS, SceneBuffers, stage_frame};
pub use shaders::{FeatureKey, Program};
pub use tiles::{PathAccumulator, render, render_region, render_tiles};
