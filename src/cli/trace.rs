//! `strahl trace`.

use super::BackendChoice;
use anyhow::Result;
use clap::{Args, ValueEnum};
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;
use strahl_core::math::Real;
use strahl_core::query::{HITS_HEADER, RayQuery, read_rays, write_hit_rows};
use strahl_core::scene::Scene;
use strahl_gpu::GpuContext;
use strahl_gpu::select::{Selected, Workload};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Precision {
    F32,
    F64,
}

#[derive(Args, Debug)]
pub struct TraceArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Rays CSV: header ox,oy,oz,dx,dy,dz[,tmin,tmax].
    #[arg(long)]
    pub rays: PathBuf,
    /// Hits CSV to write (default: standard output).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Every intersection along each ray, sorted by t, instead of the nearest.
    #[arg(long)]
    pub all: bool,
    /// Where to trace (default: STRAHL_BACKEND, else auto: a hardware GPU, else the faster of
    /// lavapipe and the cpu for ray queries; f64 always runs on the cpu).
    #[arg(long, value_enum)]
    pub backend: Option<BackendChoice>,
    /// Arithmetic: f32 (the GPU's, and the CPU's mirror of it) or f64 (the CPU oracle).
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: Precision,
}

pub fn run(a: TraceArgs) -> Result<()> {
    if (a.backend, a.precision) == (Some(BackendChoice::Gpu), Precision::F64) {
        return Err(super::usage_error("--precision f64 needs --backend cpu: the GPU traces in f32"));
    }
    if let Some(path) = &a.output {
        strahl_core::output::check_file_target(path)?;
    }
    let scene = Scene::load(&a.scene)?;
    super::print_scene_warnings(&scene);
    strahl_core::render::check_memory(&scene, strahl_core::render::available_memory())?;
    let rays = read_rays(&a.rays)?;
    let start = Instant::now();
    let csv = match a.precision {
        Precision::F64 => cpu_csv::<f64>(&scene, &rays, a.all),
        Precision::F32 => {
            let (selected, auto) = super::open_backend(a.backend, Workload::Trace)?;
            match selected {
                Selected::Cpu => cpu_csv::<f32>(&scene, &rays, a.all),
                Selected::Gpu(ctx) => super::gpu_or_cpu(
                    auto,
                    || gpu_csv(*ctx, &scene, &rays, a.all),
                    || cpu_csv::<f32>(&scene, &rays, a.all),
                )?,
            }
        }
    };
    let secs = start.elapsed().as_secs_f64();
    match &a.output {
        Some(path) => {
            strahl_core::output::write_bytes_atomic(path, csv.as_bytes())?;
            eprintln!("traced {} rays in {secs:.3} s; wrote {}", rays.len(), path.display());
        }
        None => std::io::stdout().write_all(csv.as_bytes())?,
    }
    Ok(())
}

fn cpu_csv<R: Real>(scene: &Scene, rays: &[RayQuery], all: bool) -> String {
    hits_csv(rays, &strahl_cpu::trace::<R>(scene, rays, all), all)
}

fn gpu_csv(ctx: GpuContext, scene: &Scene, rays: &[RayQuery], all: bool) -> Result<String> {
    use strahl_gpu::{SceneBuffers, trace};
    let prep = strahl_core::render::Prepared::new(scene.clone());
    let buffers = SceneBuffers::upload(&ctx, &prep.flat)?;
    let hits = trace::trace(&ctx, &buffers, rays, all)?;
    eprintln!("traced on {}", ctx.adapter_name());
    Ok(hits_csv(rays, &hits, all))
}

fn hits_csv<R: Real>(rays: &[RayQuery], hits: &[Vec<strahl_core::primitives::Hit<R>>], all: bool) -> String {
    let mut out = String::with_capacity(64 * rays.len() + HITS_HEADER.len() + 1);
    out.push_str(HITS_HEADER);
    out.push('\n');
    for (i, (q, h)) in rays.iter().zip(hits).enumerate() {
        write_hit_rows(&mut out, i, &q.ray::<R>(), h, !all);
    }
    out
}
