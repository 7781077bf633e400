//! What the command line does with its files under faults: outputs written atomically (a
//! failed write keeps the previous file), bad output paths found before any work, inputs read
//! within stated sizes, messages that print each cause once and exit statuses (1: error,
//! 2: bad argument), and the fallback to the CPU where there is no Vulkan driver.
//!
//! A full disk is a small tmpfs, mounted where the tests run as root (CI does); elsewhere
//! those tests record a skip (`common::skip`) and return. The writer-error test of
//! `strahl_core::output` always runs.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scene(name: &str) -> PathBuf {
    root().join("assets/scenes").join(name)
}

fn strahl_env<S: AsRef<std::ffi::OsStr>>(args: &[S], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_strahl"));
    c.current_dir(root()).args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("cannot run the strahl binary")
}

fn strahl<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    strahl_env(args, &[])
}

fn stderr_of(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A failure with exit status `code`, an `error:` message and no panic; returns stderr.
fn fails(out: &Output, code: i32) -> String {
    let err = stderr_of(out);
    assert_eq!(out.status.code(), Some(code), "exit status; stderr:\n{err}");
    assert!(err.contains("error:") && !err.contains("panicked"), "{err}");
    err
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// A tmpfs of `size` mounted on a fresh folder, unmounted when dropped; None (with a note)
/// where mounting is not permitted (not root, or in a container without the capability).
struct Tmpfs {
    dir: tempfile::TempDir,
}

impl Tmpfs {
    fn mount(size: &str, read_only: bool) -> Option<Tmpfs> {
        let dir = tempfile::tempdir().ok()?;
        let opts = format!("size={size}{}", if read_only { ",ro" } else { "" });
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &opts, "strahl-test"])
            .arg(dir.path())
            .output()
            .is_ok_and(|o| o.status.success());
        if !ok {
            common::skip("cannot mount a tmpfs here (not root?): the full-disk and read-only checks did not run");
            return None;
        }
        Some(Tmpfs { dir })
    }
    fn path(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.dir.path()).output();
    }
}

// ---------------------------------------------------------------------------------------
// Atomic writes.

