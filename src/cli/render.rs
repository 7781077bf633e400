//! `strahl render`.

use super::BackendChoice;
use super::finishing::FinishArgs;
use super::progress::Progress;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;
use strahl_core::image::{ExrPlacement, Image, Region};
use strahl_core::layout::FrameParams;
use strahl_core::render::Prepared;
use strahl_core::render::aov::AovImages;
use strahl_core::scene::{LoadOptions, RenderMode, Scene};
use strahl_cpu::shade::ShadeInputs;
use strahl_gpu::select::{Selected, Workload};
use strahl_gpu::{self as gpu, SceneBuffers};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file: TOML, or a glTF file (.gltf, .glb) on its own.
    pub scene: PathBuf,
    /// Output image: .png (8-bit sRGB, through --view) or .exr (linear float, scene-referred).
    #[arg(short, long, value_parser = super::image_file_name)]
    pub output: PathBuf,
    #[command(flatten)]
    pub display: super::output_image::DisplayArgs,
    #[command(flatten)]
    pub finish: super::finishing::FinishArgs,
    /// Where to render (default: STRAHL_BACKEND, else auto: a hardware GPU, else the faster
    /// of lavapipe and the cpu for the mode, the cpu without a Vulkan adapter).
    #[arg(long, value_enum)]
    pub backend: Option<BackendChoice>,
    /// Render only this pixel rectangle: columns X0..X1, rows Y0..Y1 (the ends excluded). An
    /// EXR output records where it lies (data window); `strahl merge` assembles such parts.
    #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = parse_region, conflicts_with = "tile")]
    pub region: Option<Region>,
    /// Render only band K of N (0-based) of horizontal bands of equal height, as --region.
    #[arg(long, value_name = "K/N", value_parser = parse_tile)]
    pub tile: Option<(u32, u32)>,
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

