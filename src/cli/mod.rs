//! Subcommands of `strahl`.

mod bench;
mod converge;
mod render;
mod stiff;
mod trace;
mod view;

use clap::{CommandFactory, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

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
    /// Render a scene file to a PNG or EXR image.
    Render(render::RenderArgs),
    /// Answer ray queries from a CSV file: nearest or every intersection per ray.
    Trace(trace::TraceArgs),
    /// Measure shader compile and frame times: specialised against all-features shaders.
    Bench(bench::BenchArgs),
    /// Run the numerical-stability suite: robust against textbook formulations, CPU and GPU.
    Stiff(stiff::StiffArgs),
    /// Open an interactive window that renders a scene progressively on the GPU.
    View(view::ViewArgs),
    /// Measure error against run time of progressive path tracing: CSV, plot and table.
    Converge(converge::ConvergeArgs),
}

/// Where the work runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendChoice {
    /// WGSL compute shaders through wgpu (Vulkan).
    Gpu,
    /// The CPU reference (f32 mirror of the GPU, rayon over all cores).
    Cpu,
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Render(a) => render::run(a),
        Command::Trace(a) => trace::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Stiff(a) => stiff::run(a),
        Command::View(a) => view::run(a),
        Command::Converge(a) => converge::run(a),
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
    let max = strahl::scene::file::MAX_IMAGE_PIXELS;
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

/// What loading a scene read but did not use (skipped glTF primitives, unsupported
/// extensions...), one `warning:` line each on stderr.
pub fn print_scene_warnings(scene: &strahl::scene::Scene) {
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
}

/// A progress bar on stderr for `len` steps (hidden when stderr is not a terminal).
pub fn progress_bar(len: u64, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// The one-line summary of a prepared scene, on stderr, after what loading it warned about.
pub fn print_scene_summary(prep: &strahl::render::Prepared) {
    print_scene_warnings(&prep.scene);
    eprintln!(
        "scene: {} objects, {} triangles, BVH {} nodes (depth {}) built in {:.3} s",
        prep.scene.objects.len(),
        prep.prims.triangles.len(),
        prep.bvh.nodes.len(),
        prep.bvh.depth,
        prep.build_time.as_secs_f64()
    );
}
