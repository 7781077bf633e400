//! Input files read within a stated size: scene files, meshes, rays files, images and glTF
//! buffers. A regular file
//! over the limit is refused from its size before anything is read; a stream (a pipe, a
//! device such as /dev/zero) is refused as soon as it passes the limit or shows a NUL byte
//! (no text format strahl reads has one), so nothing grows without bound.
//!
//! Files can also be held in memory ([`hold_file`]): a web page, which has no file system,
//! hands over the files a scene refers to (its meshes, glTF buffers, images) with the scene,
//! and every read here looks there first.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, RwLock};

/// Files held in memory, by their path made [`normal`].
static HELD: RwLock<BTreeMap<PathBuf, Arc<[u8]>>> = RwLock::new(BTreeMap::new());

/// `path` with `.` left out and each `..` taken back against the folder before it, as the
/// path is written (no link is followed: held files have none): `scenes/../meshes/a.obj` is
/// `meshes/a.obj`.
fn normal(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.components().next_back(), Some(Component::RootDir)) => {}
            Component::ParentDir if matches!(out.components().next_back(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// Holds `bytes` as the file at `path` until [`release_files`]: reads of that path (after
/// [`normal`]) get them instead of the file system's.
pub fn hold_file(path: &Path, bytes: Vec<u8>) {
    HELD.write().unwrap_or_else(|e| e.into_inner()).insert(normal(path), bytes.into());
}

/// Lets go of every file [`hold_file`] held.
pub fn release_files() {
    HELD.write().unwrap_or_else(|e| e.into_inner()).clear();
}

fn held(path: &Path) -> Option<Arc<[u8]>> {
    let held = HELD.read().unwrap_or_else(|e| e.into_inner());
    if held.is_empty() { None } else { held.get(&normal(path)).cloned() }
}

/// Why a text input could not be read. No variant carries a `source`, so a message chain
/// prints each cause once.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("{0}")]
    Io(String),
    #[error("is larger than {}, the most accepted", size_name(*.limit))]
    TooLarge { limit: u64 },
    #[error("is not a text file (a NUL byte on line {line})")]
    Binary { line: usize },
    #[error("is not valid UTF-8 (line {line})")]
    NotUtf8 { line: usize },
}

/// 1-based line of byte `offset` in `bytes`.
fn line_of(bytes: &[u8], offset: usize) -> usize {
    bytes[..offset.min(bytes.len())].iter().filter(|&&b| b == b'\n').count() + 1
}

/// Reads UTF-8 text of at most `limit` bytes from `reader` (a leading byte-order mark is
/// dropped).
pub fn read_text_from(mut reader: impl Read, limit: u64) -> Result<String, ReadError> {
    let mut bytes = Vec::new();
    let mut chunk = vec![0u8; 1 << 16];
    loop {
        let n = match reader.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(ReadError::Io(e.to_string())),
        };
        if let Some(i) = chunk[..n].iter().position(|&b| b == 0) {
            bytes.extend_from_slice(&chunk[..i]);
            return Err(ReadError::Binary { line: line_of(&bytes, bytes.len()) });
        }
        if bytes.len() as u64 + n as u64 > limit {
            return Err(ReadError::TooLarge { limit });
        }
        bytes.extend_from_slice(&chunk[..n]);
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        ReadError::NotUtf8 { line: line_of(e.as_bytes(), at) }
    })?;
    Ok(match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    })
}

/// Reads the text file at `path`, of at most `limit` bytes ([`read_text_from`]); a regular
/// file larger than that is refused before it is read.
pub fn read_text(path: &Path, limit: u64) -> Result<String, ReadError> {
    if let Some(bytes) = held(path) {
        return read_text_from(&bytes[..], limit);
    }
    read_text_from(std::io::BufReader::new(open_within(path, limit)?), limit)
}

/// Opens the file at `path` for reading at most `limit` bytes: a folder, or a regular file
/// larger than that, is refused before anything is read.
fn open_within(path: &Path, limit: u64) -> Result<std::fs::File, ReadError> {
    if cfg!(target_arch = "wasm32") {
        return Err(ReadError::Io("not among the files given with the scene (a web page reads no others)".into()));
    }
    let file = std::fs::File::open(path).map_err(|e| ReadError::Io(e.to_string()))?;
    let meta = file.metadata().map_err(|e| ReadError::Io(e.to_string()))?;
    if meta.is_dir() {
        return Err(ReadError::Io("is a folder".into()));
    }
    if meta.is_file() && meta.len() > limit {
        return Err(ReadError::TooLarge { limit });
    }
    Ok(file)
}