/// `X0,Y0,X1,Y1` with X0 < X1 and Y0 < Y1 (whether it fits the image is checked with the scene).
fn parse_region(s: &str) -> Result<Region, String> {
    let v: Vec<u32> = s
        .split(',')
        .map(|c| c.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected X0,Y0,X1,Y1 (four pixel coordinates), not {s:?}"))?;
    let [x0, y0, x1, y1] = v[..] else {
        return Err(format!("expected X0,Y0,X1,Y1 (four pixel coordinates), not {s:?}"));
    };
    if x0 >= x1 || y0 >= y1 {
        return Err(format!("{s}: empty; columns X0..X1 and rows Y0..Y1 need X0 < X1 and Y0 < Y1"));
    }
    Ok(Region { x0, y0, x1, y1 })
}

/// `K/N` with N >= 1 and 0 <= K < N.
fn parse_tile(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected K/N, band K (0-based) of N, not {s:?}");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n) = (k.trim().parse::<u32>().map_err(|_| bad())?, n.trim().parse::<u32>().map_err(|_| bad())?);
    if n == 0 || k >= n {
        return Err(format!("{s}: K must be from 0 to N - 1 (bands are counted from 0), and N at least 1"));
    }
    Ok((k, n))
}

pub fn run(a: RenderArgs) -> Result<()> {
    if let (Some(w), Some(h)) = (a.width, a.height) {
        super::check_image_size(w, h, true)?;
    }
    // A missing, read-only or misnamed output fails now, not after the render.
    strahl_core::output::check_file_target(&a.output)?;
    a.display.check(&a.output)?;
    a.finish.check(&a.output, a.region.is_some() || a.tile.is_some())?;
    if a.camera.is_some() && !strahl_core::scene::gltf::is_gltf_path(&a.scene) {
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
    let region = match (a.region, a.tile) {
        (Some(r), _) if !r.fits(width, height) => {
            return Err(super::usage_error(format!("--region {r}: outside the {width}x{height} image")));
        }
        (Some(r), _) => r,
        (None, Some((_, n))) if n > height => {
            return Err(super::usage_error(format!(
                "--tile: {n} bands of a {height}-row image would leave some empty; use at most {height}"
            )));
        }
        (None, Some((k, n))) => Region::band(k, n, width, height),
        (None, None) => Region::whole(width, height),
    };
    let prep = Prepared::try_new(scene)?;
    super::print_scene_summary(&prep);
    let mut frame = prep.frame(width, height);
    frame.seed = a.seed;
    let samples = region.pixel_count() as f64 * frame.spp as f64;
    let workload = match mode {
        RenderMode::Whitted => Workload::Whitted,
        RenderMode::Path => Workload::Path,
    };
    let what = if region == Region::whole(width, height) {
        format!("{width}x{height}")
    } else {
        format!("the region {region} ({}x{} of {width}x{height})", region.width(), region.height())
    };
    let progress = Progress::new(samples as u64, "render");
    let render_on_cpu = || {
        // The CPU's own tree first: the time below is the render's.
        let on_cpu = strahl_cpu::CpuScene::new(&prep);
        let start = Instant::now();
        let per_row = region.width() as u64 * frame.spp as u64;
        let tracer = strahl_cpu::PathTracer::default();
        let (img, report) = strahl_cpu::render_region_reported(&on_cpu, &frame, mode, region, tracer, false, &|rows| {
            progress.set(rows * per_row)
        });
        progress.finish();
        let secs = start.elapsed().as_secs_f64();
        let threads = rayon::current_num_threads();
        println!(
            "rendered {what} at {} spp ({}) on the cpu ({threads} threads) in {secs:.3} s: {:.2} M samples/s",
            frame.spp,
            mode.name(),
            samples / secs / 1e6
        );
        if let Some(line) = report.fallbacks.summary(&prep.scene.materials) {
            println!("{line}");
        }
        (finish_on_cpu(&a.finish, &on_cpu.inputs(&frame), region, img), "cpu", format!("cpu ({threads} threads)"))
    };
    let (selected, auto) = super::open_backend(a.backend, workload)?;
    let (Finished { image, aovs }, backend, device) = match selected {
        Selected::Cpu => render_on_cpu(),
        Selected::Gpu(ctx) => super::gpu_or_cpu(
            auto,
            || {
                let buffers = SceneBuffers::upload(&ctx, &prep.flat)?;
                let (img, stats) =
                    gpu::tiles::render_region(&ctx, &buffers, &frame, mode, buffers.key, region, &|done, total| {
                        // A step is one sample pass over one band.
                        progress.set(done * samples as u64 / total.max(1))
                    })?;
                progress.finish();
                let secs = stats.wall.as_secs_f64();
                println!(
                    "rendered {what} at {} spp ({}) on {} in {secs:.3} s ({} dispatches): {:.2} M samples/s",
                    frame.spp,
                    mode.name(),
                    ctx.adapter_name(),
                    stats.dispatches,
                    samples / secs / 1e6
                );
                println!("{}", compile_report(&stats));
                if let Some(g) = stats.gpu_time {
                    println!(
                        "gpu time from timestamp queries: {:.3} ms, {:.2} M samples/s",
                        g.as_secs_f64() * 1e3,
                        samples / g.as_secs_f64() / 1e6
                    );
                }
                let out = finish_on_gpu(&a.finish, (&ctx, &buffers, &frame), region, img)?;
                Ok((out, "gpu", ctx.adapter_name()))
            },
            render_on_cpu,
        )?,
    };
    if strahl_core::image::is_exr_path(&a.output) {
        let description = strahl_core::parts::Description { scene: &a.scene, mode, backend, device, tile: a.tile };
        let placement = ExrPlacement {
            full: (width, height),
            region,
            attributes: strahl_core::parts::describe(&description, &prep, &frame),
        };
        // Only the variables asked for: the denoiser's guides are written when named.
        let channels: Vec<(&str, Vec<f32>)> = aovs
            .map(|v| AovImages {
                layers: v.layers.into_iter().filter(|(x, _)| a.finish.written().contains(x)).collect(),
                ..v
            })
            .map(|v| v.channels())
            .unwrap_or_default();
        strahl_core::image::write_exr_with(&a.output, &image, &placement, &channels)?;
    } else {
        a.display.save_png(&image, &a.output)?;
    }
    println!("wrote {}", a.output.display());
    Ok(())
}

/// The image as written, and the output variables computed beside it.
struct Finished {
    image: Image,
    aovs: Option<AovImages>,
}

/// The output variables `finish` asks for and the image denoised where it asks, on the CPU.
fn finish_on_cpu(finish: &FinishArgs, inputs: &ShadeInputs, region: Region, image: Image) -> Finished {
    let mut out = Finished { image, aovs: None };
    let aovs = finish.computed();
    if !aovs.is_empty() {
        let start = Instant::now();
        out.aovs = Some(strahl_cpu::aov::render_aovs(inputs, region, &aovs));
        println!("output variables on the cpu in {:.3} s", start.elapsed().as_secs_f64());
    }
    if finish.denoise {
        let guides = out.aovs.as_ref().and_then(|v| v.guides()).expect("the guides were computed");
        let start = Instant::now();
        out.image = strahl_core::denoise::denoise(&out.image, &guides);
        println!("denoised on the cpu in {:.3} s", start.elapsed().as_secs_f64());
    }
    out
}

/// [`finish_on_cpu`] on the GPU that rendered `frame` of the scene in `buffers`.
fn finish_on_gpu(
    finish: &FinishArgs,
    (ctx, buffers, frame): (&gpu::GpuContext, &SceneBuffers, &FrameParams),
    region: Region,
    image: Image,
) -> Result<Finished> {
    let mut out = Finished { image, aovs: None };
    let aovs = finish.computed();
    if !aovs.is_empty() {
        let start = Instant::now();
        out.aovs = Some(gpu::aov::render_aovs(ctx, buffers, frame, region, &aovs)?);
        println!("output variables on the gpu in {:.3} s", start.elapsed().as_secs_f64());
    }
    if finish.denoise {
        let guides = out.aovs.as_ref().and_then(|v| v.guides()).expect("the guides were computed");
        let (image, took) = gpu::denoise::Denoiser::new(ctx)?.denoise(ctx, &out.image, &guides)?;
        out.image = image;
        println!("denoised on the gpu in {:.3} s", took.as_secs_f64());
    }
    Ok(out)
}

/// What preparing the shader cost, as measured: composing it and creating the pipeline, and
/// the first sample pass, in which drivers that compile at the first dispatch (lavapipe)
/// compile, beside the later passes where there are any.
fn compile_report(stats: &gpu::timing::RenderStats) -> String {
    let first = stats.first_pass.as_secs_f64();
    let later = if stats.passes > 1 {
        let mean = (stats.wall.as_secs_f64() - first).max(0.0) / (stats.passes - 1) as f64;
        format!("the later ones {mean:.3} s each")
    } else {
        "with the driver's compile where it compiles at the first dispatch (lavapipe)".to_string()
    };
    format!(
        "shader {}: composed and pipeline created in {:.3} s; first sample pass {first:.3} s ({later})",
        stats.key.label(),
        stats.compile_time.as_secs_f64()
    )
}