/// On a full disk `render` and `trace -o` fail with one clear message, and the previous file
/// is left whole (it was truncated and lost before), with no temporary file beside it.
#[test]
fn a_full_disk_keeps_the_previous_output() {
    let Some(fs) = Tmpfs::mount("96k", false) else { return };
    let d = fs.path();
    let exr = d.join("out.exr");
    let small = ["render", "--backend", "cpu", "--width", "4", "--height", "4", "-o"];
    let sphere = scene("sphere.toml");
    let out = strahl(&[&small[..], &[exr.to_str().unwrap(), sphere.to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", stderr_of(&out));
    let before = std::fs::read(&exr).unwrap();
    // 256 × 256 linear RGB floats of path-traced noise (EXR files are compressed losslessly,
    // and noise does not compress): about 190 KiB, more than the disk holds.
    let big = ["render", "--backend", "cpu", "--mode", "path", "--spp", "1", "--width", "256", "--height", "256", "-o"];
    let seed = scene("seed.toml");
    let out = strahl(&[&big[..], &[exr.to_str().unwrap(), seed.to_str().unwrap()]].concat());
    let err = fails(&out, 1);
    assert!(err.contains("cannot write") && err.contains("out.exr"), "{err}");
    assert_eq!(err.matches("No space left on device").count(), 1, "{err}");
    assert_eq!(std::fs::read(&exr).unwrap(), before, "the previous image is intact");
    assert_eq!(files_in(d), ["out.exr"], "no temporary file is left");

    // trace -o: 4000 rays give about 200 KiB of hits.
    let csv = d.join("hits.csv");
    std::fs::write(&csv, "ray,t\n").unwrap();
    let rays_dir = tempfile::tempdir().unwrap();
    let rays = rays_dir.path().join("rays.csv");
    let mut text = String::from("ox,oy,oz,dx,dy,dz\n");
    for i in 0..4000 {
        text.push_str(&format!("0,0,-10,{},{},1\n", (i % 7) as f64 * 1e-3, (i % 11) as f64 * 1e-3));
    }
    std::fs::write(&rays, text).unwrap();
    let args = ["trace", sphere.to_str().unwrap(), "--rays", rays.to_str().unwrap(), "--all", "--backend", "cpu"];
    let out = strahl(&[&args[..], &["-o", csv.to_str().unwrap()]].concat());
    fails(&out, 1);
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "ray,t\n");
    assert_eq!(files_in(d), ["hits.csv", "out.exr"]);
}

/// A written file replaces the old one only when complete: the old contents are never seen
/// half overwritten (checked here by writing over a file that is open for reading).
#[test]
fn outputs_replace_the_previous_file_whole() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("out.png");
    std::fs::write(&png, b"previous").unwrap();
    let held = std::fs::File::open(&png).unwrap();
    let args = ["render", "--backend", "cpu", "--width", "16", "--height", "12", "-o"];
    let out = strahl(&[&args[..], &[png.to_str().unwrap(), scene("sphere.toml").to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", stderr_of(&out));
    // The file still open is the previous one (a new inode took its name).
    let mut old = String::new();
    std::io::Read::read_to_string(&mut &held, &mut old).unwrap();
    assert_eq!(old, "previous");
    assert_eq!(image::open(&png).unwrap().width(), 16);
    assert_eq!(files_in(dir.path()), ["out.png"]);
}

// ---------------------------------------------------------------------------------------
// Output paths checked before the work.

/// A missing folder, a folder named like the file, and a file where a folder should be are
/// refused before the scene is even read (the scene here does not exist: its error would come
/// first otherwise), for render, trace -o and converge -o.
#[test]
fn bad_output_paths_fail_before_the_scene_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("file"), "x").unwrap();
    std::fs::create_dir(d.join("folder.png")).unwrap();
    let no_scene = d.join("no_such_scene.toml");
    let ns = no_scene.to_str().unwrap();
    let rays = d.join("rays.csv");
    std::fs::write(&rays, "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n").unwrap();
    let r = rays.to_str().unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["render".into(), ns.into(), "-o".into(), d.join("missing/out.png").display().to_string()],
            "does not exist",
        ),
        (vec!["render".into(), ns.into(), "-o".into(), d.join("folder.png").display().to_string()], "is a folder"),
        (
            vec!["render".into(), ns.into(), "-o".into(), d.join("file/out.png").display().to_string()],
            "is not a folder",
        ),
        (
            vec![
                "trace".into(),
                ns.into(),
                "--rays".into(),
                r.into(),
                "-o".into(),
                d.join("no/h.csv").display().to_string(),
            ],
            "does not exist",
        ),
        (
            vec!["converge".into(), ns.into(), "-o".into(), d.join("file/report").display().to_string()],
            "is not a folder",
        ),
    ];
    for (args, want) in cases {
        let out = strahl(&args);
        let err = fails(&out, 1);
        assert!(err.contains(want) && !err.contains("no_such_scene"), "{args:?}: {err}");
    }
    assert_eq!(files_in(d), ["file", "folder.png", "rays.csv"], "nothing was created");
}

/// A read-only folder is found before the render (a read-only mount: permission bits do not
/// stop root).
#[test]
fn a_read_only_folder_fails_before_the_render() {
    let Some(fs) = Tmpfs::mount("64k", true) else { return };
    let target = fs.path().join("out.png");
    let out = strahl(&["render", scene("seed.toml").to_str().unwrap(), "-o", target.to_str().unwrap()]);
    let err = fails(&out, 1);
    assert!(err.contains("Read-only file system"), "{err}");
    assert!(!err.contains("scene:") && out.stdout.is_empty(), "it rendered first:\n{err}");
    let report = fs.path().join("report");
    let out = strahl(&["converge", scene("seed.toml").to_str().unwrap(), "-o", report.to_str().unwrap()]);
    let err = fails(&out, 1);
    assert!(err.contains("Read-only file system") && !err.contains("scene:"), "{err}");
}

