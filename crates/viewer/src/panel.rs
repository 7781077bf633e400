//! The viewer's side panel: mode and render settings, statistics, the CPU comparison, saving
//! the image, and which objects are shown.

use super::Viewer;
use super::camera::ViewCamera;
use super::gpu::ViewMode;
use super::pacing::timing_summary;
use super::reload::object_label;
use eframe::egui;

impl Viewer {
    pub(super) fn side_panel(&mut self, ui: &mut egui::Ui) {
        egui::ScrollArea::vertical().id_salt("side").show(ui, |ui| {
            ui.heading("strahl view");
            ui.label(self.opts.scene.display().to_string());
            if let Some(e) = &self.load_error {
                ui.colored_label(egui::Color32::from_rgb(255, 90, 90), format!("reload failed; showing the last good scene:\n{e}"));
            }
            if let Some(e) = &self.gpu_error {
                ui.colored_label(egui::Color32::from_rgb(255, 90, 90), e);
            }
            ui.separator();

            ui.label("mode");
            ui.horizontal_wrapped(|ui| {
                for m in ViewMode::ALL {
                    ui.radio_value(&mut self.mode, m, m.label());
                }
            });
            if self.mode == ViewMode::Cost
                && ui
                    .add(egui::Slider::new(&mut self.heat_max, 1.0..=4096.0).logarithmic(true).text("heat scale"))
                    .changed()
            {
                self.present_dirty = true;
            }
            ui.add_enabled(
                self.mode.render_mode().is_some(),
                egui::Slider::new(&mut self.max_depth, 0..=64).text("max depth"),
            );
            ui.add(egui::Slider::new(&mut self.scale, 0.1..=1.0).text("resolution scale"));
            ui.add(egui::Slider::new(&mut self.max_samples, 1..=4096).logarithmic(true).text("sample limit"));
            let mut fov = self.camera.fov_y;
            if ui.add(egui::Slider::new(&mut fov, 1.0..=170.0).text("field of view °")).changed() {
                self.camera.fov_y = fov;
            }
            if ui.button("reset camera (R)").clicked() {
                self.camera = ViewCamera::from_scene(&self.prep.scene.camera);
            }
            ui.small("left drag: orbit · right/middle drag: pan · wheel: zoom · W A S D Q E: fly (shift: faster)");
            ui.separator();

            let acc = self.gpu.acc;
            let (gpu_ms, rays_per_s) = timing_summary(self.gpu.timings.iter());
            egui::Grid::new("stats").num_columns(2).striped(true).show(ui, |ui| {
                let tiles = self.gpu.target.as_ref().map_or(0, |t| t.band().tile_count());
                ui.label("samples");
                let progress = if acc.next_tile > 0 { format!(" (+{}/{} tiles)", acc.next_tile, tiles) } else { String::new() };
                ui.label(format!("{} / {}{progress}", acc.samples, self.max_samples));
                ui.end_row();
                if let Some(t) = &self.gpu.target {
                    ui.label("render size");
                    ui.label(format!("{} × {}", t.width, t.height));
                    ui.end_row();
                }
                ui.label("frame");
                ui.label(if self.pacer.frame_ms > 0.0 { format!("{:.1} ms (UI)", self.pacer.frame_ms) } else { "idle".into() });
                ui.end_row();
                ui.label("GPU");
                ui.label(gpu_ms.map_or("-".into(), |ms| format!("{ms:.1} ms per frame")))
                    .on_hover_text("submission to completion of this frame's sample tiles");
                ui.end_row();
                ui.label("Mrays/s");
                ui.label(rays_per_s.map_or("-".into(), |r| format!("{:.2} primary", r / 1e6)));
                ui.end_row();
                if let (Some(r), Some(t)) = (rays_per_s, &self.gpu.target) {
                    ui.label("sample pass");
                    ui.label(format!("{:.0} ms", t.width as f64 * t.height as f64 / r * 1e3));
                    ui.end_row();
                }
            });
            let compiling = if self.compile_job.is_some() { " (compiling…)" } else { "" };
            ui.add(egui::Label::new(format!("shader {}{compiling}", self.variant_label())).wrap());
            ui.add(egui::Label::new(format!("adapter {}", self.gpu.ctx.adapter_name())).wrap());
            ui.separator();

            let can_compare = self.mode.render_mode().is_some() && self.cpu_job.is_none() && !self.compare_requested;
            if ui
                .add_enabled(can_compare, egui::Button::new("compare with CPU"))
                .on_hover_text("render this view on the CPU reference with the same samples and show the difference")
                .clicked()
            {
                self.compare_requested = true;
            }
            if self.compare_requested || self.cpu_job.is_some() {
                ui.label("rendering on the CPU…");
            }
            if let Some(v) = &self.comparison {
                let a = &v.c.agreement;
                ui.label(format!(
                    "{}×{}, {} samples, CPU {:.2} s\nwithin 1 code: {:.3} %\nlargest difference: {} codes\nmean FLIP: {:.5}",
                    v.c.size[0],
                    v.c.size[1],
                    v.c.samples,
                    v.c.cpu_time.as_secs_f64(),
                    a.within_tolerance * 100.0,
                    a.max_code_diff,
                    a.mean_flip
                ));
                let width = ui.available_width();
                let size = v.texture.size_vec2();
                ui.image((v.texture.id(), egui::vec2(width, width * size.y / size.x.max(1.0))));
                ui.small("black: equal · grey: 1 code · red: more");
            }
            ui.separator();

            ui.horizontal(|ui| {
                ui.add(egui::TextEdit::singleline(&mut self.save_path).desired_width(170.0));
                if ui.button("save").on_hover_text(".png: what the image area shows; .exr: the linear values").clicked() {
                    self.save();
                }
            });
            if let Some(s) = &self.save_status {
                ui.label(s);
            }
            ui.separator();

            let n = self.visible.len();
            let mut changed = false;
            egui::CollapsingHeader::new(format!("objects ({n})")).default_open(n <= 16).show(ui, |ui| {
                let row = ui.spacing().interact_size.y;
                egui::ScrollArea::vertical().id_salt("objects").max_height(240.0).show_rows(ui, row, n, |ui, rows| {
                    for i in rows {
                        let label = object_label(&self.prep.scene, i);
                        changed |= ui.checkbox(&mut self.visible[i], label).changed();
                    }
                });
            });
            if changed {
                self.start_visibility();
            }
        });
    }
}
