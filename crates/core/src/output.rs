//! Output files: checked before any work, written atomically.
//!
//! A file is written to a temporary file in the target's folder, synced to disk, and renamed
//! over the target only once complete: a full disk, an encoder error or a kill during the
//! write leaves the previous file as it was (and no temporary file behind, except after a
//! kill). The checks ([`check_file_target`], [`check_dir_target`]) let a command fail in a
//! second on a missing, unwritable or misnamed output instead of after the render.

use anyhow::{Context, Result, anyhow, bail};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The folder a file `path` lives in ("." for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Fails unless `dir` is an existing folder in which files can be created: creates and removes
/// an empty probe file there (permission bits alone say nothing about read-only mounts, or to
/// root).
fn check_writable_folder(dir: &Path, what: &Path) -> Result<()> {
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            bail!("{}: the folder {} does not exist", what.display(), dir.display())
        }
        Err(e) => bail!("{}: cannot use the folder {}: {e}", what.display(), dir.display()),
        Ok(m) if !m.is_dir() => bail!("{}: {} is not a folder", what.display(), dir.display()),
        Ok(_) => {}
    }
    tempfile::Builder::new()
        .prefix(".strahl-probe.")
        .tempfile_in(dir)
        .map(drop)
        .map_err(|e| anyhow!("{}: cannot write in {}: {e}", what.display(), dir.display()))
}

/// Fails, before any work, unless a file can be written at `path`: its folder exists and is
/// writable, and `path` is not a folder itself.
pub fn check_file_target(path: &Path) -> Result<()> {
    if path.as_os_str().is_empty() {
        bail!("the output file name is empty");
    }
    if path.is_dir() {
        bail!("{}: is a folder; give a file name", path.display());
    }
    check_writable_folder(folder_of(path), path)
}

/// Fails, before any work, unless `dir` is a writable folder or can be created as one (the
/// nearest existing folder above it is writable). Creates nothing.
pub fn check_dir_target(dir: &Path) -> Result<()> {
    if dir.exists() {
        if !dir.is_dir() {
            bail!("{}: exists and is not a directory", dir.display());
        }
        return check_writable_folder(dir, dir);
    }
    let mut above: PathBuf = dir.to_path_buf();
    loop {
        above = folder_of(&above).to_path_buf();
        if above.exists() || above == Path::new(".") || above.parent().is_none() {
            break;
        }
    }
    check_writable_folder(&above, dir)
}

/// Writes `path` through `write` atomically: into a temporary file beside it, synced, then
/// renamed over `path`. On any error the temporary file is removed and `path` is untouched.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut BufWriter<&File>) -> Result<()>) -> Result<()> {
    let dir = folder_of(path);
    let name = path.file_name().with_context(|| format!("{}: not a file name", path.display()))?;
    let prefix = format!(".{}.", name.to_string_lossy());
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        // Created with mode 0666 less the umask, as a plain File::create would be (tempfile's
        // default is 0600).
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let tmp = builder.tempfile_in(dir).map_err(|e| anyhow!("cannot write {}: {e}", path.display()))?;
    let mut w = BufWriter::new(tmp.as_file());
    write(&mut w).with_context(|| format!("cannot write {}", path.display()))?;
    w.flush().map_err(|e| anyhow!("cannot write {}: {e}", path.display()))?;
    drop(w);
    tmp.as_file().sync_all().map_err(|e| anyhow!("cannot write {}: {e}", path.display()))?;
    tmp.persist(path).map_err(|e| anyhow!("cannot write {}: {}", path.display(), e.error))?;
    // The rename itself reaches the disk with the folder's metadata; a folder that cannot be
    // opened or synced (some file systems) leaves it to the OS.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Writes `bytes` to `path` atomically ([`write_atomic`]).
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| Ok(w.write_all(bytes)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[test]
    fn a_failing_writer_leaves_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        std::fs::write(&path, "old contents\n").unwrap();
        // An encoder that fails half-way, as a full disk makes it do.
        let err = write_atomic(&path, |w| {
            w.write_all(b"new, half written")?;
            w.flush()?;
            Err(std::io::Error::new(std::io::ErrorKind::StorageFull, "No space left on device").into())
        })
        .unwrap_err();
        let msg = format!("{err:#}");
        assert!(msg.contains("cannot write") && msg.contains("No space left on device"), "{msg}");
        assert_eq!(msg.matches("No space left").count(), 1, "{msg}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old contents\n");
        assert_eq!(entries(dir.path()), ["out.csv"], "the temporary file is removed");

        write_bytes_atomic(&path, b"new contents\n").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new contents\n");
        assert_eq!(entries(dir.path()), ["out.csv"]);
    }

    #[cfg(unix)]
    #[test]
    fn written_files_get_the_usual_permissions() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let (atomic, plain) = (dir.path().join("a"), dir.path().join("b"));
        write_bytes_atomic(&atomic, b"x").unwrap();
        std::fs::write(&plain, b"x").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&atomic), mode(&plain));
    }

    #[test]
    fn bad_targets_are_named_before_any_work() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let missing = d.join("no/such/folder/x.png");
        let e = check_file_target(&missing).unwrap_err().to_string();
        assert!(e.contains("does not exist") && e.contains("no/such/folder"), "{e}");
        let e = check_file_target(d).unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");
        std::fs::write(d.join("file"), "").unwrap();
        let e = check_file_target(&d.join("file/x.png")).unwrap_err().to_string();
        assert!(e.contains("is not a folder"), "{e}");
        check_file_target(&d.join("x.png")).unwrap();
        assert_eq!(entries(d), ["file"], "the probe leaves nothing");

        check_dir_target(&d.join("new/report")).unwrap();
        assert!(!d.join("new").exists(), "checking creates nothing");
        let e = check_dir_target(&d.join("file")).unwrap_err().to_string();
        assert!(e.contains("exists and is not a directory"), "{e}");
        let e = check_dir_target(&d.join("file/report")).unwrap_err().to_string();
        assert!(e.contains("is not a folder"), "{e}");
    }
}
