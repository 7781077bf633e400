//! The variants as WGSL text for browsers ([`crate::shaders::wgsl`]): naga reads the text
//! with exact literals as it reads its own, and Chromium's compiler, Tint, compiles every
//! variant that WebGPU can run (`tools/browser/`, in headless Chromium).

use super::*;
use crate::shaders::{exact_f32_literals, write_wgsl};
use std::path::{Path, PathBuf};

/// Records that the running test skipped its checks, as the integration tests do
/// (`tests/common/mod.rs`, `skip`): `SKIPPED <test>: <why>` on standard error and appended to
/// the file `STRAHL_SKIP_LOG` names, which `.ci/run` counts.
fn skip(why: &str) {
    let test = std::thread::current().name().unwrap_or("a test").to_string();
    let line = format!("SKIPPED {test}: {why}");
    eprintln!("{line}");
    if let Some(log) = std::env::var_os("STRAHL_SKIP_LOG") {
        use std::io::Write;
        let appended =
            std::fs::OpenOptions::new().create(true).append(true).open(&log).and_then(|mut f| writeln!(f, "{line}"));
        appended.unwrap_or_else(|e| panic!("cannot record the skip in {}: {e}", Path::new(&log).display()));
    }
}

/// naga's own WGSL of a module, and naga's reading of a WGSL text written back by naga.
fn naga_text(m: &naga::Module, info: &naga::valid::ModuleInfo) -> String {
    naga::back::wgsl::write_string(m, info, naga::back::wgsl::WriterFlags::empty()).unwrap()
}
fn reread(name: &str, text: &str) -> Result<String, String> {
    let m = naga::front::wgsl::parse_str(text)
        .map_err(|e| format!("{name}: naga cannot read it: {}", e.emit_to_string(text)))?;
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), CAPABILITIES)
        .validate(&m)
        .map_err(|e| format!("{name}: naga's validator refuses it: {:?}", e.into_inner()))?;
    Ok(naga_text(&m, &info))
}

/// For every variant [`keys_to_translate`] names: the text with exact literals is what naga
/// reads its own text as (both read back by naga, validated and written again give the same
/// text), the rewrite is done once and for all (rewriting it again changes nothing), and it
/// has no decimal f32 literal that Tint refuses.
#[test]
fn exact_literals_change_nothing_naga_reads() {
    use rayon::prelude::*;
    let variants = keys_to_translate();
    let rewritten: Vec<usize> = variants
        .par_iter()
        .map(|&(p, key)| {
            let name = format!("{p:?} {}", key.label());
            let m = compose(p, key).unwrap();
            let info = validate(p, key, &m).unwrap();
            let raw = naga_text(&m, &info);
            let exact = write_wgsl(p, key, &m, &info).unwrap();
            assert_eq!(exact_f32_literals(&exact), exact, "{name}: rewriting twice changes the text");
            assert_eq!(reread(&name, &exact), reread(&name, &raw), "{name}: naga reads the exact text otherwise");
            assert!(!exact.contains("340282350000000000000000000000000000000f"), "{name}: f32::MAX in decimal");
            let differ = raw
                .split(|c: char| !c.is_ascii_alphanumeric() && c != '.')
                .zip(exact.split(|c: char| !c.is_ascii_alphanumeric() && c != '.'));
            differ.filter(|(a, b)| a != b).count()
        })
        .collect();
    assert!(rewritten.iter().all(|&n| n > 0), "every variant has an inexact literal (f32::MAX, the tables)");
}

/// A program found on `PATH`.
fn on_path(name: &str) -> Option<PathBuf> {
    let paths = std::env::var_os("PATH")?;
    std::env::split_paths(&paths).map(|d| d.join(name)).find(|p| p.is_file())
}

/// Whether a pipeline of `p` for `key` that uses `storage` storage buffers may need more than
/// the device offers per stage (the check lists those and builds the others): the wavefront
/// tracer's kernels, which bind the scene and their queues and run only on devices with room
/// for them, and the variants of split scenes, which bind a part more per split and are
/// refused before upload where the device lacks them (`Split::plan`) — up to that bound.
fn may_exceed(p: Program, key: FeatureKey, storage: usize) -> bool {
    let split = crate::split::Split::of_key(key);
    p == Program::Wavefront || storage <= (crate::MIN_STORAGE_BUFFERS + split.extra_bindings()) as usize
}

/// A variant written for the check: its file, and per entry point the storage buffers it uses.
struct Written {
    file: String,
    program: Program,
    key: FeatureKey,
    entry_points: Vec<(String, usize)>,
}

