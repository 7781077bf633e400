//! `strahl bench`: how fast each backend renders, on the machine at hand, in one run
//! (`strahl bench rays`, BVH build and ray casting, is in [`super::bench_rays`]).
//!
//! For each scene and mode:
//! - Whitted (primary rays per second): the GPU with the scene's specialised shader and with
//!   the all-features shader, each with its compile time (composition, pipeline creation and the
//!   first dispatch, where lavapipe's JIT compiles, measured in a child process whose Mesa shader
//!   disk cache is an empty folder) and its median frame time; then the CPU backend.
//! - Path tracing (pixel samples per second, `--spp` samples per pixel a frame): the GPU's
//!   megakernel and wavefront tracers, each with its pipelines compiled before timing and the
//!   time of each kernel from timestamp queries where the adapter has them, then the CPU
//!   backend.
//!
//! Frame times are medians of `--frames` frames after one untimed frame, wall clock, on both
//! backends, the rows of a table timed in turns (one frame of each per round). Ratios are
//! measured in one run: compare them, not absolute times, across machines (here the second CPU
//! core comes and goes). Without a Vulkan adapter the CPU alone is measured. `--json` prints
//! one JSON object instead of the tables.

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand, ValueEnum};
use serde_json::{Value, json};
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};
use strahl_core::image::Region;
use strahl_core::layout::FrameParams;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene};
use strahl_cpu::accel::bundle::Isa;
use strahl_cpu::{self as cpu, PathTracer};
use strahl_gpu::tiles::{PathAccumulator, render, render_tiles};
use strahl_gpu::wavefront::Wavefront;
use strahl_gpu::{FeatureKey, GpuContext, PathKernels, SceneBuffers};

/// The scenes measured when none are named, in the repository's `assets/scenes`.
const DEFAULT_SCENES: [&str; 2] = ["seed.toml", "spheres.toml"];

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BenchMode {
    Whitted,
    Path,
    Both,
}

#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub command: Option<BenchCommand>,
    /// Scene files (default: seed.toml and spheres.toml of the repository's assets/scenes,
    /// found from the working directory or from where strahl was built).
    pub scenes: Vec<PathBuf>,
    /// Which renderers to measure.
    #[arg(long, value_enum, default_value_t = BenchMode::Both)]
    pub mode: BenchMode,
    /// Path tracing: samples per pixel of one frame.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub spp: u32,
    /// Timed frames per measurement (after one untimed frame).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub frames: u32,
    /// Image width (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,
    /// Skip the compile-time measurements (each compiles in a child process, seconds apiece).
    #[arg(long)]
    pub no_compile: bool,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
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

pub fn run(a: BenchArgs) -> Result<()> {
    if let Some(BenchCommand::Rays(r)) = a.command {
        return super::bench_rays::run(r);
    }
    match a.compile_only {
        Some(bits) => {
            let path = a.scenes.first().context("--compile-only needs a scene")?;
            let prep = Prepared::try_new(Scene::load(path)?)?;
            let ctx = GpuContext::new()?;
            let buffers = SceneBuffers::upload(&ctx, &prep.flat)?;
            println!("{}", first_dispatch(&ctx, &buffers, &prep, FeatureKey::from_bits_retain(bits))?.as_secs_f64());
            Ok(())
        }
        None => bench(a),
    }
}

/// The scenes to measure: those named, else the defaults, looked up in `assets/scenes` under
/// the working directory, then under the folder strahl was built from.
fn scenes(named: &[PathBuf]) -> Result<Vec<PathBuf>> {
    if !named.is_empty() {
        return Ok(named.to_vec());
    }
    let roots = [PathBuf::from("."), PathBuf::from(env!("CARGO_MANIFEST_DIR"))];
    for root in roots {
        let dir = root.join("assets/scenes");
        if DEFAULT_SCENES.iter().all(|s| dir.join(s).is_file()) {
            return Ok(DEFAULT_SCENES.iter().map(|s| dir.join(s)).collect());
        }
    }
    bail!(
        "no scene files given, and the default scenes ({}) are not in ./assets/scenes nor in {}/assets/scenes: name scene files",
        DEFAULT_SCENES.join(", "),
        env!("CARGO_MANIFEST_DIR")
    )
}

