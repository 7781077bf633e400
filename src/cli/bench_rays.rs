//! `strahl bench rays`: BVH build time, upload time and nearest-hit throughput on one scene,
//! with the ray sets of the Embree anchor benchmark, so the two can be run back to back.

use super::BackendChoice;
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use strahl_core::accel::Bvh;
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::Primitives;
use strahl_core::raysets;
use strahl_core::scene::Scene;
use strahl_cpu::accel::{WideBvh, wide_traverse};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RaySet {
    /// One ray per pixel centre of the scene's camera (coherent).
    Camera,
    /// From a sphere around the scene's bounds to random points of its box (incoherent).
    Random,
}

/// Most rays one run casts (the largest image strahl renders).
const MAX_RAYS: u64 = strahl_core::scene::file::MAX_IMAGE_PIXELS;
/// Random rays when `--count` is not given.
const DEFAULT_RANDOM_RAYS: u64 = 1_000_000;

#[derive(Args, Debug)]
pub struct RaysArgs {
    /// Scene file (.toml), or a mesh (.obj) with the camera in NAME_camera.json beside it
    /// (as `embree_bench.py --export-obj` writes them).
    pub scene: PathBuf,
    /// Where the rays are cast.
    #[arg(long, value_enum, default_value = "cpu")]
    pub backend: BackendChoice,
    /// Threads casting rays on the CPU (default: every core). The build always uses every
    /// core, as Embree's does.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// Which rays.
    #[arg(long, value_enum, default_value = "camera")]
    pub rays: RaySet,
    /// Number of rays. Camera rays: the image is resized to about this many pixels at its
    /// aspect ratio (default: the scene's image; 1024 pixels wide for a mesh). Random rays:
    /// default 1,000,000.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=MAX_RAYS))]
    pub count: Option<u64>,
    /// Timed repetitions of the whole ray set; the median is reported.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub reps: u32,
    /// Print one JSON object instead of the text report.
    #[arg(long)]
    pub json: bool,
    /// CPU: trace one ray at a time, as the renderers do, instead of the batch query that
    /// keeps several rays in flight (as `strahl trace` does).
    #[arg(long)]
    pub one_at_a_time: bool,
}

#[derive(serde::Serialize)]
struct Report {
    scene: String,
    backend: &'static str,
    adapter: Option<String>,
    triangles: usize,
    primitives: usize,
    load_s: f64,
    build_s: f64,
    upload_s: f64,
    sah_cost: f64,
    bvh_depth: u32,
    bytes_per_triangle: f64,
    structure_bytes: u64,
    ray_set: &'static str,
    rays: usize,
    threads: Option<usize>,
    /// CPU: "batch" (nearest_many) or "one at a time" (nearest).
    walk: Option<&'static str>,
    hit_fraction: f64,
    times_s: Vec<f64>,
    median_s: f64,
    mrays_per_s: f64,
    peak_memory_bytes: Option<u64>,
    cpu_scaling: f64,
}

