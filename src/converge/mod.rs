//! Convergence of progressive Monte Carlo rendering: error against wall time.
//!
//! A backend implements [`Progressive`]; [`measure`] adds samples on a [`Schedule`], times
//! them, and compares each intermediate mean with a reference image
//! ([`strahl_metrics::errors`]). The rows go to a CSV file ([`write_csv`]), a log-log plot
//! ([`plot`]) and a Markdown table ([`table`]).

mod plot;
mod table;

pub use plot::plot;
pub use strahl_core::Progressive;
pub use table::{table, write_csv};

use anyhow::{Context, Result, ensure};
use std::time::Instant;
use strahl_core::image::Image;
use strahl_metrics::{Errors, errors};

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
/// it stops the run). Times are wall-clock seconds.
///
/// With `denoise`, each checkpoint also gives a row of the image denoised
/// ([`Progressive::denoised`]), labelled `LABEL denoised` (backend `BACKEND+denoise`), whose
/// time is the samples' plus the guides' and the denoiser's at that checkpoint.
pub fn measure(
    p: &mut dyn Progressive,
    reference: &Image,
    schedule: &Schedule,
    denoise: bool,
    on_row: &mut dyn FnMut(&Row) -> Result<()>,
) -> Result<Vec<Row>> {
    let start = Instant::now();
    measure_with_clock(p, reference, schedule, denoise, on_row, &|| start.elapsed().as_secs_f64())
}

/// [`measure`] with time read from `clock` (seconds from any origin), so that the schedule
/// can be tested against a clock that does not depend on the machine's load.
fn measure_with_clock(
    p: &mut dyn Progressive,
    reference: &Image,
    schedule: &Schedule,
    denoise: bool,
    on_row: &mut dyn FnMut(&Row) -> Result<()>,
    clock: &dyn Fn() -> f64,
) -> Result<Vec<Row>> {
    ensure!(p.samples() == 0, "the {} renderer already holds {} samples per pixel", p.backend(), p.samples());
    let mut rows = Vec::new();
    let mut seconds = 0.0f64;
    match *schedule {
        Schedule::Doubling { max_spp } => {
            ensure!(max_spp >= 1, "max_spp must be at least 1");
            for c in doubling_checkpoints(max_spp) {
                let n = c - p.samples();
                rows.extend(step(p, n, &mut seconds, reference, denoise, on_row, clock)?);
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
                rows.extend(step(p, n, &mut seconds, reference, denoise, on_row, clock)?);
                if seconds >= budget || p.samples() >= max_spp {
                    break;
                }
            }
        }
    }
    Ok(rows)
}

