//! Work off the UI thread, and watching files for changes: the viewer's two ways of waiting
//! without blocking a frame.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime};
use strahl_core::scene::{Geometry, Scene};

/// Work done on another thread, collected without blocking.
pub struct Job<T> {
    rx: mpsc::Receiver<T>,
}

impl<T: Send + 'static> Job<T> {
    pub fn spawn(f: impl FnOnce() -> T + Send + 'static) -> Self {
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(f());
        });
        Self { rx }
    }

    /// The result once the work is done; `Err(())` if the thread died without one.
    pub fn poll(&self) -> Option<Result<T, ()>> {
        match self.rx.try_recv() {
            Ok(v) => Some(Ok(v)),
            Err(mpsc::TryRecvError::Empty) => None,
            Err(mpsc::TryRecvError::Disconnected) => Some(Err(())),
        }
    }
}

/// Polls the modification times of a scene file and the mesh files it loads.
pub struct Watcher {
    files: Vec<(PathBuf, Option<SystemTime>)>,
    last_poll: Instant,
    pub interval: Duration,
}

fn mtime(p: &Path) -> Option<SystemTime> {
    std::fs::metadata(p).and_then(|m| m.modified()).ok()
}

impl Watcher {
    /// Watches `path` and, once loaded, the meshes of `scene`.
    pub fn new(path: &Path, scene: Option<&Scene>) -> Self {
        let mut w = Self { files: Vec::new(), last_poll: Instant::now(), interval: Duration::from_millis(500) };
        w.watch(path, scene);
        w
    }

    /// Starts over with the files of `path` and `scene`, as they are now.
    pub fn watch(&mut self, path: &Path, scene: Option<&Scene>) {
        self.files = vec![(path.to_path_buf(), mtime(path))];
        if let Some(s) = scene {
            for o in &s.objects {
                if let Geometry::Mesh { file, .. } = &o.geometry
                    && !self.files.iter().any(|(p, _)| p == file)
                {
                    self.files.push((file.clone(), mtime(file)));
                }
            }
        }
    }

    /// True when, at most every `interval`, any watched file's time changed since the last
    /// poll (including appearing or disappearing).
    pub fn changed(&mut self) -> bool {
        if self.last_poll.elapsed() < self.interval {
            return false;
        }
        self.last_poll = Instant::now();
        let mut changed = false;
        for (p, t) in &mut self.files {
            let now = mtime(p);
            if now != *t {
                *t = now;
                changed = true;
            }
        }
        changed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_watcher_sees_a_rewritten_file() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a.toml");
        std::fs::write(&f, "x").unwrap();
        let mut w = Watcher::new(&f, None);
        w.interval = Duration::ZERO;
        assert!(!w.changed());
        // Coarse file-system clocks: set the time explicitly.
        let later = SystemTime::now() + Duration::from_secs(5);
        std::fs::File::options().write(true).open(&f).unwrap().set_modified(later).unwrap();
        assert!(w.changed());
        assert!(!w.changed());
    }
}
