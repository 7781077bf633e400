//! The command line, end to end: these tests run the built `strahl` binary on the shipped
//! scenes and read back what it writes (hits CSV, PNG, exit status, stderr).
//!
//! - the lecture's worked example through `strahl trace` (exact, f32 and f64), rays aimed at
//!   sphere C checked against the lecture's formula, and the `tmin < t < tmax` window;
//! - `--all` against nearest mode, and f32 against f64, on random rays over the seed scene;
//! - bad input: every failure is an error message naming the file (and line), never a panic;
//! - `strahl render` writes a PNG of the requested size that shows the sphere.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use strahl_core::rng::SplitMix64;

/// The hits CSV header (`strahl_core::query::HITS_HEADER`), spelled out: it is a file format.
const HEADER: &str = "ray,t,x,y,z,nx,ny,nz,object,prim,enter";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scene(name: &str) -> PathBuf {
    root().join("assets/scenes").join(name)
}

/// Runs `strahl` with `args` from the package root.
fn strahl<I, S>(args: I) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    Command::new(env!("CARGO_BIN_EXE_strahl"))
        .current_dir(root())
        .args(args)
        .output()
        .expect("cannot run the strahl binary")
}

fn stderr_of(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts that `out` is a clean failure: non-zero exit, an `error:` message, no panic.
fn assert_clean_failure(out: &Output) -> String {
    let err = stderr_of(out);
    assert!(!out.status.success(), "expected failure, got success; stderr:\n{err}");
    assert!(!err.contains("panicked"), "panic instead of an error message:\n{err}");
    assert!(!err.trim().is_empty(), "failure without a message");
    err
}

/// One row of a hits CSV. Numbers are parsed as f64: strahl prints each value with Rust's
/// shortest round-trip formatting, so equal f64s mean bit-equal results.
#[derive(Clone, Debug, PartialEq)]
struct Row {
    ray: usize,
    /// `None` on a miss row.
    t: Option<f64>,
    p: Option<[f64; 3]>,
    n: Option<[f64; 3]>,
    /// −1 on a miss row.
    object: i64,
    prim: Option<u32>,
    enter: Option<u8>,
}

fn opt<T: std::str::FromStr>(s: &str, what: &str, line: usize) -> Option<T> {
    if s.is_empty() { None } else { Some(s.parse().unwrap_or_else(|_| panic!("hits line {line}: {what} = {s:?}"))) }
}

fn parse_hits(csv: &str) -> Vec<Row> {
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(HEADER), "hits CSV header");
    lines
        .enumerate()
        .map(|(i, line)| {
            let ln = i + 2;
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 11, "hits line {ln}: {line:?}");
            let v3 = |k: usize, what: &str| -> Option<[f64; 3]> {
                let xs: Vec<Option<f64>> = (k..k + 3).map(|j| opt(f[j], what, ln)).collect();
                match (xs[0], xs[1], xs[2]) {
                    (Some(x), Some(y), Some(z)) => Some([x, y, z]),
                    (None, None, None) => None,
                    _ => panic!("hits line {ln}: {what} partly empty: {line:?}"),
                }
            };
            Row {
                ray: opt(f[0], "ray", ln).expect("ray index"),
                t: opt(f[1], "t", ln),
                p: v3(2, "x,y,z"),
                n: v3(5, "nx,ny,nz"),
                object: opt(f[8], "object", ln).expect("object"),
                prim: opt(f[9], "prim", ln),
                enter: opt(f[10], "enter", ln),
            }
        })
        .collect()
}

/// A rays CSV with the given columns.
fn rays_csv(header: &str, rows: &[Vec<f64>]) -> String {
    let mut s = format!("{header}\n");
    for r in rows {
        let fields: Vec<String> = r.iter().map(|x| x.to_string()).collect();
        s.push_str(&fields.join(","));
        s.push('\n');
    }
    s
}

