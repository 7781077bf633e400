//! `strahl converge`: error against wall time of progressive path tracing, per backend.

use super::BackendChoice;
use super::progress::Progress;
use anyhow::{Context, Result, bail, ensure};
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use strahl::converge::{Progressive, Row, Schedule};
use strahl_core::image::Image;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene};
use strahl_cpu as cpu;
use strahl_gpu::select::{self, Selected, Workload};
use strahl_gpu::{self as gpu, SceneBuffers};

/// Which backends to measure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ConvergeBackend {
    /// The one `strahl render --mode path` would take (see `--backend auto` there).
    Auto,
    Gpu,
    Cpu,
    /// The GPU and the CPU, one after the other (the CPU alone, with a note, without a Vulkan
    /// adapter).
    Both,
}

impl From<BackendChoice> for ConvergeBackend {
    fn from(c: BackendChoice) -> Self {
        match c {
            BackendChoice::Auto => Self::Auto,
            BackendChoice::Gpu => Self::Gpu,
            BackendChoice::Cpu => Self::Cpu,
        }
    }
}

#[derive(Args, Debug)]
pub struct ConvergeArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Which backends to measure (default: STRAHL_BACKEND, else auto).
    #[arg(long, value_enum)]
    pub backend: Option<ConvergeBackend>,
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
    /// Backend that renders the reference (default: auto, the faster one for path tracing).
    #[arg(long, value_enum, default_value = "auto")]
    pub reference_backend: BackendChoice,
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
    /// Also measure each checkpoint's image denoised (as `strahl render --denoise` would at
    /// that sample count), its time the samples' plus the guides' and the denoiser's.
    #[arg(long)]
    pub denoise: bool,
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
    strahl_core::output::check_dir_target(&a.output)?;
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
    let which = match a.backend {
        Some(b) => b,
        None => super::backend_choice(None)?.0.into(),
    };
    let mut measured = Vec::new();
    let mut open = |selected: Selected| -> Result<()> {
        measured.push(open_progressive(&prep, selected, width, height, MEASURED_SEED)?);
        Ok(())
    };
    match which {
        ConvergeBackend::Auto => open(super::open_backend(Some(BackendChoice::Auto), Workload::Path)?.0)?,
        ConvergeBackend::Cpu => open(Selected::Cpu)?,
        ConvergeBackend::Gpu => {
            open(super::open_backend(Some(BackendChoice::Gpu), Workload::Path)?.0).context("opening the gpu backend")?
        }
        ConvergeBackend::Both => {
            match select::select(BackendChoice::Gpu.into(), Workload::Path)
                .map_err(anyhow::Error::from)
                .and_then(|s| open(s.selected))
            {
                Ok(()) => {}
                Err(e) => {
                    eprintln!("gpu backend unavailable ({}); measuring the cpu only", strahl_core::errors::chain(&e))
                }
            }
            open(Selected::Cpu)?;
        }
    }

    let reference = match reference_input {
        Some(img) => img,
        None => {
            if a.max_spp.saturating_mul(4) > a.reference_spp {
                eprintln!(
                    "note: the reference ({} spp) is not much less noisy than the last measured image \
                     ({} spp); its own noise adds to the errors measured there",
                    a.reference_spp, a.max_spp
                );
            }
            render_reference(&prep, a.reference_backend, width, height, a.reference_spp)?
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
    for p in measured {
        println!("{}:", p.label());
        let pixels = width as u64 * height as u64;
        let progress = Progress::new(pixels * a.max_spp as u64, p.backend());
        let mut p = Tracked { inner: p, progress: &progress, pixels };
        let mut on_row = |r: &Row| {
            rows.push(r.clone());
            strahl::converge::write_csv(&rows, &csv)?;
            progress.suspend(|| print_row(r));
            Ok(())
        };
        strahl::converge::measure(&mut p, &reference, &schedule, a.denoise, &mut on_row)?;
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

/// The progressive path tracer of the `selected` backend for `prep` at width×height, with its
/// pipeline compiled and warmed up (one discarded pass) so that timing starts with rendering
/// only.
fn open_progressive(
    prep: &Arc<Prepared>,
    selected: Selected,
    width: u32,
    height: u32,
    seed: u32,
) -> Result<Box<dyn Progressive>> {
    let mut frame = prep.frame(width, height);
    frame.seed = seed;
    Ok(match selected {
        Selected::Cpu => Box::new(cpu::PathAccumulator::new(prep.clone(), frame)),
        Selected::Gpu(ctx) => {
            let ctx = Arc::new(*ctx);
            let buffers = SceneBuffers::upload(&ctx, &prep.flat)?;
            let mut p = gpu::tiles::PathAccumulator::new(ctx, buffers, frame)?;
            // lavapipe compiles the shader at its first dispatch.
            p.add_samples(1)?;
            p.reset();
            Box::new(p)
        }
    })
}

/// Renders `spp` samples per pixel on the backend `choice` takes for path tracing, in chunks,
/// with progress.
fn render_reference(prep: &Arc<Prepared>, choice: BackendChoice, width: u32, height: u32, spp: u32) -> Result<Image> {
    let selection = select::select(choice.into(), Workload::Path).context("opening the backend for the reference")?;
    if let Some(note) = &selection.note {
        eprintln!("reference {note}");
    }
    let id = match selection.selected {
        Selected::Cpu => "cpu",
        Selected::Gpu(_) => "gpu",
    };
    let mut p = open_progressive(prep, selection.selected, width, height, REFERENCE_SEED)
        .with_context(|| format!("opening the {id} backend for the reference"))?;
    println!("reference: rendering {spp} spp on the {id} backend");
    let pixels = width as u64 * height as u64;
    let progress = Progress::new(pixels * spp as u64, "reference");
    while p.samples() < spp {
        p.add_samples(REFERENCE_CHUNK.min(spp - p.samples()))?;
        progress.set(p.samples() as u64 * pixels);
    }
    progress.finish();
    p.image()
}

/// A measured backend with progress: each call adds its samples in up to [`TRACKED_PIECES`]
/// pieces (the same samples in the same order, so the same image) and reports after each.
struct Tracked<'a> {
    inner: Box<dyn Progressive>,
    progress: &'a Progress,
    pixels: u64,
}

/// Pieces per [`Progressive::add_samples`] call of a measured backend: enough for the progress
/// to move during the long last steps of a doubling schedule; each piece costs one wait for
/// the device, a small part of a piece's time.
const TRACKED_PIECES: u32 = 8;

impl Progressive for Tracked<'_> {
    fn label(&self) -> String {
        self.inner.label()
    }
    fn backend(&self) -> &'static str {
        self.inner.backend()
    }
    fn add_samples(&mut self, n: u32) -> Result<()> {
        let piece = n.div_ceil(TRACKED_PIECES).max(1);
        let end = self.inner.samples() + n;
        while self.inner.samples() < end {
            self.inner.add_samples(piece.min(end - self.inner.samples()))?;
            self.progress.set(self.inner.samples() as u64 * self.pixels);
        }
        Ok(())
    }
    fn samples(&self) -> u32 {
        self.inner.samples()
    }
    fn image(&mut self) -> Result<Image> {
        self.inner.image()
    }
    fn denoised(&mut self) -> Result<(Image, f64)> {
        self.inner.denoised()
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
