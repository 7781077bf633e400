//! `strahl bench`: what specialising a shader to its scene buys, on the adapter at hand
//! (`strahl bench rays` is in [`super::bench_rays`]).
//!
//! For each scene it measures, for the scene's specialised shader and for the all-features
//! shader: compile time (composition, pipeline creation, and the first dispatch, where
//! lavapipe's JIT compiles), each in a child process whose Mesa shader disk cache is an empty
//! folder so that nothing compiled before is reused; and frame time (median of `--frames` renders after the first), then the CPU
//! backend's frame time for scale. Ratios are measured in one run: compare them, not the
//! absolute times, across machines.

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use strahl::backend::gpu::{FeatureKey, GpuContext, SceneBuffers, render::render};
use strahl::render::Prepared;
use strahl::scene::Scene;

#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub command: Option<BenchCommand>,
    /// Scene files (default: assets/scenes/seed.toml and assets/scenes/spheres.toml).
    pub scenes: Vec<PathBuf>,
    /// Timed frames per variant (after one untimed frame).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub frames: u32,
    /// Image width (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,
    /// Internal: measure the compile time of one variant (feature key bits) and print it.
    #[arg(long, hide = true)]
    pub compile_only: Option<u32>,
}

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// BVH build time and nearest-hit rays per second on one scene or mesh, on the CPU or
    /// the GPU, with the ray sets of the Embree anchor benchmark.
    Rays(super::bench_rays::RaysArgs),
}

struct Row {
    scene: String,
    variant: String,
    key: String,
    compile: Duration,
    frame: Duration,
    mrays: f64,
}

pub fn run(a: BenchArgs) -> Result<()> {
    if let Some(BenchCommand::Rays(r)) = a.command {
        return super::bench_rays::run(r);
    }
    match a.compile_only {
        Some(bits) => {
            let path = a.scenes.first().context("--compile-only needs a scene")?;
            let prep = Prepared::try_new(Scene::load(path)?)?;
            let ctx = GpuContext::new()?;
            let buffers = SceneBuffers::upload(&ctx, &prep.gpu)?;
            println!("{}", first_dispatch(&ctx, &buffers, &prep, FeatureKey(bits))?.as_secs_f64());
            Ok(())
        }
        None => bench(a),
    }
}

/// Pipeline creation plus the first dispatch (one 8x8 tile), where lavapipe compiles.
fn first_dispatch(ctx: &GpuContext, buffers: &SceneBuffers, prep: &Prepared, key: FeatureKey) -> Result<Duration> {
    let start = Instant::now();
    let tiny = prep.frame(8, 8);
    render(ctx, buffers, &tiny, strahl::scene::RenderMode::Whitted, key, &|_, _| {})?;
    Ok(start.elapsed())
}

/// Compile time of `key` for `scene`, measured in a child process with an empty Mesa shader
/// cache.
fn compile_in_child(scene: &std::path::Path, key: FeatureKey) -> Result<Duration> {
    let cache = tempfile::tempdir().context("creating a shader cache folder")?;
    let out = std::process::Command::new(std::env::current_exe()?)
        .args(["bench", "--compile-only", &key.0.to_string()])
        .arg(scene)
        .env("MESA_SHADER_CACHE_DIR", cache.path())
        .output()
        .context("running the compile measurement")?;
    if !out.status.success() {
        bail!("compile measurement failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    let secs: f64 = String::from_utf8_lossy(&out.stdout).trim().parse().context("reading the compile time")?;
    Ok(Duration::from_secs_f64(secs))
}

fn bench(a: BenchArgs) -> Result<()> {
    let scenes = if a.scenes.is_empty() {
        vec![PathBuf::from("assets/scenes/seed.toml"), PathBuf::from("assets/scenes/spheres.toml")]
    } else {
        a.scenes.clone()
    };
    let ctx = GpuContext::new()?;
    println!("adapter: {}", ctx.adapter_name());
    let mut rows = Vec::new();
    for path in &scenes {
        let prep = Prepared::try_new(Scene::load(path)?)?;
        let (w, h) = (a.width.unwrap_or(prep.scene.image.width), a.height.unwrap_or(prep.scene.image.height));
        let frame = prep.frame(w, h);
        let rays = w as f64 * h as f64 * frame.spp as f64;
        let buffers = SceneBuffers::upload(&ctx, &prep.gpu)?;
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let mut variants = vec![("specialised", buffers.key)];
        if buffers.key != FeatureKey::ALL {
            if !buffers.runs_with(FeatureKey::ALL) {
                bail!("{name}: the all-features shader needs a scene with a BVH");
            }
            variants.push(("all features", FeatureKey::ALL));
        }
        for (variant, key) in variants {
            let compile = compile_in_child(path, key)?;
            first_dispatch(&ctx, &buffers, &prep, key)?;
            let mut times = Vec::new();
            for i in 0..=a.frames {
                let (_, stats) = render(&ctx, &buffers, &frame, strahl::scene::RenderMode::Whitted, key, &|_, _| {})?;
                if i > 0 {
                    times.push(stats.gpu_time.unwrap_or(stats.wall));
                }
            }
            times.sort();
            let median = times[times.len() / 2];
            rows.push(Row {
                scene: name.clone(),
                variant: variant.into(),
                key: key.label(),
                compile,
                frame: median,
                mrays: rays / median.as_secs_f64() / 1e6,
            });
        }
        let start = Instant::now();
        strahl::backend::cpu::render(&prep, &frame, strahl::scene::RenderMode::Whitted, &|_| {});
        let cpu = start.elapsed();
        rows.push(Row {
            scene: name.clone(),
            variant: format!("cpu ({} threads)", rayon::current_num_threads()),
            key: "-".into(),
            compile: Duration::ZERO,
            frame: cpu,
            mrays: rays / cpu.as_secs_f64() / 1e6,
        });
    }
    println!(
        "frame time: {} of GPU time{}",
        if ctx.timestamps { "median" } else { "median wall time" },
        if ctx.timestamps { " (timestamp queries)" } else { "" }
    );
    println!("| scene | variant | compile s | frame ms | M primary rays/s | features |");
    println!("|---|---|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {} | {:.3} | {:.1} | {:.3} | {} |",
            r.scene,
            r.variant,
            r.compile.as_secs_f64(),
            r.frame.as_secs_f64() * 1e3,
            r.mrays,
            r.key
        );
    }
    for pair in rows.chunks(3) {
        if let [spec, all, _] = pair {
            println!(
                "{}: the specialised shader compiles {:.2}x faster and renders {:.2}x faster than the all-features shader",
                spec.scene,
                all.compile.as_secs_f64() / spec.compile.as_secs_f64(),
                all.frame.as_secs_f64() / spec.frame.as_secs_f64()
            );
        }
    }
    Ok(())
}
