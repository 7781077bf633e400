//! `strahl converge`: error against wall time of progressive path tracing, per backend.

use super::{BackendChoice, progress_bar};
use anyhow::{Context, Result, bail, ensure};
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use strahl::backend::cpu;
use strahl::backend::gpu::{self, GpuContext, SceneBuffers};
use strahl::converge::{Progressive, Row, Schedule};
use strahl::image::Image;
use strahl::render::Prepared;
use strahl::scene::{RenderMode, Scene};

/// Which backends to measure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ConvergeBackend {
    Gpu,
    Cpu,
    Both,
}

impl ConvergeBackend {
    fn list(self) -> Vec<BackendChoice> {
        match self {
            Self::Gpu => vec![BackendChoice::Gpu],
            Self::Cpu => vec![BackendChoice::Cpu],
            Self::Both => vec![BackendChoice::Gpu, BackendChoice::Cpu],
        }
    }
}

#[derive(Args, Debug)]
pub struct ConvergeArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Which backends to measure.
    #[arg(long, value_enum, default_value = "both")]
    pub backend: ConvergeBackend,
    /// Reference image (linear EXR) at the render size; default: render one.
    #[arg(
        long,
        value_name = "REF.exr",
        value_parser = super::exr_file_name,
        conflicts_with_all = ["reference_spp", "reference_backend"]
    )]
    pub reference: Option<PathBuf>,
    /// Samples per pixel of the rendered reference.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub reference_spp: u32,
    /// Backend that renders the reference (default: gpu when it is measured, else cpu).
    #[arg(long, value_enum)]
    pub reference_backend: Option<BackendChoice>,
    /// Most samples per pixel per backend: measured at 1, 2, 4, ... and this.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub max_spp: u32,
    /// Render each backend for this many seconds instead (at most --max-spp samples per pixel).
    #[arg(long, value_name = "S", value_parser = positive_seconds)]
    pub time: Option<f64>,
    /// Image width (default: the scene's [image] width).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,
    /// Image height (default: the scene's [image] height).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,
    /// Directory for reference.exr, convergence.csv and convergence.png (created if missing).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
}

fn positive_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|_| format!("not a number: {s:?}"))?;
    if v.is_finite() && v > 0.0 { Ok(v) } else { Err(format!("must be a positive number of seconds, not {s}")) }
}

/// Samples per pixel added per step of the reference render, so that its progress bar moves.
const REFERENCE_CHUNK: u32 = 16;

pub fn run(a: ConvergeArgs) -> Result<()> {
    if let (Some(w), Some(h)) = (a.width, a.height) {
        super::check_image_size(w, h, true)?;
    }
    // Problems with the output folder or the reference surface before any work.
    strahl::output::check_dir_target(&a.output)?;
    if let Some(r) = &a.reference
        && !r.is_file()
    {
        bail!("{}: no such reference image", r.display());
    }
    let mut scene = Scene::load(&a.scene)?;
    scene.render.mode = RenderMode::Path;
    let width = a.width.unwrap_or(scene.image.width);
    let height = a.height.unwrap_or(scene.image.height);
    super::check_image_size(width, height, a.width.is_some() || a.height.is_some())?;
    let schedule = match a.time {
        Some(seconds) => Schedule::FixedTime { seconds, max_spp: a.max_spp },
        None => Schedule::Doubling { max_spp: a.max_spp },
    };
    let reference_input = match &a.reference {
        Some(path) => Some(load_reference(path, width, height)?),
        None => None,
    };

    let prep = Arc::new(Prepared::try_new(scene)?);
    super::print_scene_summary(&prep);

    // Every measured backend is opened (and the GPU's pipeline compiled) before anything is
    // rendered or written: without a GPU, `both` measures the CPU alone, `gpu` fails here.
    let mut measured = Vec::new();
    for backend in a.backend.list() {
        match open_backend(&prep, backend, width, height, MEASURED_SEED) {
            Ok(p) => measured.push(p),
            Err(e) if a.backend == ConvergeBackend::Both && backend == BackendChoice::Gpu => {
                eprintln!("gpu backend unavailable ({}); measuring the cpu only", strahl::errors::chain(&e));
            }
            Err(e) => return Err(e.context(format!("opening the {} backend", backend_id(backend)))),
        }
    }
    let gpu_measured = measured.iter().any(|p| p.backend() == "gpu");

    let reference = match reference_input {
        Some(img) => img,
        None => {
            let backend =
                a.reference_backend.unwrap_or(if gpu_measured { BackendChoice::Gpu } else { BackendChoice::Cpu });
            if a.max_spp.saturating_mul(4) > a.reference_spp {
                eprintln!(
                    "note: the reference ({} spp) is not much less noisy than the last measured image \
                     ({} spp); its own noise adds to the errors measured there",
                    a.reference_spp, a.max_spp
                );
            }
            render_reference(&prep, backend, width, height, a.reference_spp)?
        }
    };
    let bad = reference.non_finite_count();
    ensure!(bad == 0, "the reference has {bad} non-finite (NaN or infinite) pixels");

    // The folder holds one run: the previous run's files go before this run writes any.
    let out = RunFolder::start(&a.output, a.reference.as_deref())?;
    if a.reference.is_none() {
        let path = out.path(REFERENCE_FILE);
        reference.save(&path)?;
        println!("reference: {} spp, wrote {}", a.reference_spp, path.display());
    } else if let Some(path) = &a.reference {
        println!("reference: {}", path.display());
    }

    // The CSV is rewritten (atomically) after every row: an interrupted run keeps its rows.
    let csv = out.path(CSV_FILE);
    let mut rows = Vec::new();
    for mut p in measured {
        println!("{}:", p.label());
        let mut on_row = |r: &Row| {
            rows.push(r.clone());
            strahl::converge::write_csv(&rows, &csv)?;
            print_row(r);
            Ok(())
        };
        strahl::converge::measure(p.as_mut(), &reference, &schedule, &mut on_row)?;
    }
    let png = out.path(PLOT_FILE);
    strahl::converge::plot(&rows, &plot_title(&a.scene, width, height), &png)?;
    println!();
    print!("{}", strahl::converge::table(&rows));
    println!();
    println!("wrote {}", csv.display());
    println!("wrote {}", png.display());
    Ok(())
}

