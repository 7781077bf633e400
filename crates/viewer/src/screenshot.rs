//! `strahl view --screenshot`: render a fixed number of whole sample passes, save the window
//! as a PNG, print what was rendered and how fast, and close.

use super::Viewer;
use super::pacing::timing_summary;
use anyhow::{Context as _, Result, anyhow};
use eframe::egui;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Filled by the screenshot callback: whether the PNG was written.
pub(super) type ShotResult = Arc<Mutex<Option<Result<(), String>>>>;

/// Screenshot mode: where the shot stands.
pub(super) enum Shot {
    Rendering,
    Requested { at: Instant, result: ShotResult },
    Closing,
}

impl Viewer {
    /// Screenshot mode, after this frame's passes: ask for the shot once the samples are in,
    /// then close when it is saved.
    pub(super) fn drive_screenshot(&mut self, ctx: &egui::Context) {
        let Some(path) = self.opts.screenshot.clone() else { return };
        if let Some(e) = &self.gpu_error {
            *self.failure.lock().expect("failure lock") = Some(anyhow!("{e}"));
            self.shot = Some(Shot::Closing);
        }
        match &self.shot {
            Some(Shot::Rendering) if self.gpu.acc.samples >= self.max_samples => {
                let [x, y, w, h] = self.image_rect_px;
                let t = self.gpu.target.as_ref().expect("target");
                println!("image_rect {x} {y} {w} {h}");
                println!("render_size {} {}", t.width, t.height);
                println!("samples {}", self.gpu.acc.samples);
                println!("variant {}", self.variant_label());
                println!("adapter {}", self.gpu.ctx.adapter_name());
                let result: ShotResult = Arc::default();
                let slot = result.clone();
                let repaint = ctx.clone();
                ctx.request_screenshot(move |img| {
                    let saved = save_screenshot(&img, &path).map_err(|e| format!("{e:#}"));
                    *slot.lock().expect("screenshot lock") = Some(saved);
                    repaint.request_repaint();
                });
                self.shot = Some(Shot::Requested { at: Instant::now(), result });
            }
            Some(Shot::Requested { at, result }) => {
                let done = result.lock().expect("screenshot lock").take();
                match done {
                    Some(Ok(())) => {
                        println!("wrote {}", path.display());
                        self.print_timings();
                        self.shot = Some(Shot::Closing);
                    }
                    Some(Err(e)) => {
                        *self.failure.lock().expect("failure lock") = Some(anyhow!("saving the screenshot: {e}"));
                        self.shot = Some(Shot::Closing);
                    }
                    None if at.elapsed() > Duration::from_secs(30) => {
                        *self.failure.lock().expect("failure lock") =
                            Some(anyhow!("no screenshot arrived within 30 s"));
                        self.shot = Some(Shot::Closing);
                    }
                    None => ctx.request_repaint_after(Duration::from_millis(20)),
                }
            }
            _ => {}
        }
        if matches!(self.shot, Some(Shot::Closing)) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        } else {
            ctx.request_repaint();
        }
    }

    pub(super) fn print_timings(&self) {
        let mut ui_ms = self.pacer.frame_log.clone();
        ui_ms.sort_by(f64::total_cmp);
        let median = |v: &[f64]| if v.is_empty() { f64::NAN } else { v[v.len() / 2] };
        let (gpu_ms, rays) = timing_summary(self.gpu.timings.iter());
        let (w, h) = self.gpu.target.as_ref().map_or((0, 0), |t| (t.width, t.height));
        println!(
            "timing: {} frames at {w}x{h}, UI frame median {:.1} ms, GPU per frame median {}, {} M primary rays/s, {} samples",
            ui_ms.len(),
            median(&ui_ms),
            gpu_ms.map_or("-".into(), |m| format!("{m:.1} ms")),
            rays.map_or("-".into(), |r| format!("{:.2}", r / 1e6)),
            self.gpu.acc.samples
        );
    }
}

fn save_screenshot(img: &egui::ColorImage, path: &Path) -> Result<()> {
    let [w, h] = img.size;
    let rgb: Vec<u8> = img.pixels.iter().flat_map(|c| [c.r(), c.g(), c.b()]).collect();
    let img = image::RgbImage::from_raw(w as u32, h as u32, rgb).context("screenshot size")?;
    strahl_core::image::save_encoded(&img, image::ImageFormat::Png, path)
}
