//! strahl: a ray tracer whose main path runs as WGSL compute shaders through wgpu, with a CPU
//! reference that proves it right.
//!
//! Data flows one way: scene file → [`scene::Scene`] → [`primitives::Primitives`] →
//! [`accel::Bvh`] → a backend ([`cpu`] or `gpu`) → [`image::Image`] → output or metrics.

pub mod accel;
pub mod geometry;
pub mod math;
pub mod primitives;
pub mod scene;
pub mod backend;
pub mod gpu_types;
pub mod image;
pub mod render;
pub mod query;
