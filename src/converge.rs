//! Convergence of progressive Monte Carlo rendering: error against wall time.
//!
//! A backend implements [`Progressive`]; [`measure`] adds samples on a [`Schedule`], times
//! them, and compares each intermediate mean with a reference image ([`errors`]). The rows go
//! to a CSV file ([`write_csv`]), a log-log plot ([`plot`]) and a Markdown table ([`table`]).

use crate::image::Image;
use anyhow::{Context, Result, bail, ensure};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// A renderer that adds samples to a running per-pixel mean (one backend).
pub trait Progressive {
    /// Name for tables and plots, e.g. "gpu (llvmpipe (LLVM 15.0.6, 256 bits))" or "cpu (2 threads)".
    fn label(&self) -> String;
    /// Short backend id for CSV: "gpu" or "cpu".
    fn backend(&self) -> &'static str;
    /// Adds `n` samples per pixel (sample indices samples()..samples()+n) and returns when they are done.
    fn add_samples(&mut self, n: u32) -> Result<()>;
    /// Samples per pixel accumulated so far.
    fn samples(&self) -> u32;
    /// The current mean image (reading it back is not timed).
    fn image(&mut self) -> Result<Image>;
}

/// Errors of an image against a reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Errors {
    /// Root mean square error over all pixel channels, linear radiance.
    pub rmse: f64,
    /// RMSE of both images clamped to [0, 1], as `rmse_clamped` of the Mitsuba anchor script
    /// (shared/anchors/mitsuba_seed_scene_bench.py).
    pub rmse_clamped: f64,
    /// Relative MSE: mean over channels of (x − r)² / (r² + ε), ε = [`REL_MSE_EPSILON`].
    pub rel_mse: f64,
    /// Mean FLIP error of the 8-bit sRGB images ([`crate::metrics::mean_flip`]).
    pub mean_flip: f64,
}

/// The ε of the relative MSE, (x − r)² / (r² + ε): 0.01, the usual choice (Rousselle et al.
/// 2011, "Adaptive sampling and reconstruction using greedy error minimization"), which keeps
/// dark pixels from dominating.
pub const REL_MSE_EPSILON: f64 = 0.01;

/// Errors of `test` against `reference`. Fails when the sizes differ or when either image
/// has non-finite pixels (they would make every metric NaN).
pub fn errors(reference: &Image, test: &Image) -> Result<Errors> {
    if (reference.width, reference.height) != (test.width, test.height) {
        bail!("image is {}x{}, the reference is {}x{}", test.width, test.height, reference.width, reference.height);
    }
    ensure!(
        reference.pixels.len() == reference.width as usize * reference.height as usize
            && test.pixels.len() == reference.pixels.len(),
        "image buffers do not hold width x height pixels"
    );
    for (what, img) in [("reference", reference), ("image", test)] {
        let bad = img.non_finite_count();
        ensure!(bad == 0, "the {what} has {bad} non-finite (NaN or infinite) pixels of {}", img.pixels.len());
    }
    let (mut se, mut se_clamped, mut rel) = (0.0f64, 0.0f64, 0.0f64);
    for (r, t) in reference.pixels.iter().flatten().zip(test.pixels.iter().flatten()) {
        let (r, t) = (*r as f64, *t as f64);
        let d = t - r;
        se += d * d;
        let dc = t.clamp(0.0, 1.0) - r.clamp(0.0, 1.0);
        se_clamped += dc * dc;
        rel += d * d / (r * r + REL_MSE_EPSILON);
    }
    let n = (reference.pixels.len() * 3).max(1) as f64;
    Ok(Errors {
        rmse: (se / n).sqrt(),
        rmse_clamped: (se_clamped / n).sqrt(),
        rel_mse: rel / n,
        mean_flip: if reference.pixels.is_empty() { 0.0 } else { crate::metrics::mean_flip(reference, test) as f64 },
    })
}

