//! The cluster examples of `deploy/` run as their schedulers would run them, on this machine:
//! the Slurm scripts under a stand-in `sbatch` that runs each array task at once with the
//! environment Slurm gives it (`SLURM_ARRAY_TASK_ID`, `SLURM_CPUS_PER_TASK`) and the merge job
//! after them, and the Kubernetes Indexed Job's command once per completion index with the
//! job's environment. The merged image must equal a whole render bit for bit.

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

/// Small and quick, and path traced so that every pixel draws from its own random streams.
const FLAGS: [&str; 10] = ["--backend", "cpu", "--mode", "path", "--spp", "2", "--width", "96", "--height", "61"];

/// Every pixel's channels as bits, so that -0.0 and 0.0 are told apart.
fn bits(p: &Path) -> Vec<[u32; 3]> {
    strahl_core::image::read_exr(p).unwrap().image.pixels.iter().map(|px| px.map(f32::to_bits)).collect()
}

/// The whole image rendered at once with `flags`, as bits.
fn whole(dir: &Path, flags: &[&str]) -> Vec<[u32; 3]> {
    let whole = dir.join("whole.exr");
    run(
        Command::new(env!("CARGO_BIN_EXE_strahl"))
            .args(["render", "assets/scenes/seed.toml", "-o", whole.to_str().unwrap()])
            .args(flags),
        None,
    );
    bits(&whole)
}

/// A stand-in for `sbatch` as `deploy/slurm/submit.sh` calls it: an array job runs its tasks
/// one after another, each with the environment Slurm sets; a job with `--dependency=afterok:ID`
/// is refused unless job ID succeeded; `--wrap` runs its command with sh. Prints the job id
/// (as `--parsable` does).
const FAKE_SBATCH: &str = r#"#!/bin/bash
set -u
jobs=$(dirname "$0")/jobs
mkdir -p "$jobs"
id=$(( $(ls "$jobs" | wc -l) + 100 ))
array= wrap= script=
while (($#)); do
    case $1 in
        --array=*) array=${1#--array=} ;;
        --wrap) wrap=$2; shift ;;
        --dependency=afterok:*)
            dep=${1#--dependency=afterok:}
            [[ $(cat "$jobs/$dep" 2>/dev/null) == ok ]] || { echo "sbatch: job $dep did not succeed" >&2; exit 1; } ;;
        --*) ;;
        *) script=$1; shift; break ;;
    esac
    shift
done
status=ok
if [[ -n $wrap ]]; then
    sh -c "$wrap" >&2 || status=failed
else
    first=${array%-*} last=${array#*-}
    for ((t = first; t <= last; t++)); do
        SLURM_ARRAY_JOB_ID=$id SLURM_ARRAY_TASK_ID=$t SLURM_CPUS_PER_TASK=1 bash "$script" "$@" >&2 || status=failed
    done
fi
echo "$status" > "$jobs/$id"
echo "$id"
"#;

#[test]
fn the_slurm_array_renders_bands_that_merge_into_the_whole_image() {
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    let sbatch = bin.join("sbatch");
    std::fs::write(&sbatch, FAKE_SBATCH).unwrap();
    std::fs::set_permissions(&sbatch, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    // A space in the output folder: the merge job's command must quote it.
    let out = dir.path().join("seed render");
    run(
        Command::new("bash")
            .args(["deploy/slurm/submit.sh", "assets/scenes/seed.toml", out.to_str().unwrap(), "4"])
            .args(FLAGS),
        Some(&bin),
    );
    for k in 0..4 {
        assert!(out.join(format!("part-{k}.exr")).is_file(), "band {k} of 4");
    }
    assert!(!out.join("part-4.exr").exists());
    let png = image::open(out.join("image.png")).expect("the merge job writes image.png").to_rgb8();
    assert_eq!(png.dimensions(), (96, 61));
    assert!(bits(&out.join("image.exr")) == whole(dir.path(), &FLAGS), "the merged bands differ from the whole render");
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
