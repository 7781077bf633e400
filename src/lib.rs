//! strahl: a ray tracer whose main path runs as WGSL compute shaders through wgpu, with a CPU
//! reference that proves it right.
//!
//! Data flows one way: scene file → [`scene::Scene`] → [`primitives::Primitives`] →
//! [`accel::Bvh`] → a backend ([`cpu`] or `gpu`) → [`image::Image`] → output or metrics.
//! [`parts`] assembles images rendered a region at a time.
//!
//! Cargo feature `viewer` (default): the interactive window (`viewer`, on eframe).

// `!(x >= 0.0)` is used on purpose throughout: unlike `x < 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod accel;
pub mod backend;
pub mod converge;
pub mod errors;
pub mod geometry;
pub mod gpu_types;
pub mod image;
pub mod input;
pub mod math;
pub mod metrics;
pub mod output;
pub mod parts;
pub mod primitives;
pub mod query;
pub mod raysets;
pub mod render;
pub mod rng;
pub mod scene;
pub mod stiff;
#[cfg(feature = "viewer")]
pub mod viewer;
