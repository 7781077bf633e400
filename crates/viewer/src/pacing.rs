//! Frame pacing: how many sample tiles each UI frame dispatches, and how much coarser to
//! render while the camera moves. Pure logic over measured times, so it is tested without a
//! window or a GPU.

use super::camera::ViewCamera;
use super::gpu::{GpuTiming, MAX_TILES_PER_FRAME};
use std::time::{Duration, Instant};

/// GPU time per UI frame the progressive passes aim at (ms).
pub const GPU_MS_PER_FRAME: f64 = 20.0;

/// GPU time of one whole sample pass while the camera moves (ms); see [`preview_factor`].
pub const PREVIEW_PASS_MS: f64 = 40.0;

/// How long after its last change the camera still counts as moving.
const MOVING_FOR: Duration = Duration::from_millis(300);

/// The pacing state carried from one UI frame to the next.
pub struct Pacer {
    /// Tiles per UI frame (adapted to keep their GPU time near [`GPU_MS_PER_FRAME`]).
    pub budget: f64,
    last_ui: Option<Instant>,
    /// Smoothed interval of UI frames that did work, in ms (0: idle).
    pub frame_ms: f64,
    /// Shortest recent UI frame interval (ms), the cost of a frame without samples.
    base_ms: f64,
    /// The GPU timing the budget was last adapted to.
    adapted_to: Option<Instant>,
    /// Whether the last frame dispatched any tiles.
    pub worked_last_frame: bool,
    /// Intervals of the frames that did work (ms), for the `--frames` summary.
    pub frame_log: Vec<f64>,
    /// The camera of the last frame, and until when it counts as moving.
    last_camera: Option<ViewCamera>,
    moving_until: Option<Instant>,
}

impl Default for Pacer {
    fn default() -> Self {
        Self {
            budget: 4.0,
            last_ui: None,
            frame_ms: 0.0,
            base_ms: f64::INFINITY,
            adapted_to: None,
            worked_last_frame: false,
            frame_log: Vec::new(),
            last_camera: None,
            moving_until: None,
        }
    }
}

impl Pacer {
    /// At the start of a UI frame at `now`: measures the interval since the last one and,
    /// if the last frame did work, adapts the budget to it and to `latest` (the newest GPU
    /// timing, if any).
    pub fn frame_started(&mut self, now: Instant, latest: Option<&GpuTiming>) {
        if let Some(prev) = self.last_ui {
            let dt = (now - prev).as_secs_f64() * 1e3;
            if self.worked_last_frame && dt < 1000.0 {
                self.frame_ms = if self.frame_ms == 0.0 { dt } else { 0.9 * self.frame_ms + 0.1 * dt };
                self.frame_log.push(dt);
                self.adapt_budget(dt, latest);
            } else if !self.worked_last_frame {
                self.frame_ms = 0.0;
            }
        }
        self.last_ui = Some(now);
    }

    /// Sets the tiles per UI frame so that their GPU time stays near [`GPU_MS_PER_FRAME`]:
    /// grown or shrunk by the latest measured frame (measured time includes fixed costs
    /// per submission, so it is not assumed proportional to the tiles), or, before any
    /// measurement, so that frames with work last at most a little longer than the
    /// fastest frames seen.
    fn adapt_budget(&mut self, dt_ms: f64, latest: Option<&GpuTiming>) {
        let max = MAX_TILES_PER_FRAME as f64;
        if let Some(t) = latest {
            if self.adapted_to == Some(t.at) {
                return;
            }
            self.adapted_to = Some(t.at);
            let ms = t.gpu.as_secs_f64() * 1e3;
            let factor = if ms < 0.25 * GPU_MS_PER_FRAME {
                2.0
            } else if ms < 0.8 * GPU_MS_PER_FRAME {
                1.25
            } else if ms > 1.25 * GPU_MS_PER_FRAME {
                0.8
            } else {
                1.0
            };
            self.budget = (self.budget * factor).clamp(1.0, max);
            return;
        }
        self.base_ms = self.base_ms.min(dt_ms).max(1.0) * 1.01;
        if dt_ms > self.base_ms + 2.0 * GPU_MS_PER_FRAME {
            self.budget = (self.budget * 0.75).max(1.0);
        } else if dt_ms < self.base_ms + GPU_MS_PER_FRAME {
            self.budget = (self.budget * 1.25 + 0.25).min(max);
        }
    }

