//! Subcommands of `strahl`.

mod adapters;
mod bench;
mod bench_rays;
mod converge;
mod finishing;
mod merge;
mod output_image;
mod progress;
mod query;
mod render;
mod stiff;
mod trace;
#[cfg(feature = "viewer")]
mod view;

use clap::{CommandFactory, Parser, Subcommand};
use std::path::PathBuf;
use strahl_gpu::select::Choice;

/// `--backend`: [`Choice`] as a flag's values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendChoice {
    /// A hardware GPU if there is one; else the faster of lavapipe and the CPU backend for the
    /// work at hand; the CPU backend without any GPU adapter.
    Auto,
    /// WGSL compute shaders through wgpu (the best adapter: WGPU_BACKEND and WGPU_ADAPTER_NAME
    /// choose); an error without an adapter.
    Gpu,
    /// The CPU reference (f32 mirror of the GPU, rayon over all cores).
    Cpu,
}

impl From<BackendChoice> for Choice {
    fn from(c: BackendChoice) -> Self {
        match c {
            BackendChoice::Auto => Choice::Auto,
            BackendChoice::Gpu => Choice::Gpu,
            BackendChoice::Cpu => Choice::Cpu,
        }
    }
}

impl From<Choice> for BackendChoice {
    fn from(c: Choice) -> Self {
        match c {
            Choice::Auto => BackendChoice::Auto,
            Choice::Gpu => BackendChoice::Gpu,
            Choice::Cpu => BackendChoice::Cpu,
        }
    }
}
use strahl_gpu::select::{Selected, Workload};

#[derive(Parser, Debug)]
#[command(
    name = "strahl",
    version,
    about = "A ray tracer on WGSL compute shaders, with a CPU reference that proves it right"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a scene file (or a region of it) to a PNG or EXR image.
    Render(render::RenderArgs),
    /// Assemble EXR parts rendered with --region or --tile into one image.
    Merge(merge::MergeArgs),
    /// Answer ray queries from a CSV file: nearest or every intersection per ray.
    Trace(trace::TraceArgs),
    /// Answer point queries: the nearest surface point and the (signed) distance of each point
    /// of a CSV file, or a distance grid over the scene.
    Query(query::QueryArgs),
    /// Measure shader compile and frame times (specialised against all-features shaders), or
    /// with `bench rays` BVH build time and rays per second.
    Bench(bench::BenchArgs),
    /// Run the numerical-stability suite: robust against textbook formulations, CPU and GPU.
    Stiff(stiff::StiffArgs),
    /// Open an interactive window that renders a scene progressively on the GPU.
    #[cfg(feature = "viewer")]
    View(view::ViewArgs),
    /// Open an interactive window (not in this build: it was built without the `viewer` feature).
    #[cfg(not(feature = "viewer"))]
    View(NoViewer),
    /// Measure error against run time of progressive path tracing: CSV, plot and table.
    Converge(converge::ConvergeArgs),
    /// List every GPU adapter of every backend, its limits and whether strahl runs on it.
    Adapters(adapters::AdaptersArgs),
}

/// `strahl view`'s arguments in a build without the viewer: whatever they are, the command
/// says how to get the viewer.
#[cfg(not(feature = "viewer"))]
#[derive(clap::Args, Debug)]
pub struct NoViewer {
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    args: Vec<String>,
}

impl Command {
    /// Whether the command shows a window (and so may present to a display).
    pub fn presents(&self) -> bool {
        matches!(self, Command::View(_))
    }
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Render(a) => render::run(a),
        Command::Merge(a) => merge::run(a),
        Command::Trace(a) => trace::run(a),
        Command::Query(a) => query::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Stiff(a) => stiff::run(a),
        #[cfg(feature = "viewer")]
        Command::View(a) => view::run(a),
        #[cfg(not(feature = "viewer"))]
        Command::View(_) => Err(anyhow::anyhow!(
            "this strahl was built without the viewer (cargo feature `viewer`); build it with the default \
             features, `cargo build --release`, for `strahl view`"
        )),
        Command::Converge(a) => converge::run(a),
        Command::Adapters(a) => adapters::run(a),
    }
}

/// A bad argument found after parsing (a value valid alone but not with the scene or the other
/// flags): printed with the usage and exit status 2, like clap's own errors.
pub fn usage_error(message: impl std::fmt::Display) -> anyhow::Error {
    Cli::command().error(clap::error::ErrorKind::ValueValidation, message).into()
}

/// Fails with a usage error when `width`×`height` exceeds the pixel limit and a flag set one
/// of them (else the scene file is at fault, which names its own error).
pub fn check_image_size(width: u32, height: u32, flags: bool) -> anyhow::Result<()> {
    let max = strahl_core::scene::file::MAX_IMAGE_PIXELS;
    if width as u64 * height as u64 > max {
        let message = format!("--width/--height: {width}x{height} is more than {max} pixels");
        return Err(if flags { usage_error(message) } else { anyhow::anyhow!(message) });
    }
    Ok(())
}

