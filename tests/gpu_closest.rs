//! Closest-point queries on the GPU (`shaders/closest.wgsl`, `strahl_gpu::closest`) against
//! their CPU twin (`accel::gpu_bvh::closest`, the same walk in f32) and the binary tree's walk
//! (`proximity::closest`), on the mixed scene and the shipped scenes, for points on, near,
//! inside and far from the surfaces: the same primitive but at ties (two primitives whose CPU
//! distances lie within the bound of each other, which the GPU's rounding may order the other
//! way), and distances within the bound the docs state, 4ε·(max|pᵢ| + the scene's extent).

mod common;

use common::gpu;
use std::sync::Arc;
use strahl_core::accel::gpu_bvh::{self, GpuBvh};
use strahl_core::geometry::Triangle;
use strahl_core::geometry::testutil::{TestRays, TestRng};
use strahl_core::math::V3;
use strahl_core::primitives::{PrimKind, Primitives, Tagged};
use strahl_core::proximity::{self, Closest};
use strahl_core::render::Prepared;
use strahl_core::scene::{Camera, ImageSize, Scene};
use strahl_gpu::{GpuContext, SceneBuffers};

/// `prims` as a prepared scene (one grey material: the mixed scene's tags name material 0).
fn prepared(prims: Primitives<f32>) -> Prepared {
    let camera = Camera { eye: V3::new(0.0, 0.0, -5.0), look_at: V3::zero(), up: V3::new(0.0, 1.0, 0.0), fov_y: 40.0 };
    let scene = Scene::empty(camera, ImageSize { width: 8, height: 8 });
    Prepared::from_prims(scene, prims, std::time::Instant::now())
}

/// The scene's extent: the largest coordinate magnitude of its bounded primitives' boxes and
/// of its planes' points (1 for an empty scene), and its bounded primitives' box.
fn extent(prims: &Primitives<f32>) -> (f64, V3<f64>, V3<f64>) {
    let (mut lo, mut hi) = (V3::splat(f64::INFINITY), V3::splat(f64::NEG_INFINITY));
    for r in prims.bounded_refs() {
        let (a, b) = prims.bounds_f64(r);
        (lo, hi) = (lo.min_elem(a), hi.max_elem(b));
    }
    let mut e: f64 = 1.0;
    if prims.bounded_count() > 0 {
        e = e.max(lo.abs().max_component()).max(hi.abs().max_component());
    } else {
        (lo, hi) = (V3::splat(-1.0), V3::splat(1.0));
    }
    for p in &prims.planes {
        e = e.max(p.shape.point.to_f64().abs().max_component());
    }
    (e, lo, hi)
}

/// Query points for a scene whose bounded primitives lie in (lo, hi): feet of random points
/// (on a surface), points 10⁻³ of the box's size off them, points in the box, around it (three
/// times its size) and far from it (a hundred times).
fn query_points(prep: &Prepared, lo: V3<f64>, hi: V3<f64>, n: usize, seed: u64) -> Vec<V3<f32>> {
    let mut rng = TestRng(seed);
    let (c, h) = ((lo + hi) * 0.5, ((hi - lo) * 0.5).max_component().max(1e-3));
    let around = |rng: &mut TestRng, scale: f64| c + rng.in_cube(h * scale);
    (0..n)
        .map(|k| {
            let p = match k % 5 {
                0 | 1 => {
                    let q = around(&mut rng, 1.2).cast::<f32>();
                    let foot = proximity::closest(&prep.bvh, &prep.prims, q).map_or(q, |b| b.foot.point);
                    if k % 5 == 0 { foot.cast() } else { foot.cast::<f64>() + rng.unit_vector() * (1e-3 * h) }
                }
                2 => around(&mut rng, 1.0),
                3 => around(&mut rng, 3.0),
                _ => around(&mut rng, 100.0),
            };
            p.cast()
        })
        .collect()
}

/// What one scene's comparison found.
#[derive(Default)]
struct Stats {
    points: usize,
    /// The largest |GPU − CPU| distance over the bound.
    worst: f64,
    /// Points whose GPU primitive is not the CPU's (a tie within the bound), and of those,
    /// exact ties (the CPU's distances of both equal).
    other_prim: usize,
    exact_ties: usize,
    /// The largest |GPU foot − CPU foot| over the bound, where the primitive and part agree.
    worst_foot: f64,
    /// Points whose part differs though the primitive agrees.
    other_part: usize,
    /// Answers equal to the CPU twin's bit for bit (primitive, foot, distance, uv and part).
    identical: usize,
}

