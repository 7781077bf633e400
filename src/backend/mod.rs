//! Backends turn a [`crate::render::Prepared`] scene into images and answer ray queries:
//! [`cpu`] (the reference) and `gpu` (WGSL compute through wgpu).

pub mod cpu;
pub mod select;

/// A spawned-ray query's answer: the first hit, and the nearest hit of the ray spawned from it.
pub type SpawnHits = (Option<crate::primitives::Hit<f32>>, Option<crate::primitives::Hit<f32>>);
pub mod gpu;