/// Runs `strahl trace SCENE --rays <tmp> EXTRA...` and returns the parsed rows.
fn trace(scene: &Path, rays_csv: &str, extra: &[&str]) -> Vec<Row> {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.csv");
    std::fs::write(&rays, rays_csv).unwrap();
    let mut args = vec!["trace".as_ref(), scene.as_os_str(), "--rays".as_ref(), rays.as_os_str()];
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    let out = strahl(&args);
    let err = stderr_of(&out);
    assert!(out.status.success(), "strahl trace {extra:?} failed:\n{err}");
    assert!(!err.contains("panicked"), "{err}");
    parse_hits(&String::from_utf8(out.stdout).expect("UTF-8 output"))
}

/// Expected hit of the lecture example: (t, point, object, enter).
fn hit(t: f64, p: [f64; 3], object: i64, enter: u8) -> (f64, [f64; 3], i64, u8) {
    (t, p, object, enter)
}

fn assert_rows_exact(rows: &[Row], want: &[(f64, [f64; 3], i64, u8)], what: &str) {
    let got: Vec<_> = rows.iter().map(|r| (r.t.unwrap(), r.p.unwrap(), r.object, r.enter.unwrap())).collect();
    assert_eq!(got, want, "{what}: rows {rows:#?}");
    for r in rows {
        assert_eq!(r.prim, Some(0), "{what}: a sphere has prim 0");
        let n = r.n.unwrap();
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-6, "{what}: normal {n:?} not unit");
    }
}

// ---------------------------------------------------------------------------------------
// The lecture's worked example.

/// "Problem Time": p_v = (0, 0, −10), the ray through p_i = (0, 0, 0), d = (0, 0, 10)/10.
/// Enters A at μ = 3, B at 6, leaves B at 12, A at 13; misses C. Every number is exact in
/// both precisions (the direction given as (0, 0, 10) is normalised by strahl).
#[test]
fn lecture_example_all_hits_exact_in_both_precisions() {
    let rays = rays_csv("ox,oy,oz,dx,dy,dz", &[vec![0.0, 0.0, 0.0, 0.0, 0.0, 10.0]]);
    let want = [
        hit(3.0, [0.0, 0.0, 3.0], 0, 1),
        hit(6.0, [0.0, 0.0, 6.0], 1, 1),
        hit(12.0, [0.0, 0.0, 12.0], 1, 0),
        hit(13.0, [0.0, 0.0, 13.0], 0, 0),
    ];
    for precision in ["f32", "f64"] {
        let rows = trace(&scene("lecture.toml"), &rays, &["--all", "--precision", precision]);
        assert!(rows.iter().all(|r| r.ray == 0));
        assert!(rows.iter().all(|r| r.object != 2), "{precision}: sphere C must be missed");
        assert_rows_exact(&rows, &want, precision);
        // Entering through the near side faces the ray: the normal is −z there, +z on exit.
        assert_eq!(rows[0].n, Some([0.0, 0.0, -1.0]));
        assert_eq!(rows[3].n, Some([0.0, 0.0, 1.0]));
    }
}

#[test]
fn lecture_example_nearest_and_miss() {
    let rays = rays_csv(
        "ox,oy,oz,dx,dy,dz",
        &[
            vec![0.0, 0.0, 0.0, 0.0, 0.0, 10.0],
            // Parallel to the view axis but 10 above it: clear of every sphere.
            vec![0.0, 10.0, 0.0, 0.0, 0.0, 1.0],
        ],
    );
    for precision in ["f32", "f64"] {
        let rows = trace(&scene("lecture.toml"), &rays, &["--precision", precision]);
        assert_eq!(rows.len(), 2, "{precision}: one row per ray in nearest mode: {rows:#?}");
        assert_rows_exact(&rows[..1], &[hit(3.0, [0.0, 0.0, 3.0], 0, 1)], precision);
        let miss = &rows[1];
        assert_eq!(miss.ray, 1);
        assert_eq!(miss.object, -1, "{precision}: a miss has object -1");
        assert_eq!((miss.t, miss.p, miss.n, miss.prim, miss.enter), (None, None, None, None, None));
        // In --all mode a miss has no row at all.
        let rows = trace(&scene("lecture.toml"), &rays, &["--all", "--precision", precision]);
        assert_eq!(rows.len(), 4);
        assert!(rows.iter().all(|r| r.ray == 0));
    }
}

