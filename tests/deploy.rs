//! The cluster examples of `deploy/` where no real scheduler runs here: the Kubernetes Indexed
//! Job's command once per completion index with the job's environment (nothing here can run
//! a cluster or pull an image), the merged image equal to a whole render bit for bit; and the
//! Slurm task script's own errors, run as a task would be. The Slurm scripts themselves run
//! under a real Slurm cluster in tests/slurm.rs.

mod common;

use common::{exr_bits as bits, seed_whole_bits as whole};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// PATH with the built `strahl` (and `extra`, if any) first, as on a node where it is installed.
fn path_with_strahl(extra: Option<&Path>) -> std::ffi::OsString {
    let bin = Path::new(env!("CARGO_BIN_EXE_strahl")).parent().unwrap().to_path_buf();
    let rest = std::env::var_os("PATH").unwrap_or_default();
    let first = extra.map(Path::to_path_buf).into_iter().chain([bin]);
    std::env::join_paths(first.chain(std::env::split_paths(&rest))).unwrap()
}

/// Runs `c` from the repository root with `strahl` on PATH and no backend from the caller's
/// environment.
fn output(c: &mut Command, extra_path: Option<&Path>) -> Output {
    c.current_dir(root()).env("PATH", path_with_strahl(extra_path)).env_remove("STRAHL_BACKEND").output().unwrap()
}

fn run(c: &mut Command, extra_path: Option<&Path>) {
    let out = output(c, extra_path);
    assert!(
        out.status.success(),
        "{c:?}:\nstdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn the_slurm_task_script_says_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let task = |id: Option<&str>, args: &[&str]| {
        let mut c = Command::new("bash");
        c.arg("deploy/slurm/render-tile.sbatch").args(args).env_remove("SLURM_ARRAY_TASK_ID");
        if let Some(id) = id {
            c.env("SLURM_ARRAY_TASK_ID", id);
        }
        let o = output(&mut c, None);
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (code, err) = task(None, &["assets/scenes/seed.toml", out, "4"]);
    assert!(code != Some(0) && err.contains("job array"), "{code:?} {err}");
    let (code, err) = task(Some("0"), &["assets/scenes/seed.toml", out]);
    assert!(code == Some(2) && err.contains("usage"), "{code:?} {err}");
    // Task 4 of an array of 4 bands: strahl refuses the band.
    let (code, err) = task(Some("4"), &["assets/scenes/seed.toml", out, "4"]);
    assert!(code == Some(2) && err.contains("--tile") && err.contains("4/4"), "{code:?} {err}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "no part written");
}

/// The lines of the folded block (`- >-`) that follows `key:` in a manifest, joined as YAML
/// folds them (with spaces).
fn folded_args(manifest: &str, key: &str) -> String {
    let mut lines = manifest.lines().skip_while(|l| l.trim() != format!("{key}:")).skip(1);
    let head = lines.next().expect("args");
    assert_eq!(head.trim(), "- >-", "args as one folded block");
    let indent = |l: &str| l.len() - l.trim_start().len();
    let block: Vec<&str> = lines.take_while(|l| indent(l) > indent(head)).map(str::trim).collect();
    block.join(" ")
}

/// The value of `name:` in a manifest (the first such line), without quotes and comments.
fn value(manifest: &str, name: &str) -> String {
    let line = manifest.lines().find(|l| l.trim_start().starts_with(&format!("{name}:"))).expect(name);
    let v = line.split_once(':').unwrap().1;
    v.split('#').next().unwrap().trim().trim_matches('"').to_string()
}

#[test]
fn the_kubernetes_indexed_job_renders_bands_that_merge_into_the_whole_image() {
    let tiles = std::fs::read_to_string(root().join("deploy/kubernetes/render-tiles.yaml")).unwrap();
    let merge = std::fs::read_to_string(root().join("deploy/kubernetes/merge.yaml")).unwrap();
    let n: u32 = value(&tiles, "completions").parse().unwrap();
    let tiles_env = tiles.lines().skip_while(|l| !l.contains("name: TILES")).nth(1).unwrap();
    assert_eq!(value(tiles_env, "value"), n.to_string(), "TILES equals completions");
    assert_eq!(value(&tiles, "completionMode"), "Indexed");

    // The pod's paths on this machine: the image's assets are the repository's, /out a folder.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let local = |cmd: String| {
        cmd.replace("/opt/strahl/", &format!("{}/", root().display())).replace("/out/", &format!("{}/", out.display()))
    };
    // Small and quick: the size and backend set after the manifest's flags.
    let render = local(folded_args(&tiles, "args")) + " --width 64 --height 40 --backend cpu";
    assert!(render.contains("--spp") && render.contains("--mode path"), "{render}");
    for index in 0..n {
        run(
            Command::new("sh")
                .args(["-c", &render])
                .env("JOB_COMPLETION_INDEX", index.to_string())
                .env("TILES", n.to_string())
                .env("RAYON_NUM_THREADS", "1"),
            None,
        );
    }
    run(Command::new("sh").args(["-c", &local(folded_args(&merge, "args"))]), None);
    assert!(image::open(out.join("image.png")).is_ok(), "the merge job writes image.png");
    let spp = render.split_whitespace().skip_while(|w| *w != "--spp").nth(1).unwrap().to_string();
    let flags = ["--backend", "cpu", "--mode", "path", "--spp", &spp, "--width", "64", "--height", "40"];
    assert!(bits(&out.join("image.exr")) == whole(dir.path(), &flags), "the merged bands differ from the whole render");
}
