//! Progress of long runs on standard error: samples done, primary rays per second and the time
//! left, drawn only where standard error is a terminal and only once the run has taken a
//! second (a quick render prints nothing extra, and logs and pipes never get bar frames).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};
use std::io::IsTerminal;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// How long a run goes before its progress shows.
const SHOW_AFTER: Duration = Duration::from_secs(1);

/// Progress over `total` pixel samples (one primary ray each).
pub struct Progress {
    bar: ProgressBar,
    /// Set by [`Progress::finish`]; the thread that shows the bar checks it under the lock.
    finished: Arc<Mutex<bool>>,
}

impl Progress {
    pub fn new(total: u64, what: &str) -> Self {
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
        let style = ProgressStyle::with_template("{msg} [{bar:30}] {done}/{all} samples, {rate} M rays/s, {eta} left")
            .expect("static template")
            .with_key("done", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{}", short(s.pos()));
            })
            .with_key("all", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{}", short(s.len().unwrap_or(0)));
            })
            .with_key("rate", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{:.2}", s.per_sec() / 1e6);
            })
            .progress_chars("=> ");
        bar.set_style(style);
        bar.set_message(what.to_string());
        let finished = Arc::new(Mutex::new(false));
        if std::io::stderr().is_terminal() {
            // Shown after a second whether or not work has been reported by then (a first
            // GPU pass may take longer than that), unless the run is over.
            let (bar, finished) = (bar.clone(), finished.clone());
            std::thread::spawn(move || {
                std::thread::sleep(SHOW_AFTER);
                let done = finished.lock().expect("progress lock");
                if !*done {
                    bar.set_draw_target(ProgressDrawTarget::stderr());
                    bar.enable_steady_tick(Duration::from_millis(250));
                }
            });
        }
        Self { bar, finished }
    }

    /// `done` samples of the total are finished (callable from any thread).
    pub fn set(&self, done: u64) {
        self.bar.set_position(done);
    }

    /// Runs `f` (which prints) with the bar, if drawn, out of the way.
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.bar.suspend(f)
    }

    /// Removes the bar (if it was drawn) before the run's result is printed.
    pub fn finish(&self) {
        let mut done = self.finished.lock().expect("progress lock");
        *done = true;
        self.bar.finish_and_clear();
    }
}

impl Drop for Progress {
    /// A run that fails leaves no bar behind either.
    fn drop(&mut self) {
        self.finish();
    }
}

/// "12.3M", "456.7k" or "890".
fn short(n: u64) -> String {
    match n {
        0..1_000 => n.to_string(),
        1_000..1_000_000 => format!("{:.1}k", n as f64 / 1e3),
        _ => format!("{:.1}M", n as f64 / 1e6),
    }
}