/// When [`measure`] stops to compare the image with the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Schedule {
    /// At 1, 2, 4, … samples per pixel, and at `max_spp` itself.
    Doubling { max_spp: u32 },
    /// Until `seconds` of rendering (or `max_spp`), in batches that double the samples so far
    /// while they fit the time left; the last row is the error reached in that time.
    FixedTime { seconds: f64, max_spp: u32 },
}

/// One measurement: a backend's error after `spp` samples per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Short backend id ([`Progressive::backend`]).
    pub backend: String,
    /// [`Progressive::label`].
    pub label: String,
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
    /// Samples per pixel so far.
    pub spp: u32,
    /// Wall time of all `add_samples` calls so far (reading the image back is not counted).
    pub seconds: f64,
    pub errors: Errors,
}

impl Row {
    /// Pixel samples per second over the whole run so far (infinite when no time was measured).
    pub fn samples_per_second(&self) -> f64 {
        self.width as f64 * self.height as f64 * self.spp as f64 / self.seconds
    }
}

/// Samples per pixel at which [`Schedule::Doubling`] measures: powers of two below
/// `max_spp`, then `max_spp`.
pub fn doubling_checkpoints(max_spp: u32) -> Vec<u32> {
    let mut c: Vec<u32> =
        std::iter::successors(Some(1u32), |&s| s.checked_mul(2)).take_while(|&s| s < max_spp).collect();
    if max_spp > 0 {
        c.push(max_spp);
    }
    c
}

/// Renders with `p` from zero samples on `schedule`, compares the mean with `reference` at
/// every checkpoint and calls `on_row` with each row as soon as it is measured (an error from
/// it stops the run).
pub fn measure(
    p: &mut dyn Progressive,
    reference: &Image,
    schedule: &Schedule,
    on_row: &mut dyn FnMut(&Row) -> Result<()>,
) -> Result<Vec<Row>> {
    ensure!(p.samples() == 0, "the {} renderer already holds {} samples per pixel", p.backend(), p.samples());
    let mut rows = Vec::new();
    let mut seconds = 0.0f64;
    match *schedule {
        Schedule::Doubling { max_spp } => {
            ensure!(max_spp >= 1, "max_spp must be at least 1");
            for c in doubling_checkpoints(max_spp) {
                let n = c - p.samples();
                rows.push(step(p, n, &mut seconds, reference, on_row)?);
            }
        }
        Schedule::FixedTime { seconds: budget, max_spp } => {
            ensure!(budget.is_finite() && budget > 0.0, "the time budget must be positive and finite, not {budget}");
            ensure!(max_spp >= 1, "max_spp must be at least 1");
            loop {
                let spp = p.samples();
                let n = fixed_time_batch(spp, seconds, budget, max_spp);
                if n == 0 {
                    break;
                }
                rows.push(step(p, n, &mut seconds, reference, on_row)?);
                if seconds >= budget || p.samples() >= max_spp {
                    break;
                }
            }
        }
    }
    Ok(rows)
}

/// Adds `n` samples, adds their wall time to `seconds`, and measures the new mean.
fn step(
    p: &mut dyn Progressive,
    n: u32,
    seconds: &mut f64,
    reference: &Image,
    on_row: &mut dyn FnMut(&Row) -> Result<()>,
) -> Result<Row> {
    let backend = p.backend();
    let before = p.samples();
    let start = Instant::now();
    p.add_samples(n).with_context(|| format!("{backend}: adding {n} samples per pixel to {before}"))?;
    *seconds += start.elapsed().as_secs_f64();
    let spp = p.samples();
    ensure!(
        spp == before + n,
        "{backend}: holds {spp} samples per pixel after adding {n} to {before}, expected {}",
        before + n
    );
    let image = p.image().with_context(|| format!("{backend}: reading the image back at {spp} spp"))?;
    let errors = errors(reference, &image).with_context(|| format!("{backend} at {spp} spp"))?;
    let row = Row {
        backend: backend.to_string(),
        label: p.label(),
        width: reference.width,
        height: reference.height,
        spp,
        seconds: *seconds,
        errors,
    };
    on_row(&row)?;
    Ok(row)
}

