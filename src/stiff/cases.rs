//! The stiff cases of `strahl stiff`, each run on the variants asked for.

use super::{Row, Stats, Variant, oracle, rel_err, textbook, ulps};
use crate::accel::{Bvh, traverse};
use crate::backend::gpu::{GpuContext, GpuError, SceneBuffers, trace};
use crate::geometry::{Cylinder, Part, Shape, Sphere, Triangle};
use crate::gpu_types::GpuScene;
use crate::math::{Ray, V3};
use crate::primitives::{PrimKind, PrimRef, Primitives, Tag, Tagged};
use crate::query::RayQuery;
use crate::scene::{Camera, ImageSize, Material, RenderMode, RenderSettings, Scene};
use std::time::Instant;

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
pub use crate::rng::SplitMix64 as Rng;

/// A ray as strahl takes it: f64 origin and direction rounded to f32.
fn ray32(o: V3<f64>, d: V3<f64>) -> Ray<f32> {
    Ray::new(o.cast(), d.normalize().cast())
}

/// A scene of just these primitives (one grey material, no lights), for the GPU.
fn upload(ctx: &GpuContext, prims: &Primitives<f32>) -> Result<SceneBuffers, GpuError> {
    let scene = Scene {
        camera: Camera { eye: V3::new(0.0, 0.0, -1.0), look_at: V3::zero(), up: V3::new(0.0, 1.0, 0.0), fov_y: 45.0 },
        image: ImageSize { width: 1, height: 1 },
        render: RenderSettings::default(),
        materials: vec![Material::default_grey()],
        objects: Vec::new(),
        lights: Vec::new(),
        textures: Vec::new(),
        environment: None,
        warnings: Vec::new(),
    };
    SceneBuffers::upload(ctx, &GpuScene::new(&scene, prims, &Bvh::build(prims)))
}

fn query(r: &Ray<f32>) -> RayQuery {
    RayQuery { origin: r.origin.to_f64(), dir: r.dir.to_f64(), tmin: 0.0, tmax: f64::INFINITY }
}

#[derive(Clone, Copy, Debug)]
pub enum Quadric {
    Sphere(Sphere<f32>),
    Cylinder(Cylinder<f32>),
}

impl Quadric {
    fn robust(&self, r: &Ray<f32>) -> Vec<f32> {
        let roots = match self {
            Quadric::Sphere(s) => s.roots(r, 0.0, f32::INFINITY),
            Quadric::Cylinder(c) => c.roots(r, 0.0, f32::INFINITY),
        };
        roots.iter().map(|(t, _)| t).collect()
    }
    fn textbook(&self, r: &Ray<f32>) -> Vec<f32> {
        match self {
            Quadric::Sphere(s) => textbook::sphere_roots(s, r, 0.0, f32::INFINITY),
            Quadric::Cylinder(c) => textbook::cylinder_roots(c, r, 0.0, f32::INFINITY),
        }
    }
    fn oracle(&self, r: &Ray<f32>) -> (Vec<f64>, bool) {
        match self {
            Quadric::Sphere(s) => oracle::sphere_roots(s, r),
            Quadric::Cylinder(c) => oracle::cylinder(c, r),
        }
    }
    fn prims(&self) -> Primitives<f32> {
        let mut p = Primitives::default();
        match *self {
            Quadric::Sphere(shape) => p.spheres.push(Tagged { shape, tag: Tag::default() }),
            Quadric::Cylinder(shape) => p.cylinders.push(Tagged { shape, tag: Tag::default() }),
        }
        p
    }
}

/// One shape and the rays shot at it.
pub struct Group {
    pub shape: Quadric,
    pub rays: Vec<Ray<f32>>,
}

