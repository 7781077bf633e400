//! Renders split across machines, end to end through the binary: `render --region` and
//! `--tile` write EXR parts whose data windows are their regions, `merge` assembles them into
//! exactly the pixels of a whole render (bit for bit, per backend, in Whitted and path modes),
//! and parts that overlap, leave pixels out or come from different renders are refused.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;
use strahl_core::image::{Region, read_exr, read_exr_placement};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn strahl(args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_strahl"))
        .current_dir(root())
        .args(args)
        .output()
        .expect("cannot run the strahl binary")
}

fn ok(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "stderr:\n{err}");
    err
}

/// A failure with exit status `code` and an `error:` message (no panic); returns stderr.
fn fails(out: &Output, code: i32) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "exit status; stderr:\n{err}");
    assert!(err.contains("error") && !err.contains("panicked"), "{err}");
    err
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The seed scene at 300x200 (tiles of 128 pixels straddle every cut below), 3 path samples.
const SIZE: [&str; 4] = ["--width", "300", "--height", "200"];

fn render(out: &Path, backend: &str, mode: &str, extra: &[&str]) {
    let spp: &[&str] = match (extra.contains(&"--spp"), mode) {
        (true, _) => &[],
        (false, "path") => &["--spp", "3"],
        (false, _) => &["--spp", "1"],
    };
    let args = [
        &["render", "assets/scenes/seed.toml", "-o", s(out), "--backend", backend, "--mode", mode][..],
        spp,
        &SIZE,
        extra,
    ]
    .concat();
    ok(&strahl(&args));
}

/// Every pixel's channels as bits, so that -0.0 and 0.0 or two NaNs are told apart.
fn bits(path: &Path) -> (Vec<[u32; 3]>, Region, (u32, u32)) {
    let f = read_exr(path).unwrap();
    (f.image.pixels.iter().map(|p| p.map(f32::to_bits)).collect(), f.placement.region, f.placement.full)
}

fn split_equals_whole(backend: &str, mode: &str) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = d.join("whole.exr");
    render(&whole, backend, mode, &[]);
    // Three bands, and an irregular split by regions whose corners are not on tile bounds.
    let mut tiles = Vec::new();
    for k in 0..3 {
        let part = d.join(format!("band{k}.exr"));
        render(&part, backend, mode, &["--tile", &format!("{k}/3")]);
        tiles.push(part);
    }
    let cuts = ["0,0,131,77", "131,0,300,77", "0,77,300,190", "0,190,7,200", "7,190,300,200"];
    let mut regions = Vec::new();
    for (i, r) in cuts.iter().enumerate() {
        let part = d.join(format!("region{i}.exr"));
        render(&part, backend, mode, &["--region", r]);
        regions.push(part);
    }
    let (want, _, _) = bits(&whole);
    assert!(want.iter().any(|p| p.iter().any(|&c| f32::from_bits(c) > 0.0)), "the render is not black");

    // Each part is a data window of the whole 300x200 display window.
    let p = read_exr_placement(&regions[1]).unwrap();
    assert_eq!((p.full, p.region), ((300, 200), Region { x0: 131, y0: 0, x1: 300, y1: 77 }));
    let p = read_exr_placement(&tiles[1]).unwrap();
    assert_eq!((p.full, p.region), ((300, 200), Region { x0: 0, y0: 66, x1: 300, y1: 133 }));

    for (name, parts) in [("bands", &tiles), ("regions", &regions)] {
        let merged = d.join(format!("merged-{name}.exr"));
        let mut args = vec!["merge"];
        // In reverse order: the order of the parts does not matter.
        args.extend(parts.iter().rev().map(|p| s(p)));
        args.extend(["-o", s(&merged)]);
        let out = strahl(&args);
        ok(&out);
        let (got, region, full) = bits(&merged);
        assert_eq!((region, full), (Region::whole(300, 200), (300, 200)));
        let differ = got.iter().zip(&want).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{backend} {mode}: {differ} pixels of the merged {name} differ from the whole render");
    }
}

#[test]
fn merged_parts_equal_the_whole_render_on_the_cpu() {
    split_equals_whole("cpu", "whitted");
    split_equals_whole("cpu", "path");
}

#[test]
fn merged_parts_equal_the_whole_render_on_the_gpu() {
    if common::gpu().is_none() {
        return;
    }
    split_equals_whole("gpu", "whitted");
    split_equals_whole("gpu", "path");
}

