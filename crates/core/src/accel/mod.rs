//! Acceleration structure: a binned-SAH BVH over every bounded primitive, flattened depth-first
//! ([`bvh`]), with its binary traversal loops ([`traverse`]); the same tree collapsed into the
//! layout the GPU walks ([`gpu_bvh`]), whose walk is the twin of `shaders/modules/traverse.wgsl`; and
//! into the 8-wide nodes the CPU renderers walk ([`wide`], [`wide_traverse`]; every hit:
//! [`wide_all`]) with lane-parallel box and triangle tests ([`simd`]).

pub mod bundle;
pub mod bvh;
pub mod gpu_bvh;
pub mod huge_pages;
#[cfg(target_arch = "x86_64")]
pub mod packet;
mod record;
pub mod simd;
pub mod traverse;
pub mod wide;
pub mod wide_all;
pub mod wide_traverse;

pub use bvh::{Bvh, BvhNode};
pub use wide::WideBvh;
