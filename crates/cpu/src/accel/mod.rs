//! The walks only the CPU takes, over the tree `strahl-core` builds: the binary tree's walk in
//! any precision ([`binary`]: f32, and f64 for the oracle), and the 8-wide tree the CPU
//! renderers and queries walk ([`wide`], [`wide_traverse`]; every hit: [`wide_all`]) with
//! lane-parallel box and triangle tests ([`simd`], AVX2 where the processor has it);
//! [`packet`] walks eight coherent rays of a batch query together, [`bundle`] 16 (AVX-512), 8
//! (AVX2) or 4 rays of any directions together, one per SIMD lane, for the lane path tracer;
//! [`record`] is the hit record the one-ray and packet walks make. The GPU's walk and its CPU
//! twin are `strahl_core::accel::gpu_bvh`.

pub mod binary;
pub mod bundle;
#[cfg(target_arch = "x86_64")]
pub mod packet;
mod record;
pub mod simd;
pub mod wide;
pub mod wide_all;
pub mod wide_closest;
pub mod wide_traverse;

pub use wide::WideBvh;