pub fn run(a: RaysArgs) -> Result<()> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let scaling = spin_scaling(cores);
    let start = Instant::now();
    let scene = load(&a.scene)?;
    strahl_core::render::check_memory(&scene, strahl_core::render::available_memory())?;
    let prims = Primitives::<f32>::from_scene(&scene);
    let load_s = start.elapsed().as_secs_f64();
    if prims.bounded_count() == 0 {
        bail!("{}: nothing to aim rays at: the scene has no bounded primitive", a.scene.display());
    }
    // The build: the binary tree and the layout the backend walks (the CPU's 8-wide tree, or
    // the flattened scene with the GPU's collapsed tree), as Embree's build ends with its own.
    let start = Instant::now();
    let bvh = Bvh::build(&prims);
    let wide = (a.backend == BackendChoice::Cpu).then(|| WideBvh::new(&bvh, &prims));
    let flat = wide.is_none().then(|| strahl_core::layout::FlatScene::new(&scene, &prims, &bvh));
    let build_s = start.elapsed().as_secs_f64();

    let root = bvh.nodes[0];
    let (lo, hi) = (V3::from_array(root.bmin).to_f64(), V3::from_array(root.bmax).to_f64());
    let rays = match a.rays {
        RaySet::Camera => {
            let (w, h) = match a.count {
                Some(n) => raysets::camera_size(n, scene.image.width as f64 / scene.image.height as f64),
                None => (scene.image.width, scene.image.height),
            };
            raysets::camera_rays(&scene.camera, w, h)
        }
        RaySet::Random => raysets::random_rays(a.count.unwrap_or(DEFAULT_RANDOM_RAYS) as usize, lo, hi, 1),
    };

    let triangles = prims.triangles.len();
    let (adapter, upload_s, structure_bytes, threads, times, hits) = match (&wide, flat) {
        (Some(wide), _) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(a.threads.map_or(0, |t| t as usize))
                .build()
                .context("starting the ray-casting threads")?;
            let threads = pool.current_num_threads();
            let mut times = Vec::new();
            let mut hits = 0;
            for _ in 0..a.reps {
                let t = Instant::now();
                hits = pool.install(|| cast_cpu(wide, &prims, &rays, a.one_at_a_time));
                times.push(t.elapsed());
            }
            (None, 0.0, wide.bytes() as u64, Some(threads), times, hits)
        }
        (None, flat) => {
            if a.threads.is_some() {
                bail!("--threads applies to --backend cpu only");
            }
            let flat = flat.expect("the GPU layout is built without the CPU's");
            let (adapter, upload_s, bytes, times, hits) = cast_gpu(&flat, &rays, a.reps)?;
            (Some(adapter), upload_s, bytes, None, times, hits)
        }
    };
    let mut sorted = times.clone();
    sorted.sort();
    let median = sorted[sorted.len() / 2].as_secs_f64();
    let report = Report {
        scene: a.scene.display().to_string(),
        backend: if wide.is_some() { "cpu" } else { "gpu" },
        adapter,
        triangles,
        primitives: prims.bounded_count() + prims.planes.len(),
        load_s,
        build_s,
        upload_s,
        sah_cost: bvh.sah_cost(),
        bvh_depth: bvh.depth,
        bytes_per_triangle: structure_bytes as f64 / triangles.max(1) as f64,
        structure_bytes,
        ray_set: match a.rays {
            RaySet::Camera => "camera",
            RaySet::Random => "random",
        },
        rays: rays.len(),
        threads,
        walk: wide.as_ref().map(|_| if a.one_at_a_time { "one at a time" } else { "batch" }),
        hit_fraction: hits as f64 / rays.len() as f64,
        times_s: times.iter().map(Duration::as_secs_f64).collect(),
        median_s: median,
        mrays_per_s: rays.len() as f64 / median / 1e6,
        peak_memory_bytes: peak_memory(),
        cpu_scaling: scaling,
    };
    if a.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_report(&report, cores);
    }
    Ok(())
}

fn load(path: &Path) -> Result<Scene> {
    Ok(strahl_core::scene::procedural::scene_or_obj(path)?)
}

/// Nearest hits of `rays` on the current rayon pool, as a batch query or one ray at a time;
/// returns how many hit.
fn cast_cpu(wide: &WideBvh, prims: &Primitives<f32>, rays: &[Ray<f32>], one_at_a_time: bool) -> usize {
    rays.par_chunks(4096)
        .map(|chunk| {
            if one_at_a_time {
                chunk.iter().filter(|r| wide_traverse::nearest(wide, prims, r, 0.0, f32::INFINITY).is_some()).count()
            } else {
                let mut out = vec![None; chunk.len()];
                wide_traverse::nearest_many(wide, prims, chunk, 0.0, f32::INFINITY, &mut out);
                out.iter().filter(|h| h.is_some()).count()
            }
        })
        .sum()
}