#[test]
fn merge_refuses_overlapping_missing_and_mismatched_parts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let part = |name: &str, extra: &[&str]| {
        let p = d.join(name);
        render(&p, "cpu", "whitted", extra);
        p
    };
    let top = part("top.exr", &["--region", "0,0,300,100"]);
    let bottom = part("bottom.exr", &["--region", "0,100,300,200"]);
    let left = part("left.exr", &["--region", "0,100,150,200"]);
    let band = part("band.exr", &["--tile", "1/4"]);
    let out = d.join("out.exr");
    let merge = |parts: &[&Path]| {
        let mut args = vec!["merge"];
        args.extend(parts.iter().map(|p| s(p)));
        args.extend(["-o", s(&out)]);
        strahl(&args)
    };

    let err = fails(&merge(&[&top, &bottom, &band]), 1);
    assert!(err.contains("overlap") && err.contains("region 0,50,300,100") && err.contains("band.exr"), "{err}");
    let err = fails(&merge(&[&top, &top, &bottom]), 1);
    assert!(err.contains("overlap in 30000 pixels"), "{err}");

    let err = fails(&merge(&[&top, &left]), 1);
    assert!(err.contains("15000") && err.contains("--region 150,100,300,200"), "{err}");
    // Bands (--tile) are named by number where every part is one.
    let err = fails(&merge(&[&band]), 1);
    assert!(err.contains("bands 0, 2, 3 of 4 missing") && err.contains("--tile 0/4"), "{err}");
    let err = fails(&merge(&[&band, &left]), 1);
    assert!(err.contains("uncovered") && err.contains("within the region 0,0,300,200"), "{err}");

    // A part of another render: more samples, another seed, another scene, another size.
    for (extra, what) in [
        (&["--spp", "2"][..], "samples per pixel 1 against 2"),
        (&["--seed", "7"][..], "seed 0 against 7"),
        (&["--max-depth", "2"][..], "max depth 5 against 2"),
    ] {
        let other = part("other.exr", &[&["--region", "0,100,300,200"][..], extra].concat());
        let err = fails(&merge(&[&top, &other]), 1);
        assert!(err.contains("come from different renders") && err.contains(what), "{extra:?}: {err}");
    }
    let other = d.join("other.exr");
    let args =
        ["render", "assets/scenes/spheres.toml", "-o", s(&other), "--backend", "cpu", "--region", "0,100,300,200"];
    ok(&strahl(&[&args[..], &SIZE].concat()));
    let err = fails(&merge(&[&top, &other]), 1);
    assert!(err.contains("different renders") && err.contains("scene (geometry"), "{err}");
    let args = ["render", "assets/scenes/seed.toml", "-o", s(&other), "--backend", "cpu", "--tile", "1/2"];
    ok(&strahl(&[&args[..], &["--width", "300", "--height", "201"]].concat()));
    let err = fails(&merge(&[&top, &other]), 1);
    assert!(err.contains("part of a 300x201 image") && err.contains("300x200"), "{err}");

    // Not an EXR part at all.
    let png = d.join("x.png");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let err = fails(&merge(&[&png]), 1);
    assert!(err.contains("x.png") && err.contains("not a readable OpenEXR file"), "{err}");
    assert!(!out.exists(), "a refused merge writes nothing");

    // A part is not a whole image: reading it as one says what to do.
    let err = strahl_core::image::Image::load(&top).unwrap_err().to_string();
    assert!(err.contains("strahl merge"), "{err}");
}

#[test]
fn bad_regions_and_tiles_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.exr");
    for (flags, says) in [
        (&["--region", "0,0,301,10"][..], "outside the 300x200 image"),
        (&["--region", "10,0,10,5"], "empty"),
        (&["--region", "1,2,3"], "X0,Y0,X1,Y1"),
        (&["--region", "a,b,c,d"], "X0,Y0,X1,Y1"),
        (&["--tile", "3/3"], "0 to N - 1"),
        (&["--tile", "0/0"], "N at least 1"),
        (&["--tile", "1"], "K/N"),
        (&["--tile", "0/201"], "at most 200"),
        (&["--tile", "0/2", "--region", "0,0,1,1"], "cannot be used with"),
    ] {
        let args =
            [&["render", "assets/scenes/seed.toml", "-o", s(&out), "--backend", "cpu"][..], &SIZE, flags].concat();
        let err = fails(&strahl(&args), 2);
        assert!(err.contains(says), "{flags:?}: {err}");
    }
    assert!(!out.exists());
}
