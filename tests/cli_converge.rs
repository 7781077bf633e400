//! `strahl converge` end to end on the CPU backend at a small size: the files it writes, that
//! its error falls as samples accumulate, and its refusals.

use std::path::PathBuf;
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn strahl(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strahl"))
        .current_dir(root())
        .args(args)
        .output()
        .expect("cannot run the strahl binary")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn converge_writes_csv_plot_and_reference_and_its_error_falls() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("report");
    let o = out_dir.to_str().unwrap();
    let args = ["converge", "assets/scenes/seed.toml", "--backend", "cpu", "--width", "64", "--height", "48"];
    let out = strahl(&[&args[..], &["--reference-spp", "256", "--max-spp", "16", "-o", o]].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    for f in ["reference.exr", "convergence.csv", "convergence.png"] {
        assert!(out_dir.join(f).metadata().is_ok_and(|m| m.len() > 0), "{f} missing");
    }
    let csv = std::fs::read_to_string(out_dir.join("convergence.csv")).unwrap();
    let rows: Vec<Vec<String>> = csv.lines().skip(1).map(|l| l.rsplitn(7, ',').map(String::from).collect()).collect();
    // Checkpoints 1, 2, 4, 8, 16; rsplitn gives the fields from the right: mean_flip first.
    assert_eq!(rows.len(), 5, "{csv}");
    let spp: Vec<u32> = rows.iter().map(|r| r[5].parse().unwrap()).collect();
    assert_eq!(spp, [1, 2, 4, 8, 16]);
    let rmse: Vec<f64> = rows.iter().map(|r| r[3].parse().unwrap()).collect();
    // Independent noise against the reference: 16 times the samples, about a quarter the RMSE.
    assert!(rmse[4] < 0.5 * rmse[0], "RMSE {rmse:?}");
    assert!(text(&out.stdout).contains("| cpu ("), "the table is printed");

    // The reference it wrote is accepted back, and a wrong size is refused by name.
    let reference = out_dir.join("reference.exr");
    let r = reference.to_str().unwrap();
    let again = strahl(&[&args[..], &["--reference", r, "--max-spp", "1", "-o", o]].concat());
    assert!(again.status.success(), "{}", text(&again.stderr));
    let wrong = strahl(&["converge", "assets/scenes/seed.toml", "--backend", "cpu", "--reference", r, "-o", o]);
    let err = text(&wrong.stderr);
    assert!(!wrong.status.success() && err.contains("the reference is 64x48, the render size is 640x480"), "{err}");
}

/// A run into a folder an earlier run filled: the earlier files go first (no mix of runs),
/// and the CSV holds every row printed so far, so a run killed half-way keeps them.
#[test]
fn an_interrupted_run_keeps_its_rows_and_no_earlier_files() {
    use std::io::BufRead;
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report");
    std::fs::create_dir(&report).unwrap();
    for f in ["reference.exr", "convergence.csv", "convergence.png"] {
        std::fs::write(report.join(f), "from an earlier run").unwrap();
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_strahl"))
        .current_dir(root())
        .args(["converge", "assets/scenes/seed.toml", "--backend", "cpu", "--width", "32", "--height", "24"])
        .args(["--reference-spp", "16", "--max-spp", "65536", "-o", report.to_str().unwrap()])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut printed = 0;
    for line in stdout.lines() {
        let line = line.unwrap();
        if line.trim_start().starts_with("cpu ") && line.contains(" spp ") {
            printed += 1;
            if printed == 3 {
                break;
            }
        }
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(printed, 3, "the run printed its rows");
    let csv = std::fs::read_to_string(report.join("convergence.csv")).unwrap();
    let spp: Vec<&str> = csv.lines().skip(1).map(|l| l.rsplit(',').nth(5).unwrap()).collect();
    assert!(spp.len() >= 3 && spp[..3] == ["1", "2", "4"], "{csv}");
    assert!(image::open(report.join("reference.exr")).is_ok(), "this run's reference");
    assert!(!report.join("convergence.png").exists(), "the earlier run's plot is gone");
}

#[test]
fn converge_refuses_bad_flags_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("file");
    std::fs::write(&file, "x").unwrap();
    let f = file.to_str().unwrap();
    let never = dir.path().join("never");
    let n = never.to_str().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (&["--time", "0", "-o", n], "positive number of seconds"),
        (&["--max-spp", "0", "-o", n], "--max-spp"),
        (&["-o", f], "exists and is not a directory"),
        (&["--reference", "/no/such.exr", "-o", n], "no such reference image"),
    ];
    for (extra, want) in cases {
        let out = strahl(&[&["converge", "assets/scenes/seed.toml", "--backend", "cpu"][..], extra].concat());
        let err = text(&out.stderr);
        assert!(!out.status.success() && err.contains(want), "{extra:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(!never.exists(), "a refused run creates nothing");
}
