//! Image formation both backends share, as stages named like the shaders: [`camera`]
//! (`camera.wgsl`), [`spawn`] (`spawn.wgsl`), [`surface`] (`surface.wgsl`), [`texture`]
//! (`texture.wgsl`), [`environment`] (`environment.wgsl`), and for path tracing [`sampler`]
//! (`sampler.wgsl`), [`bsdf`] (`bsdf.wgsl`), [`microfacet`], [`pbr`], [`layers`] and [`sheen`], [`emitters`]
//! (`emitters.wgsl`), and the output variables besides radiance [`aov`] (`aov.wgsl`); [`limits`] holds the depths and reaches the tracers share, [`flatten`]
//! the scene made into the buffers both read. The CPU backend (`strahl-cpu`) runs these
//! functions in its tracers (`shade.rs`, `path.rs`, and lane by lane `lanes/`); the GPU runs
//! their WGSL twins.

pub mod aov;
pub mod bsdf;
pub mod camera;
pub mod dielectric;
pub mod emitters;
pub mod environment;
pub mod flatten;
pub mod layers;
pub mod limits;
pub mod microfacet;
pub mod pbr;
pub mod sampler;
pub mod sheen;
pub mod spawn;
pub mod surface;
pub mod texture;
pub mod view_camera;

use crate::accel::Bvh;
use crate::layout::{FlatScene, FrameParams};
use crate::primitives::Primitives;
use crate::scene::Scene;
use std::time::Duration;
use web_time::Instant;

/// A scene made ready for rendering: flattened, with its BVH built and collapsed into the
/// layout both backends read. Each backend builds what only it walks from here (the CPU its
/// 8-wide tree).
pub struct Prepared {
    pub scene: Scene,
    pub prims: Primitives<f32>,
    pub bvh: Bvh,
    pub flat: FlatScene,
    /// Time spent building the BVH (the binary tree).
    pub build_time: Duration,
    /// Time spent preparing the whole scene: its primitives, the tree and the flat layout
    /// (materials, lights, emitters, textures, environment) included.
    pub prepare_time: Duration,
}

/// Memory [`Prepared`] allocates per bounded primitive, at most: the flattened primitive
/// (48 bytes for a triangle), the build's record and reference (36), the binary tree (up to
/// 64; 36 typical), its 8-wide form (about 72: nodes and leaf blocks with vertex copies), and
/// the GPU layout (the triangle in scene order and in leaf order, 48 bytes each, and the
/// 64-byte two-child nodes: about 125), rounded up with room.
pub const BYTES_PER_PRIMITIVE: u64 = 352;

/// A scene too large for this machine, found before anything is allocated for it.
#[derive(Debug, thiserror::Error)]
#[error(
    "preparing {primitives} primitives needs about {} MiB ({BYTES_PER_PRIMITIVE} bytes each for the BVH and the CPU and GPU layouts), more than the {} MiB of memory available",
    need / (1 << 20),
    available / (1 << 20)
)]
pub struct TooLarge {
    pub primitives: u64,
    pub need: u64,
    pub available: u64,
}

/// Memory the system can give without swapping (`MemAvailable`), where it says.
pub fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Whether preparing `scene` fits in `available` bytes (no limit when unknown).
pub fn check_memory(scene: &Scene, available: Option<u64>) -> Result<(), TooLarge> {
    let primitives = scene.objects.iter().map(|o| o.geometry.primitive_count() as u64).sum::<u64>();
    let need = primitives.saturating_mul(BYTES_PER_PRIMITIVE);
    match available {
        Some(available) if need > available => Err(TooLarge { primitives, need, available }),
        _ => Ok(()),
    }
}

impl Prepared {
    /// Flattens `scene` and builds its BVH over the objects whose `visible` entry is true (a
    /// missing entry counts as visible). Hidden objects' primitives are left out; every other
    /// primitive keeps its object id, so object numbers mean what they mean in the file.
    pub fn with_visible(scene: Scene, visible: &[bool]) -> Self {
        if visible.iter().all(|&v| v) {
            return Self::new(scene);
        }
        let start = Instant::now();
        let shown = |object: u32| visible.get(object as usize).copied().unwrap_or(true);
        let mut prims = Primitives::<f32>::from_scene(&scene);
        prims.spheres.retain(|p| shown(p.tag.object));
        prims.cylinders.retain(|p| shown(p.tag.object));
        prims.triangles.retain(|p| shown(p.tag.object));
        prims.planes.retain(|p| shown(p.tag.object));
        Self::from_prims(scene, prims, start)
    }

    /// [`Prepared::new`] after checking that the scene fits in the memory available now.
    pub fn try_new(scene: Scene) -> Result<Self, TooLarge> {
        check_memory(&scene, available_memory())?;
        Ok(Self::new(scene))
    }

    pub fn new(scene: Scene) -> Self {
        let start = Instant::now();
        let prims = Primitives::<f32>::from_scene(&scene);
        Self::from_prims(scene, prims, start)
    }

    /// Builds the tree and the flat layout over `prims` (flattened from `scene`, perhaps with
    /// objects left out); `start` is when the preparation began.
    pub fn from_prims(scene: Scene, prims: Primitives<f32>, start: Instant) -> Self {
        let built = Instant::now();
        let bvh = Bvh::build(&prims);
        let build_time = built.elapsed();
        let flat = FlatScene::new(&scene, &prims, &bvh);
        Self { scene, prims, bvh, flat, build_time, prepare_time: start.elapsed() }
    }

    /// [`Prepared::frame`] seen from `view` instead of the scene's camera (the viewer's and
    /// the web page's moved camera).
    pub fn frame_from(&self, view: &crate::scene::Camera, width: u32, height: u32) -> FrameParams {
        let mut f = self.frame(width, height);
        let c = camera::frame(view, width, height);
        (f.eye, f.forward, f.right, f.up) = (c.eye, c.forward, c.right, c.up);
        f
    }

    /// The frame parameters for rendering the whole image at `width`×`height`.
    pub fn frame(&self, width: u32, height: u32) -> FrameParams {
        let s = &self.scene.render;
        let mut f = camera::frame(&self.scene.camera, width, height);
        f.spp = s.spp;
        f.max_depth = s.max_depth;
        f.background = s.background.map(|c| c as f32);
        f.ambient = s.ambient.map(|c| c as f32);
        f.num_lights = self.flat.lights.len() as u32;
        f.num_emitters = self.flat.emitters.len() as u32;
        f.emitter_norm = self.flat.emitter_norm;
        f.rr_depth = limits::RR_DEPTH;
        f.tile_size = [width, height];
        f.out_pitch = width;
        if !self.flat.environment.is_empty() {
            f.flags |= crate::layout::FRAME_ENVIRONMENT;
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_beyond_the_memory_available_are_refused_before_preparing() {
        let scene = crate::scene::procedural::torus_scene(20_000);
        let n = scene.triangle_count() as u64;
        let err = check_memory(&scene, Some(n * BYTES_PER_PRIMITIVE - 1)).unwrap_err();
        assert_eq!((err.primitives, err.need), (n, n * BYTES_PER_PRIMITIVE));
        let msg = err.to_string();
        assert!(msg.contains(&format!("{n} primitives")) && msg.contains("MiB of memory available"), "{msg}");
        assert!(check_memory(&scene, Some(n * BYTES_PER_PRIMITIVE)).is_ok());
        assert!(check_memory(&scene, None).is_ok());
    }
}