// ---------------------------------------------------------------------------------------
// Inputs within stated sizes.

/// /dev/zero as a scene or a rays file fails at once (it read until the kernel killed it).
#[test]
fn endless_inputs_fail_at_once() {
    let png = tempfile::tempdir().unwrap();
    let out = strahl(&["render", "/dev/zero", "-o", png.path().join("x.png").to_str().unwrap()]);
    let err = fails(&out, 1);
    assert!(err.contains("/dev/zero: cannot read scene file: is not a text file"), "{err}");
    let out = strahl(&["trace", scene("sphere.toml").to_str().unwrap(), "--rays", "/dev/zero"]);
    let err = fails(&out, 1);
    assert!(err.contains("/dev/zero:1: not a text file"), "{err}");
}

/// A scene file over the limit is refused from its size, unread.
#[test]
fn oversized_scene_files_are_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.toml");
    // Sparse: 300 MiB claimed, nothing written.
    std::fs::File::create(&big).unwrap().set_len(300 << 20).unwrap();
    let out = strahl(&["render", big.to_str().unwrap(), "-o", dir.path().join("x.png").to_str().unwrap()]);
    let err = fails(&out, 1);
    assert!(err.contains("big.toml: cannot read scene file: is larger than 256 MiB, the most accepted"), "{err}");
}

// ---------------------------------------------------------------------------------------
// Messages and exit statuses.

#[test]
fn os_errors_are_printed_once() {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("x.png");
    let out = strahl(&["render", dir.path().join("nope.toml").to_str().unwrap(), "-o", x.to_str().unwrap()]);
    let err = fails(&out, 1);
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, b"[camera]\xff\xfe\n").unwrap();
    let out = strahl(&["render", bad.to_str().unwrap(), "-o", x.to_str().unwrap()]);
    let err = fails(&out, 1);
    assert!(err.contains("bad.toml: cannot read scene file: is not valid UTF-8 (line 1)"), "{err}");
    assert_eq!(err.matches("UTF-8").count(), 1, "{err}");
    let bad_rays = dir.path().join("rays.csv");
    std::fs::write(&bad_rays, b"ox,oy,oz,dx,dy,dz\n0,0,\xff,0,0,1\n").unwrap();
    let out = strahl(&["trace", scene("sphere.toml").to_str().unwrap(), "--rays", bad_rays.to_str().unwrap()]);
    let err = fails(&out, 1);
    assert_eq!(err.matches("UTF-8").count(), 1, "{err}");
    assert!(err.contains("rays.csv:2:"), "{err}");
}

