//! Spawned rays: secondary rays must not hit the surface they leave.

use super::*;
use strahl_core::accel::Bvh;
use strahl_core::geometry::{Part, Shape, Sphere};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{PrimKind, PrimRef, Primitives, Tag, Tagged};
use strahl_gpu::{GpuError, trace};

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
        let tag = Tag { object: k as u32, face: 0, material: 0 };
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
    each_variant(opt, |variant| {
        let (rehits, nan) = match variant {
            Variant::Cpu => count_rehits(&strahl_cpu::trace_spawn(&prims, &bvh, &pairs), &targets),
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
        Ok(Some(Row {
            case: format!("spawned rays, {shapes} shapes r=1e-4..1e4 at up to 1e6"),
            rays: n,
            fails: rehits + nan,
            fail_kind: "re-hits",
            ..Row::default()
        }))
    })
}

/// Re-hits among the pairs whose first hit is their target, on the part the exact hit is
/// on (shapes may overlap, so a ray can first meet another one; those pairs judge nothing),
/// and NaN outputs.
fn count_rehits(results: &[strahl_core::SpawnHits], targets: &[(Quadric, PrimRef, Part)]) -> (usize, usize) {
    let mut rehits = 0;
    let mut nan = 0;
    for ((first, second), (_, prim, part)) in results.iter().zip(targets) {
        if let (Some(a), Some(b)) = (first, second) {
            rehits += (a.prim_ref == *prim && a.part == *part && b.prim_ref == *prim) as usize;
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