/// Compares the GPU's answers for `points` with the CPU twin's and the binary walk's.
fn compare(ctx: &GpuContext, name: &str, prep: &Prepared, points: &[V3<f32>]) -> Stats {
    let buffers = SceneBuffers::upload(ctx, &prep.flat).unwrap_or_else(|e| panic!("{name}: {e}"));
    let answers = strahl_gpu::closest::closest(ctx, &buffers, points).unwrap_or_else(|e| panic!("{name}: {e}"));
    ctx.check().unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(answers.len(), points.len(), "{name}: an answer per point");
    let tree = GpuBvh::collapse(&prep.bvh, &prep.prims).unwrap();
    let (scale, _, _) = extent(&prep.prims);
    let mut s = Stats { points: points.len(), ..Default::default() };
    for (k, (&p, got)) in points.iter().zip(&answers).enumerate() {
        let want = gpu_bvh::closest(&tree, &prep.prims, p);
        assert_eq!(
            want,
            proximity::closest(&prep.bvh, &prep.prims, p),
            "{name}: the twin and the binary walk, point {k}"
        );
        let (Some(got), Some(want)) = (got, want) else {
            assert_eq!(got.is_none(), want.is_none(), "{name}: point {k} at {p:?}: {got:?} vs {want:?}");
            continue;
        };
        s.identical += usize::from(*got == want);
        let bound = 4.0 * f32::EPSILON as f64 * (p.to_f64().abs().max_component() + scale);
        let (dg, dc) = ((got.foot.dist2 as f64).sqrt(), (want.foot.dist2 as f64).sqrt());
        s.worst = s.worst.max((dg - dc).abs() / bound);
        assert!((dg - dc).abs() <= bound, "{name}: point {k} at {p:?}: GPU {got:?}, CPU {want:?}");
        // The foot lies at the distance reported (in f64, from its f32 coordinates).
        let to_foot = (p.to_f64() - got.foot.point.to_f64()).length();
        assert!((to_foot - dg).abs() <= bound, "{name}: point {k}: the foot is {to_foot} away, not {dg}");
        if got.prim_ref != want.prim_ref {
            // A tie: the CPU's distance to the GPU's primitive is as near, within the bound.
            let other = (prep.prims.closest_of(got.prim_ref, p).dist2 as f64).sqrt();
            assert!(
                (other - dc).abs() <= bound,
                "{name}: point {k} at {p:?}: GPU {got:?} at {other} on the CPU, CPU {want:?}"
            );
            s.other_prim += 1;
            s.exact_ties += usize::from(other == dc);
            continue;
        }
        if got.foot.part != want.foot.part {
            s.other_part += 1;
            continue;
        }
        let foot_diff = (got.foot.point.to_f64() - want.foot.point.to_f64()).length();
        s.worst_foot = s.worst_foot.max(foot_diff / bound);
        if got.prim_ref.kind() == PrimKind::Triangle {
            // The (u, v) name the foot on its triangle. (Not compared with the CPU's: a
            // degenerate triangle's foot on the line its edges share has a (u, v) per edge,
            // and devices that round differently pick different edges.)
            let t = prep.prims.triangles[got.prim_ref.index()].shape.cast::<f64>();
            let [u, v] = got.foot.uv.map(|x| x as f64);
            let at = t.v[0] * (1.0 - u - v) + t.v[1] * u + t.v[2] * v;
            let off = (at - got.foot.point.to_f64()).length();
            assert!(off <= 4.0 * bound, "{name}: point {k}: uv {:?} name a point {off} from the foot", got.foot.uv);
        }
    }
    eprintln!(
        "{name} on {}: {} points, {} answers identical to the CPU twin's; largest distance difference \
         {:.3e} of the bound, feet {:.3e} of it; {} other primitives ({} exact ties), {} other parts",
        ctx.adapter_name(),
        s.points,
        s.identical,
        s.worst,
        s.worst_foot,
        s.other_prim,
        s.exact_ties,
        s.other_part
    );
    s
}

