//! The install scripts' logic, run with `--dry-run` (they print what they would change and
//! change nothing) under stand-ins for dpkg-query and apt-get: a fresh machine, whose dpkg has
//! never heard of Mesa's package, and machines with an old and a current Mesa.

use std::path::PathBuf;
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A folder of stand-in programs: `dpkg-query` answering `dpkg_query` (a shell script body),
/// and an `apt-get` that must never run in a dry run.
fn stand_ins(dpkg_query: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, body: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    };
    write("dpkg-query", dpkg_query);
    write("apt-get", "echo 'apt-get ran in a dry run' >&2; exit 99");
    dir
}

/// Standard error of `script --dry-run` under the stand-ins ([`stand_ins`]), which must succeed
/// and run no apt-get.
fn dry_run(script: &str, dpkg_query: &str) -> String {
    let bin = stand_ins(dpkg_query);
    let path = std::env::join_paths(
        std::iter::once(bin.path().to_path_buf())
            .chain(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())),
    )
    .unwrap();
    let out: Output =
        Command::new("bash").arg(root().join(script)).arg("--dry-run").env("PATH", path).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{script}: exit {:?}: {err}", out.status.code());
    assert!(!err.contains("apt-get ran"), "{err}");
    err
}

/// dpkg-query as on a fresh machine: mesa-vulkan-drivers is unknown, exit status 1 (a script
/// under `set -o pipefail` that took that status for an answer ended there, silently).
const UNKNOWN: &str = "echo \"dpkg-query: no packages found matching $3\" >&2; exit 1";

#[test]
fn on_a_fresh_machine_lavapipe_would_be_installed() {
    let err = dry_run("tools/install-lavapipe", UNKNOWN);
    assert!(
        err.contains("would run: ") && err.contains("apt-get install") && err.contains("mesa-vulkan-drivers"),
        "{err}"
    );
}

#[test]
fn an_old_mesa_is_replaced_and_a_current_one_kept() {
    let err = dry_run("tools/install-lavapipe", "printf 'install ok installed 22.3.6-1+deb12u1'");
    assert!(err.contains("apt-get install"), "{err}");
    let err = dry_run("tools/install-lavapipe", "printf 'install ok installed 25.0.7-2~bpo12+1'");
    assert!(err.contains("mesa-vulkan-drivers 25.0.7-2~bpo12+1 is installed") && !err.contains("would run"), "{err}");
}

#[test]
fn install_deps_names_every_missing_package_on_a_fresh_machine() {
    let err = dry_run("tools/install-deps", UNKNOWN);
    for package in ["libxcursor1", "libxi6", "libxkbcommon-x11-0", "mesa-vulkan-drivers"] {
        assert!(err.contains(package), "{package} not named: {err}");
    }
}

#[test]
fn a_bad_argument_is_refused() {
    for script in ["tools/install-lavapipe", "tools/install-deps"] {
        let out = Command::new("bash").arg(root().join(script)).arg("--frobnicate").output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{script}: {err}");
        assert!(err.contains("unknown argument --frobnicate"), "{script}: {err}");
    }
}
