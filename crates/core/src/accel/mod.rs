//! Acceleration structure: a binned-SAH BVH over every bounded primitive, flattened depth-first
//! ([`bvh`]); the same tree collapsed into the layout the GPU walks ([`gpu_bvh`]), whose CPU
//! walk is the twin of `shaders/modules/traverse.wgsl`; and the slab test every walk shares
//! ([`slab`]). The CPU's own walks (the binary tree's, and the 8-wide, packet and bundle walks)
//! are in `strahl-cpu`.

pub mod bvh;
pub mod gpu_bvh;
pub mod huge_pages;
pub mod slab;

pub use bvh::{Bvh, BvhNode};