/// Runs a quadric case: every variant's roots against the oracle.
pub fn quadric_case(name: &str, groups: &[Group], opt: &Options) -> Result<Vec<Row>, GpuError> {
    let rays: usize = groups.iter().map(|g| g.rays.len()).sum();
    let mut rows = Vec::new();
    for variant in opt.variants() {
        let start = Instant::now();
        let results: Vec<Vec<Vec<f32>>> = match variant {
            Variant::Cpu => groups.iter().map(|g| g.rays.iter().map(|r| g.shape.robust(r)).collect()).collect(),
            Variant::Textbook => groups.iter().map(|g| g.rays.iter().map(|r| g.shape.textbook(r)).collect()).collect(),
            Variant::Gpu => {
                let ctx = opt.gpu.expect("gpu variant without a context");
                let mut all = Vec::new();
                for g in groups {
                    let buffers = upload(ctx, &g.shape.prims())?;
                    let qs: Vec<RayQuery> = g.rays.iter().map(query).collect();
                    let hits = trace::trace(ctx, &buffers, &qs, true)?;
                    all.push(hits.into_iter().map(|h| h.into_iter().map(|h| h.t).collect()).collect());
                }
                all
            }
        };
        let ns = start.elapsed().as_nanos() as f64 / rays as f64;
        let (mut disagree, mut nan) = (0, 0);
        let (mut rel, mut ul) = (Vec::new(), Vec::new());
        for (g, res) in groups.iter().zip(&results) {
            for (r, got) in g.rays.iter().zip(res) {
                nan += got.iter().filter(|t| !t.is_finite()).count();
                let (exact, clear) = g.shape.oracle(r);
                if !clear {
                    continue;
                }
                if exact.len() != got.len() {
                    disagree += 1;
                    continue;
                }
                for (&t, &te) in got.iter().zip(&exact) {
                    rel.push(rel_err(t as f64, te));
                    ul.push(ulps(r.at(t), oracle::point(r, te)));
                }
            }
        }
        rows.push(Row {
            case: name.into(),
            variant: Some(variant),
            rays,
            disagree,
            rel_t: Stats::of(rel),
            ulps: Stats::of(ul),
            fails: nan,
            fail_kind: "NaN",
            ns_per_ray: ns,
        });
    }
    Ok(rows)
}

/// Small spheres (r ≈ 1) 1e3 to 1e5 away, rays from the origin.
pub fn small_far_spheres(n_shapes: usize, rays: usize, rng: &mut Rng) -> Vec<Group> {
    (0..n_shapes)
        .map(|_| {
            let center = rng.direction() * 10f64.powf(rng.range(3.0, 5.0));
            let radius = 10f64.powf(rng.range(-0.3, 0.3));
            let s = Sphere { center, radius }.cast::<f32>();
            let rays = (0..rays).map(|_| ray32(V3::zero(), center + rng.cube(1.3 * radius))).collect();
            Group { shape: Quadric::Sphere(s), rays }
        })
        .collect()
}

/// Huge spheres (r = 1e4 to 1e6), ray origins 1e-2 outside the surface.
pub fn huge_spheres_near_origin(n_shapes: usize, rays: usize, rng: &mut Rng) -> Vec<Group> {
    (0..n_shapes)
        .map(|_| {
            let radius = 10f64.powf(rng.range(4.0, 6.0));
            let center = rng.cube(10.0);
            let s = Sphere { center, radius }.cast::<f32>();
            let rays = (0..rays)
                .map(|_| {
                    let o = center + rng.direction() * (radius + 1e-2);
                    ray32(o, rng.direction())
                })
                .collect();
            Group { shape: Quadric::Sphere(s), rays }
        })
        .collect()
}

/// A ray passing at distance `m` from the point `c`, across direction `d`, starting `back`
/// before it.
fn passing(rng: &mut Rng, c: V3<f64>, d: V3<f64>, m: f64, back: f64) -> Ray<f32> {
    let e = rng.perpendicular(d);
    ray32(c + e * m - d * back, d)
}

/// Tangent and grazing rays: closest approach r·(1 ± 10^−k), k = 1..7.
pub fn tangent_spheres(n_shapes: usize, rays: usize, rng: &mut Rng) -> Vec<Group> {
    (0..n_shapes)
        .map(|_| {
            let radius = 10f64.powf(rng.range(-1.0, 1.0));
            let center = rng.cube(10.0);
            let s = Sphere { center, radius }.cast::<f32>();
            let rays = (0..rays)
                .map(|i| {
                    let k = 1 + (i % 7) as i32;
                    let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                    let d = rng.direction();
                    passing(rng, center, d, radius * (1.0 + sign * 10f64.powi(-k)), 5.0 * radius)
                })
                .collect();
            Group { shape: Quadric::Sphere(s), rays }
        })
        .collect()
}

fn random_cylinder(rng: &mut Rng, radius: f64, length: f64, at: V3<f64>) -> Cylinder<f64> {
    let axis = rng.direction();
    Cylinder { p1: at - axis * (0.5 * length), p2: at + axis * (0.5 * length), radius, caps: true }
}

/// A capped cylinder of radius 10^U[−1, 1] and 1 to 6 radii long, near the origin; with its
/// unit axis and radius.
fn moderate_cylinder(rng: &mut Rng) -> (Cylinder<f64>, V3<f64>, f64) {
    let radius = 10f64.powf(rng.range(-1.0, 1.0));
    let (length, at) = (radius * rng.range(1.0, 6.0), rng.cube(10.0));
    let c = random_cylinder(rng, radius, length, at);
    (c, (c.p2 - c.p1).normalize(), radius)
}