/// The next batch of [`Schedule::FixedTime`]: as many samples as are in already (one at
/// first), at most as many as the time left fits at the time per sample measured so far, and
/// at most `max_spp` in all. Zero when not even one more sample is predicted to fit.
fn fixed_time_batch(spp: u32, seconds: f64, budget: f64, max_spp: u32) -> u32 {
    if spp == 0 {
        return 1.min(max_spp);
    }
    let per_sample = seconds / spp as f64;
    let fits = if per_sample > 0.0 { ((budget - seconds) / per_sample).floor().max(0.0) } else { f64::INFINITY };
    let n = (spp as f64).min(fits).min(max_spp.saturating_sub(spp) as f64);
    n as u32
}

/// Writes `rows` as CSV: `backend,label,spp,seconds,rmse,rmse_clamped,rel_mse,mean_flip`,
/// atomically (a run rewrites it after every row, so an interrupted run keeps what it measured).
pub fn write_csv(rows: &[Row], path: &Path) -> Result<()> {
    let mut s = String::from("backend,label,spp,seconds,rmse,rmse_clamped,rel_mse,mean_flip\n");
    for r in rows {
        let e = &r.errors;
        writeln!(
            s,
            "{},{},{},{},{},{},{},{}",
            csv_field(&r.backend),
            csv_field(&r.label),
            r.spp,
            r.seconds,
            e.rmse,
            e.rmse_clamped,
            e.rel_mse,
            e.mean_flip
        )
        .expect("writing to a String");
    }
    crate::output::write_bytes_atomic(path, s.as_bytes())
}

/// A CSV field, quoted (RFC 4180) when it holds a comma, a quote or a line break.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

/// A Markdown table of `rows`, one line each.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| backend | spp | seconds | samples/s (M) | RMSE | RMSE clamped | relMSE | mean FLIP |\n\
         |---|--:|--:|--:|--:|--:|--:|--:|\n",
    );
    for r in rows {
        let rate = r.samples_per_second();
        let rate = if rate.is_finite() { format!("{:.2}", rate / 1e6) } else { "-".to_string() };
        let e = &r.errors;
        writeln!(
            s,
            "| {} | {} | {:.3} | {} | {} | {} | {} | {} |",
            r.label.replace('|', "\\|"),
            r.spp,
            r.seconds,
            rate,
            sig4(e.rmse),
            sig4(e.rmse_clamped),
            sig4(e.rel_mse),
            sig4(e.mean_flip)
        )
        .expect("writing to a String");
    }
    s
}

/// `x` to 4 significant digits, in scientific notation when it is very small or large.
fn sig4(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let mag = x.abs().log10().floor() as i32;
    if (-3..=4).contains(&mag) { format!("{:.*}", (3 - mag).max(0) as usize, x) } else { format!("{x:.3e}") }
}

/// Plot size in pixels.
const PLOT_SIZE: (u32, u32) = (1000, 700);

/// Registers the fonts the plots use (Ubuntu Light, bundled with egui) with plotters, once.
fn register_fonts() -> Result<()> {
    static DONE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        plotters::style::register_font(
            "sans-serif",
            plotters::style::FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .is_ok()
    });
    ensure!(ok, "the bundled plot font does not load");
    Ok(())
}

