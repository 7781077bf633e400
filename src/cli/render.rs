//! `strahl render`.

use super::{BackendChoice, progress_bar};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;
use strahl::backend::gpu::{self, GpuContext, SceneBuffers};
use strahl::render::Prepared;
use strahl::scene::{LoadOptions, RenderMode, Scene};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file: TOML, or a glTF file (.gltf, .glb) on its own.
    pub scene: PathBuf,
    /// Output image: .png (8-bit sRGB) or .exr (linear float).
    #[arg(short, long, value_parser = super::image_file_name)]
    pub output: PathBuf,
    /// Where to render (default: gpu, falling back to cpu when no Vulkan adapter exists).
    #[arg(long, value_enum)]
    pub backend: Option<BackendChoice>,
    /// Image width (default: the scene's [image] width).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,
    /// Image height (default: the scene's [image] height).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,
    /// Samples per pixel (default: the scene's [render] spp).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub spp: Option<u32>,
    /// Light transport (default: the scene's [render] mode, else whitted).
    #[arg(long, value_enum)]
    pub mode: Option<ModeChoice>,
    /// Longest path or reflection chain (default: the scene's [render] max_depth).
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub max_depth: Option<u32>,
    /// Seed of the path tracer's random numbers (renders with different seeds are independent).
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
    /// A glTF file's camera to render from: its index in the file's `cameras` (default: the
    /// first perspective camera placed in the scene).
    #[arg(long)]
    pub camera: Option<usize>,
}

/// `--mode`: how light transport is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ModeChoice {
    /// Whitted ray tracing: point/directional lights, hard shadows, perfect mirrors and glass.
    Whitted,
    /// Monte Carlo path tracing: area lights, next-event estimation with MIS, soft shadows.
    Path,
}

impl From<ModeChoice> for RenderMode {
    fn from(m: ModeChoice) -> Self {
        match m {
            ModeChoice::Whitted => RenderMode::Whitted,
            ModeChoice::Path => RenderMode::Path,
        }
    }
}

pub fn run(a: RenderArgs) -> Result<()> {
    if let (Some(w), Some(h)) = (a.width, a.height) {
        super::check_image_size(w, h, true)?;
    }
    // A missing, read-only or misnamed output fails now, not after the render.
    strahl::output::check_file_target(&a.output)?;
    if a.camera.is_some() && !strahl::scene::gltf::is_gltf_path(&a.scene) {
        return Err(super::usage_error("--camera: only a glTF file (.gltf, .glb) has cameras to choose from"));
    }
    let mut scene = Scene::load_with(&a.scene, &LoadOptions { camera: a.camera })?;
    if let Some(spp) = a.spp {
        scene.render.spp = spp;
    }
    if let Some(mode) = a.mode {
        scene.render.mode = mode.into();
    }
    if let Some(d) = a.max_depth {
        scene.render.max_depth = d;
    }
    let mode = scene.render.mode;
    let width = a.width.unwrap_or(scene.image.width);
    let height = a.height.unwrap_or(scene.image.height);
    super::check_image_size(width, height, a.width.is_some() || a.height.is_some())?;
    let prep = Prepared::new(scene);
    super::print_scene_summary(&prep);
    let mut frame = prep.frame(width, height);
    frame.seed = a.seed;
    let samples = width as f64 * height as f64 * frame.spp as f64;
    let gpu = match a.backend {
        Some(BackendChoice::Cpu) => None,
        Some(BackendChoice::Gpu) => Some(GpuContext::new()?),
        None => match GpuContext::new() {
            Ok(ctx) => Some(ctx),
            Err(e) => {
                eprintln!("gpu backend unavailable ({e}); rendering on the cpu");
                None
            }
        },
    };
    let image = match gpu {
        None => {
            let bar = progress_bar(height as u64, "cpu");
            let start = Instant::now();
            let img = strahl::backend::cpu::render(&prep, &frame, mode, &|rows| bar.set_position(rows));
            bar.finish_and_clear();
            let secs = start.elapsed().as_secs_f64();
            println!(
                "rendered {width}x{height} at {} spp ({}) on the cpu ({} threads) in {secs:.3} s: {:.2} M samples/s",
                frame.spp,
                mode.name(),
                rayon::current_num_threads(),
                samples / secs / 1e6
            );
            img
        }
        Some(ctx) => {
            let buffers = SceneBuffers::upload(&ctx, &prep.gpu)?;
            let bar = progress_bar(1, "gpu");
            let (img, stats) = gpu::render::render(&ctx, &buffers, &frame, mode, buffers.key, &|done, total| {
                bar.set_length(total);
                bar.set_position(done)
            })?;
            bar.finish_and_clear();
            let secs = stats.wall.as_secs_f64();
            println!(
                "rendered {width}x{height} at {} spp ({}) on {} in {secs:.3} s ({} dispatches, shader {} compiled in {:.3} s): {:.2} M samples/s",
                frame.spp,
                mode.name(),
                ctx.adapter_name(),
                stats.dispatches,
                stats.key.label(),
                stats.compile_time.as_secs_f64(),
                samples / secs / 1e6
            );
            if let Some(g) = stats.gpu_time {
                println!(
                    "gpu time from timestamp queries: {:.3} ms, {:.2} M samples/s",
                    g.as_secs_f64() * 1e3,
                    samples / g.as_secs_f64() / 1e6
                );
            }
            img
        }
    };
    image.save(&a.output)?;
    println!("wrote {}", a.output.display());
    Ok(())
}
