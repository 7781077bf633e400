//! The viewer's "compare with CPU": the GPU image read back, the same samples rendered by the
//! CPU reference on a worker thread, and their per-pixel difference shown as an image.

use super::Viewer;
use super::jobs::Job;
use eframe::egui;
use std::time::{Duration, Instant};
use strahl_core::layout::FrameParams;
use strahl_metrics::Agreement;

/// A finished GPU-against-CPU comparison.
pub(super) struct Comparison {
    pub samples: u32,
    pub size: [u32; 2],
    pub cpu_time: Duration,
    pub agreement: Agreement,
    /// Largest channel difference per pixel, in 8-bit sRGB codes.
    pub diff: Vec<u8>,
}

pub(super) struct ComparisonView {
    pub c: Comparison,
    pub texture: egui::TextureHandle,
}

impl Viewer {
    /// Reads the GPU image back and starts the CPU render of the same samples, once the
    /// accumulation sits on a whole number of passes.
    pub(super) fn maybe_start_comparison(&mut self, frame: &FrameParams) {
        let acc = self.gpu.acc;
        if !self.compare_requested || self.cpu_job.is_some() || acc.samples == 0 || acc.next_tile != 0 {
            return;
        }
        self.compare_requested = false;
        let Some(render_mode) = self.mode.render_mode() else {
            return;
        };
        let gpu_image = match self.gpu.read_mean() {
            Ok(i) => i,
            Err(e) => {
                self.gpu_error = Some(e.to_string());
                return;
            }
        };
        let prep = self.prep.clone();
        let frame = FrameParams { spp: acc.samples, sample_base: 0, flags: 0, ..*frame };
        self.cpu_job = Some(Job::spawn(move || {
            let start = Instant::now();
            let cpu = strahl_cpu::render(&strahl_cpu::CpuScene::new(&prep), &frame, render_mode, &|_| {});
            let cpu_time = start.elapsed();
            let agreement = strahl_metrics::agreement(&cpu, &gpu_image, 1);
            let (a, b) = (cpu.to_srgb8(), gpu_image.to_srgb8());
            let diff = a
                .chunks(3)
                .zip(b.chunks(3))
                .map(|(p, q)| p.iter().zip(q).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0))
                .collect();
            Comparison { samples: acc.samples, size: [frame.width, frame.height], cpu_time, agreement, diff }
        }));
    }

    /// Shows a finished comparison.
    pub(super) fn poll_comparison(&mut self, ctx: &egui::Context) {
        if let Some(job) = &self.cpu_job
            && let Some(r) = job.poll()
        {
            self.cpu_job = None;
            if let Ok(c) = r {
                let rgb: Vec<u8> = c.diff.iter().flat_map(|&d| diff_colour(d)).collect();
                let image = egui::ColorImage::from_rgb([c.size[0] as usize, c.size[1] as usize], &rgb);
                let texture = ctx.load_texture("gpu-cpu difference", image, egui::TextureOptions::NEAREST);
                self.comparison = Some(ComparisonView { c, texture });
            }
        }
    }
}

/// Colour of a per-pixel difference of `d` 8-bit codes in the comparison image.
fn diff_colour(d: u8) -> [u8; 3] {
    match d {
        0 => [0, 0, 0],
        1 => [90, 90, 90],
        _ => [(96 + 16 * d as u32).min(255) as u8, 0, 0],
    }
}