/// `--all` on the default backend (the GPU where there is one) when no ray hits anything,
/// and a rays file with no rays: the header and nothing else, exit status 0.
#[test]
fn no_hits_and_no_rays_give_just_the_header() {
    let no_hits = rays_csv("ox,oy,oz,dx,dy,dz", &[vec![0.0, 20.0, 0.0, 0.0, 0.0, 1.0]]);
    for rays in [no_hits.as_str(), "ox,oy,oz,dx,dy,dz\n"] {
        assert!(trace(&scene("lecture.toml"), rays, &["--all"]).is_empty(), "{rays:?}");
        assert!(trace(&scene("lecture.toml"), rays, &["--all", "--backend", "cpu"]).is_empty());
    }
    let rows = trace(&scene("lecture.toml"), &no_hits, &[]);
    assert_eq!((rows.len(), rows[0].object), (1, -1), "nearest mode keeps its miss row");
}

/// `-o HITS.csv` writes exactly what standard output would carry.
#[test]
fn output_file_matches_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.csv");
    std::fs::write(&rays, "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n0,10,0,0,0,1\n").unwrap();
    let hits = dir.path().join("hits.csv");
    let lecture = scene("lecture.toml");
    let to_stdout =
        strahl(["trace".as_ref(), lecture.as_os_str(), "--rays".as_ref(), rays.as_os_str(), "--all".as_ref()]);
    assert!(to_stdout.status.success(), "{}", stderr_of(&to_stdout));
    let to_file = strahl([
        "trace".as_ref(),
        lecture.as_os_str(),
        "--rays".as_ref(),
        rays.as_os_str(),
        "--all".as_ref(),
        "-o".as_ref(),
        hits.as_os_str(),
    ]);
    assert!(to_file.status.success(), "{}", stderr_of(&to_file));
    assert!(to_file.stdout.is_empty(), "with -o nothing goes to standard output");
    assert_eq!(std::fs::read(&hits).unwrap(), to_stdout.stdout);
}

/// The window is open at both ends: tmin < t < tmax. With tmin = 3 the entry into A (at
/// exactly 3) is not reported; with tmax = 12 the exit from B (at exactly 12) is not either.
#[test]
fn tmin_and_tmax_are_exclusive() {
    let rays = rays_csv("ox,oy,oz,dx,dy,dz,tmin,tmax", &[vec![0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 3.0, 12.0]]);
    for precision in ["f32", "f64"] {
        let rows = trace(&scene("lecture.toml"), &rays, &["--all", "--precision", precision]);
        assert_rows_exact(&rows, &[hit(6.0, [0.0, 0.0, 6.0], 1, 1)], precision);
        let rows = trace(&scene("lecture.toml"), &rays, &["--precision", precision]);
        assert_rows_exact(&rows, &[hit(6.0, [0.0, 0.0, 6.0], 1, 1)], precision);
    }
}

// ---------------------------------------------------------------------------------------
// Rays at sphere C, against the lecture's formula.