    /// Whether the camera moved within the last [`MOVING_FOR`], given this frame's camera.
    pub fn camera_moving(&mut self, camera: &ViewCamera, now: Instant) -> bool {
        if self.last_camera.as_ref() != Some(camera) {
            if self.last_camera.is_some() {
                self.moving_until = Some(now + MOVING_FOR);
            }
            self.last_camera = Some(camera.clone());
        }
        let moving = self.moving_until.is_some_and(|t| now < t);
        if !moving {
            self.moving_until = None;
        }
        moving
    }
}

/// How much coarser to render while the camera moves: enough that a whole sample pass of
/// `rays` primary rays takes about [`PREVIEW_PASS_MS`] of GPU time at `rays_per_s`
/// (1: no change, or no measurement yet).
pub fn preview_factor(rays: f64, rays_per_s: Option<f64>) -> f32 {
    let Some(r) = rays_per_s else { return 1.0 };
    let pass_ms = rays / r * 1e3;
    (pass_ms / PREVIEW_PASS_MS).sqrt().clamp(1.0, 8.0) as f32
}

/// GPU ms per UI frame (median of the 32 most recent frames) and primary rays per second
/// over them; `timings` oldest first.
pub fn timing_summary<'a>(timings: impl DoubleEndedIterator<Item = &'a GpuTiming>) -> (Option<f64>, Option<f64>) {
    let recent: Vec<_> = timings.rev().take(32).collect();
    if recent.is_empty() {
        return (None, None);
    }
    let mut ms: Vec<f64> = recent.iter().map(|t| t.gpu.as_secs_f64() * 1e3).collect();
    ms.sort_by(f64::total_cmp);
    let rays: u64 = recent.iter().map(|t| t.rays).sum();
    let secs: f64 = recent.iter().map(|t| t.gpu.as_secs_f64()).sum();
    (Some(ms[ms.len() / 2]), (secs > 0.0).then(|| rays as f64 / secs))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timing(at: Instant, ms: u64, rays: u64) -> GpuTiming {
        GpuTiming { at, gpu: Duration::from_millis(ms), rays }
    }

    /// Runs frames `dt_ms` apart that all did work, each with a new GPU timing of `gpu_ms`.
    fn run(p: &mut Pacer, t0: Instant, frames: u64, dt_ms: u64, gpu_ms: Option<u64>) -> Instant {
        let mut now = t0;
        for _ in 0..frames {
            now += Duration::from_millis(dt_ms);
            let t = gpu_ms.map(|ms| timing(now, ms, 1000));
            p.worked_last_frame = true;
            p.frame_started(now, t.as_ref());
        }
        now
    }

    #[test]
    fn the_budget_grows_while_frames_are_cheap_and_shrinks_when_they_are_dear() {
        let t0 = Instant::now();
        let mut p = Pacer::default();
        p.frame_started(t0, None);
        let t = run(&mut p, t0, 8, 16, Some(1));
        assert_eq!(p.budget, 4.0 * 2f64.powi(8), "GPU frames of 1 ms double the budget every frame");
        run(&mut p, t, 3, 16, Some(100));
        assert_eq!(p.budget, 4.0 * 2f64.powi(8) * 0.8f64.powi(3), "100 ms frames shrink it by 0.8");
        let mut q = Pacer { budget: 1.0, ..Pacer::default() };
        q.frame_started(t0, None);
        run(&mut q, t0, 4, 16, Some(100));
        assert_eq!(q.budget, 1.0, "never below one tile");
        let mut r = Pacer::default();
        r.frame_started(t0, None);
        run(&mut r, t0, 20, 16, Some(0));
        assert_eq!(r.budget, MAX_TILES_PER_FRAME as f64, "never above the per-frame cap");
    }

    #[test]
    fn one_gpu_timing_adapts_the_budget_once() {
        let t0 = Instant::now();
        let mut p = Pacer::default();
        p.frame_started(t0, None);
        let stale = timing(t0, 1, 1000);
        for k in 1..5 {
            p.worked_last_frame = true;
            p.frame_started(t0 + Duration::from_millis(16 * k), Some(&stale));
        }
        assert_eq!(p.budget, 8.0);
    }

    #[test]
    fn before_any_gpu_timing_the_ui_interval_steers_the_budget() {
        let t0 = Instant::now();
        let mut p = Pacer::default();
        p.frame_started(t0, None);
        // Frames as fast as the fastest seen: grow by 1.25 and a quarter tile each.
        let t = run(&mut p, t0, 2, 10, None);
        assert_eq!(p.budget, (4.0 * 1.25 + 0.25) * 1.25 + 0.25);
        // Much slower than the fastest (by more than twice the target): shrink by 0.75.
        let b = p.budget;
        run(&mut p, t, 1, 10 + 3 * GPU_MS_PER_FRAME as u64, None);
        assert_eq!(p.budget, b * 0.75);
        assert_eq!(p.frame_log.len(), 3);
        assert!(p.frame_ms > 10.0);
    }

    #[test]
    fn idle_frames_leave_the_budget_and_clear_the_frame_time() {
        let t0 = Instant::now();
        let mut p = Pacer::default();
        p.frame_started(t0, None);
        run(&mut p, t0, 1, 16, Some(1));
        let b = p.budget;
        p.worked_last_frame = false;
        p.frame_started(t0 + Duration::from_millis(500), Some(&timing(t0, 1, 1)));
        assert_eq!((p.budget, p.frame_ms), (b, 0.0));
    }

    #[test]
    fn the_camera_counts_as_moving_for_a_while_after_each_change() {
        let t0 = Instant::now();
        let mut p = Pacer::default();
        let mut cam = ViewCamera::from_scene(&strahl_core::scene::Camera {
            eye: strahl_core::math::V3::new(0.0, 0.0, -5.0),
            look_at: strahl_core::math::V3::new(0.0, 0.0, 0.0),
            up: strahl_core::math::V3::new(0.0, 1.0, 0.0),
            fov_y: 40.0,
        });
        assert!(!p.camera_moving(&cam, t0), "the first frame's camera is not a move");
        cam.orbit(0.1, 0.0);
        assert!(p.camera_moving(&cam, t0));
        assert!(p.camera_moving(&cam, t0 + MOVING_FOR / 2));
        assert!(!p.camera_moving(&cam, t0 + MOVING_FOR));
    }

    #[test]
    fn preview_passes_aim_at_their_gpu_time() {
        assert_eq!(preview_factor(1e6, None), 1.0);
        // 1e6 rays at 1e6 rays/s: a 1000 ms pass, 25 times the aim: 5 times coarser per side.
        assert_eq!(preview_factor(1e6, Some(1e6)), 5.0);
        assert_eq!(preview_factor(1e3, Some(1e6)), 1.0, "never finer than asked");
        assert_eq!(preview_factor(1e9, Some(1e3)), 8.0, "at most 8 times coarser");
    }

    #[test]
    fn the_summary_is_the_median_of_recent_frames_and_their_ray_rate() {
        let t0 = Instant::now();
        assert_eq!(timing_summary([].iter()), (None, None));
        let mut v: Vec<GpuTiming> = (0..40).map(|_| timing(t0, 1000, 1)).collect();
        for (i, t) in v.iter_mut().rev().take(32).enumerate() {
            t.gpu = Duration::from_millis(i as u64 + 1);
            t.rays = 1000;
        }
        let (ms, rate) = timing_summary(v.iter());
        assert_eq!(ms, Some(17.0), "median of 1..=32 ms, upper middle");
        let secs = (1..=32).sum::<u64>() as f64 / 1e3;
        assert!((rate.unwrap() - 32_000.0 / secs).abs() < 1e-6);
    }
}
