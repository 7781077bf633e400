//! `strahl.render`: an image of a scene, Whitted or path traced, on the GPU or the CPU, as
//! `strahl render` makes it, returned as linear RGB floats instead of written to a file.

use crate::device::{self, gpu_error};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use strahl_core::render::Prepared;
use strahl_core::render::aov::Aov;
use strahl_core::scene::{Camera, RenderMode, Scene};
use strahl_gpu::select::Workload;

/// Largest image side, as strahl's scene files allow.
pub const MAX_SIDE: u32 = 16384;

pub struct Request {
    pub mode: RenderMode,
    pub spp: u32,
    pub width: u32,
    pub height: u32,
    pub max_depth: Option<u32>,
    pub seed: u32,
    pub device: strahl_gpu::select::Choice,
    /// Denoise the image on the backend that rendered it, as `strahl render --denoise` does.
    pub denoise: bool,
}

pub fn parse_mode(mode: &str) -> PyResult<RenderMode> {
    RenderMode::ALL
        .into_iter()
        .find(|m| m.name() == mode.trim().to_ascii_lowercase())
        .ok_or_else(|| PyValueError::new_err(format!("mode={mode:?}: use \"whitted\" or \"path\"")))
}

/// A camera as Python passes it: (eye, look_at, up, fov_y in degrees).
pub type CameraArgs = ([f64; 3], [f64; 3], [f64; 3], f64);

/// Checks a camera given as (eye, look_at, up, fov_y).
pub fn camera(eye: [f64; 3], look_at: [f64; 3], up: [f64; 3], fov_y: f64) -> PyResult<Camera> {
    let all = eye.iter().chain(&look_at).chain(&up);
    if !all.into_iter().all(|x| x.is_finite()) {
        return Err(PyValueError::new_err("eye, look_at and up must be finite"));
    }
    let c = Camera {
        eye: strahl_core::math::V3::from_array(eye),
        look_at: strahl_core::math::V3::from_array(look_at),
        up: strahl_core::math::V3::from_array(up),
        fov_y,
    };
    let forward = c.look_at - c.eye;
    if !(forward.length() > 0.0) {
        return Err(PyValueError::new_err("look_at must differ from eye"));
    }
    if !(forward.cross(c.up).length() > 0.0) {
        return Err(PyValueError::new_err("up must not be parallel to the view direction (look_at − eye)"));
    }
    if !(fov_y > 0.0 && fov_y < 180.0) {
        return Err(PyValueError::new_err(format!("fov_y={fov_y}: the field of view must be in (0, 180) degrees")));
    }
    Ok(c)
}

impl Request {
    pub fn check(&self) -> PyResult<()> {
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if !(1..=MAX_SIDE).contains(&v) {
                return Err(PyValueError::new_err(format!("{name}={v}: must be in 1..={MAX_SIDE}")));
            }
        }
        if !(1..=1 << 20).contains(&self.spp) {
            return Err(PyValueError::new_err(format!("spp={}: must be in 1..=1048576", self.spp)));
        }
        if let Some(d) = self.max_depth
            && !(1..=64).contains(&d)
        {
            return Err(PyValueError::new_err(format!("max_depth={d}: must be in 1..=64")));
        }
        Ok(())
    }

    /// Renders `scene`; returns the pixels (row-major, row 0 at the top, RGB) and where they
    /// were rendered. Runs without the GIL.
    pub fn run(&self, scene: Scene) -> PyResult<(Vec<f32>, String)> {
        let workload = match self.mode {
            RenderMode::Whitted => Workload::Whitted,
            RenderMode::Path => Workload::Path,
        };
        let mut scene = scene;
        scene.render.spp = self.spp;
        if let Some(d) = self.max_depth {
            scene.render.max_depth = d;
        }
        let prep = Prepared::try_new(scene).map_err(|e| pyo3::exceptions::PyMemoryError::new_err(e.to_string()))?;
        let mut frame = prep.frame(self.width, self.height);
        frame.seed = self.seed;
        let (ctx, note) = device::open(self.device, workload).map_err(gpu_error)?;
        let whole = strahl_core::image::Region::whole(frame.width, frame.height);
        let guides = [Aov::Albedo, Aov::Normal];
        let on_cpu = || {
            let cpu = strahl_cpu::CpuScene::new(&prep);
            let image = strahl_cpu::render(&cpu, &frame, self.mode, &|_| ());
            if !self.denoise {
                return image;
            }
            let aovs = strahl_cpu::aov::render_aovs(&cpu.inputs(&frame), whole, &guides);
            strahl_core::denoise::denoise(&image, &aovs.guides().expect("both guides were computed"))
        };
        let (image, on) = match ctx {
            None => (on_cpu(), note.unwrap_or_else(|| "cpu".into())),
            Some(ctx) => {
                let gpu = strahl_gpu::SceneBuffers::upload(&ctx, &prep.flat).and_then(|buffers| {
                    let (image, _) =
                        strahl_gpu::tiles::render(&ctx, &buffers, &frame, self.mode, buffers.key, &|_, _| ())?;
                    if !self.denoise {
                        return Ok((image, ()));
                    }
                    let aovs = strahl_gpu::aov::render_aovs(&ctx, &buffers, &frame, whole, &guides)?;
                    let g = aovs.guides().expect("both guides were computed");
                    let (image, _) = strahl_gpu::denoise::Denoiser::new(&ctx)?.denoise(&ctx, &image, &g)?;
                    Ok((image, ()))
                });
                match gpu {
                    Ok((image, _)) => (image, format!("gpu ({})", ctx.adapter_name())),
                    // Where the user left the choice to strahl, a scene the GPU cannot take
                    // renders on the CPU, as `strahl render` does.
                    Err(e) if note.is_some() => (on_cpu(), format!("cpu (the GPU failed: {e})")),
                    Err(e) => return Err(gpu_error(e)),
                }
            }
        };
        Ok((image.pixels.into_iter().flatten().collect(), on))
    }
}