/// Reads the binary file at `path` (images, glTF buffers), of at most `limit` bytes: a regular
/// file larger than that is refused before it is read, a stream as soon as it passes it.
pub fn read_bytes(path: &Path, limit: u64) -> Result<Vec<u8>, ReadError> {
    if let Some(bytes) = held(path) {
        if bytes.len() as u64 > limit {
            return Err(ReadError::TooLarge { limit });
        }
        return Ok(bytes.to_vec());
    }
    let file = open_within(path, limit)?;
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| ReadError::Io(e.to_string()))?;
    if bytes.len() as u64 > limit {
        return Err(ReadError::TooLarge { limit });
    }
    Ok(bytes)
}

/// `bytes` as a size for messages: "256 MiB", "4 GiB", "1500 bytes".
pub fn size_name(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 && b % (1 << 30) == 0 => format!("{} GiB", b >> 30),
        b if b >= 1 << 20 && b % (1 << 20) == 0 => format!("{} MiB", b >> 20),
        b => format!("{b} bytes"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_stop_at_the_limit_or_at_binary_data() {
        assert_eq!(read_text_from(&b"ab\ncd"[..], 5).unwrap(), "ab\ncd");
        assert!(matches!(read_text_from(&b"ab\ncde"[..], 5), Err(ReadError::TooLarge { limit: 5 })));
        // An endless stream of zeros (as /dev/zero) ends at its first byte.
        let zeros = std::io::repeat(0);
        assert!(matches!(read_text_from(zeros, 1 << 40), Err(ReadError::Binary { line: 1 })));
        // An endless text stream ends at the limit.
        let text = std::io::repeat(b'x');
        assert!(matches!(read_text_from(text, 1 << 20), Err(ReadError::TooLarge { .. })));
        assert!(matches!(read_text_from(&b"a\nb\n\xff"[..], 99), Err(ReadError::NotUtf8 { line: 3 })));
        assert!(matches!(read_text_from(&b"a\n\n\0"[..], 99), Err(ReadError::Binary { line: 3 })));
        assert_eq!(read_text_from("\u{feff}ox,oy".as_bytes(), 99).unwrap(), "ox,oy", "the BOM is dropped");
    }

    #[test]
    fn held_files_are_read_before_the_file_system_by_their_normal_path() {
        assert_eq!(normal(Path::new("scenes/../meshes/./a.obj")), Path::new("meshes/a.obj"));
        assert_eq!(normal(Path::new("../a.obj")), Path::new("../a.obj"));
        assert_eq!(normal(Path::new("/x/../../a")), Path::new("/a"));
        // A path no test writes to disk, so only the held bytes can answer.
        let path = Path::new("strahl-held-test/meshes/a.obj");
        hold_file(path, b"v 0 0 0\n".to_vec());
        assert_eq!(read_text(Path::new("strahl-held-test/scenes/../meshes/a.obj"), 99).unwrap(), "v 0 0 0\n");
        assert!(matches!(read_bytes(path, 3), Err(ReadError::TooLarge { limit: 3 })));
        assert!(matches!(read_text(Path::new("strahl-held-test/b.obj"), 99), Err(ReadError::Io(_))));
        release_files();
        assert!(matches!(read_text(path, 99), Err(ReadError::Io(_))));
    }

    #[test]
    fn regular_files_over_the_limit_are_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.toml");
        // Sparse: claims 1 GiB without using the disk.
        std::fs::File::create(&path).unwrap().set_len(1 << 30).unwrap();
        assert!(matches!(read_text(&path, 1 << 20), Err(ReadError::TooLarge { .. })));
        assert_eq!(size_name(1 << 30), "1 GiB");
        assert_eq!(size_name(256 << 20), "256 MiB");
        assert_eq!(size_name(1500), "1500 bytes");
        assert!(matches!(read_bytes(&path, 1 << 20), Err(ReadError::TooLarge { .. })));
        std::fs::write(&path, [0u8, 1, 2]).unwrap();
        assert_eq!(read_bytes(&path, 3).unwrap(), vec![0, 1, 2]);
        assert!(matches!(read_bytes(&path, 2), Err(ReadError::TooLarge { .. })));
    }
}
