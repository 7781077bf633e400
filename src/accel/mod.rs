//! Acceleration structure: a binned-SAH BVH over every bounded primitive, flattened into the
//! node array the GPU walks ([`bvh`]), and the traversal loops ([`traverse`]), whose WGSL twin
//! is `shaders/traverse.wgsl`.

pub mod bvh;
pub mod traverse;

pub use bvh::{Bvh, BvhNode};
