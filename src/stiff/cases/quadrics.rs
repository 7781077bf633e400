//! Quadric cases: spheres and cylinders at extreme sizes, distances and angles, every
//! variant's roots against the f64 oracle.

use super::*;
use strahl_core::geometry::{Cylinder, Shape, Sphere};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{Primitives, Tag, Tagged};
use strahl_core::query::RayQuery;
use strahl_gpu::{GpuError, trace};

#[derive(Clone, Copy, Debug)]
pub enum Quadric {
    Sphere(Sphere<f32>),
    Cylinder(Cylinder<f32>),
}

impl Quadric {
    pub(super) fn robust(&self, r: &Ray<f32>) -> Vec<f32> {
        let roots = match self {
            Quadric::Sphere(s) => s.roots(r, 0.0, f32::INFINITY),
            Quadric::Cylinder(c) => c.roots(r, 0.0, f32::INFINITY),
        };
        roots.iter().map(|(t, _)| t).collect()
    }
    pub(super) fn textbook(&self, r: &Ray<f32>) -> Vec<f32> {
        match self {
            Quadric::Sphere(s) => textbook::sphere_roots(s, r, 0.0, f32::INFINITY),
            Quadric::Cylinder(c) => textbook::cylinder_roots(c, r, 0.0, f32::INFINITY),
        }
    }
    pub(super) fn oracle(&self, r: &Ray<f32>) -> (Vec<f64>, bool) {
        match self {
            Quadric::Sphere(s) => oracle::sphere_roots(s, r),
            Quadric::Cylinder(c) => oracle::cylinder(c, r),
        }
    }
    pub(super) fn prims(&self) -> Primitives<f32> {
        let mut p = Primitives::default();
        match *self {
            Quadric::Sphere(shape) => p.spheres.push(Tagged { shape, tag: Tag::default() }),
            Quadric::Cylinder(shape) => p.cylinders.push(Tagged { shape, tag: Tag::default() }),
        }
        p
    }
}

/// Runs a quadric case: every variant's roots against the oracle.
pub fn quadric_case(name: &str, groups: &[Group], opt: &Options) -> Result<Vec<Row>, GpuError> {
    let rays: usize = groups.iter().map(|g| g.rays.len()).sum();
    each_variant(opt, |variant| {
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
        Ok(Some(Row {
            case: name.into(),
            rays,
            disagree,
            rel_t: Stats::of(rel),
            ulps: Stats::of(ul),
            fails: nan,
            fail_kind: "NaN",
            ..Row::default()
        }))
    })
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
pub(super) fn passing(rng: &mut Rng, c: V3<f64>, d: V3<f64>, m: f64, back: f64) -> Ray<f32> {
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

pub(super) fn random_cylinder(rng: &mut Rng, radius: f64, length: f64, at: V3<f64>) -> Cylinder<f64> {
    let axis = rng.direction();
    Cylinder { p1: at - axis * (0.5 * length), p2: at + axis * (0.5 * length), radius, caps: true }
}

/// A capped cylinder of radius 10^U[−1, 1] and 1 to 6 radii long, near the origin; with its
/// unit axis and radius.
pub(super) fn moderate_cylinder(rng: &mut Rng) -> (Cylinder<f64>, V3<f64>, f64) {
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
