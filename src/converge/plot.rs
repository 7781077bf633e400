//! `strahl converge`'s plot: RMSE against wall time on log-log axes, one line per backend.

use super::Row;
use anyhow::{Context, Result, ensure};
use std::path::Path;

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
    strahl_core::image::save_encoded(&img, image::ImageFormat::Png, path)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::converge::table::tests::sample_rows;

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