/// Grazing rays on cylinders: across the side at r·(1 ± 10^−k) from the axis, and in the
/// plane of a cap (edge-on).
pub fn grazing_cylinders(n_shapes: usize, rays: usize, rng: &mut Rng) -> Vec<Group> {
    (0..n_shapes)
        .map(|_| {
            let (c, axis, radius) = moderate_cylinder(rng);
            let rays = (0..rays)
                .map(|i| {
                    let d = rng.perpendicular(axis);
                    if i % 4 == 3 {
                        // In the plane of the p2 cap, towards its centre: edge-on.
                        ray32(c.p2 - d * (3.0 * radius), d)
                    } else {
                        let k = 1 + (i % 7) as i32;
                        let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                        let mid = c.p1 + (c.p2 - c.p1) * rng.range(0.2, 0.8);
                        passing(rng, mid, d, radius * (1.0 + sign * 10f64.powi(-k)), 5.0 * radius)
                    }
                })
                .collect();
            Group { shape: Quadric::Cylinder(c.cast()), rays }
        })
        .collect()
}

/// Rays parallel (exactly, and within 1e-6) to a cylinder's axis, inside and outside it.
pub fn parallel_to_axis(n_shapes: usize, rays: usize, rng: &mut Rng) -> Vec<Group> {
    (0..n_shapes)
        .map(|_| {
            let (c, axis, radius) = moderate_cylinder(rng);
            let rays = (0..rays)
                .map(|i| {
                    let inside = i % 2 == 0;
                    let off = rng.perpendicular(axis)
                        * radius
                        * if inside { rng.range(0.05, 0.9) } else { rng.range(1.1, 3.0) };
                    let d = if i % 4 < 2 { axis } else { (axis + rng.direction() * 1e-6).normalize() };
                    ray32(c.p1 + off - axis * radius, d)
                })
                .collect();
            Group { shape: Quadric::Cylinder(c.cast()), rays }
        })
        .collect()
}

/// Very thin (r = 1e-4) or very fat (r = 1e4) cylinders, random rays at them.
pub fn extreme_cylinders(n_shapes: usize, rays: usize, radius: f64, rng: &mut Rng) -> Vec<Group> {
    (0..n_shapes)
        .map(|_| {
            let length = if radius < 1.0 { rng.range(0.5, 5.0) } else { radius * rng.range(0.1, 2.0) };
            let at = rng.cube(10.0);
            let c = random_cylinder(rng, radius, length, at);
            let size = length.max(radius);
            let rays = (0..rays)
                .map(|_| {
                    let o = (c.p1 + c.p2) * 0.5 + rng.direction() * (size * rng.range(1.5, 10.0));
                    let target = c.p1 + (c.p2 - c.p1) * rng.unit() + rng.cube(1.5 * radius);
                    ray32(o, target - o)
                })
                .collect();
            Group { shape: Quadric::Cylinder(c.cast()), rays }
        })
        .collect()
}

/// Spawned rays: `shapes` spheres and capped cylinders with radii 10^U[−4, 4] at offsets up to
/// 1e6, `rays` rays each; each hit spawns a ray into the outside hemisphere, which must not
/// hit the surface it starts on. The robust variants use the Wächter–Binder offset; the
/// textbook one moves the point by ε = 1e-4 along the normal.
/// The shapes and ray pairs of the spawned-rays case, with each pair's target: its shape, its
/// PrimRef and the part of its surface the exact first hit lies on.
pub type SpawnSetup = (Primitives<f32>, Vec<(Ray<f32>, V3<f32>)>, Vec<(Quadric, PrimRef, Part)>);

pub fn spawn_setup(shapes: usize, rays: usize, rng: &mut Rng) -> SpawnSetup {
    let mut prims = Primitives::<f32>::default();
    let mut pairs = Vec::new();
    let mut targets = Vec::new();
    for k in 0..shapes {
        let radius = 10f64.powf(rng.range(-4.0, 4.0));
        let at = rng.cube(1e6);
        let tag = Tag { object: k as u32, prim: 0, material: 0 };
        let prim_ref = if k % 2 == 0 {
            PrimRef::new(PrimKind::Sphere, prims.spheres.len())
        } else {
            PrimRef::new(PrimKind::Cylinder, prims.cylinders.len())
        };
        let shape: Quadric = if k % 2 == 0 {
            let s = Sphere { center: at, radius }.cast::<f32>();
            prims.spheres.push(Tagged { shape: s, tag });
            Quadric::Sphere(s)
        } else {
            let length = radius * rng.range(0.5, 4.0);
            let c = random_cylinder(rng, radius, length, at).cast::<f32>();
            prims.cylinders.push(Tagged { shape: c, tag });
            Quadric::Cylinder(c)
        };
        let centre = match shape {
            Quadric::Sphere(s) => s.center.to_f64(),
            Quadric::Cylinder(c) => ((c.p1 + c.p2) * 0.5).to_f64(),
        };
        let mut made = 0;
        let mut tries = 0;
        while made < rays && tries < 20 * rays {
            tries += 1;
            let o = centre + rng.direction() * (radius * 10f64.powf(rng.range(0.5, 2.0)));
            let ray = ray32(o, centre + rng.cube(0.7 * radius) - o);
            // The exact entry point and normal decide the outside hemisphere.
            let (exact, clear) = shape.oracle(&ray);
            let Some(&t) = exact.first() else { continue };
            if !clear {
                continue;
            }
            let (n, part) = exact_normal(&shape, &ray, t);
            let mut d2 = rng.direction();
            if d2.dot(n) < 0.0 {
                d2 = -d2;
            }
            if d2.dot(n) < 0.05 {
                continue;
            }
            pairs.push((ray, d2.cast::<f32>()));
            targets.push((shape, prim_ref, part));
            made += 1;
        }
    }
    (prims, pairs, targets)
}