/// The lecture scene's spheres: (centre, radius), in `[[objects]]` order.
const LECTURE_SPHERES: [([f64; 3], f64); 3] = [([0.0, 0.0, 8.0], 5.0), ([0.0, 0.0, 9.0], 3.0), ([0.0, -3.0, 8.0], 2.0)];

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Every crossing of the ray with the lecture's spheres, by the lecture's formula
/// μ = −d·Δp ± √((d·Δp)² − |Δp|² + r²) with Δp = p0 − p_s and d normalised, keeping μ > 0:
/// (μ, object, enter), sorted by μ. Also returns the smallest |discriminant| / r² over the
/// spheres, so callers can stay clear of tangent rays.
fn lecture_crossings(o: [f64; 3], d: [f64; 3]) -> (Vec<(f64, i64, u8)>, f64) {
    let len = dot(d, d).sqrt();
    let d = d.map(|c| c / len);
    let mut out = Vec::new();
    let mut closest = f64::INFINITY;
    for (i, (c, r)) in LECTURE_SPHERES.iter().enumerate() {
        let dp = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
        let b = dot(d, dp);
        let disc = b * b - dot(dp, dp) + r * r;
        closest = closest.min(disc.abs() / (r * r));
        if disc > 0.0 {
            let s = disc.sqrt();
            for (mu, enter) in [(-b - s, 1), (-b + s, 0)] {
                if mu > 0.0 {
                    out.push((mu, i as i64, enter));
                }
            }
        }
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    (out, closest)
}

fn assert_matches_lecture(rows: &[Row], o: [f64; 3], d: [f64; 3], tol: f64, what: &str) {
    let (want, _) = lecture_crossings(o, d);
    let got: Vec<(f64, i64, u8)> = rows.iter().map(|r| (r.t.unwrap(), r.object, r.enter.unwrap())).collect();
    assert_eq!(got.len(), want.len(), "{what}: got {got:?}, want {want:?}");
    for (g, w) in got.iter().zip(&want) {
        assert_eq!((g.1, g.2), (w.1, w.2), "{what}: got {got:?}, want {want:?}");
        assert!((g.0 - w.0).abs() <= tol * w.0.max(1.0), "{what}: got {got:?}, want {want:?}");
    }
    let len = dot(d, d).sqrt();
    for r in rows {
        // The reported point is p0 + t·d on the ray, with d normalised.
        let (t, p) = (r.t.unwrap(), r.p.unwrap());
        for k in 0..3 {
            let exp = o[k] + t * d[k] / len;
            assert!((p[k] - exp).abs() <= tol * t.max(1.0), "{what}: point {p:?} at t {t}");
        }
    }
}

/// The ray 4 below the lecture's axis, along +z: it enters A at μ = 15 (half-chord 3),
/// crosses C at μ = 18 ∓ √3 (C's centre is 1 away from the line) and leaves A at 21; it
/// passes 4 from B's centre, clear of B (r = 3). (The ray 3 below the axis would graze B
/// tangentially at μ = 19, which is no test of anything but the tangency convention.)
#[test]
fn ray_through_sphere_c_matches_the_lecture_formula() {
    let (o, d) = ([0.0, -4.0, -10.0], [0.0, 0.0, 1.0]);
    let (want, _) = lecture_crossings(o, d);
    let s3 = 3f64.sqrt();
    assert_eq!(want, vec![(15.0, 0, 1), (18.0 - s3, 2, 1), (18.0 + s3, 2, 0), (21.0, 0, 0)]);
    let rays = rays_csv("ox,oy,oz,dx,dy,dz", &[[o, d].concat()]);
    for (precision, tol) in [("f32", 1e-6), ("f64", 1e-14)] {
        let rows = trace(&scene("lecture.toml"), &rays, &["--all", "--precision", precision]);
        assert_matches_lecture(&rows, o, d, tol, precision);
        let near = trace(&scene("lecture.toml"), &rays, &["--precision", precision]);
        assert_eq!((near.len(), near[0].t, near[0].object), (1, Some(15.0), 0), "{precision}");
    }
}

/// From C's centre along +x: C is left at μ = 2 and A at μ = 4 (A's surface at y = −3,
/// z = 8 is at x = ±4); B is √10 from the line and missed. Exact in both precisions.
#[test]
fn ray_from_inside_sphere_c_leaves_c_then_a() {
    let rays = rays_csv("ox,oy,oz,dx,dy,dz", &[vec![0.0, -3.0, 8.0, 1.0, 0.0, 0.0]]);
    for precision in ["f32", "f64"] {
        let rows = trace(&scene("lecture.toml"), &rays, &["--all", "--precision", precision]);
        assert_rows_exact(&rows, &[hit(2.0, [2.0, -3.0, 8.0], 2, 0), hit(4.0, [4.0, -3.0, 8.0], 0, 0)], precision);
        assert_eq!(rows[0].n, Some([1.0, 0.0, 0.0]));
    }
}

/// C touches A from inside at (0, −5, 8). The ray up the line x = 0, z = 8 meets both
/// there at μ = 5: equal t are ordered by object (the primitive order), and nearest mode
/// reports the first of them.
#[test]
fn equal_t_hits_are_ordered_by_object() {
    let rays = rays_csv("ox,oy,oz,dx,dy,dz", &[vec![0.0, -10.0, 8.0, 0.0, 1.0, 0.0]]);
    for precision in ["f32", "f64"] {
        let rows = trace(&scene("lecture.toml"), &rays, &["--all", "--precision", precision]);
        let firsts: Vec<_> = rows.iter().take(2).map(|r| (r.t, r.object, r.enter)).collect();
        assert_eq!(firsts, [(Some(5.0), 0, Some(1)), (Some(5.0), 2, Some(1))], "{precision}");
        assert_eq!(rows.len(), 6, "{precision}: A, C, B, C, B, A: {rows:#?}");
        let near = trace(&scene("lecture.toml"), &rays, &["--precision", precision]);
        assert_eq!((near[0].t, near[0].object), (Some(5.0), 0), "{precision}");
    }
}

/// Rays from all around, aimed at points inside C (away from its rim): every crossing
/// with A, B and C as the lecture's formula gives it.
#[test]
fn rays_aimed_at_sphere_c_from_all_sides() {
    let mut rng = SplitMix64(0x5EED);
    let c = LECTURE_SPHERES[2].0;
    let mut rays = Vec::new();
    while rays.len() < 40 {
        let o = add(c, scale(rng.direction().to_array(), 30.0));
        let target = add(c, scale(rng.direction().to_array(), 1.2 * rng.unit()));
        let d = sub(target, o);
        // Stay clear of tangency with any sphere (hit or miss is decided by rounding there).
        if lecture_crossings(o, d).1 > 1e-3 {
            rays.push((o, d));
        }
    }
    let csv = rays_csv("ox,oy,oz,dx,dy,dz", &rays.iter().map(|(o, d)| [*o, *d].concat()).collect::<Vec<_>>());
    for (precision, tol) in [("f32", 2e-5), ("f64", 1e-12)] {
        let rows = trace(&scene("lecture.toml"), &csv, &["--all", "--precision", precision]);
        for (i, (o, d)) in rays.iter().enumerate() {
            let mine: Vec<Row> = rows.iter().filter(|r| r.ray == i).cloned().collect();
            assert!(mine.iter().any(|r| r.object == 2), "{precision} ray {i} missed C");
            assert_matches_lecture(&mine, *o, *d, tol, &format!("{precision} ray {i}"));
        }
    }
}

// ---------------------------------------------------------------------------------------
// Random rays over the seed scene.

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    a.map(|c| c * s)
}

