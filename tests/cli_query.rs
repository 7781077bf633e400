//! `strahl query`, end to end: the built binary on shipped scenes, its CSV and `.npy` read
//! back and checked against strahl-core's walks (`strahl_core::proximity`) and closed forms.
//!
//! - f64 rows equal the library's oracle bit for bit (values are printed in Rust's shortest
//!   round-trip form); f32 rows lie within the stated bound of them;
//! - `--signed` on the seed scene's spheres: negative exactly inside the solids;
//! - `--grid`: a valid `.npy` whose values are the `--points` answers at the grid's points;
//! - bad input: an error naming the file and line, or the flag, never a panic.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use strahl_core::math::V3;
use strahl_core::primitives::Primitives;
use strahl_core::proximity::closest;
use strahl_core::rng::SplitMix64;
use strahl_core::scene::Scene;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs `strahl query` with `args` from the package root.
fn strahl<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strahl")).current_dir(root()).arg("query").args(args).output().expect("run strahl")
}

fn ok(out: Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "strahl failed:\n{err}");
    String::from_utf8(out.stdout).expect("UTF-8 output")
}

fn failure(out: Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "expected a failure; stderr:\n{err}");
    assert!(!err.contains("panicked"), "a panic:\n{err}");
    err
}

/// One row of the output CSV: distance, foot, object, prim.
type Row = (f64, [f64; 3], i64, i64);

/// Rows of the output CSV; `None` for an empty scene's row.
fn rows(csv: &str) -> Vec<Option<Row>> {
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("point,distance,x,y,z,nx,ny,nz,object,prim"));
    lines
        .enumerate()
        .map(|(i, l)| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 10, "{l}");
            assert_eq!(f[0].parse::<usize>().unwrap(), i);
            if f[1].is_empty() {
                assert_eq!(f[8], "-1");
                return None;
            }
            let x = |k: usize| f[k].parse::<f64>().unwrap();
            Some((x(1), [x(2), x(3), x(4)], f[8].parse().unwrap(), f[9].parse().unwrap()))
        })
        .collect()
}

fn points_file(dir: &Path, points: &[V3<f64>]) -> PathBuf {
    let mut text = String::from("x,y,z\n");
    for p in points {
        text.push_str(&format!("{},{},{}\n", p.x, p.y, p.z));
    }
    let path = dir.join("points.csv");
    std::fs::write(&path, text).unwrap();
    path
}

fn seed_points(n: usize) -> Vec<V3<f64>> {
    let mut rng = SplitMix64(17);
    (0..n).map(|_| rng.cube(12.0) + V3::new(0.0, 0.0, 8.0)).collect()
}

#[test]
fn f64_rows_are_the_oracle_s_and_f32_rows_lie_within_the_bound() {
    let dir = tempfile::tempdir().unwrap();
    let points = seed_points(400);
    let file = points_file(dir.path(), &points);
    let seed = root().join("assets/scenes/seed.toml");
    let f64_rows = rows(&ok(strahl(&[
        seed.as_os_str(),
        "--points".as_ref(),
        file.as_os_str(),
        "--precision".as_ref(),
        "f64".as_ref(),
    ])));
    let f32_rows = rows(&ok(strahl(&[seed.as_os_str(), "--points".as_ref(), file.as_os_str()])));
    let scene = Scene::load(&seed).unwrap();
    let prims = Primitives::<f64>::from_scene(&scene);
    let bvh = strahl_core::accel::Bvh::build(&prims);
    for (k, p) in points.iter().enumerate() {
        let want = closest(&bvh, &prims, *p).unwrap();
        let tag = prims.tag(want.prim_ref);
        let (d, foot, object, prim) = f64_rows[k].unwrap();
        assert_eq!(d, want.distance(), "point {k}");
        assert_eq!(foot, want.foot.point.to_array(), "point {k}");
        assert_eq!((object, prim), (tag.object as i64, tag.face as i64), "point {k}");
        let (d32, ..) = f32_rows[k].unwrap();
        let bound = 4.0 * f32::EPSILON as f64 * (p.abs().max_component() + 40.0);
        assert!((d32 - d).abs() <= bound, "point {k}: f32 {d32}, f64 {d}");
    }
}