pub fn spawned_rays(shapes: usize, rays: usize, opt: &Options, rng: &mut Rng) -> Result<Vec<Row>, GpuError> {
    let (prims, pairs, targets) = spawn_setup(shapes, rays, rng);
    let bvh = Bvh::build(&prims);
    let n = pairs.len();
    let mut rows = Vec::new();
    for variant in opt.variants() {
        let start = Instant::now();
        let (rehits, nan) = match variant {
            Variant::Cpu => count_rehits(&crate::backend::cpu::trace_spawn(&prims, &bvh, &pairs), &targets),
            Variant::Gpu => {
                let ctx = opt.gpu.expect("gpu");
                let buffers = upload(ctx, &prims)?;
                count_rehits(&trace::trace_spawn(ctx, &buffers, &pairs)?, &targets)
            }
            Variant::Textbook => {
                let mut rehits = 0;
                for ((ray, d2), (shape, _, _)) in pairs.iter().zip(&targets) {
                    let Some(&t) = shape.textbook(ray).first() else { continue };
                    let p = ray.at(t);
                    let n = robust_normal(shape, ray, t);
                    let o2 = textbook::offset_by_epsilon(p, if d2.dot(n) >= 0.0 { n } else { -n });
                    rehits += !shape.textbook(&Ray::new(o2, *d2)).is_empty() as usize;
                }
                (rehits, 0)
            }
        };
        rows.push(Row {
            case: format!("spawned rays, {shapes} shapes r=1e-4..1e4 at up to 1e6"),
            variant: Some(variant),
            rays: n,
            fails: rehits + nan,
            fail_kind: "re-hits",
            ns_per_ray: start.elapsed().as_nanos() as f64 / n as f64,
            ..Row::default()
        });
    }
    Ok(rows)
}

/// Re-hits among the pairs whose first hit is their target, on the part the exact hit is
/// on (shapes may overlap, so a ray can first meet another one; those pairs judge nothing),
/// and NaN outputs.
fn count_rehits(results: &[crate::backend::SpawnHits], targets: &[(Quadric, PrimRef, Part)]) -> (usize, usize) {
    let mut rehits = 0;
    let mut nan = 0;
    for ((first, second), (_, prim, part)) in results.iter().zip(targets) {
        if let (Some(a), Some(b)) = (first, second) {
            rehits += (a.prim == *prim && a.part == *part && b.prim == *prim) as usize;
        }
        for h in [first, second].into_iter().flatten() {
            nan += (!h.t.is_finite() || !h.normal.is_finite()) as usize;
        }
    }
    (rehits, nan)
}

/// The outward normal and the part of the surface at the exact first hit `t`.
fn exact_normal(shape: &Quadric, ray: &Ray<f32>, t: f64) -> (V3<f64>, Part) {
    let r64 = ray.cast::<f64>();
    match shape {
        Quadric::Sphere(s) => (s.cast::<f64>().normal(&r64, t, Part::Surface), Part::Surface),
        Quadric::Cylinder(c) => {
            let c = c.cast::<f64>();
            let roots = c.roots(&r64, 0.0, f64::INFINITY);
            let part =
                roots.iter().min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs())).map_or(Part::Surface, |r| r.1);
            (c.normal(&r64, t, part), part)
        }
    }
}

fn robust_normal(shape: &Quadric, ray: &Ray<f32>, t: f32) -> V3<f32> {
    match shape {
        Quadric::Sphere(s) => s.normal(ray, t, Part::Surface),
        Quadric::Cylinder(c) => {
            let part = c.roots(ray, 0.0, f32::INFINITY).first().map_or(Default::default(), |r| r.1);
            c.normal(ray, t, part)
        }
    }
}

