//! strahl-cpu: strahl's CPU backend. It renders and answers ray queries with the f32 twins of
//! the GPU's stages (`strahl_core::render`), over a tree of its own: the 8-wide form of the
//! binary BVH that `strahl-core` builds ([`accel::wide`]), walked one ray at a time, as packets
//! of coherent rays or as bundles of one ray per SIMD lane.
//!
//! - [`render`]: images, Whitted ([`shade`], `shade.wgsl`'s twin) and path tracing ([`path`],
//!   `path.wgsl`'s twin, one path at a time; [`lanes`], many paths at a time in SIMD lanes, the
//!   same image bit for bit), rows spread over rayon's threads;
//! - [`accumulate`]: progressive path tracing ([`PathAccumulator`]);
//! - [`aov`]: the output variables besides radiance (`aov.wgsl`'s twin);
//! - [`trace`]: ray queries in f32 (the GPU's mirror) and f64 (the oracle);
//! - [`accel`]: the walks only the CPU takes.

// `!(x >= 0.0)` is used on purpose throughout: unlike `x < 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod accel;
pub mod accumulate;
pub mod aov;
pub mod lanes;
pub mod path;
pub mod render;
pub mod shade;
pub mod trace;

pub use accumulate::PathAccumulator;
pub use render::{
    PathTracer, Report, render, render_path_timed, render_region, render_region_reported, render_region_with,
};
pub use trace::{trace, trace_spawn};

use accel::WideBvh;
use strahl_core::layout::FrameParams;
use strahl_core::render::Prepared;

/// A prepared scene with the CPU's own tree: what the CPU backend renders. Build it once per
/// scene and render it as often as needed.
pub struct CpuScene<'p> {
    pub prep: &'p Prepared,
    /// The 8-wide form of `prep`'s BVH, which every CPU walk takes.
    pub wide: WideBvh,
}

impl<'p> CpuScene<'p> {
    /// Builds the CPU's tree of `prep`.
    pub fn new(prep: &'p Prepared) -> Self {
        Self { prep, wide: WideBvh::new(&prep.bvh, &prep.prims) }
    }

    /// What the shading stages read to render `frame`.
    pub fn inputs<'a>(&'a self, frame: &'a FrameParams) -> shade::ShadeInputs<'a> {
        shade::ShadeInputs { prims: &self.prep.prims, wide: &self.wide, flat: &self.prep.flat, frame }
    }
}

impl std::ops::Deref for CpuScene<'_> {
    type Target = Prepared;
    fn deref(&self) -> &Prepared {
        self.prep
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimate covers what preparing really holds: the sizes of the structures built for
    /// a mesh stay below strahl_core::render::BYTES_PER_PRIMITIVE per triangle.
    #[test]
    fn the_memory_estimate_covers_the_structures_built() {
        let prep = Prepared::new(strahl_core::scene::procedural::torus_scene(100_000));
        let cpu = CpuScene::new(&prep);
        let n = prep.prims.triangles.len();
        let bytes = |len: usize, size: usize| (len * size) as u64;
        let held = bytes(n, size_of_val(&prep.prims.triangles[0]))
            + bytes(prep.bvh.nodes.len(), size_of::<strahl_core::accel::BvhNode>())
            + bytes(prep.bvh.prim_refs.len(), 4)
            + cpu.wide.bytes() as u64
            + bytes(prep.flat.triangles.len(), size_of::<strahl_core::layout::FlatTriangle>())
            + bytes(prep.flat.leaf_triangles.len(), size_of::<strahl_core::accel::gpu_bvh::GpuLeafTriangle>())
            + bytes(prep.flat.nodes.len(), size_of::<strahl_core::accel::gpu_bvh::GpuNode>())
            + bytes(prep.flat.shape_refs.len(), 4)
            // The build's records, freed before the collapse.
            + bytes(n, 32);
        eprintln!("prepared: {} bytes per triangle", held / n as u64);
        assert!(held < n as u64 * strahl_core::render::BYTES_PER_PRIMITIVE, "{} bytes per triangle", held / n as u64);
        assert!(
            held > n as u64 * strahl_core::render::BYTES_PER_PRIMITIVE / 2,
            "the estimate is far too high: {} per triangle",
            held / n as u64
        );
    }
}