/// Uploads the flattened scene `gpu` and casts `rays` through `strahl trace`'s GPU path `reps`
/// times: (adapter, upload seconds, bytes of the walk's nodes, triangles and references, times,
/// hits).
fn cast_gpu(
    gpu: &strahl_core::layout::FlatScene,
    rays: &[Ray<f32>],
    reps: u32,
) -> Result<(String, f64, u64, Vec<Duration>, usize)> {
    use strahl_core::query::RayQuery;
    use strahl_gpu::{GpuContext, SceneBuffers, trace};
    let ctx = GpuContext::new()?;
    let start = Instant::now();
    let buffers = SceneBuffers::upload(&ctx, gpu)?;
    let upload_s = start.elapsed().as_secs_f64();
    // What the walk reads: nodes, leaf-order triangles and shape references.
    let bytes = std::mem::size_of_val(gpu.leaf_triangles.as_slice())
        + std::mem::size_of_val(gpu.nodes.as_slice())
        + std::mem::size_of_val(gpu.shape_refs.as_slice());
    let queries: Vec<RayQuery> = rays
        .iter()
        .map(|r| RayQuery { origin: r.origin.to_f64(), dir: r.dir.to_f64(), tmin: 0.0, tmax: f64::INFINITY })
        .collect();
    // The first batch compiles the pipeline (lavapipe compiles at the first dispatch).
    trace::trace(&ctx, &buffers, &queries[..queries.len().min(64)], false)?;
    let mut times = Vec::new();
    let mut hits = 0;
    for _ in 0..reps {
        let t = Instant::now();
        let out = trace::trace(&ctx, &buffers, &queries, false)?;
        times.push(t.elapsed());
        hits = out.iter().filter(|h| !h.is_empty()).count();
    }
    Ok((ctx.adapter_name(), upload_s, bytes as u64, times, hits))
}

fn print_report(r: &Report, cores: usize) {
    println!("scene: {} ({} triangles, {} primitives)", r.scene, r.triangles, r.primitives);
    if let Some(adapter) = &r.adapter {
        println!("adapter: {adapter}");
    }
    println!(
        "cores: {cores} reported, spin-loop scaling {cores} threads vs 1: {:.2}x (about {:.1} delivered)",
        r.cpu_scaling, r.cpu_scaling
    );
    println!("load + flatten: {:.3} s", r.load_s);
    println!(
        "BVH build: {:.3} s ({:.2} M triangles/s), SAH cost {:.2}, depth {}",
        r.build_s,
        r.triangles as f64 / r.build_s / 1e6,
        r.sah_cost,
        r.bvh_depth
    );
    if r.backend == "gpu" {
        println!("upload: {:.3} s", r.upload_s);
    }
    println!(
        "{}: {:.1} bytes per triangle ({:.1} MiB)",
        if r.backend == "cpu" { "8-wide nodes + leaf blocks" } else { "GPU triangles + nodes + references" },
        r.bytes_per_triangle,
        r.structure_bytes as f64 / (1 << 20) as f64
    );
    let threads = r.threads.map_or(String::new(), |t| format!(", {t} thread{}", if t == 1 { "" } else { "s" }));
    let threads = match r.walk {
        Some(walk) => format!("{threads}, {walk}"),
        None => threads,
    };
    println!(
        "{} rays x{} on the {}{threads}: median {:.3} s -> {:.2} M rays/s, {:.1}% hit (reps {})",
        r.ray_set,
        r.rays,
        r.backend,
        r.median_s,
        r.mrays_per_s,
        100.0 * r.hit_fraction,
        r.times_s.iter().map(|t| format!("{t:.3}")).collect::<Vec<_>>().join(", ")
    );
    if let Some(peak) = r.peak_memory_bytes {
        println!("peak memory: {:.0} MiB", peak as f64 / (1 << 20) as f64);
    }
}

/// How many cores the machine delivers now: the work `n` threads spinning for a moment get
/// done, over what one thread gets done (the anchor scripts' spin-loop check).
fn spin_scaling(n: usize) -> f64 {
    let spin = |threads: usize| -> u64 {
        let dur = Duration::from_millis(300);
        std::thread::scope(|s| {
            let hs: Vec<_> = (0..threads)
                .map(|_| {
                    s.spawn(move || {
                        let t = Instant::now();
                        let mut k = 0u64;
                        while t.elapsed() < dur {
                            for _ in 0..1000 {
                                k = std::hint::black_box(k + 1);
                            }
                        }
                        k
                    })
                })
                .collect();
            hs.into_iter().map(|h| h.join().unwrap_or(0)).sum()
        })
    };
    let one = spin(1).max(1);
    spin(n) as f64 / one as f64
}

/// The process's peak resident memory (VmHWM), where the system reports it.
fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