/// A closed UV sphere: `nu` segments around, `nv` rings, single vertices at the poles.
pub fn uv_sphere(nu: usize, nv: usize, radius: f64, centre: V3<f64>) -> (Vec<V3<f64>>, Vec<[u32; 3]>) {
    let mut v = vec![centre + V3::new(0.0, radius, 0.0)];
    for j in 1..nv {
        let th = std::f64::consts::PI * j as f64 / nv as f64;
        for i in 0..nu {
            let ph = 2.0 * std::f64::consts::PI * i as f64 / nu as f64;
            v.push(centre + V3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * radius);
        }
    }
    v.push(centre - V3::new(0.0, radius, 0.0));
    let ring = |j: usize, i: usize| (1 + (j - 1) * nu + i % nu) as u32;
    let south = (v.len() - 1) as u32;
    let mut f = Vec::new();
    for i in 0..nu {
        f.push([0, ring(1, i + 1), ring(1, i)]);
        f.push([south, ring(nv - 1, i), ring(nv - 1, i + 1)]);
    }
    for j in 1..nv - 1 {
        for i in 0..nu {
            let (a, b, c, d) = (ring(j, i), ring(j, i + 1), ring(j + 1, i + 1), ring(j + 1, i));
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
    }
    (v, f)
}

/// Closed meshes shot from inside at their vertices, edges and faces: no ray may escape.
/// The textbook variant (Möller–Trumbore) is judged on the triangles around the vertex or
/// edge aimed at, where the ray must cross the surface.
pub fn closed_mesh_leaks(total_rays: usize, opt: &Options, rng: &mut Rng) -> Result<Vec<Row>, GpuError> {
    let centre = V3::new(0.5, -0.25, 0.125);
    let meshes = [
        ("UV sphere", uv_sphere(96, 48, 1.0, centre)),
        ("torus", {
            let (v, f) = crate::scene::mesh::bumpy_torus(160, 80, 2.0, 0.8);
            (v.into_iter().map(|p| p + centre).collect(), f)
        }),
    ];
    let mut rows: Vec<Row> = Vec::new();
    for (name, (verts, faces)) in &meshes {
        let mut prims = Primitives::<f32>::default();
        for (i, f) in faces.iter().enumerate() {
            let tri = Triangle { v: f.map(|k| verts[k as usize]) }.cast::<f32>();
            prims.triangles.push(Tagged { shape: tri, tag: Tag { object: 0, prim: i as u32, material: 0 } });
        }
        let bvh = Bvh::build(&prims);
        let mut incident: Vec<Vec<u32>> = vec![Vec::new(); verts.len()];
        for (i, f) in faces.iter().enumerate() {
            for &k in f {
                incident[k as usize].push(i as u32);
            }
        }
        let buffers = match opt.gpu {
            Some(ctx) => Some(upload(ctx, &prims)?),
            None => None,
        };
        let per_mesh = total_rays / meshes.len();
        let mut escapes = [0usize; 3];
        let mut secs = [0f64; 3];
        let chunk = 1 << 20;
        let mut done = 0;
        while done < per_mesh {
            let n = chunk.min(per_mesh - done);
            done += n;
            let mut rays = Vec::with_capacity(n);
            let mut around = Vec::with_capacity(n);
            for i in 0..n {
                let origin = if *name == "torus" {
                    let a = rng.range(0.0, std::f64::consts::TAU);
                    centre + V3::new(2.0 * a.cos(), 0.0, 2.0 * a.sin()) + rng.cube(0.25)
                } else {
                    centre + rng.cube(0.5)
                };
                let f = faces[rng.next_u64() as usize % faces.len()];
                // The triangles hold these same casts, so the targets are exactly their corners.
                let vtx = f.map(|k| verts[k as usize].cast::<f32>());
                let (target, near): (V3<f32>, Vec<u32>) = match i % 5 {
                    0 | 1 => (vtx[0], incident[f[0] as usize].clone()),
                    2 | 3 => {
                        let s = if i % 10 < 5 { 0.5 } else { rng.unit() as f32 };
                        let e = vtx[0] + (vtx[1] - vtx[0]) * s;
                        let shared = incident[f[0] as usize]
                            .iter()
                            .filter(|t| incident[f[1] as usize].contains(t))
                            .copied()
                            .collect();
                        (e, shared)
                    }
                    _ => {
                        let (a, b) = (rng.unit() as f32, rng.unit() as f32);
                        let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
                        (vtx[0] + (vtx[1] - vtx[0]) * a + (vtx[2] - vtx[0]) * b, Vec::new())
                    }
                };
                let o = origin.cast::<f32>();
                rays.push(Ray::new(o, (target - o).normalize()));
                around.push(near);
            }
            for (slot, variant) in [Variant::Cpu, Variant::Gpu, Variant::Textbook].into_iter().enumerate() {
                let start = Instant::now();
                match variant {
                    Variant::Cpu if opt.cpu => {
                        use rayon::prelude::*;
                        escapes[slot] += rays
                            .par_iter()
                            .filter(|r| traverse::nearest(&bvh, &prims, r, 0.0, f32::INFINITY).is_none())
                            .count();
                    }
                    Variant::Gpu => {
                        if let (Some(ctx), Some(b)) = (opt.gpu, &buffers) {
                            let qs: Vec<RayQuery> = rays.iter().map(query).collect();
                            escapes[slot] += trace::trace(ctx, b, &qs, false)?.iter().filter(|h| h.is_empty()).count();
                        }
                    }
                    Variant::Textbook if opt.cpu => {
                        for (r, near) in rays.iter().zip(&around) {
                            if !near.is_empty() {
                                let hit = near.iter().any(|&t| {
                                    textbook::triangle_hit(&prims.triangles[t as usize].shape, r, 0.0, f32::INFINITY)
                                        .is_some()
                                });
                                escapes[slot] += !hit as usize;
                            }
                        }
                    }
                    _ => {}
                }
                secs[slot] += start.elapsed().as_secs_f64();
            }
        }
        for (slot, variant) in [Variant::Cpu, Variant::Gpu, Variant::Textbook].into_iter().enumerate() {
            if !opt.variants().contains(&variant) {
                continue;
            }
            let rays = if variant == Variant::Textbook { per_mesh * 4 / 5 } else { per_mesh };
            rows.push(Row {
                case: format!("closed {name} ({} tris), rays from inside at vertices/edges", faces.len()),
                variant: Some(variant),
                rays,
                fails: escapes[slot],
                fail_kind: "escapes",
                ns_per_ray: secs[slot] * 1e9 / rays as f64,
                ..Row::default()
            });
        }
    }
    Ok(rows)
}

/// Needle, sliver and degenerate (collinear, repeated-vertex) triangles: rays at each. A hit
/// the oracle places clearly outside the triangle (or on a degenerate one) is false; no output
/// may be NaN.
pub fn thin_triangles(per_kind: usize, rays: usize, opt: &Options, rng: &mut Rng) -> Result<Vec<Row>, GpuError> {
    let mut prims = Primitives::<f32>::default();
    for k in 0..4 * per_kind {
        let g = V3::new((k % 32) as f64, ((k / 32) % 32) as f64, (k / 1024) as f64) * 100.0;
        let s = 10f64.powf(rng.range(-2.0, 1.0));
        let (a, b) = (rng.direction(), rng.direction());
        let v = match k % 4 {
            // Needle: two vertices 1e-5·s apart.
            0 => [g, g + a * (s * 1e-5), g + b * s],
            // Sliver: the third vertex 1e-6·s off the line of the other two.
            1 => {
                let off = rng.perpendicular(a) * (s * 1e-6);
                [g, g + a * s, g + a * (0.5 * s) + off]
            }
            // Exactly collinear in f32 (axis-aligned, representable).
            2 => [g, g + V3::new(1.0, 0.0, 0.0), g + V3::new(0.5, 0.0, 0.0)],
            // Repeated vertex.
            _ => [g, g + a * s, g + a * s],
        };
        let tri = Triangle { v }.cast::<f32>();
        prims.triangles.push(Tagged { shape: tri, tag: Tag { object: k as u32, prim: 0, material: 0 } });
    }
    let mut ray_list = Vec::new();
    for t in &prims.triangles {
        let tri = t.shape.cast::<f64>();
        let (lo, hi) = tri.bounds().expect("triangles are bounded");
        let size = (hi - lo).length().max(1e-3);
        for _ in 0..rays {
            let target = lo + (hi - lo).mul_elem(V3::new(rng.unit(), rng.unit(), rng.unit())) + rng.cube(0.1 * size);
            let o = target + rng.direction() * (3.0 * size);
            ray_list.push((t.tag.object as usize, ray32(o, target - o)));
        }
    }
    let bvh = Bvh::build(&prims);
    let n = ray_list.len();
    let judge = |r: &Ray<f32>, k: usize, t: f32, normal: V3<f32>| -> (usize, usize) {
        if !t.is_finite() || !normal.is_finite() {
            return (1, 0);
        }
        let false_hit = match oracle::triangle(&prims.triangles[k].shape, r) {
            None => true,
            Some((_, margin, inside)) => !inside && margin > 1e-6,
        };
        (0, false_hit as usize)
    };
    let mut rows = Vec::new();
    for variant in opt.variants() {
        let start = Instant::now();
        let (mut nan, mut false_hits) = (0, 0);
        let mut add = |(a, b): (usize, usize)| {
            nan += a;
            false_hits += b;
        };
        match variant {
            Variant::Cpu => {
                for (_, r) in &ray_list {
                    if let Some(h) = traverse::nearest(&bvh, &prims, r, 0.0, f32::INFINITY) {
                        add(judge(r, h.prim.index(), h.t, h.normal));
                    }
                }
            }
            Variant::Gpu => {
                let ctx = opt.gpu.expect("gpu");
                let buffers = upload(ctx, &prims)?;
                let qs: Vec<RayQuery> = ray_list.iter().map(|(_, r)| query(r)).collect();
                for ((_, r), h) in ray_list.iter().zip(trace::trace(ctx, &buffers, &qs, false)?) {
                    if let Some(h) = h.first() {
                        add(judge(r, h.prim.index(), h.t, h.normal));
                    }
                }
            }
            Variant::Textbook => {
                for (k, r) in &ray_list {
                    let tri = &prims.triangles[*k].shape;
                    if let Some(t) = textbook::triangle_hit(tri, r, 0.0, f32::INFINITY) {
                        add(judge(r, *k, t, tri.face_normal().normalize()));
                    }
                }
            }
        }
        rows.push(Row {
            case: format!("needle, sliver, degenerate triangles ({})", prims.triangles.len()),
            variant: Some(variant),
            rays: n,
            fails: nan + false_hits,
            fail_kind: "NaN or false hits",
            ns_per_ray: start.elapsed().as_nanos() as f64 / n as f64,
            ..Row::default()
        });
    }
    Ok(rows)
}

/// A small scene, as is and translated by (1e5, 1e5, 1e5).
pub fn scene_at(offset: f64) -> Scene {
    let text = format!(
        r#"
[camera]
eye = [{o}, {y3}, {zm9}]
look_at = [{o}, {y12}, {o}]
up = [0, 1, 0]
fov_y = 40
[image]
width = 160
height = 120
[[materials]]
name = "clay"
type = "diffuse"
color = [0.8, 0.6, 0.4]
[[materials]]
name = "chrome"
type = "mirror"
color = [0.9, 0.9, 0.9]
[[objects]]
type = "plane"
point = [{o}, {o}, {o}]
normal = [0, 1, 0]
[[objects]]
type = "sphere"
center = [{o}, {y15}, {o}]
radius = 1.5
material = "clay"
[[objects]]
type = "sphere"
center = [{x3}, {y1}, {zm1}]
radius = 1.0
material = "chrome"
[[objects]]
type = "cylinder"
p1 = [{xm3}, {o}, {z1}]
p2 = [{xm3}, {y3}, {z1}]
radius = 0.7
material = "clay"
[[lights]]
type = "point"
position = [{xm5}, {y8}, {zm6}]
intensity = [300, 300, 300]
"#,
        o = offset,
        y3 = offset + 3.0,
        zm9 = offset - 9.0,
        y12 = offset + 1.2,
        y15 = offset + 1.5,
        x3 = offset + 3.0,
        y1 = offset + 1.0,
        zm1 = offset - 1.0,
        xm3 = offset - 3.0,
        z1 = offset + 1.0,
        xm5 = offset - 5.0,
        y8 = offset + 8.0,
        zm6 = offset - 6.0,
    );
    crate::scene::file::parse(&text, std::path::Path::new("far.toml"), std::path::Path::new(".")).expect("valid scene")
}

/// `scene` with every position and length multiplied by `s`: the camera, the objects and the
/// point lights, whose intensities are multiplied by s² so that the irradiance they give is
/// unchanged (emissive radiance and directional irradiance do not depend on the scale). Up to
/// rounding it renders the same image at any scale.
pub fn scaled(scene: &Scene, s: f64) -> Scene {
    use crate::scene::{Geometry, Light};
    let tri = |t: &Triangle<f64>| Triangle { v: t.v.map(|p| p * s) };
    let mut out = scene.clone();
    out.camera.eye = scene.camera.eye * s;
    out.camera.look_at = scene.camera.look_at * s;
    for o in &mut out.objects {
        o.geometry = match &o.geometry {
            Geometry::Sphere(sp) => Geometry::Sphere(Sphere { center: sp.center * s, radius: sp.radius * s }),
            Geometry::Cylinder(c) => {
                Geometry::Cylinder(Cylinder { p1: c.p1 * s, p2: c.p2 * s, radius: c.radius * s, ..*c })
            }
            Geometry::Plane(p) => Geometry::Plane(crate::geometry::Plane { point: p.point * s, normal: p.normal }),
            Geometry::Triangle(t) => Geometry::Triangle(tri(t)),
            Geometry::Polygon { vertices, triangles } => Geometry::Polygon {
                vertices: vertices.iter().map(|&v| v * s).collect(),
                triangles: triangles.iter().map(tri).collect(),
            },
            Geometry::Mesh { file, triangles, uvs, materials } => Geometry::Mesh {
                file: file.clone(),
                triangles: triangles.iter().map(tri).collect(),
                uvs: uvs.clone(),
                materials: materials.clone(),
            },
        };
    }
    for l in &mut out.lights {
        if let Light::Point { position, intensity } = l {
            *position = *position * s;
            *intensity = intensity.map(|i| i * s * s);
        }
    }
    out
}

/// Acne (a lit pixel rendered much darker: the surface shadows itself) and holes (background
/// where there is geometry, or the reverse) of a render against the reference.
pub fn acne_and_holes(reference: &crate::image::Image, test: &crate::image::Image, background: [f32; 3]) -> usize {
    let lum = |p: &[f32; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    reference
        .pixels
        .iter()
        .zip(&test.pixels)
        .filter(|(r, t)| {
            let hole = (**r == background) != (**t == background);
            let acne = lum(r) > 0.05 && lum(t) < 0.7 * lum(r);
            hole || acne
        })
        .count()
}

/// The Whitted image of `prep` on the robust `variant` (None for the textbook one, which
/// renders nothing).
fn render_on(
    variant: Variant,
    prep: &crate::render::Prepared,
    frame: &crate::gpu_types::GpuFrame,
    opt: &Options,
) -> Result<Option<crate::image::Image>, GpuError> {
    Ok(match variant {
        Variant::Cpu => Some(crate::backend::cpu::render(prep, frame, RenderMode::Whitted, &|_| {})),
        Variant::Gpu => {
            let ctx = opt.gpu.expect("gpu");
            let b = SceneBuffers::upload(ctx, &prep.gpu)?;
            Some(crate::backend::gpu::render::render(ctx, &b, frame, RenderMode::Whitted, b.key, &|_, _| {})?.0)
        }
        Variant::Textbook => None,
    })
}

/// The scene translated by 1e5 must render as it does at the origin: no acne, no holes.
pub fn far_from_origin(opt: &Options) -> Result<Vec<Row>, GpuError> {
    let near = crate::render::Prepared::new(scene_at(0.0));
    let far = crate::render::Prepared::new(scene_at(1e5));
    let frame_near = near.frame(160, 120);
    let frame_far = far.frame(160, 120);
    let reference = crate::backend::cpu::render(&near, &frame_near, RenderMode::Whitted, &|_| {});
    let bg = near.scene.render.background.map(|c| c as f32);
    let mut rows = Vec::new();
    for variant in opt.variants() {
        let start = Instant::now();
        let Some(img) = render_on(variant, &far, &frame_far, opt)? else { continue };
        rows.push(Row {
            case: "scene translated by 1e5 (160x120 render vs at the origin)".into(),
            variant: Some(variant),
            rays: 160 * 120,
            fails: acne_and_holes(&reference, &img, bg) + img.non_finite_count(),
            fail_kind: "acne/hole/NaN pixels",
            ns_per_ray: start.elapsed().as_nanos() as f64 / (160.0 * 120.0),
            ..Row::default()
        });
    }
    Ok(rows)
}

/// Pixels of two images whose 8-bit sRGB codes differ by more than `codes` in some channel.
pub fn pixels_off_by_more_than(a: &crate::image::Image, b: &crate::image::Image, codes: u8) -> usize {
    let (a, b) = (a.to_srgb8(), b.to_srgb8());
    a.chunks(3).zip(b.chunks(3)).filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| x.abs_diff(*y) > codes)).count()
}