/// Draws RMSE against wall time on log-log axes, one line per backend (by label), as a PNG.
pub fn plot(rows: &[Row], title: &str, path: &Path) -> Result<()> {
    use plotters::prelude::*;
    register_fonts()?;
    ensure!(!rows.is_empty(), "no measurements to plot");
    // Log axes cannot show zeros (no time measured, an exact image): they sit a decade below
    // the smallest positive value.
    let x_floor = log_floor(rows.iter().map(|r| r.seconds));
    let y_floor = log_floor(rows.iter().map(|r| r.errors.rmse));
    let mut series: Vec<(&str, Vec<(f64, f64)>)> = Vec::new();
    for r in rows {
        let point = (r.seconds.max(x_floor), r.errors.rmse.max(y_floor));
        match series.iter_mut().find(|(label, _)| *label == r.label) {
            Some((_, points)) => points.push(point),
            None => series.push((&r.label, vec![point])),
        }
    }
    let points = || series.iter().flat_map(|(_, p)| p.iter());
    let x_range = log_range(points().map(|p| p.0));
    let y_range = log_range(points().map(|p| p.1));

    let (w, h) = PLOT_SIZE;
    let mut buf = vec![0u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 28))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(log_axis(x_range), log_axis(y_range))
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .x_desc("wall time [s]")
            .y_desc("RMSE (linear)")
            .axis_desc_style(("sans-serif", 20))
            .label_style(("sans-serif", 16))
            .x_label_formatter(&|v| axis_label(*v))
            .y_label_formatter(&|v| axis_label(*v))
            .draw()
            .map_err(plot_error)?;
        for (i, (label, points)) in series.iter().enumerate() {
            let color = SERIES_COLORS[i % SERIES_COLORS.len()];
            chart
                .draw_series(LineSeries::new(points.iter().copied(), color.stroke_width(2)).point_size(4))
                .map_err(plot_error)?
                .label(*label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(plot_error)?;
        root.present().map_err(plot_error)?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).context("plot buffer size mismatch")?;
    crate::image::save_encoded(&img, image::ImageFormat::Png, path)
}

const SERIES_COLORS: [plotters::style::RGBColor; 6] = [
    plotters::style::RGBColor(31, 119, 180),
    plotters::style::RGBColor(214, 39, 40),
    plotters::style::RGBColor(44, 160, 44),
    plotters::style::RGBColor(148, 103, 189),
    plotters::style::RGBColor(255, 127, 14),
    plotters::style::RGBColor(23, 190, 207),
];

fn plot_error<E: std::error::Error + Send + Sync + 'static>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plotting: {e}")
}

/// A tenth of the smallest positive finite value (1e-6 when there is none).
fn log_floor(values: impl Iterator<Item = f64>) -> f64 {
    let min = values.filter(|v| v.is_finite() && *v > 0.0).fold(f64::INFINITY, f64::min);
    if min.is_finite() { min / 10.0 } else { 1e-6 }
}

/// A log-axis range around positive `values` with some room on both sides; at least a factor
/// of 10 wide so that one point, or equal ones, still get an axis with ticks.
fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (1.0, 1.0) };
    let pad = ((10.0 * lo / hi).sqrt()).max(1.25);
    lo / pad..hi * pad
}

/// A log axis over `range` with ticks at 1, 2, 5 × 10^k (more or fewer steps per decade as
/// the range is narrow or wide) and grid lines at 1…9 × 10^k.
fn log_axis(
    range: std::ops::Range<f64>,
) -> plotters::coord::combinators::WithKeyPoints<plotters::coord::combinators::LogCoord<f64>> {
    use plotters::coord::combinators::{BindKeyPoints, IntoLogRange};
    let (lo, hi) = (range.start, range.end);
    let decades = (hi / lo).log10();
    let (mantissas, every): (&[f64], i32) = match decades {
        d if d < 1.2 => (&[1.0, 1.5, 2.0, 3.0, 5.0, 7.0], 1),
        d if d < 3.0 => (&[1.0, 2.0, 5.0], 1),
        d if d < 8.0 => (&[1.0], 1),
        d => (&[1.0], (d / 8.0).ceil() as i32),
    };
    let powers = || (lo.log10().floor() as i32..=hi.log10().ceil() as i32).map(|k| 10f64.powi(k));
    let within = |v: &f64| (lo..=hi).contains(v);
    let bold: Vec<f64> = powers()
        .filter(|p| p.log10().round() as i32 % every == 0)
        .flat_map(|p| mantissas.iter().map(move |m| m * p))
        .filter(within)
        .collect();
    let light: Vec<f64> = if decades < 8.0 {
        powers().flat_map(|p| (1..10).map(move |m| m as f64 * p)).filter(within).collect()
    } else {
        vec![]
    };
    range.log_scale().with_key_points(bold).with_light_points(light)
}