/// `n` rays over the seed scene, in three families: from a sphere of radius 45 around the
/// scene aimed at random points of the region holding its objects (spheres, cylinder, light;
/// many reach the ground), from the same sphere aimed at the torus's box (the 100k-triangle
/// mesh, where f32 rounding decides between neighbouring triangles), and from the camera's
/// eye through random points of its view.
fn seed_rays(n: usize, seed: u64) -> String {
    let mut rng = SplitMix64(seed);
    let centre = [1.0, 4.0, 9.0];
    let mut rows = Vec::with_capacity(n);
    for i in 0..n {
        let around = add(centre, scale(rng.direction().to_array(), 45.0));
        let (o, target) = match i % 3 {
            0 => {
                let t = [rng.range(-8.0, 12.0), rng.range(-5.5, 14.5), rng.range(2.0, 18.0)];
                (around, t)
            }
            1 => {
                // The torus: R = 2, r = 0.8 (bumps up to 8%), centred on (8.5, -2.4, 15).
                let t = [rng.range(5.5, 11.5), rng.range(-5.0, 0.2), rng.range(12.0, 18.0)];
                (around, t)
            }
            _ => {
                let t = [rng.range(-8.0, 8.0), rng.range(-6.0, 6.0), 0.0];
                ([0.0, 0.0, -10.0], t)
            }
        };
        rows.push([o, sub(target, o)].concat());
    }
    rays_csv("ox,oy,oz,dx,dy,dz", &rows)
}

