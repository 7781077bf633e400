//! The stiff cases of `strahl stiff`, each run on the variants asked for: quadrics
//! ([`quadrics`]), spawned rays ([`spawn`]), closed and thin meshes ([`meshes`]) and whole
//! scenes ([`scenes`]).

mod meshes;
mod quadrics;
mod scenes;
mod spawn;

pub use meshes::*;
pub use quadrics::*;
pub use scenes::*;
pub use spawn::*;

use super::{Row, Stats, Variant, oracle, rel_err, textbook, ulps};
use std::time::Instant;
use strahl_core::accel::Bvh;
use strahl_core::layout::FlatScene;
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::Primitives;
use strahl_core::query::RayQuery;
use strahl_core::scene::{Camera, ImageSize, Scene};
use strahl_gpu::{GpuContext, GpuError, SceneBuffers};

/// Where and how much to run.
pub struct Options<'a> {
    pub cpu: bool,
    pub gpu: Option<&'a GpuContext>,
    /// Fraction of the full ray counts (1.0: the counts the issue asks for).
    pub scale: f64,
}

impl Options<'_> {
    fn n(&self, full: usize) -> usize {
        ((full as f64 * self.scale) as usize).max(1)
    }
    fn variants(&self) -> Vec<Variant> {
        let mut v = Vec::new();
        if self.cpu {
            v.push(Variant::Cpu);
        }
        if self.gpu.is_some() {
            v.push(Variant::Gpu);
        }
        if self.cpu {
            v.push(Variant::Textbook);
        }
        v
    }
}

/// The cases' generator.
pub use strahl_core::rng::SplitMix64 as Rng;

/// A ray as strahl takes it: f64 origin and direction rounded to f32.
fn ray32(o: V3<f64>, d: V3<f64>) -> Ray<f32> {
    Ray::new(o.cast(), d.normalize().cast())
}

/// A scene of just these primitives (one grey material, no lights), for the GPU.
fn upload(ctx: &GpuContext, prims: &Primitives<f32>) -> Result<SceneBuffers, GpuError> {
    let camera = Camera { eye: V3::new(0.0, 0.0, -1.0), look_at: V3::zero(), up: V3::new(0.0, 1.0, 0.0), fov_y: 45.0 };
    let scene = Scene::empty(camera, ImageSize { width: 1, height: 1 });
    SceneBuffers::upload(ctx, &FlatScene::new(&scene, prims, &Bvh::build(prims)))
}

fn query(r: &Ray<f32>) -> RayQuery {
    RayQuery { origin: r.origin.to_f64(), dir: r.dir.to_f64(), tmin: 0.0, tmax: f64::INFINITY }
}

/// One shape and the rays shot at it.
pub struct Group {
    pub shape: Quadric,
    pub rays: Vec<Ray<f32>>,
}

/// A case run on every variant the options ask for, in one loop for all cases: `measure`
/// runs the case on a variant and returns its row (None: the variant renders nothing), and
/// this names the variant in the row and times the run per ray.
fn each_variant(
    opt: &Options,
    mut measure: impl FnMut(Variant) -> Result<Option<Row>, GpuError>,
) -> Result<Vec<Row>, GpuError> {
    let mut rows = Vec::new();
    for variant in opt.variants() {
        let start = Instant::now();
        let Some(row) = measure(variant)? else { continue };
        let ns_per_ray = start.elapsed().as_nanos() as f64 / row.rays.max(1) as f64;
        rows.push(Row { variant: Some(variant), ns_per_ray, ..row });
    }
    Ok(rows)
}

/// Every case, in table order.
pub fn run_all(opt: &Options) -> Result<Vec<Row>, GpuError> {
    let mut rng = Rng(0x5EED);
    let shapes = opt.n(100).max(4);
    let per = |full: usize| (opt.n(full * 100) / shapes).max(8);
    let mut rows = Vec::new();
    rows.extend(quadric_case("small sphere 1e3..1e5 away", &small_far_spheres(shapes, per(1000), &mut rng), opt)?);
    rows.extend(quadric_case(
        "origin 1e-2 outside huge sphere r=1e4..1e6",
        &huge_spheres_near_origin(shapes, per(1000), &mut rng),
        opt,
    )?);
    rows.extend(quadric_case(
        "tangent/grazing spheres (1 +- 1e-k)",
        &tangent_spheres(shapes, per(700), &mut rng),
        opt,
    )?);
    rows.extend(quadric_case("grazing cylinders, caps edge-on", &grazing_cylinders(shapes, per(800), &mut rng), opt)?);
    rows.extend(quadric_case("rays parallel to cylinder axis", &parallel_to_axis(shapes, per(400), &mut rng), opt)?);
    rows.extend(quadric_case("thin cylinders r=1e-4", &extreme_cylinders(shapes, per(500), 1e-4, &mut rng), opt)?);
    rows.extend(quadric_case("fat cylinders r=1e4", &extreme_cylinders(shapes, per(500), 1e4, &mut rng), opt)?);
    let spawn_shapes = opt.n(1000).max(10);
    rows.extend(spawned_rays(spawn_shapes, (opt.n(1_000_000) / spawn_shapes).max(10), opt, &mut rng)?);
    rows.extend(closed_mesh_leaks(opt.n(10_000_000).max(1000), opt, &mut rng)?);
    rows.extend(thin_triangles(opt.n(1000).max(8), 100, opt, &mut rng)?);
    rows.extend(far_from_origin(opt)?);
    rows.extend(scaled_scenes(opt)?);
    Ok(rows)
}
