//! Acceleration structure: a binned-SAH BVH over every bounded primitive, flattened depth-first
//! ([`bvh`]), with the traversal loops the CPU renderer runs ([`traverse`]); and the same tree
//! collapsed into the layout the GPU walks ([`gpu_bvh`]), whose walk is the twin of
//! `shaders/modules/traverse.wgsl`.

pub mod bvh;
pub mod gpu_bvh;
pub mod traverse;

pub use bvh::{Bvh, BvhNode};