/// Rows grouped by ray index (`n` rays).
fn by_ray(rows: Vec<Row>, n: usize) -> Vec<Vec<Row>> {
    let mut out = vec![Vec::new(); n];
    let mut last = 0;
    for r in rows {
        assert!(r.ray >= last, "rows out of ray order");
        last = r.ray;
        out[r.ray].push(r);
    }
    out
}

/// The first `--all` row of each ray is its nearest row (same t, object, prim, normal);
/// a ray without `--all` rows is a miss in nearest mode; `--all` rows ascend in t.
#[test]
fn all_mode_starts_with_the_nearest_hit_on_seed_scene() {
    const N: usize = 600;
    let rays = seed_rays(N, 11);
    for precision in ["f32", "f64"] {
        let all = by_ray(trace(&scene("seed.toml"), &rays, &["--all", "--precision", precision]), N);
        let near = by_ray(trace(&scene("seed.toml"), &rays, &["--precision", precision]), N);
        let mut hits = 0;
        let mut multi = 0;
        for i in 0..N {
            assert_eq!(near[i].len(), 1, "{precision} ray {i}: one nearest row");
            let n = &near[i][0];
            match all[i].first() {
                None => assert_eq!(n.object, -1, "{precision} ray {i}: no --all rows but a hit"),
                Some(first) => {
                    assert_eq!(first, n, "{precision} ray {i}");
                    hits += 1;
                }
            }
            multi += (all[i].len() > 1) as usize;
            for w in all[i].windows(2) {
                assert!(w[0].t.unwrap() <= w[1].t.unwrap(), "{precision} ray {i}: t descends");
            }
        }
        assert!(hits > N / 2, "{precision}: only {hits} of {N} rays hit: the test proves little");
        assert!(multi > N / 4, "{precision}: only {multi} rays cross more than one surface");
    }
}

/// f32 (the GPU's mirror) against f64 (the oracle) on the seed scene: the same object for
/// at least 99.9% of rays, and where they agree, t within a relative 1e-4.
#[test]
fn f32_agrees_with_f64_on_seed_scene() {
    const N: usize = 3000;
    let rays = seed_rays(N, 12);
    let r32 = trace(&scene("seed.toml"), &rays, &["--precision", "f32"]);
    let r64 = trace(&scene("seed.toml"), &rays, &["--precision", "f64"]);
    assert_eq!((r32.len(), r64.len()), (N, N));
    let mut same = 0;
    let mut hits = 0;
    let mut worst = 0.0f64;
    let mut per_object = std::collections::BTreeMap::new();
    for (a, b) in r32.iter().zip(&r64) {
        *per_object.entry(b.object).or_insert(0usize) += 1;
        assert_eq!(a.ray, b.ray);
        if a.object != b.object {
            continue;
        }
        same += 1;
        if a.object >= 0 {
            hits += 1;
            let (ta, tb) = (a.t.unwrap(), b.t.unwrap());
            let rel = (ta - tb).abs() / tb;
            worst = worst.max(rel);
            assert!(rel < 1e-4, "ray {}: f32 t {ta}, f64 t {tb} (object {})", a.ray, a.object);
        }
    }
    assert!(same * 1000 >= N * 999, "objects agree on only {same} of {N} rays");
    assert!(hits > N / 2, "only {hits} hits: the test proves little");
    // Every object the rays can see first is reached (B and C lie inside glass sphere A).
    assert!([0, 3, 4, 5, 6].iter().all(|o| per_object.contains_key(o)), "objects hit: {per_object:?}");
    eprintln!(
        "f32 vs f64: same object on {same}/{N} rays; worst relative t difference {worst:e}; \
         rays per object (f64): {per_object:?}"
    );
}

// ---------------------------------------------------------------------------------------
// Bad input.