/// `-o`/`--output` of an image: a `.png` or `.exr` file name (checked while parsing).
pub fn image_file_name(s: &str) -> Result<PathBuf, String> {
    file_name_with(s, &["png", "exr"], "use a .png or .exr file name")
}

/// A PNG file name (checked while parsing).
#[cfg(feature = "viewer")]
pub fn png_file_name(s: &str) -> Result<PathBuf, String> {
    file_name_with(s, &["png"], "the screenshot is saved as PNG; use a .png file name")
}

/// A linear EXR image's file name (checked while parsing).
pub fn exr_file_name(s: &str) -> Result<PathBuf, String> {
    file_name_with(s, &["exr"], "the reference must be a linear EXR image; use a .exr file")
}

fn file_name_with(s: &str, extensions: &[&str], hint: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(s);
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if extensions.iter().any(|x| x.eq_ignore_ascii_case(e)) => Ok(path),
        _ => Err(format!("{s}: unknown image format; {hint}")),
    }
}

/// The backend `--backend` asks for or, without the flag, `STRAHL_BACKEND` (else auto), and
/// whether it came from the environment. A bad `STRAHL_BACKEND` is a usage error.
pub fn backend_choice(flag: Option<BackendChoice>) -> anyhow::Result<(BackendChoice, bool)> {
    if let Some(c) = flag {
        return Ok((c, false));
    }
    match Choice::from_env().map_err(usage_error)? {
        Some(c) => Ok((c.into(), true)),
        None => Ok((BackendChoice::Auto, false)),
    }
}

/// Opens the backend for `workload` that `--backend` (`flag`) or `STRAHL_BACKEND` asks for and
/// says on stderr, in one line, which one `auto` took and why (or that the environment forced
/// one); with whether `auto` chose it (neither the flag nor the environment forced one).
pub fn open_backend(flag: Option<BackendChoice>, workload: Workload) -> anyhow::Result<(Selected, bool)> {
    let (choice, from_env) = backend_choice(flag)?;
    let selection = strahl_gpu::select::select(choice.into(), workload)?;
    match (&selection.note, from_env) {
        (Some(note), _) => eprintln!("{note}"),
        (None, true) => eprintln!(
            "backend: {} ({}={})",
            if matches!(selection.selected, Selected::Cpu) { "cpu" } else { "gpu" },
            strahl_gpu::select::ENV,
            std::env::var(strahl_gpu::select::ENV).unwrap_or_default().trim()
        ),
        (None, false) => {}
    }
    Ok((selection.selected, choice == BackendChoice::Auto))
}

/// The result of `gpu`, the job on the GPU; where `auto` chose the GPU and the device fails
/// ([`strahl_gpu::GpuError`]), the result of `cpu` after a line on standard error
/// that says so. Where the user forced the GPU, its error.
pub fn gpu_or_cpu<T>(
    auto: bool,
    gpu: impl FnOnce() -> anyhow::Result<T>,
    cpu: impl FnOnce() -> T,
) -> anyhow::Result<T> {
    match gpu() {
        Err(e) if auto && e.downcast_ref::<strahl_gpu::GpuError>().is_some() => {
            eprintln!("backend: cpu (the gpu failed: {}; running on the cpu instead)", strahl_core::errors::chain(&e));
            Ok(cpu())
        }
        done => done,
    }
}

/// What loading a scene read but did not use (skipped glTF primitives, unsupported
/// extensions...), one `warning:` line each on stderr.
pub fn print_scene_warnings(scene: &strahl_core::scene::Scene) {
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
}

/// The one-line summary of a prepared scene, on stderr, after what loading it warned about.
pub fn print_scene_summary(prep: &strahl_core::render::Prepared) {
    print_scene_warnings(&prep.scene);
    eprintln!(
        "scene: {} objects, {} triangles, BVH {} nodes (depth {}) built in {:.3} s, prepared in {:.3} s",
        prep.scene.objects.len(),
        prep.prims.triangles.len(),
        prep.bvh.nodes.len(),
        prep.bvh.depth,
        prep.build_time.as_secs_f64(),
        prep.prepare_time.as_secs_f64()
    );
}

#[cfg(test)]
mod tests {
    use super::gpu_or_cpu;
    use strahl_gpu::GpuError;

    #[test]
    fn auto_falls_back_to_the_cpu_when_the_gpu_fails_and_a_forced_gpu_does_not() {
        let lost = || -> anyhow::Result<&str> { Err(GpuError::Lost("test".into()).into()) };
        assert_eq!(gpu_or_cpu(true, lost, || "cpu").unwrap(), "cpu");
        let e = gpu_or_cpu(false, lost, || "cpu").unwrap_err();
        assert!(e.to_string().contains("device was lost"), "{e}");
        // Only device errors fall back: a bad scene is the user's to fix on either backend.
        let bad = || -> anyhow::Result<&str> { Err(anyhow::anyhow!("scene.toml: bad")) };
        assert!(gpu_or_cpu(true, bad, || "cpu").is_err());
        assert_eq!(gpu_or_cpu(true, || Ok("gpu"), || "cpu").unwrap(), "gpu");
    }
}