const REFERENCE_FILE: &str = "reference.exr";
const CSV_FILE: &str = "convergence.csv";
const PLOT_FILE: &str = "convergence.png";

/// The output folder of one run. [`RunFolder::start`] creates it if missing and removes the
/// files an earlier run left there (except an input reference among them), so the folder never
/// holds a mix of two runs.
struct RunFolder {
    dir: PathBuf,
}

impl RunFolder {
    fn start(dir: &Path, keep: Option<&Path>) -> Result<Self> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let keep = keep.and_then(|k| k.canonicalize().ok());
        for name in [REFERENCE_FILE, CSV_FILE, PLOT_FILE] {
            let old = dir.join(name);
            if old.is_file() && old.canonicalize().ok() != keep {
                std::fs::remove_file(&old)
                    .with_context(|| format!("cannot remove the earlier run's {}", old.display()))?;
            }
        }
        Ok(Self { dir: dir.to_path_buf() })
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }
}

/// The reference image at `path`: a linear OpenEXR file (by its contents, not only its name)
/// of the render size.
fn load_reference(path: &Path, width: u32, height: u32) -> Result<Image> {
    let format = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| anyhow::anyhow!("cannot read image {}: {e}", path.display()))?
        .format();
    ensure!(
        format == Some(image::ImageFormat::OpenExr),
        "{}: the reference must be a linear OpenEXR image; this file is {}",
        path.display(),
        format.map_or("of an unknown format".to_string(), |f| format!("{f:?}"))
    );
    let img = Image::load(path)?;
    ensure!(
        (img.width, img.height) == (width, height),
        "{}: the reference is {}x{}, the render size is {width}x{height}",
        path.display(),
        img.width,
        img.height
    );
    Ok(img)
}

/// Seed of the measured runs; the rendered reference uses [`REFERENCE_SEED`], so its noise is
/// independent of theirs.
const MEASURED_SEED: u32 = 0;
const REFERENCE_SEED: u32 = 0x9e37_79b9;

/// The progressive path tracer of `backend` for `prep` at width×height, with its pipeline
/// compiled and warmed up (one discarded pass) so that timing starts with rendering only.
fn open_backend(
    prep: &Arc<Prepared>,
    backend: BackendChoice,
    width: u32,
    height: u32,
    seed: u32,
) -> Result<Box<dyn Progressive>> {
    let mut frame = prep.frame(width, height);
    frame.seed = seed;
    Ok(match backend {
        BackendChoice::Cpu => Box::new(cpu::Progressive::new(prep.clone(), frame)),
        BackendChoice::Gpu => {
            let ctx = Arc::new(GpuContext::new()?);
            let buffers = SceneBuffers::upload(&ctx, &prep.gpu)?;
            let mut p = gpu::render::Progressive::new(ctx, buffers, frame)?;
            // lavapipe compiles the shader at its first dispatch.
            p.add_samples(1)?;
            p.reset();
            Box::new(p)
        }
    })
}

/// Renders `spp` samples per pixel on `backend`, in chunks under a progress bar.
fn render_reference(prep: &Arc<Prepared>, backend: BackendChoice, width: u32, height: u32, spp: u32) -> Result<Image> {
    let mut p = open_backend(prep, backend, width, height, REFERENCE_SEED)
        .with_context(|| format!("opening the {} backend for the reference", backend_id(backend)))?;
    println!("reference: rendering {spp} spp on the {} backend", backend_id(backend));
    let bar = progress_bar(spp as u64, &format!("reference ({})", backend_id(backend)));
    while p.samples() < spp {
        p.add_samples(REFERENCE_CHUNK.min(spp - p.samples()))?;
        bar.set_position(p.samples() as u64);
    }
    bar.finish_and_clear();
    p.image()
}

fn backend_id(b: BackendChoice) -> &'static str {
    match b {
        BackendChoice::Gpu => "gpu",
        BackendChoice::Cpu => "cpu",
    }
}

fn print_row(r: &Row) {
    let e = &r.errors;
    println!(
        "  {} {:>6} spp {:>9.3} s  RMSE {:.5}  clamped {:.5}  relMSE {:.3e}  FLIP {:.4}",
        r.backend, r.spp, r.seconds, e.rmse, e.rmse_clamped, e.rel_mse, e.mean_flip
    );
}

/// "seed.toml (640x480): RMSE against wall time".
fn plot_title(scene: &Path, width: u32, height: u32) -> String {
    let name = scene.file_name().map_or_else(|| scene.display().to_string(), |n| n.to_string_lossy().into_owned());
    format!("{name} ({width}x{height}): RMSE against wall time")
}