/// Pipeline creation plus the first dispatch (one 8x8 tile), where lavapipe compiles.
fn first_dispatch(ctx: &GpuContext, buffers: &SceneBuffers, prep: &Prepared, key: FeatureKey) -> Result<Duration> {
    let start = Instant::now();
    let tiny = prep.frame(8, 8);
    render(ctx, buffers, &tiny, RenderMode::Whitted, key, &|_, _| {})?;
    Ok(start.elapsed())
}

/// Compile time of `key` for `scene`, measured in a child process with an empty Mesa shader
/// cache.
fn compile_in_child(scene: &Path, key: FeatureKey) -> Result<Duration> {
    let cache = tempfile::tempdir().context("creating a shader cache folder")?;
    let out = std::process::Command::new(std::env::current_exe()?)
        .args(["bench", "--compile-only", &key.bits().to_string()])
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

/// One frame of one row of a table: a closure that renders it.
type Frame<'a> = Box<dyn FnMut() -> Result<()> + 'a>;

/// Median wall time of `frames` calls of each of `rows`, after one untimed call of each, the
/// rows taken in turns (row 0, row 1, .., row 0, ..): on a machine whose speed drifts (here the
/// second core comes and goes for minutes), every row then meets the same slow and fast spells
/// and their ratios hold, where timing all frames of one row before the next would compare
/// different spells.
fn median_times(frames: u32, rows: &mut [Frame<'_>]) -> Result<Vec<Duration>> {
    for f in rows.iter_mut() {
        f()?;
    }
    let mut times = vec![Vec::with_capacity(frames as usize); rows.len()];
    for _ in 0..frames {
        for (f, t) in rows.iter_mut().zip(&mut times) {
            let start = Instant::now();
            f()?;
            t.push(start.elapsed());
        }
    }
    Ok(times
        .into_iter()
        .map(|mut t| {
            t.sort();
            t[t.len() / 2]
        })
        .collect())
}

/// "1.52x faster" or "2.10x slower": `ratio` is the first rate over the second.
fn faster_or_slower(ratio: f64) -> String {
    if ratio >= 1.0 { format!("{ratio:.2}x faster") } else { format!("{:.2}x slower", 1.0 / ratio) }
}

fn bench(a: BenchArgs) -> Result<()> {
    let scenes = scenes(&a.scenes)?;
    // Without a Vulkan adapter only the CPU backend is measured.
    let ctx = match GpuContext::new() {
        Ok(ctx) => Some(Arc::new(ctx)),
        Err(e) => {
            eprintln!("gpu backend unavailable ({e}); measuring the cpu only");
            None
        }
    };
    let adapter = ctx.as_ref().map(|c| {
        let i = &c.adapter_info;
        json!({
            "name": i.name,
            "driver": i.driver,
            "driver_info": i.driver_info,
            "device_type": format!("{:?}", i.device_type),
            "backend": format!("{:?}", i.backend),
            "timestamps": c.timestamps,
        })
    });
    let mut results = Vec::new();
    for path in &scenes {
        let prep = Prepared::try_new(Scene::load(path)?)?;
        let (w, h) = (a.width.unwrap_or(prep.scene.image.width), a.height.unwrap_or(prep.scene.image.height));
        super::check_image_size(w, h, a.width.is_some() || a.height.is_some())?;
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let mut scene = json!({
            "scene": name,
            "width": w,
            "height": h,
            "triangles": prep.prims.triangles.len(),
        });
        if a.mode != BenchMode::Path {
            scene["whitted"] = bench_whitted(&a, ctx.as_deref(), path, &prep, w, h)?;
        }
        if a.mode != BenchMode::Whitted {
            scene["path"] = bench_path(&a, ctx.as_ref(), &prep, w, h)?;
        }
        results.push(scene);
    }
    let report = json!({
        "adapter": adapter,
        "cpu_threads": rayon::current_num_threads(),
        "scenes": results,
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report);
    }
    Ok(())
}

/// Whitted rows: the GPU's specialised and all-features shaders, then the CPU backend.
fn bench_whitted(
    a: &BenchArgs,
    ctx: Option<&GpuContext>,
    path: &Path,
    prep: &Prepared,
    w: u32,
    h: u32,
) -> Result<Value> {
    let frame = prep.frame(w, h);
    let rays = w as f64 * h as f64 * frame.spp as f64;
    let buffers = match ctx {
        Some(ctx) => Some(SceneBuffers::upload(ctx, &prep.flat)?),
        None => None,
    };
    let mut variants = Vec::new();
    if let Some(buffers) = &buffers {
        variants.push(("specialised", buffers.key));
        if buffers.key != FeatureKey::ALL && buffers.runs_with(FeatureKey::ALL) {
            variants.push(("all features", FeatureKey::ALL));
        }
    }
    // Per GPU row, the GPU time of each of its frames (timestamp queries).
    let gpu_times: Vec<RefCell<Vec<Duration>>> = variants.iter().map(|_| RefCell::default()).collect();
    let mut gpu = Vec::new();
    // The GPU rows (each compiled before any timing), then the CPU backend's; timed in turns.
    // The CPU backend's tree, built once, outside the timed frames.
    let on_cpu = cpu::CpuScene::new(prep);
    let mut rows: Vec<Frame<'_>> = Vec::new();
    if let (Some(ctx), Some(buffers)) = (ctx, &buffers) {
        for (&(variant, key), times) in variants.iter().zip(&gpu_times) {
            let compile = if a.no_compile { None } else { Some(compile_in_child(path, key)?.as_secs_f64()) };
            first_dispatch(ctx, buffers, prep, key)?;
            gpu.push(json!({
                "variant": variant,
                "features": ctx.variant(strahl_gpu::Program::Whitted, key).label(),
                "compile_s": compile,
            }));
            let frame = &frame;
            rows.push(Box::new(move || {
                let (_, stats) = render(ctx, buffers, frame, RenderMode::Whitted, key, &|_, _| {})?;
                times.borrow_mut().extend(stats.gpu_time);
                Ok(())
            }));
        }
    }
    rows.push(Box::new(|| {
        cpu::render(&on_cpu, &frame, RenderMode::Whitted, &|_| {});
        Ok(())
    }));
    let walls = median_times(a.frames, &mut rows)?;
    drop(rows);
    for ((row, wall), times) in gpu.iter_mut().zip(&walls).zip(&gpu_times) {
        let mut times = times.take();
        // The untimed first frame is left out here too.
        if !times.is_empty() {
            times.remove(0);
        }
        times.sort();
        row["frame_s"] = json!(wall.as_secs_f64());
        row["gpu_time_s"] = json!(times.get(times.len() / 2).map(Duration::as_secs_f64));
        row["mrays_per_s"] = json!(rays / wall.as_secs_f64() / 1e6);
    }
    let cpu = walls[walls.len() - 1];
    Ok(json!({
        "spp": frame.spp,
        "gpu": gpu,
        "cpu": { "frame_s": cpu.as_secs_f64(), "mrays_per_s": rays / cpu.as_secs_f64() / 1e6 },
    }))
}

/// Path-tracing rows: the GPU's megakernel and wavefront tracers (per-kernel times from one
/// timed render with timestamp queries; frame times from progressive renders) and the CPU
/// backend, `a.spp` samples per pixel a frame.
fn bench_path(a: &BenchArgs, ctx: Option<&Arc<GpuContext>>, prep: &Prepared, w: u32, h: u32) -> Result<Value> {
    let frame = FrameParams { spp: a.spp, ..prep.frame(w, h) };
    let samples = w as f64 * h as f64 * a.spp as f64;
    let row = |kernels: &str, features: String, wall: Duration, times: &[(&str, Duration)]| {
        let kernel_times: serde_json::Map<String, Value> =
            times.iter().map(|(k, t)| (k.to_string(), json!(t.as_secs_f64()))).collect();
        json!({
            "kernels": kernels,
            "features": features,
            "frame_s": wall.as_secs_f64(),
            "msamples_per_s": samples / wall.as_secs_f64() / 1e6,
            "kernel_time_s": kernel_times,
        })
    };
    // The GPU tracers (pipelines compiled and kernels timed once before), then the CPU backend;
    // frames timed in turns.
    let mut labels = Vec::new();
    // The CPU backend's tree, built once, outside the timed frames.
    let on_cpu = &cpu::CpuScene::new(prep);
    let mut rows: Vec<Frame<'_>> = Vec::new();
    if let Some(ctx) = ctx {
        let buffers = SceneBuffers::upload(ctx, &prep.flat)?;
        let key = buffers.key;
        // Compile (lavapipe compiles at the first dispatch), then per-kernel GPU times from one
        // render with timestamp queries.
        let mega =
            PathAccumulator::with_kernels(ctx.clone(), buffers.clone(), prep.frame(8, 8), PathKernels::Megakernel);
        mega?.add_samples(1)?;
        let whole = Region::whole(frame.width, frame.height);
        let (_, stats) = render_tiles(ctx, &buffers, &frame, RenderMode::Path, key, whole, &|_, _| {})?;
        let mut progressive =
            PathAccumulator::with_kernels(ctx.clone(), buffers.clone(), frame, PathKernels::Megakernel)?;
        labels.push(("megakernel", stats.key.label(), stats.kernel_times));
        rows.push(Box::new(move || {
            progressive.reset();
            Ok(progressive.add_samples(a.spp)?)
        }));
        if ctx.has_wavefront(&buffers) {
            let wf = Wavefront::new(ctx, buffers.clone(), key, frame)?;
            let (_, wf_stats) = wf.render(ctx, &|_, _| {})?;
            let mut progressive = PathAccumulator::with_kernels(ctx.clone(), buffers, frame, PathKernels::Wavefront)?;
            labels.push(("wavefront", wf.key().label(), wf_stats.kernel_times));
            rows.push(Box::new(move || {
                progressive.reset();
                Ok(progressive.add_samples(a.spp)?)
            }));
        }
    }
    // The CPU's tracers: the lanes of each lane set this processor runs (the widest is the
    // backend's), then the one-path-at-a-time reference. Their stage times come from one
    // timed render each, summed over the threads.
    let mut cpu_tracers: Vec<(String, Value)> = Vec::new();
    for isa in Isa::available() {
        let (_, t) = cpu::render_path_timed(on_cpu, &frame, isa);
        let stages = json!({
            "generate": t.generate.as_secs_f64(),
            "trace": t.trace.as_secs_f64(),
            "shade": t.shade.as_secs_f64(),
            "shadow": t.shadow.as_secs_f64(),
        });
        cpu_tracers.push((format!("lanes ({}, {} wide)", isa.name(), isa.width()), stages));
        rows.push(Box::new(move || {
            cpu::render_region_with(
                on_cpu,
                &frame,
                RenderMode::Path,
                whole_frame(&frame),
                PathTracer::Lanes(isa),
                &|_| {},
            );
            Ok(())
        }));
    }
    cpu_tracers.push(("one path at a time".to_string(), Value::Null));
    rows.push(Box::new(|| {
        cpu::render_region_with(on_cpu, &frame, RenderMode::Path, whole_frame(&frame), PathTracer::OneByOne, &|_| {});
        Ok(())
    }));
    let walls = median_times(a.frames, &mut rows)?;
    drop(rows);
    let n_cpu = cpu_tracers.len();
    let cpu_walls = &walls[walls.len() - n_cpu..];
    let cpu_rows: Vec<Value> = cpu_tracers
        .into_iter()
        .zip(cpu_walls)
        .map(|((tracer, stages), wall)| {
            json!({
                "tracer": tracer,
                "frame_s": wall.as_secs_f64(),
                "msamples_per_s": samples / wall.as_secs_f64() / 1e6,
                "stage_time_s": stages,
            })
        })
        .collect();
    let gpu: Vec<Value> = labels
        .into_iter()
        .zip(&walls)
        .map(|((kernels, features, times), &wall)| row(kernels, features, wall, &times))
        .collect();
    Ok(json!({
        "spp": a.spp,
        "max_depth": frame.max_depth,
        "gpu": gpu,
        "cpu": cpu_rows[0].clone(),
        "cpu_tracers": cpu_rows,
    }))
}

fn whole_frame(frame: &FrameParams) -> Region {
    Region::whole(frame.width, frame.height)
}

fn print_report(r: &Value) {
    match &r["adapter"] {
        Value::Null => println!("adapter: none (no GPU measured)"),
        a => println!(
            "adapter: {} ({}, {}: {}), {} device, timestamp queries: {}",
            a["name"].as_str().unwrap_or(""),
            a["backend"].as_str().unwrap_or(""),
            a["driver"].as_str().unwrap_or(""),
            a["driver_info"].as_str().unwrap_or(""),
            a["device_type"].as_str().unwrap_or(""),
            a["timestamps"]
        ),
    }
    println!(
        "cpu backend: {} threads; frame times: median wall time of the frames after the first, the rows of a table timed in turns",
        r["cpu_threads"]
    );
    let f = |v: &Value, scale: f64, digits: usize| {
        v.as_f64().map_or("-".to_string(), |x| format!("{:.*}", digits, x * scale))
    };
    let mut summary = Vec::new();
    for s in r["scenes"].as_array().into_iter().flatten() {
        let name = s["scene"].as_str().unwrap_or("");
        if let Some(wh) = s.get("whitted") {
            println!("\n{name}, Whitted, {}x{}, {} spp:", s["width"], s["height"], wh["spp"]);
            println!("| backend | variant | compile s | frame ms | gpu time ms | M primary rays/s | features |");
            println!("|---|---|---|---|---|---|---|");
            for g in wh["gpu"].as_array().into_iter().flatten() {
                println!(
                    "| gpu | {} | {} | {} | {} | {} | {} |",
                    g["variant"].as_str().unwrap_or(""),
                    f(&g["compile_s"], 1.0, 3),
                    f(&g["frame_s"], 1e3, 1),
                    f(&g["gpu_time_s"], 1e3, 1),
                    f(&g["mrays_per_s"], 1.0, 3),
                    g["features"].as_str().unwrap_or("")
                );
            }
            let c = &wh["cpu"];
            println!("| cpu | - | - | {} | - | {} | - |", f(&c["frame_s"], 1e3, 1), f(&c["mrays_per_s"], 1.0, 3));
            let gpus = wh["gpu"].as_array().cloned().unwrap_or_default();
            if let (Some(spec), Some(cpu)) = (gpus.first(), c["mrays_per_s"].as_f64()) {
                let g = spec["mrays_per_s"].as_f64().unwrap_or(0.0);
                summary.push(format!("{name}, Whitted: the GPU is {} than the CPU backend", faster_or_slower(g / cpu)));
            }
            if let [spec, all] = gpus.as_slice() {
                let ratio = |k: &str| all[k].as_f64().unwrap_or(f64::NAN) / spec[k].as_f64().unwrap_or(f64::NAN);
                let compile = if spec["compile_s"].is_null() {
                    String::new()
                } else {
                    format!("compiles {} and ", faster_or_slower(ratio("compile_s")))
                };
                summary.push(format!(
                    "{name}, Whitted: the specialised shader {compile}renders {} than the all-features shader",
                    faster_or_slower(ratio("frame_s"))
                ));
            }
        }
        if let Some(p) = s.get("path") {
            println!(
                "\n{name}, path tracing, {}x{}, {} spp, max_depth {}:",
                s["width"], s["height"], p["spp"], p["max_depth"]
            );
            println!("| backend | kernels or tracer | frame ms | M samples/s | kernel or stage times ms | features |");
            println!("|---|---|---|---|---|---|");
            let c = &p["cpu"];
            for g in p["gpu"].as_array().into_iter().flatten() {
                let kernels: Vec<String> = g["kernel_time_s"]
                    .as_object()
                    .into_iter()
                    .flatten()
                    .map(|(k, t)| format!("{k} {}", f(t, 1e3, 1)))
                    .collect();
                println!(
                    "| gpu | {} | {} | {} | {} | {} |",
                    g["kernels"].as_str().unwrap_or(""),
                    f(&g["frame_s"], 1e3, 1),
                    f(&g["msamples_per_s"], 1.0, 3),
                    if kernels.is_empty() { "-".to_string() } else { kernels.join(", ") },
                    g["features"].as_str().unwrap_or("")
                );
                if let (Some(gs), Some(cs)) = (g["msamples_per_s"].as_f64(), c["msamples_per_s"].as_f64()) {
                    summary.push(format!(
                        "{name}, path tracing: the GPU's {} is {} than the CPU backend",
                        g["kernels"].as_str().unwrap_or(""),
                        faster_or_slower(gs / cs)
                    ));
                }
            }
            let reference = p["cpu_tracers"].as_array().and_then(|t| t.last()).cloned().unwrap_or(Value::Null);
            for t in p["cpu_tracers"].as_array().into_iter().flatten() {
                let stages: Vec<String> = t["stage_time_s"]
                    .as_object()
                    .into_iter()
                    .flatten()
                    .map(|(k, v)| format!("{k} {}", f(v, 1e3, 1)))
                    .collect();
                println!(
                    "| cpu | {} | {} | {} | {} | - |",
                    t["tracer"].as_str().unwrap_or(""),
                    f(&t["frame_s"], 1e3, 1),
                    f(&t["msamples_per_s"], 1.0, 3),
                    if stages.is_empty() { "-".to_string() } else { stages.join(", ") },
                );
            }
            if let (Some(fast), Some(slow)) = (c["msamples_per_s"].as_f64(), reference["msamples_per_s"].as_f64()) {
                summary.push(format!(
                    "{name}, path tracing: the CPU's {} is {} than one path at a time",
                    c["tracer"].as_str().unwrap_or(""),
                    faster_or_slower(fast / slow)
                ));
            }
        }
    }
    if !summary.is_empty() {
        println!();
        for line in summary {
            println!("{line}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratios_read_as_faster_or_slower() {
        assert_eq!(faster_or_slower(1.5), "1.50x faster");
        assert_eq!(faster_or_slower(0.5), "2.00x slower");
        assert_eq!(faster_or_slower(1.0), "1.00x faster");
    }

    #[test]
    fn rows_are_timed_in_turns_after_one_untimed_frame_each() {
        let calls = RefCell::new(Vec::new());
        let mut rows: Vec<Frame<'_>> = (0..3)
            .map(|i| {
                let calls = &calls;
                Box::new(move || {
                    calls.borrow_mut().push(i);
                    Ok(())
                }) as Frame<'_>
            })
            .collect();
        let medians = median_times(2, &mut rows).unwrap();
        assert_eq!(medians.len(), 3);
        assert_eq!(*calls.borrow(), [0, 1, 2, 0, 1, 2, 0, 1, 2]);
    }

    #[test]
    fn a_failing_row_ends_the_measurement() {
        let mut rows: Vec<Frame<'_>> = vec![Box::new(|| Ok(())), Box::new(|| bail!("device lost"))];
        let e = median_times(3, &mut rows).unwrap_err();
        assert!(e.to_string().contains("device lost"), "{e}");
    }

    #[test]
    fn default_scenes_are_found_from_the_build_folder() {
        let found = scenes(&[]).unwrap();
        assert_eq!(found.len(), DEFAULT_SCENES.len());
        assert!(found.iter().all(|p| p.is_file()), "{found:?}");
        let named = vec![PathBuf::from("x.toml")];
        assert_eq!(scenes(&named).unwrap(), named);
    }
}