#[test]
fn signed_distances_are_negative_inside_the_solids() {
    let dir = tempfile::tempdir().unwrap();
    // On the axis of the seed scene's spheres (centres (0, 0, 8) r 5, (0, 0, 9) r 3,
    // (0, −3, 8) r 2): inside the first two, 1 from the third; inside the first, 0.5 from
    // it and the second; outside, 4 from the first; 5 above the ground (y = −5).
    let points = [V3::new(0.0, 0.0, 8.0), V3::new(0.0, 0.0, 12.5), V3::new(0.0, 0.0, -1.0), V3::new(0.0, 0.0, 20.0)];
    let file = points_file(dir.path(), &points);
    let out = rows(&ok(strahl(&[
        "assets/scenes/seed.toml",
        "--points",
        file.to_str().unwrap(),
        "--signed",
        "--precision",
        "f64",
    ])));
    let d: Vec<f64> = out.iter().map(|r| r.unwrap().0).collect();
    assert_eq!(d, vec![-1.0, -0.5, 4.0, 5.0]);
}

#[test]
fn grids_are_npy_arrays_of_the_points_answers() {
    let dir = tempfile::tempdir().unwrap();
    let npy = dir.path().join("sdf.npy");
    let out = strahl(&["assets/scenes/seed.toml", "--grid", "5", "--signed", "-o", npy.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    let bytes = std::fs::read(&npy).unwrap();
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!((10 + hlen) % 64, 0);
    let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
    assert!(header.contains("'descr': '<f4'") && header.contains("'shape': (5, 5, 5)"), "{header}");
    let values: Vec<f32> = bytes[10 + hlen..].chunks(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert_eq!(values.len(), 125);
    // The grid's points, from the bounds and spacing it printed, answered through --points.
    let nums = |label: &str| -> Vec<f64> {
        let s = &err[err.find(label).unwrap() + label.len()..];
        let s = &s[s.find('(').unwrap() + 1..s.find(')').unwrap()];
        s.split(',').map(|v| v.trim().parse().unwrap()).collect()
    };
    let (lo, step) = (nums("over "), nums("spacing "));
    let mut points = Vec::new();
    for k in 0..5 {
        for j in 0..5 {
            for i in 0..5 {
                points.push(V3::new(
                    lo[0] + i as f64 * step[0],
                    lo[1] + j as f64 * step[1],
                    lo[2] + k as f64 * step[2],
                ));
            }
        }
    }
    let file = points_file(dir.path(), &points);
    let answers = rows(&ok(strahl(&["assets/scenes/seed.toml", "--points", file.to_str().unwrap(), "--signed"])));
    for (i, (v, a)) in values.iter().zip(&answers).enumerate() {
        let d = a.unwrap().0;
        // The printed points are the grid's to 17 digits: equal f32 distances, or within a
        // rounding of them.
        assert!((*v as f64 - d).abs() <= 1e-5 * d.abs().max(1.0), "grid point {i}: {v} vs {d}");
    }
    assert!(values.iter().any(|v| *v < 0.0) && values.iter().any(|v| *v > 0.0));
}

#[test]
fn bad_input_is_an_error_that_says_where() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "x,y,z\n0,0,0\n1,nan,2\n").unwrap();
    let err = failure(strahl(&["assets/scenes/seed.toml", "--points", bad.to_str().unwrap()]));
    assert!(err.contains("bad.csv:3: y: must be finite"), "{err}");
    let err = failure(strahl(&["assets/scenes/seed.toml", "--grid", "0", "-o", "x.npy"]));
    assert!(err.contains("--grid 0: the grid's side must be 2 to 1024"), "{err}");
    let err = failure(strahl(&["assets/scenes/seed.toml", "--grid", "8"]));
    assert!(err.contains("give -o FILE.npy"), "{err}");
    // The plane scene without its sphere: nothing bounded to lay a grid over.
    let text = std::fs::read_to_string(root().join("assets/scenes/plane.toml")).unwrap();
    let sphere = text.find("[[objects]]\ntype = \"sphere\"").expect("plane.toml's sphere");
    let rest = sphere + text[sphere..].find("[[lights]]").unwrap();
    let planes = dir.path().join("planes.toml");
    std::fs::write(&planes, format!("{}{}", &text[..sphere], &text[rest..])).unwrap();
    let err =
        failure(strahl(&[planes.to_str().unwrap(), "--grid", "8", "-o", dir.path().join("p.npy").to_str().unwrap()]));
    assert!(err.contains("no bounded geometry"), "{err}");
    let err = failure(strahl(&["assets/scenes/seed.toml", "--points", dir.path().join("none.csv").to_str().unwrap()]));
    assert!(err.contains("none.csv: cannot read points file"), "{err}");
    assert!(!dir.path().join("p.npy").exists());
}