/// Scales of [`scaled_scenes`].
pub const SCALES: [f64; 4] = [1e-6, 1e-3, 1e3, 1e6];

/// The scene of [`far_from_origin`] scaled by 10⁻⁶ … 10⁶ (camera, objects and light
/// together, [`scaled`]) must render as at scale 1: a fail is a pixel more than 2 codes off,
/// or not finite. Fixed offsets near the origin made the small scales lose shadows and
/// reflections (and glass, in the seed scene).
pub fn scaled_scenes(opt: &Options) -> Result<Vec<Row>, GpuError> {
    let (w, h) = (160, 120);
    let base = crate::render::Prepared::new(scene_at(0.0));
    let reference = crate::backend::cpu::render(&base, &base.frame(w, h), RenderMode::Whitted, &|_| {});
    let mut rows = Vec::new();
    for s in SCALES {
        let prep = crate::render::Prepared::new(scaled(&base.scene, s));
        let frame = prep.frame(w, h);
        for variant in opt.variants() {
            let start = Instant::now();
            let Some(img) = render_on(variant, &prep, &frame, opt)? else { continue };
            rows.push(Row {
                case: format!("scene scaled by {s:e} ({w}x{h} render vs at scale 1)"),
                variant: Some(variant),
                rays: (w * h) as usize,
                fails: pixels_off_by_more_than(&reference, &img, 2) + img.non_finite_count(),
                fail_kind: "pixels > 2 codes off",
                ns_per_ray: start.elapsed().as_nanos() as f64 / (w * h) as f64,
                ..Row::default()
            });
        }
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
