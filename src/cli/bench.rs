//! `strahl bench`: what specialising a shader to its scene buys, on the adapter at hand.
//!
//! For each scene it measures, for the scene's specialised shader and for the all-features
//! shader: compile time (composition, pipeline creation, and the first dispatch, where
//! lavapipe's JIT compiles), each in a child process whose Mesa shader disk cache is an empty
//! folder so that nothing compiled before is reused; and frame time (median of `--frames` renders after the first), then the CPU
//! backend's frame time for scale. Ratios are measured in one run: compare them, not the
//! absolute times, across machines. Without a Vulkan adapter it says so and measures the CPU
//! alone.

use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use strahl::backend::gpu::{FeatureKey, GpuContext, SceneBuffers, render::render};
use strahl::render::Prepared;
use strahl::scene::Scene;

#[derive(Args, Debug)]
pub struct BenchArgs {
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

struct Row {
    scene: String,
    variant: String,
    key: String,
    compile: Duration,
    frame: Duration,
    mrays: f64,
}

pub fn run(a: BenchArgs) -> Result<()> {
    match a.compile_only {
        Some(bits) => {
            let path = a.scenes.first().context("--compile-only needs a scene")?;
            let prep = Prepared::new(Scene::load(path)?);
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
    // Without a Vulkan adapter only the CPU backend is measured.
    let ctx = match GpuContext::new() {
        Ok(ctx) => {
            println!("adapter: {}", ctx.adapter_name());
            Some(ctx)
        }
        Err(e) => {
            eprintln!("gpu backend unavailable ({e}); measuring the cpu only");
            println!("adapter: none (no GPU measured)");
            None
        }
    };
    let mut rows = Vec::new();
    for path in &scenes {
        let prep = Prepared::new(Scene::load(path)?);
        let (w, h) = (a.width.unwrap_or(prep.scene.image.width), a.height.unwrap_or(prep.scene.image.height));
        super::check_image_size(w, h, a.width.is_some() || a.height.is_some())?;
        let frame = prep.frame(w, h);
        let rays = w as f64 * h as f64 * frame.spp as f64;
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        if let Some(ctx) = &ctx {
            rows.extend(gpu_rows(ctx, path, &prep, &frame, &name, a.frames)?);
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
    match &ctx {
        Some(c) if c.timestamps => println!("frame time: median GPU time (timestamp queries); cpu: wall time"),
        Some(_) => println!("frame time: median wall time; cpu: wall time"),
        None => println!("frame time: wall time of one cpu render"),
    }
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

/// The GPU rows of one scene (rendered as `frame`, `rays` primary rays a frame): its
/// specialised shader and, unless that is it, the all-features shader, each with its compile
/// time and median frame time.
fn gpu_rows(
    ctx: &GpuContext,
    path: &std::path::Path,
    prep: &Prepared,
    frame: &strahl::gpu_types::GpuFrame,
    name: &str,
    frames: u32,
) -> Result<Vec<Row>> {
    let rays = frame.width as f64 * frame.height as f64 * frame.spp as f64;
    let buffers = SceneBuffers::upload(ctx, &prep.gpu)?;
    let mut variants = vec![("specialised", buffers.key)];
    if buffers.key != FeatureKey::ALL {
        if !buffers.runs_with(FeatureKey::ALL) {
            bail!("{name}: the all-features shader needs a scene with a BVH");
        }
        variants.push(("all features", FeatureKey::ALL));
    }
    let mut rows = Vec::new();
    for (variant, key) in variants {
        let compile = compile_in_child(path, key)?;
        first_dispatch(ctx, &buffers, prep, key)?;
        let mut times = Vec::new();
        for i in 0..=frames {
            let (_, stats) = render(ctx, &buffers, frame, strahl::scene::RenderMode::Whitted, key, &|_, _| {})?;
            if i > 0 {
                times.push(stats.gpu_time.unwrap_or(stats.wall));
            }
        }
        times.sort();
        let median = times[times.len() / 2];
        rows.push(Row {
            scene: name.to_string(),
            variant: variant.into(),
            key: key.label(),
            compile,
            frame: median,
            mrays: rays / median.as_secs_f64() / 1e6,
        });
    }
    Ok(rows)
}