#[test]
fn missing_scene_file_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.csv");
    std::fs::write(&rays, "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n").unwrap();
    let missing = dir.path().join("no_such_scene.toml");
    let out = strahl(["trace".as_ref(), missing.as_os_str(), "--rays".as_ref(), rays.as_os_str()]);
    let err = assert_clean_failure(&out);
    assert!(err.contains(&missing.display().to_string()), "{err}");
    let png = dir.path().join("out.png");
    let out = strahl(["render".as_ref(), missing.as_os_str(), "-o".as_ref(), png.as_os_str()]);
    let err = assert_clean_failure(&out);
    assert!(err.contains(&missing.display().to_string()), "{err}");
    assert!(!png.exists());
}

#[test]
fn bad_rays_csv_names_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.csv");
    std::fs::write(&rays, "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n0,0,1.5x,0,0,1\n0,0,0,0,0,1\n").unwrap();
    let lecture = scene("lecture.toml");
    let out = strahl(["trace".as_ref(), lecture.as_os_str(), "--rays".as_ref(), rays.as_os_str()]);
    let err = assert_clean_failure(&out);
    assert!(err.contains(&format!("{}:3:", rays.display())), "file and line 3 expected:\n{err}");
    assert!(err.contains("oz"), "the column should be named:\n{err}");
    assert!(out.stdout.is_empty(), "no partial output on error");

    let missing = dir.path().join("no_such_rays.csv");
    let out = strahl(["trace".as_ref(), lecture.as_os_str(), "--rays".as_ref(), missing.as_os_str()]);
    let err = assert_clean_failure(&out);
    assert!(err.contains(&missing.display().to_string()), "{err}");
}

/// The output format is checked before the scene is read: a .bmp name fails at once, even
/// for a scene that does not exist, and no image is written.
#[test]
fn unknown_output_extension_fails_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let bmp = dir.path().join("out.bmp");
    let seed = scene("seed.toml");
    let out = strahl(["render".as_ref(), seed.as_os_str(), "-o".as_ref(), bmp.as_os_str()]);
    let err = assert_clean_failure(&out);
    assert!(err.contains("out.bmp"), "{err}");
    assert!(!err.contains("scene:"), "the scene was loaded before the name was checked:\n{err}");
    assert!(!String::from_utf8_lossy(&out.stdout).contains("rendered"));
    assert!(!bmp.exists());
    let missing = dir.path().join("no_such_scene.toml");
    let out = strahl(["render".as_ref(), missing.as_os_str(), "-o".as_ref(), bmp.as_os_str()]);
    let err = assert_clean_failure(&out);
    assert!(err.contains("out.bmp") && !err.contains("no_such_scene"), "{err}");
}

#[test]
fn zero_spp_is_rejected_by_the_argument_parser() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("out.png");
    let sphere = scene("sphere.toml");
    let out =
        strahl(["render".as_ref(), sphere.as_os_str(), "-o".as_ref(), png.as_os_str(), "--spp".as_ref(), "0".as_ref()]);
    let err = assert_clean_failure(&out);
    // clap's usage errors exit with status 2.
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--spp"), "{err}");
    assert!(!png.exists());
}

// ---------------------------------------------------------------------------------------
// Rendering.

#[test]
fn render_writes_a_png_showing_the_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("sphere.png");
    let sphere = scene("sphere.toml");
    let out = strahl([
        "render".as_ref(),
        sphere.as_os_str(),
        "-o".as_ref(),
        png.as_os_str(),
        "--backend".as_ref(),
        "cpu".as_ref(),
        "--width".as_ref(),
        "64".as_ref(),
        "--height".as_ref(),
        "48".as_ref(),
    ]);
    let err = stderr_of(&out);
    assert!(out.status.success(), "render failed:\n{err}");
    assert!(!err.contains("panicked"), "{err}");
    let img = image::open(&png).expect("a readable PNG").to_rgb8();
    assert_eq!(img.dimensions(), (64, 48));
    let centre = img.get_pixel(32, 24);
    let corner = img.get_pixel(0, 0);
    assert_ne!(centre, corner, "the sphere should cover the centre but not the corner");
    // The corner sees the background, the centre the lit orange sphere: red dominates there.
    assert!(centre[0] > centre[2], "centre {centre:?} is not orange");
}
