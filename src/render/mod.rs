//! Image formation shared by both backends, as stages named like the shaders:
//! [`camera`] (`raygen.wgsl`), [`spawn`] (`spawn.wgsl`), [`shade`] (`shade.wgsl`, Whitted),
//! and for path tracing [`sampler`] (`sampler.wgsl`), [`bsdf`] (`bsdf.wgsl`), [`emitters`]
//! (`emitters.wgsl`) and [`path`] (`path.wgsl`); [`texture`] (`texture.wgsl`) and
//! [`environment`] (`environment.wgsl`) for both modes.
//! The CPU backend runs these functions; the GPU runs their WGSL twins.

pub mod bsdf;
pub mod camera;
pub mod emitters;
pub mod environment;
pub mod path;
pub mod sampler;
pub mod shade;
pub mod spawn;
pub mod texture;

use crate::accel::Bvh;
use crate::gpu_types::{GpuFrame, GpuScene};
use crate::primitives::Primitives;
use crate::scene::Scene;
use std::time::{Duration, Instant};

/// A scene made ready for rendering: flattened, with its BVH built.
pub struct Prepared {
    pub scene: Scene,
    pub prims: Primitives<f32>,
    pub bvh: Bvh,
    pub gpu: GpuScene,
    /// Time spent flattening and building the BVH.
    pub build_time: Duration,
}

impl Prepared {
    pub fn new(scene: Scene) -> Self {
        let start = Instant::now();
        let prims = Primitives::<f32>::from_scene(&scene);
        let bvh = Bvh::build(&prims);
        let gpu = GpuScene::new(&scene, &prims, &bvh);
        Self { scene, prims, bvh, gpu, build_time: start.elapsed() }
    }

    /// The frame parameters for rendering the whole image at `width`×`height`.
    pub fn frame(&self, width: u32, height: u32) -> GpuFrame {
        let s = &self.scene.render;
        let mut f = camera::frame(&self.scene.camera, width, height);
        f.spp = s.spp;
        f.max_depth = s.max_depth;
        f.background = s.background.map(|c| c as f32);
        f.ambient = s.ambient.map(|c| c as f32);
        f.num_planes = self.gpu.planes.len() as u32;
        f.num_lights = self.gpu.lights.len() as u32;
        f.num_emitters = self.gpu.emitters.len() as u32;
        f.emitter_norm = self.gpu.emitter_norm;
        f.rr_depth = path::RR_DEPTH;
        f.tile_size = [width, height];
        f.out_pitch = width;
        if !self.gpu.environment.is_empty() {
            f.flags |= crate::gpu_types::FRAME_ENVIRONMENT;
        }
        f
    }
}
