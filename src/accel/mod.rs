//! Acceleration structure: a binned-SAH BVH over every bounded primitive, flattened into the
//! node array the GPU walks ([`bvh`]), and its traversal loops ([`traverse`]), whose WGSL twin
//! is `shaders/traverse.wgsl`. The CPU walks the same tree collapsed into 8-wide nodes
//! ([`wide`], [`wide_traverse`]) with lane-parallel box and triangle tests ([`simd`]).

pub mod bvh;
pub mod huge_pages;
pub mod simd;
pub mod traverse;
pub mod wide;
pub mod wide_traverse;

pub use bvh::{Bvh, BvhNode};
pub use wide::WideBvh;