/// Adds `n` samples, adds their time on `clock` to `seconds`, and measures the new mean (and,
/// with `denoise`, the mean denoised).
fn step(
    p: &mut dyn Progressive,
    n: u32,
    seconds: &mut f64,
    reference: &Image,
    denoise: bool,
    on_row: &mut dyn FnMut(&Row) -> Result<()>,
    clock: &dyn Fn() -> f64,
) -> Result<Vec<Row>> {
    let backend = p.backend();
    let before = p.samples();
    let start = clock();
    p.add_samples(n).with_context(|| format!("{backend}: adding {n} samples per pixel to {before}"))?;
    *seconds += clock() - start;
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
    let mut rows = vec![row];
    if denoise {
        let start = clock();
        let (image, _) = p.denoised().with_context(|| format!("{backend}: denoising at {spp} spp"))?;
        let took = clock() - start;
        let errors =
            strahl_metrics::errors(reference, &image).with_context(|| format!("{backend} denoised at {spp} spp"))?;
        let row = Row {
            backend: format!("{backend}+denoise"),
            label: format!("{} denoised", rows[0].label),
            seconds: *seconds + took,
            errors,
            ..rows[0].clone()
        };
        on_row(&row)?;
        rows.push(row);
    }
    Ok(rows)
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;
    use std::rc::Rc;
    use strahl_core::rng::SplitMix64;

    /// A smooth image in [0.3, 0.7].
    fn gradient(w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            let (x, y) = ((i as u32 % w) as f32 / w as f32, (i as u32 / w) as f32 / h as f32);
            *p = [0.3 + 0.4 * x, 0.5, 0.3 + 0.4 * y];
        }
        img
    }

    /// A progressive mean of `reference` + uniform noise in [−0.3, 0.3) (within [0, 1] for
    /// [`gradient`]): its error falls as 1/sqrt(spp). Adding n samples advances `clock` by n ×
    /// `cost` seconds.
    struct Noisy {
        reference: Image,
        sum: Vec<[f64; 3]>,
        spp: u32,
        rng: SplitMix64,
        clock: Rc<Cell<f64>>,
        cost: f64,
    }

    impl Noisy {
        fn new(reference: &Image, cost: f64) -> Self {
            Self {
                reference: reference.clone(),
                sum: vec![[0.0; 3]; reference.pixels.len()],
                spp: 0,
                rng: SplitMix64(7),
                clock: Rc::default(),
                cost,
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
            self.clock.set(self.clock.get() + self.cost * n as f64);
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
    fn doubling_measures_at_powers_of_two_and_max_spp() {
        assert_eq!(doubling_checkpoints(8), [1, 2, 4, 8]);
        assert_eq!(doubling_checkpoints(12), [1, 2, 4, 8, 12]);
        assert_eq!(doubling_checkpoints(1), [1]);
        assert_eq!(doubling_checkpoints(u32::MAX).len(), 33);
        let reference = gradient(8, 8);
        for (max_spp, expected) in [(8, vec![1, 2, 4, 8]), (12, vec![1, 2, 4, 8, 12])] {
            let mut p = Noisy::new(&reference, 0.0);
            let mut seen = Vec::new();
            let rows = measure(&mut p, &reference, &Schedule::Doubling { max_spp }, false, &mut |r| {
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
        let mut p = Noisy::new(&reference, 0.0);
        let rows = measure(&mut p, &reference, &Schedule::Doubling { max_spp: 64 }, false, &mut |_| Ok(())).unwrap();
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
    fn fixed_time_stops_at_its_budget() {
        let reference = gradient(8, 8);
        // Binary fractions, so that the times add up exactly.
        let (cost, budget) = (1.0 / 1024.0, 50.0 / 1024.0);
        let mut p = Noisy::new(&reference, cost);
        let clock = p.clock.clone();
        let schedule = Schedule::FixedTime { seconds: budget, max_spp: 1_000_000 };
        let rows = measure_with_clock(&mut p, &reference, &schedule, false, &mut |_| Ok(()), &|| clock.get()).unwrap();
        // Batches double the samples while they fit; the last one fills the 18 samples left.
        assert_eq!(rows.iter().map(|r| r.spp).collect::<Vec<_>>(), [1, 2, 4, 8, 16, 32, 50]);
        assert!(rows.iter().all(|r| r.seconds == r.spp as f64 * cost));
        assert_eq!(p.samples(), 50);
        // Another budget: 31 samples by doubling, then the 9 that fit.
        let mut q = Noisy::new(&reference, cost);
        let clock = q.clock.clone();
        let slow = Schedule::FixedTime { seconds: 40.0 * cost, max_spp: 1_000_000 };
        let rows = measure_with_clock(&mut q, &reference, &slow, false, &mut |_| Ok(()), &|| clock.get()).unwrap();
        assert_eq!(rows.last().unwrap().spp, 40);
    }

    #[test]
    fn fixed_time_stops_at_max_spp() {
        let reference = gradient(4, 4);
        let mut p = Noisy::new(&reference, 0.0);
        let schedule = Schedule::FixedTime { seconds: 1000.0, max_spp: 10 };
        let rows = measure(&mut p, &reference, &schedule, false, &mut |_| Ok(())).unwrap();
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
        let mut p = Lazy(Noisy::new(&reference, 0.0));
        let msg = measure(&mut p, &reference, &Schedule::Doubling { max_spp: 4 }, false, &mut |_| Ok(())).unwrap_err();
        assert!(msg.to_string().contains("holds 3 samples per pixel after adding 2 to 2, expected 4"), "{msg}");
    }
}
