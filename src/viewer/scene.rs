//! The viewer's scene: loading off the UI thread, per-object visibility, and watching the
//! files on disk for hot reload.

use crate::accel::Bvh;
use crate::gpu_types::GpuScene;
use crate::primitives::Primitives;
use crate::render::Prepared;
use crate::scene::{Geometry, Scene};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime};

/// Flattens `scene` and builds its BVH over the objects whose `visible` entry is true (a
/// missing entry counts as visible). Hidden objects' primitives are left out; every other
/// primitive keeps its object id, so object numbers mean what they mean in the file.
pub fn prepare(scene: Scene, visible: &[bool]) -> Prepared {
    if visible.iter().all(|&v| v) {
        return Prepared::new(scene);
    }
    let start = Instant::now();
    let shown = |object: u32| visible.get(object as usize).copied().unwrap_or(true);
    let mut prims = Primitives::<f32>::from_scene(&scene);
    prims.spheres.retain(|p| shown(p.tag.object));
    prims.cylinders.retain(|p| shown(p.tag.object));
    prims.triangles.retain(|p| shown(p.tag.object));
    prims.planes.retain(|p| shown(p.tag.object));
    let bvh = Bvh::build(&prims);
    let gpu = GpuScene::new(&scene, &prims, &bvh);
    Prepared { scene, prims, bvh, gpu, build_time: start.elapsed() }
}

/// "3 mesh (glass)": an object's line in the visibility list.
pub fn object_label(scene: &Scene, index: usize) -> String {
    let o = &scene.objects[index];
    let material = scene.materials.get(o.material as usize).map_or("?", |m| m.name.as_str());
    let extra = match &o.geometry {
        Geometry::Mesh { triangles, file, .. } => format!(
            " {}, {} triangles",
            file.file_name().map_or_else(|| file.display().to_string(), |f| f.to_string_lossy().into_owned()),
            triangles.len()
        ),
        Geometry::Polygon { vertices, .. } => format!(" {} vertices", vertices.len()),
        _ => String::new(),
    };
    format!("{index} {}{extra} ({material})", o.geometry.kind().name())
}

/// Work done on another thread, collected without blocking.
pub struct Job<T> {
    rx: mpsc::Receiver<T>,
    pub started: Instant,
}

impl<T: Send + 'static> Job<T> {
    pub fn spawn(f: impl FnOnce() -> T + Send + 'static) -> Self {
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(f());
        });
        Self { rx, started: Instant::now() }
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

/// Loads a scene file and prepares it with every object visible. The error is the full
/// [`crate::scene::SceneError`] text.
pub fn load(path: &Path) -> Result<Prepared, String> {
    Scene::load(path).map(Prepared::new).map_err(|e| e.to_string())
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
    fn hidden_objects_leave_the_scene_and_the_rest_keep_their_ids() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/lecture.toml");
        let scene = Scene::load(&path).unwrap();
        let n = scene.objects.len();
        assert!(n >= 3);
        let all = prepare(scene.clone(), &vec![true; n]);
        let mut visible = vec![true; n];
        visible[1] = false;
        let some = prepare(scene.clone(), &visible);
        let ids = |p: &Prepared| p.gpu.spheres.iter().map(|s| s.object).collect::<Vec<_>>();
        assert_eq!(ids(&all).len(), ids(&some).len() + 1);
        assert!(ids(&some).iter().all(|&o| o != 1) && ids(&some).contains(&2));
        assert!(object_label(&scene, 0).starts_with("0 sphere"));
    }

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
