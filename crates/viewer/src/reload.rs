//! Reloading in the viewer: the scene file re-read when it or its meshes change, and the
//! scene re-prepared when objects are hidden or shown, both off the UI thread.

use super::Viewer;
use super::camera::ViewCamera;
use super::jobs::Job;
use std::path::Path;
use std::sync::Arc;
use strahl_core::primitives::Primitives;
use strahl_core::render::Prepared;
use strahl_core::scene::{Geometry, Scene};
use strahl_gpu::{FeatureKey, SceneBuffers};

/// Loaded off the UI thread: the prepared scene (hidden objects left out) and the key of
/// the whole scene.
pub(super) type Loaded = Result<(Prepared, FeatureKey, Vec<bool>), String>;

/// The key of the shader that can render every object of `scene`.
pub(super) fn full_key(scene: &strahl_core::scene::Scene) -> FeatureKey {
    FeatureKey::of_scene(scene, &Primitives::<f32>::from_scene(scene))
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

/// Loads a scene file and prepares it with every object visible. The error is the full
/// [`strahl_core::scene::SceneError`] text.
pub fn load(path: &Path) -> Result<Prepared, String> {
    let scene = Scene::load(path).map_err(|e| e.to_string())?;
    strahl_core::render::check_memory(&scene, strahl_core::render::available_memory()).map_err(|e| e.to_string())?;
    Ok(Prepared::new(scene))
}

impl Viewer {
    pub(super) fn install(&mut self, prep: Prepared) {
        match SceneBuffers::upload(&self.gpu.ctx, &prep.flat) {
            Ok(b) => {
                self.buffers = b;
                self.prep = Arc::new(prep);
                self.scene_gen += 1;
                self.gpu_error = None;
            }
            Err(e) => self.gpu_error = Some(e.to_string()),
        }
    }

    pub(super) fn start_reload(&mut self) {
        if self.load_job.is_some() {
            return;
        }
        let path = self.opts.scene.clone();
        let visible = self.visible.clone();
        self.load_job = Some(Job::spawn(move || {
            let scene = strahl_core::scene::Scene::load(&path).map_err(|e| e.to_string())?;
            let key = full_key(&scene);
            let visible = if visible.len() == scene.objects.len() { visible } else { vec![true; scene.objects.len()] };
            Ok((Prepared::with_visible(scene, &visible), key, visible))
        }));
    }

    pub(super) fn start_visibility(&mut self) {
        if self.visibility_job.is_some() {
            self.visibility_dirty = true;
            return;
        }
        let scene = self.prep.scene.clone();
        let visible = self.visible.clone();
        let file_gen = self.file_gen;
        self.visibility_job = Some(Job::spawn(move || (file_gen, Prepared::with_visible(scene, &visible))));
    }

    /// Takes in a finished reload or re-preparation.
    pub(super) fn poll_reload(&mut self) {
        if let Some(job) = &self.load_job
            && let Some(r) = job.poll()
        {
            self.load_job = None;
            match r {
                Ok(Ok((prep, key, visible))) => {
                    if prep.scene.camera != self.prep.scene.camera {
                        self.camera = ViewCamera::from_scene(&prep.scene.camera);
                    }
                    if prep.scene.render != self.prep.scene.render {
                        self.max_depth = prep.scene.render.max_depth;
                    }
                    self.watcher.watch(&self.opts.scene, Some(&prep.scene));
                    // Checkboxes changed while it loaded: apply them to the new scene next.
                    if self.visible.len() == visible.len() && self.visible != visible {
                        self.visibility_dirty = true;
                    } else {
                        self.visible = visible;
                    }
                    self.full_key = key;
                    self.load_error = None;
                    self.failed_compile = None;
                    self.file_gen += 1;
                    self.install(prep);
                }
                Ok(Err(text)) => self.load_error = Some(text),
                Err(()) => self.load_error = Some("loading the scene failed (the loader thread panicked)".into()),
            }
        }
        if let Some(job) = &self.visibility_job
            && let Some(r) = job.poll()
        {
            self.visibility_job = None;
            match r {
                // Prepared from the file as it is loaded now.
                Ok((file_gen, prep)) if file_gen == self.file_gen => self.install(prep),
                // A reload came in between: it kept the checkboxes; apply them to it.
                Ok(_) => self.visibility_dirty = true,
                Err(()) => {}
            }
        }
        if self.visibility_dirty && self.visibility_job.is_none() && self.load_job.is_none() {
            self.visibility_dirty = false;
            self.start_visibility();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hidden_objects_leave_the_scene_and_the_rest_keep_their_ids() {
        let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/scenes/lecture.toml"));
        let scene = Scene::load(path).unwrap();
        let n = scene.objects.len();
        assert!(n >= 3);
        let all = Prepared::with_visible(scene.clone(), &vec![true; n]);
        let mut visible = vec![true; n];
        visible[1] = false;
        let some = Prepared::with_visible(scene.clone(), &visible);
        let ids = |p: &Prepared| p.flat.spheres.iter().map(|s| s.object).collect::<Vec<_>>();
        assert_eq!(ids(&all).len(), ids(&some).len() + 1);
        assert!(ids(&some).iter().all(|&o| o != 1) && ids(&some).contains(&2));
        assert!(object_label(&scene, 0).starts_with("0 sphere"));
    }
}
