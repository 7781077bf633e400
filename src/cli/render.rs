//! `strahl render`.

use super::{BackendChoice, progress_bar};
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;
use strahl::render::Prepared;
use strahl::scene::Scene;

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output image: .png (8-bit sRGB) or .exr (linear float).
    #[arg(short, long)]
    pub output: PathBuf,
    #[arg(long, value_enum, default_value = "cpu")]
    pub backend: BackendChoice,
    /// Image width (default: the scene's [image] width).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,
    /// Image height (default: the scene's [image] height).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,
    /// Samples per pixel (default: the scene's [render] spp).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub spp: Option<u32>,
}

pub fn run(a: RenderArgs) -> Result<()> {
    check_output_extension(&a.output)?;
    let mut scene = Scene::load(&a.scene)?;
    if let Some(spp) = a.spp {
        scene.render.spp = spp;
    }
    let width = a.width.unwrap_or(scene.image.width);
    let height = a.height.unwrap_or(scene.image.height);
    if width as u64 * height as u64 > strahl::scene::file::MAX_IMAGE_PIXELS {
        bail!("{width}x{height} is more than {} pixels", strahl::scene::file::MAX_IMAGE_PIXELS);
    }
    let prep = Prepared::new(scene);
    eprintln!(
        "scene: {} objects, {} triangles, BVH {} nodes (depth {}) built in {:.3} s",
        prep.scene.objects.len(),
        prep.prims.triangles.len(),
        prep.bvh.nodes.len(),
        prep.bvh.depth,
        prep.build_time.as_secs_f64()
    );
    let frame = prep.frame(width, height);
    let start = Instant::now();
    let image = match a.backend {
        BackendChoice::Cpu => {
            let bar = progress_bar(height as u64, "cpu");
            let img = strahl::backend::cpu::render(&prep, &frame, &|rows| bar.set_position(rows));
            bar.finish_and_clear();
            img
        }
        BackendChoice::Gpu => bail!("the GPU backend is not available in this build yet; use --backend cpu"),
    };
    let secs = start.elapsed().as_secs_f64();
    let samples = width as f64 * height as f64 * frame.spp as f64;
    println!(
        "rendered {width}x{height} at {} spp on {} in {secs:.3} s: {:.2} M primary rays/s",
        frame.spp,
        backend_name(a.backend),
        samples / secs / 1e6
    );
    image.save(&a.output).with_context(|| format!("writing {}", a.output.display()))?;
    println!("wrote {}", a.output.display());
    Ok(())
}

fn backend_name(b: BackendChoice) -> String {
    match b {
        BackendChoice::Cpu => format!("cpu ({} threads)", rayon::current_num_threads()),
        BackendChoice::Gpu => "gpu".into(),
    }
}

/// Fails before any work when the output format is unknown.
fn check_output_extension(path: &std::path::Path) -> Result<()> {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("png" | "exr") => Ok(()),
        _ => bail!("{}: unknown image format; use a .png or .exr file name", path.display()),
    }
}
