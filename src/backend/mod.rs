//! Backends turn a [`crate::render::Prepared`] scene into images and answer ray queries:
//! [`cpu`] (the reference) and `gpu` (WGSL compute through wgpu).

pub mod cpu;
pub mod gpu;