/// Flag values that are bad alone or together exit with status 2, as clap's own errors do.
#[test]
fn bad_arguments_exit_with_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("x.png");
    let xe = dir.path().join("x.exr");
    let xe = xe.to_str().unwrap();
    let sphere = scene("sphere.toml");
    let s = sphere.to_str().unwrap();
    let rays = dir.path().join("rays.csv");
    std::fs::write(&rays, "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n").unwrap();
    // 8192 × 8192 pixels in the file: at the limit, so one more row from a flag is too many.
    let wide = dir.path().join("wide.toml");
    let text = std::fs::read_to_string(&sphere).unwrap();
    let (before, after) = text.split_once("[image]").unwrap();
    let after = after.split_once("\n[").map_or(String::new(), |(_, rest)| format!("\n[{rest}"));
    std::fs::write(&wide, format!("{before}[image]\nwidth = 8192\nheight = 8192\n{after}")).unwrap();
    let cases: Vec<Vec<&str>> = vec![
        vec!["render", s, "-o", x.to_str().unwrap(), "--width", "10000", "--height", "10000"],
        vec!["render", wide.to_str().unwrap(), "-o", x.to_str().unwrap(), "--height", "8193"],
        vec!["render", s, "-o", "out.bmp"],
        vec!["trace", s, "--rays", rays.to_str().unwrap(), "--backend", "gpu", "--precision", "f64"],
        vec!["stiff", "--scale", "0"],
        vec!["converge", s, "--reference", "ref.png", "-o", dir.path().to_str().unwrap()],
        vec!["render", s, "-o", x.to_str().unwrap(), "--view", "filmic"],
        vec!["render", s, "-o", x.to_str().unwrap(), "--exposure", "nan"],
        vec!["render", s, "-o", x.to_str().unwrap(), "--exposure", "40"],
        vec!["render", s, "-o", xe, "--view", "agx"],
        vec!["render", s, "-o", xe, "--exposure", "-1"],
        vec!["merge", "part.exr", "-o", xe, "--view", "neutral"],
    ];
    // Without the viewer every `view` is refused before its arguments are read (below).
    let views: Vec<Vec<&str>> = vec![vec!["view", s, "--scale", "2"], vec!["view", s, "--screenshot", "shot.jpg"]];
    let cases = if cfg!(feature = "viewer") { [cases, views].concat() } else { cases };
    for args in cases {
        let out = strahl(&args);
        let err = stderr_of(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.starts_with("error:") && !err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(!x.exists() && !dir.path().join("x.exr").exists());
}

/// An orange lamp of radiance (50, 12, 2) seen directly: the standard view clips it to white,
/// AgX and Khronos PBR Neutral keep its hue (red above green above blue, blue below white), and
/// four stops less exposure show it orange in the standard view too. The pixels are those
/// `strahl_core::display` computes from the same radiance, so the PNG went through the view.
#[test]
fn png_views_keep_the_hue_of_a_bright_lamp() {
    use strahl_core::display::ViewTransform;
    let dir = tempfile::tempdir().unwrap();
    let lamp = dir.path().join("lamp.toml");
    std::fs::write(
        &lamp,
        "[camera]\neye = [0.0, 0.0, -5.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 30.0\n\
         [image]\nwidth = 8\nheight = 8\n[render]\nambient = [0.0, 0.0, 0.0]\nbackground = [0.0, 0.0, 0.0]\n\
         [[materials]]\nname = \"lamp\"\ntype = \"emissive\"\ncolor = [0.0, 0.0, 0.0]\nradiance = [50.0, 12.0, 2.0]\n\
         [[objects]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"lamp\"\n",
    )
    .unwrap();
    let centre = |args: &[&str]| {
        let png = dir.path().join("lamp.png");
        let base = ["render", lamp.to_str().unwrap(), "-o", png.to_str().unwrap(), "--backend", "cpu"];
        let out = strahl(&[&base[..], args].concat());
        assert!(out.status.success(), "{args:?}: {}", stderr_of(&out));
        image::open(&png).unwrap().to_rgb8().get_pixel(4, 4).0
    };
    // The emitter's radiance reaches the camera unchanged (no light, black background).
    let expect = |v: ViewTransform, ev: f32| v.encode8([50.0, 12.0, 2.0], ev);
    assert_eq!(centre(&[]), [255, 255, 255]);
    assert_eq!(centre(&["--view", "standard"]), [255, 255, 255]);
    for (name, v) in [("agx", ViewTransform::Agx), ("neutral", ViewTransform::Neutral)] {
        let got = centre(&["--view", name]);
        assert_eq!(got, expect(v, 0.0), "{name}");
        assert!(got[0] > got[1] && got[1] > got[2] && got[2] < 255, "{name}: {got:?}");
    }
    let dim = centre(&["--exposure", "-4"]);
    assert_eq!(dim, expect(ViewTransform::Standard, -4.0));
    assert!(dim[0] == 255 && dim[1] < 255 && dim[2] < dim[1], "{dim:?}");
}

/// A BOM-prefixed rays CSV (as spreadsheets write) reads as without one.
#[test]
fn a_byte_order_mark_in_a_rays_file_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.csv");
    std::fs::write(&rays, "\u{feff}ox,oy,oz,dx,dy,dz\n0,0,0,0,0,10\n").unwrap();
    let out = strahl(&["trace", scene("lecture.toml").to_str().unwrap(), "--rays", rays.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr_of(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("\n0,3,0,0,3,"));
}

/// `converge --reference` takes a linear EXR only: a PNG given a .exr name is refused too.
#[test]
fn converge_refuses_an_8_bit_reference() {
    let dir = tempfile::tempdir().unwrap();
    let fake = dir.path().join("ref.exr");
    image::RgbImage::new(64, 48).save_with_format(&fake, image::ImageFormat::Png).unwrap();
    let report = dir.path().join("report");
    let args = ["converge", "assets/scenes/seed.toml", "--backend", "cpu", "--width", "64", "--height", "48"];
    let out = strahl(&[&args[..], &["--reference", fake.to_str().unwrap(), "-o", report.to_str().unwrap()]].concat());
    let err = fails(&out, 1);
    assert!(err.contains("must be a linear OpenEXR image; this file is Png"), "{err}");
    assert!(!report.exists(), "a refused run creates nothing");
}

// ---------------------------------------------------------------------------------------
// No Vulkan driver.

/// No Vulkan driver, and no other backend searched (GL would find llvmpipe).
const NO_DRIVER: [(&str, &str); 2] = [("VK_DRIVER_FILES", "/nonexistent"), ("WGPU_BACKEND", "vulkan")];

/// Without a Vulkan driver converge, stiff and bench measure the CPU, as render falls back to
/// it; converge --backend gpu fails and leaves no folder behind.
#[test]
fn without_a_vulkan_driver_the_cpu_is_measured() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report");
    let small = ["--width", "16", "--height", "12", "--max-spp", "4", "--reference-spp", "16"];
    let r = report.to_str().unwrap();
    let both = [&["converge", "assets/scenes/sphere.toml", "--backend", "both"][..], &small, &["-o", r]].concat();
    let out = strahl_env(&both, &NO_DRIVER);
    let err = stderr_of(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("gpu backend unavailable") && err.contains("measuring the cpu only"), "{err}");
    let csv = std::fs::read_to_string(report.join("convergence.csv")).unwrap();
    assert!(csv.lines().skip(1).all(|l| l.starts_with("cpu,")) && csv.lines().count() == 4, "{csv}");
    // By default (auto) the CPU is measured and renders the reference, each said in one line.
    let out = strahl_env(&[&["converge", "assets/scenes/sphere.toml"][..], &small, &["-o", r]].concat(), &NO_DRIVER);
    let err = stderr_of(&out);
    assert!(out.status.success(), "{err}");
    assert_eq!(err.matches("backend: cpu (no GPU adapter found)").count(), 2, "{err}");
    let csv = std::fs::read_to_string(report.join("convergence.csv")).unwrap();
    assert!(csv.lines().skip(1).all(|l| l.starts_with("cpu,")) && csv.lines().count() == 4, "{csv}");

    let gpu_only = dir.path().join("gpu_only");
    let args = [
        &["converge", "assets/scenes/sphere.toml", "--backend", "gpu"][..],
        &small,
        &["-o", gpu_only.to_str().unwrap()],
    ];
    let out = strahl_env(&args.concat(), &NO_DRIVER);
    let err = fails(&out, 1);
    assert!(err.contains("no GPU adapter"), "{err}");
    assert!(!gpu_only.exists(), "a failed run leaves no folder");

    let out = strahl_env(&["stiff", "--scale", "0.0001"], &NO_DRIVER);
    let err = stderr_of(&out);
    assert!(out.status.success() && err.contains("running the cpu rows only"), "{err}");
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("robust cpu") && !table.contains("robust gpu"), "{table}");

    let out = strahl_env(
        &["bench", "--width", "16", "--height", "12", "--frames", "1", "assets/scenes/sphere.toml"],
        &NO_DRIVER,
    );
    let err = stderr_of(&out);
    assert!(out.status.success() && err.contains("measuring the cpu only"), "{err}");
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("\n| cpu | ") && !table.contains("\n| gpu"), "{table}");
    assert!(table.contains("adapter: none"), "{table}");
}