/// Every variant [`keys_to_translate`] names that WebGPU can run (not LOAD64: WebGPU has no
/// 64-bit integers), written as WGSL by [`crate::shaders::wgsl`], compiles in Tint, Chromium's
/// WGSL compiler (headless Chromium, WebGPU on SwiftShader, through `tools/browser/`):
/// no error in `getCompilationInfo()` (warnings are printed), and every compute pipeline
/// (`layout: 'auto'`) builds whose entry point uses (by naga's count) no more storage buffers
/// than the device offers per stage, and every one over that count is refused. Those are
/// listed, and allowed only where [`may_exceed`] says.
///
/// Without `node`, Chromium (`/usr/bin/chromium`, or `$CHROMIUM`) or the package's
/// `npm ci`, it records a skip; `.ci/run` installs all three.
#[test]
fn every_variant_compiles_in_tint() {
    use rayon::prelude::*;
    let started = std::time::Instant::now();
    let package = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/browser");
    let Some(node) = on_path("node") else {
        return skip("node not found: install the Debian packages nodejs and npm (.ci/run does)");
    };
    let chromium = std::env::var_os("CHROMIUM").map_or_else(|| PathBuf::from("/usr/bin/chromium"), PathBuf::from);
    if !chromium.is_file() {
        return skip(&format!(
            "no Chromium at {}: install the Debian package chromium (.ci/run does)",
            chromium.display()
        ));
    }
    if !package.join("node_modules/playwright-core").is_dir() {
        return skip(&format!("playwright-core is not installed: run npm ci in {}", package.display()));
    }
    // STRAHL_TINT_DIR=DIR keeps the files there, to run tools/browser/tint.js on by hand.
    let temporary = tempfile::tempdir().unwrap();
    let dir = std::env::var_os("STRAHL_TINT_DIR").map_or_else(|| temporary.path().to_path_buf(), PathBuf::from);
    std::fs::create_dir_all(&dir).unwrap();
    let variants: Vec<(Program, FeatureKey)> =
        keys_to_translate().into_iter().filter(|(_, k)| !k.contains(FeatureKey::LOAD64)).collect();
    let files: Vec<Written> = variants
        .par_iter()
        .enumerate()
        .map(|(i, &(p, key))| {
            let m = compose(p, key).unwrap();
            let info = validate(p, key, &m).unwrap();
            let name = format!("{i:03}.wgsl");
            let text = write_wgsl(p, key, &m, &info).unwrap();
            std::fs::write(dir.join(&name), format!("// {p:?} {}\n{text}", key.label())).unwrap();
            let storage = |e: usize| {
                let uses = info.get_entry_point(e);
                let storage =
                    m.global_variables.iter().filter(|(_, g)| matches!(g.space, naga::AddressSpace::Storage { .. }));
                storage.filter(|&(h, _)| !uses[h].is_empty()).count()
            };
            let entry_points = m.entry_points.iter().enumerate().map(|(e, ep)| (ep.name.clone(), storage(e))).collect();
            Written { file: name, program: p, key, entry_points }
        })
        .collect();
    let written = started.elapsed();
    // The report and messages go to files (a pipe would fill), and a hung browser is stopped.
    let report_dir = tempfile::tempdir().unwrap();
    let (stdout, stderr) = (report_dir.path().join("report.json"), report_dir.path().join("stderr"));
    let mut child = std::process::Command::new(node)
        .arg(package.join("tint.js"))
        .args(["--chromium".as_ref(), chromium.as_os_str()])
        .arg(&dir)
        .stdout(std::fs::File::create(&stdout).unwrap())
        .stderr(std::fs::File::create(&stderr).unwrap())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(900);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("tools/browser/tint.js ran for 15 minutes: {}", std::fs::read_to_string(&stderr).unwrap());
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    };
    let messages = std::fs::read_to_string(&stderr).unwrap();
    assert!(status.success(), "tools/browser/tint.js failed ({status}): {messages}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&stdout).unwrap()).expect("the check's JSON report");
    let limit = report["limits"]["maxStorageBuffersPerShaderStage"].as_u64().expect("the device's limit") as usize;
    let modules = report["modules"].as_array().expect("the report's modules");
    assert_eq!(modules.len(), files.len(), "a report per module");
    let (mut failures, mut warnings, mut over, mut pipelines) = (Vec::new(), Vec::new(), Vec::new(), 0);
    for (module, Written { file, program: p, key, entry_points }) in modules.iter().zip(&files) {
        assert_eq!(module["name"], file.as_str());
        let name = format!("{p:?} {} ({file})", key.label());
        let strings = |v: &serde_json::Value| -> Vec<String> {
            v.as_array().unwrap().iter().map(|s| s.as_str().unwrap().to_string()).collect()
        };
        failures.extend(strings(&module["errors"]).iter().map(|e| format!("{name}: {e}")));
        warnings.extend(strings(&module["warnings"]).iter().map(|w| format!("{name}: {w}")));
        if !strings(&module["errors"]).is_empty() {
            continue;
        }
        let built = module["pipelines"].as_array().unwrap();
        let found: Vec<&str> = built.iter().map(|b| b["entryPoint"].as_str().unwrap()).collect();
        let wanted: Vec<&str> = entry_points.iter().map(|(e, _)| e.as_str()).collect();
        assert_eq!(found, wanted, "{name}: the check's entry points");
        for (b, (entry_point, storage)) in built.iter().zip(entry_points) {
            pipelines += 1;
            if *storage > limit {
                let allowed = may_exceed(*p, *key, *storage);
                over.push((allowed, format!("{name} {entry_point}: {storage} storage buffers: {}", b["errors"])));
                // One that builds means naga's count is not the browser's: the limits to be
                // checked would be wrong.
                if b["ok"] == true {
                    failures
                        .push(format!("{name} {entry_point}: builds with {storage} storage buffers (naga's count)"));
                }
            } else if b["ok"] != true {
                failures.push(format!("{name} {entry_point} ({storage} storage buffers): {}", b["errors"]));
            }
        }
    }
    eprintln!(
        "{} modules, {pipelines} pipelines, {} over the device's {limit} storage buffers per stage, {} warnings: \
         written in {written:.1?}, all in {:.1?} ({}, {})",
        files.len(),
        over.len(),
        warnings.len(),
        started.elapsed(),
        report["browser"],
        report["adapter"]["architecture"]
    );
    for (_, o) in over.iter().take(5) {
        eprintln!("over the limit: {o}");
    }
    for w in warnings.iter().take(5) {
        eprintln!("warning: {w}");
    }
    assert!(failures.is_empty(), "{} failures in Tint, first: {}", failures.len(), failures[0]);
    let unexpected: Vec<&String> = over.iter().filter(|(allowed, _)| !allowed).map(|(_, o)| o).collect();
    assert!(unexpected.is_empty(), "over the device's storage buffers: {unexpected:?}");
}