/// The mixed scene with sliver, collinear, point-like and segment-like triangles added (as
/// `proximity`'s f32 test adds them), so that the triangles' thin-triangle fallback, the
/// nearest edge, is taken too.
fn mixed_with_degenerate_triangles() -> Primitives<f32> {
    let mut p: Primitives<f64> = strahl_core::primitives::testutil::mixed_scene(3).cast();
    let mut rng = TestRng(21);
    let tag = p.triangles[0].tag;
    for k in 0..200 {
        let a = rng.in_cube(40.0);
        let d = rng.unit_vector();
        let v = match k % 4 {
            0 => [a, a + d * 5.0, a + d * 10.0 + rng.unit_vector() * 1e-6],
            1 => [a, a + d * 5.0, a + d * 2.5],
            2 => [a, a, a],
            _ => [a, a, a + d * 3.0],
        };
        p.triangles.push(Tagged { shape: Triangle { v }, tag });
    }
    p.cast()
}

#[test]
fn gpu_closest_points_agree_with_the_cpu_on_the_mixed_scene() {
    let Some(ctx) = gpu() else { return };
    let prep = prepared(mixed_with_degenerate_triangles());
    let (_, lo, hi) = extent(&prep.prims);
    let points = query_points(&prep, lo, hi, 20_000, 7);
    let s = compare(&ctx, "mixed scene", &prep, &points);
    // Some points are nearest a degenerate triangle (those after the mixed scene's 3000).
    let on_degenerate = points
        .iter()
        .filter_map(|&p| proximity::closest(&prep.bvh, &prep.prims, p))
        .filter(|c| c.prim_ref.kind() == PrimKind::Triangle && c.prim_ref.index() >= 3000)
        .count();
    eprintln!("{on_degenerate} points nearest a degenerate triangle");
    assert!(on_degenerate >= 50, "only {on_degenerate} points nearest a degenerate triangle");
    // Ties are rare: random points are almost never as near two primitives.
    assert!(s.other_prim * 1000 <= s.points, "{} other primitives", s.other_prim);
    assert!(s.other_part * 1000 <= s.points, "{} other parts", s.other_part);
}

#[test]
fn gpu_closest_points_agree_with_the_cpu_on_the_shipped_scenes() {
    let Some(ctx) = gpu() else { return };
    let ctx = Arc::new(ctx);
    let mut brute = 0;
    for path in strahl_core::testutil::shipped_scenes() {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let prep = Prepared::new(scene);
        // Tiny scenes test every primitive instead of walking the tree (FeatureKey::BVH).
        brute += usize::from(prep.prims.bounded_count() <= strahl_gpu::FeatureKey::BRUTE_FORCE_MAX);
        let (_, lo, hi) = extent(&prep.prims);
        let points = query_points(&prep, lo, hi, 3000, 11);
        let s = compare(&ctx, &name, &prep, &points);
        // Each of them a tie (checked above); a mesh's vertices and edges, shared by several
        // triangles, make many, more where a device rounds otherwise (llvmpipe's GL: 1.8 % of
        // mesh.toml's points).
        assert!(s.other_prim * 20 <= s.points, "{name}: {} other primitives", s.other_prim);
    }
    assert!(brute > 0, "no shipped scene runs the brute-force variant");
}

/// An empty scene answers None for every point, no points give no answers, a scene of planes
/// only has no BVH, and a batch larger than a workgroup's multiple is answered whole.
#[test]
fn closest_points_of_empty_scenes_no_points_and_planes_only() {
    let Some(ctx) = gpu() else { return };
    let empty = prepared(Primitives::default());
    let buffers = SceneBuffers::upload(&ctx, &empty.flat).unwrap();
    let points: Vec<V3<f32>> = (0..130).map(|i| V3::new(i as f32, -2.0, 0.5)).collect();
    let answers = strahl_gpu::closest::closest(&ctx, &buffers, &points).unwrap();
    assert_eq!(answers.len(), points.len());
    assert!(answers.iter().all(Option::is_none));
    assert!(strahl_gpu::closest::closest(&ctx, &buffers, &[]).unwrap().is_empty());

    let mut planes = strahl_core::primitives::testutil::mixed_scene(1);
    (planes.spheres, planes.cylinders, planes.triangles) = (Vec::new(), Vec::new(), Vec::new());
    let planes = prepared(planes);
    let buffers = SceneBuffers::upload(&ctx, &planes.flat).unwrap();
    let answers = strahl_gpu::closest::closest(&ctx, &buffers, &points).unwrap();
    for (p, a) in points.iter().zip(answers) {
        let a: Closest<f32> = a.expect("a plane is everywhere");
        assert_eq!(Some(a), proximity::closest_brute(&planes.prims, *p), "{p:?}");
    }
    ctx.check().unwrap();
}