/// A tick label on a log axis: at most two significant digits, without float noise.
fn axis_label(v: f64) -> String {
    let trim = |s: String| if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
    if !(1e-3..1e4).contains(&v) {
        let s = format!("{v:.1e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        format!("{}e{exponent}", trim(mantissa.to_string()))
    } else {
        let decimals = (1 - v.log10().floor() as i32).max(0) as usize;
        trim(format!("{v:.decimals$}"))
    }
}

/// The CPU backend's progressive path tracer.
impl Progressive for crate::backend::cpu::Progressive {
    fn label(&self) -> String {
        format!("cpu ({} threads)", rayon::current_num_threads())
    }
    fn backend(&self) -> &'static str {
        "cpu"
    }
    fn add_samples(&mut self, n: u32) -> Result<()> {
        crate::backend::cpu::Progressive::add_samples(self, n);
        Ok(())
    }
    fn samples(&self) -> u32 {
        crate::backend::cpu::Progressive::samples(self)
    }
    fn image(&mut self) -> Result<Image> {
        Ok(crate::backend::cpu::Progressive::image(self))
    }
}

/// The GPU backend's progressive path tracer.
impl Progressive for crate::backend::gpu::render::Progressive {
    fn label(&self) -> String {
        format!("gpu ({})", self.context().adapter_info.name)
    }
    fn backend(&self) -> &'static str {
        "gpu"
    }
    fn add_samples(&mut self, n: u32) -> Result<()> {
        Ok(crate::backend::gpu::render::Progressive::add_samples(self, n)?)
    }
    fn samples(&self) -> u32 {
        crate::backend::gpu::render::Progressive::samples(self)
    }
    fn image(&mut self) -> Result<Image> {
        Ok(crate::backend::gpu::render::Progressive::image(self)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;
    use std::time::Duration;

    fn gradient(w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            let (x, y) = ((i as u32 % w) as f32 / w as f32, (i as u32 / w) as f32 / h as f32);
            *p = [0.3 + 0.4 * x, 0.5, 0.3 + 0.4 * y];
        }
        img
    }

    /// A progressive mean of `reference` + uniform noise in [−0.3, 0.3) (within [0, 1] for
    /// [`gradient`]): its error falls as 1/sqrt(spp). Adding n samples sleeps n × `sleep`.
    struct Noisy {
        reference: Image,
        sum: Vec<[f64; 3]>,
        spp: u32,
        rng: SplitMix64,
        sleep: Duration,
    }

    impl Noisy {
        fn new(reference: &Image, sleep: Duration) -> Self {
            Self {
                reference: reference.clone(),
                sum: vec![[0.0; 3]; reference.pixels.len()],
                spp: 0,
                rng: SplitMix64(7),
                sleep,
            }
        }
    }

    impl Progressive for Noisy {
        fn label(&self) -> String {
            "fake (noise, 1 thread)".to_string()
        }
        fn backend(&self) -> &'static str {
            "cpu"
        }
        fn add_samples(&mut self, n: u32) -> Result<()> {
            std::thread::sleep(self.sleep * n);
            for _ in 0..n {
                for (s, r) in self.sum.iter_mut().flatten().zip(self.reference.pixels.iter().flatten()) {
                    *s += *r as f64 + self.rng.range(-0.3, 0.3);
                }
            }
            self.spp += n;
            Ok(())
        }
        fn samples(&self) -> u32 {
            self.spp
        }
        fn image(&mut self) -> Result<Image> {
            let mut img = Image::new(self.reference.width, self.reference.height);
            for (p, s) in img.pixels.iter_mut().zip(&self.sum) {
                *p = s.map(|v| (v / self.spp as f64) as f32);
            }
            Ok(img)
        }
    }

    #[test]
    fn identical_images_have_zero_error() {
        let a = gradient(16, 8);
        let e = errors(&a, &a.clone()).unwrap();
        assert_eq!(e, Errors { rmse: 0.0, rmse_clamped: 0.0, rel_mse: 0.0, mean_flip: 0.0 });
    }

    #[test]
    fn a_constant_offset_gives_the_exact_errors() {
        let mut r = Image::new(4, 4);
        for p in &mut r.pixels {
            *p = [0.5, 0.25, 0.9];
        }
        let mut t = r.clone();
        for p in &mut t.pixels {
            *p = p.map(|c| c + 0.125);
        }
        let e = errors(&r, &t).unwrap();
        assert!((e.rmse - 0.125).abs() < 1e-7, "{e:?}");
        // 0.9 + 0.125 clamps to 1: that channel differs by 0.1 only.
        let clamped = ((2.0 * 0.125f64.powi(2) + 0.1f64.powi(2)) / 3.0).sqrt();
        assert!((e.rmse_clamped - clamped).abs() < 1e-6, "{e:?}");
        let rel = [0.5f64, 0.25, 0.9].iter().map(|r| 0.125f64.powi(2) / (r * r + 0.01)).sum::<f64>() / 3.0;
        assert!((e.rel_mse - rel).abs() < 1e-6, "{e:?}");
        assert!(e.mean_flip > 0.0);
    }

    #[test]
    fn size_mismatch_and_non_finite_pixels_are_errors() {
        let msg = errors(&Image::new(4, 3), &Image::new(3, 4)).unwrap_err().to_string();
        assert!(msg.contains("3x4") && msg.contains("4x3"), "{msg}");
        let mut t = Image::new(4, 3);
        t.pixels[2][1] = f32::NAN;
        t.pixels[5][0] = f32::INFINITY;
        let msg = errors(&Image::new(4, 3), &t).unwrap_err().to_string();
        assert!(msg.contains("2 non-finite"), "{msg}");
        let msg = errors(&t, &Image::new(4, 3)).unwrap_err().to_string();
        assert!(msg.contains("reference has 2"), "{msg}");
    }

    #[test]
    fn doubling_measures_at_powers_of_two_and_max_spp() {
        assert_eq!(doubling_checkpoints(8), [1, 2, 4, 8]);
        assert_eq!(doubling_checkpoints(12), [1, 2, 4, 8, 12]);
        assert_eq!(doubling_checkpoints(1), [1]);
        assert_eq!(doubling_checkpoints(u32::MAX).len(), 33);
        let reference = gradient(8, 8);
        for (max_spp, expected) in [(8, vec![1, 2, 4, 8]), (12, vec![1, 2, 4, 8, 12])] {
            let mut p = Noisy::new(&reference, Duration::ZERO);
            let mut seen = Vec::new();
            let rows = measure(&mut p, &reference, &Schedule::Doubling { max_spp }, &mut |r| {
                seen.push(r.spp);
                Ok(())
            })
            .unwrap();
            assert_eq!(rows.iter().map(|r| r.spp).collect::<Vec<_>>(), expected);
            assert_eq!(seen, expected);
            assert_eq!(p.samples(), max_spp);
            assert!(rows.windows(2).all(|w| w[0].seconds <= w[1].seconds));
            assert!(rows.iter().all(|r| r.backend == "cpu" && r.label == p.label() && (r.width, r.height) == (8, 8)));
        }
    }

    #[test]
    fn doubling_error_falls_as_one_over_sqrt_spp() {
        let reference = gradient(32, 32);
        let mut p = Noisy::new(&reference, Duration::ZERO);
        let rows = measure(&mut p, &reference, &Schedule::Doubling { max_spp: 64 }, &mut |_| Ok(())).unwrap();
        assert_eq!(rows.len(), 7);
        // Uniform noise of half-width 0.3 has σ = 0.3/√3; 3072 channels estimate it within a few %.
        let sigma = 0.3 / 3f64.sqrt();
        for r in &rows {
            let expected = sigma / (r.spp as f64).sqrt();
            let ratio = r.errors.rmse / expected;
            assert!((0.9..1.1).contains(&ratio), "spp {}: rmse {} expected {expected}", r.spp, r.errors.rmse);
            assert_eq!(r.errors.rmse, r.errors.rmse_clamped);
        }
        // Without accumulation (each checkpoint a fresh batch) this would be √(64/32) = 1.4 or less.
        let fall = rows[0].errors.rmse / rows[6].errors.rmse;
        assert!((7.0..9.0).contains(&fall), "rmse 1 spp / 64 spp = {fall}");
        assert!(rows[0].errors.mean_flip > rows[6].errors.mean_flip);
    }

    #[test]
    fn fixed_time_stops_near_its_budget() {
        let reference = gradient(8, 8);
        let budget = 0.05;
        let mut p = Noisy::new(&reference, Duration::from_millis(1));
        let schedule = Schedule::FixedTime { seconds: budget, max_spp: 1_000_000 };
        let rows = measure(&mut p, &reference, &schedule, &mut |_| Ok(())).unwrap();
        let last = rows.last().unwrap();
        assert!(last.spp >= 1 && last.spp == p.samples());
        assert!(last.seconds <= budget * 3.0, "{} s for a {budget} s budget", last.seconds);
        assert_eq!(rows[0].spp, 1);
        assert!(rows.windows(2).all(|w| w[0].spp < w[1].spp && w[0].seconds <= w[1].seconds));
        // Batches at most double the samples so far.
        assert!(rows.windows(2).all(|w| w[1].spp <= 2 * w[0].spp));
    }

    #[test]
    fn fixed_time_stops_at_max_spp() {
        let reference = gradient(4, 4);
        let mut p = Noisy::new(&reference, Duration::ZERO);
        let schedule = Schedule::FixedTime { seconds: 1000.0, max_spp: 10 };
        let rows = measure(&mut p, &reference, &schedule, &mut |_| Ok(())).unwrap();
        assert_eq!(rows.iter().map(|r| r.spp).collect::<Vec<_>>(), [1, 2, 4, 8, 10]);
    }

    #[test]
    fn fixed_time_batches_fit_the_time_left() {
        assert_eq!(fixed_time_batch(0, 0.0, 1.0, 100), 1);
        assert_eq!(fixed_time_batch(4, 0.4, 10.0, 100), 4);
        assert_eq!(fixed_time_batch(4, 0.4, 0.75, 100), 3);
        assert_eq!(fixed_time_batch(4, 0.4, 0.45, 100), 0);
        assert_eq!(fixed_time_batch(4, 0.4, 10.0, 6), 2);
        assert_eq!(fixed_time_batch(4, 0.0, 10.0, 100), 4);
    }

    #[test]
    fn a_renderer_that_miscounts_samples_is_an_error() {
        struct Lazy(Noisy);
        impl Progressive for Lazy {
            fn label(&self) -> String {
                self.0.label()
            }
            fn backend(&self) -> &'static str {
                "gpu"
            }
            fn add_samples(&mut self, _n: u32) -> Result<()> {
                self.0.add_samples(1)
            }
            fn samples(&self) -> u32 {
                self.0.samples()
            }
            fn image(&mut self) -> Result<Image> {
                self.0.image()
            }
        }
        let reference = gradient(4, 4);
        let mut p = Lazy(Noisy::new(&reference, Duration::ZERO));
        let msg = measure(&mut p, &reference, &Schedule::Doubling { max_spp: 4 }, &mut |_| Ok(())).unwrap_err();
        assert!(msg.to_string().contains("holds 3 samples per pixel after adding 2 to 2, expected 4"), "{msg}");
    }

    fn sample_rows() -> Vec<Row> {
        let e = |rmse: f64| Errors { rmse, rmse_clamped: rmse / 2.0, rel_mse: rmse * 2.0, mean_flip: rmse / 4.0 };
        let row = |backend: &str, label: &str, spp: u32, seconds: f64, rmse: f64| Row {
            backend: backend.to_string(),
            label: label.to_string(),
            width: 640,
            height: 480,
            spp,
            seconds,
            errors: e(rmse),
        };
        vec![
            row("gpu", "gpu (llvmpipe (LLVM 15.0.6, 256 bits))", 1, 0.02, 0.1),
            row("gpu", "gpu (llvmpipe (LLVM 15.0.6, 256 bits))", 2, 0.04, 0.071),
            row("gpu", "gpu (llvmpipe (LLVM 15.0.6, 256 bits))", 4, 0.08, 0.05),
            row("cpu", "cpu (2 threads)", 1, 0.3, 0.1),
            row("cpu", "cpu (2 threads)", 2, 0.6, 0.071),
            row("cpu", "cpu (2 threads)", 4, 1.2, 0.05),
        ]
    }

    #[test]
    fn csv_has_the_header_and_one_quoted_line_per_row() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.csv");
        let mut rows = sample_rows();
        rows[5].label = "say \"hi\"".to_string();
        write_csv(&rows, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "backend,label,spp,seconds,rmse,rmse_clamped,rel_mse,mean_flip");
        assert_eq!(lines.len(), rows.len() + 1);
        assert_eq!(lines[1], "gpu,\"gpu (llvmpipe (LLVM 15.0.6, 256 bits))\",1,0.02,0.1,0.05,0.2,0.025");
        assert!(lines[4].starts_with("cpu,cpu (2 threads),1,0.3,"));
        assert!(lines[6].starts_with("cpu,\"say \"\"hi\"\"\",4,1.2,"));
    }

    #[test]
    fn table_has_one_line_per_row() {
        let mut rows = sample_rows();
        rows[0].seconds = 0.0;
        let t = table(&rows);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), rows.len() + 2);
        assert!(lines[0].starts_with("| backend | spp | seconds | samples/s (M) |"));
        assert_eq!(lines[1].matches('|').count(), lines[0].matches('|').count());
        assert_eq!(
            lines[2],
            "| gpu (llvmpipe (LLVM 15.0.6, 256 bits)) | 1 | 0.000 | - | 0.1000 | 0.05000 | 0.2000 | 0.02500 |"
        );
        // 640 × 480 × 4 samples in 1.2 s.
        assert!(lines[7].contains("| 1.02 |"), "{}", lines[7]);
        assert_eq!(sig4(12345.6), "12346");
        assert_eq!(sig4(123456.0), "1.235e5");
        assert_eq!(sig4(0.000_012_34), "1.234e-5");
        assert_eq!(sig4(1.5), "1.500");
    }

    #[test]
    fn log_axis_labels_are_short() {
        let labels = [0.0015, 0.015, 0.1, 0.2, 1.5, 15.0, 20000.0, 1.5e-5, 1e-6].map(axis_label);
        assert_eq!(labels, ["0.0015", "0.015", "0.1", "0.2", "1.5", "15", "2e4", "1.5e-5", "1e-6"]);
    }

    #[test]
    fn plot_writes_a_png_even_for_degenerate_rows() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        plot(&sample_rows(), "seed: RMSE against wall time", &path).unwrap();
        let img = image::open(&path).unwrap();
        assert_eq!((img.width(), img.height()), PLOT_SIZE);
        let mut one = sample_rows();
        one.truncate(1);
        one[0].seconds = 0.0;
        one[0].errors.rmse = 0.0;
        plot(&one, "one row", &path).unwrap();
        assert_eq!(image::open(&path).unwrap().width(), PLOT_SIZE.0);
        assert!(plot(&[], "none", &path).is_err());
    }
}
