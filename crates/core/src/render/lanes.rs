//! The lane path tracer: the CPU backend's path tracing, many paths at a time.
//!
//! A batch holds the samples of a few neighbouring pixels, one path each. Every round traces
//! the rays of the batch's live paths a bundle at a time ([`crate::accel::bundle`]: 16 lanes
//! with AVX-512, 8 with AVX2), shades their vertices, traces the shadow rays of next-event
//! estimation a bundle at a time, and compacts the live paths, so that the bundles stay full
//! while paths end.
//!
//! Every path performs the operations of [`super::path::radiance`] in the same order (the
//! bundle walk's hits are the one-ray walk's, bit for bit), and each pixel adds its samples in
//! sample order, so the image equals the one-path-at-a-time tracer's ([`super::path`]) bit for
//! bit; `tests/path_tracing.rs` checks it on every scene it renders.

use super::path::{self, NeeRay, PathState};
use super::sampler::Sampler;
use super::shade::ShadeInputs;
use crate::accel::bundle::{self, Isa, MAX_WIDTH};
use crate::math::{Ray, V3};
use crate::primitives::Hit;
use std::time::Duration;
use web_time::Instant;

/// Paths per batch, about: enough that bundles stay full for most rounds, few enough that the
/// batch stays in the first two cache levels.
const BATCH: usize = 256;

/// Where a batch's time went.
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// Camera rays made and pixels summed.
    pub generate: Duration,
    /// Nearest hits of the paths' rays.
    pub trace: Duration,
    /// Vertices shaded (emission, delta lights with their shadow rays, light and BSDF
    /// sampling, Russian roulette).
    pub shade: Duration,
    /// Shadow rays towards the sampled area lights.
    pub shadow: Duration,
}

impl StageTimes {
    pub fn add(&mut self, o: &StageTimes) {
        self.generate += o.generate;
        self.trace += o.trace;
        self.shade += o.shade;
        self.shadow += o.shadow;
    }
    pub fn total(&self) -> Duration {
        self.generate + self.trace + self.shade + self.shadow
    }
}

/// The lane tracer's working memory, kept from batch to batch.
pub struct Tracer {
    isa: Isa,
    paths: Vec<PathState>,
    rngs: Vec<Sampler>,
    live: Vec<u32>,
    hits: Vec<Option<Hit<f32>>>,
    shadow: Vec<(u32, NeeRay)>,
    pub times: StageTimes,
    /// Measure stage times (two clock reads per stage and round).
    timed: bool,
}

impl Tracer {
    pub fn new(isa: Isa, timed: bool) -> Self {
        Self {
            isa,
            paths: Vec::with_capacity(BATCH + MAX_WIDTH),
            rngs: Vec::with_capacity(BATCH + MAX_WIDTH),
            live: Vec::with_capacity(BATCH + MAX_WIDTH),
            hits: vec![None; MAX_WIDTH],
            shadow: Vec::with_capacity(BATCH + MAX_WIDTH),
            times: StageTimes::default(),
            timed,
        }
    }

    #[inline]
    fn clock(&self) -> Option<Instant> {
        self.timed.then(Instant::now)
    }

    #[inline]
    fn lap(&self, since: Option<Instant>, into: &mut Duration) -> Option<Instant> {
        since.map(|s| {
            let n = Instant::now();
            *into += n - s;
            n
        })
    }

    /// Samples `samples` of pixels `x0 .. x0 + colors.len()` of row `y`: each pixel's radiance
    /// of sample s (0-based in `samples`) goes to `add(pixel offset, s, radiance)`, for every
    /// pixel in sample order.
    pub fn row(
        &mut self,
        inp: &ShadeInputs,
        y: u32,
        x0: u32,
        width: u32,
        samples: std::ops::Range<u32>,
        add: &mut dyn FnMut(usize, V3<f32>),
    ) {
        let spp = samples.len().max(1);
        let per_batch = (BATCH / spp).max(1);
        let mut x = 0;
        while x < width as usize {
            let n = per_batch.min(width as usize - x);
            self.batch(inp, y, x0 + x as u32, n, samples.clone());
            // Radiance per path, pixel-major: pixel i's samples in order.
            for (k, p) in self.paths.iter().enumerate() {
                let c = p.sum;
                add(x + k / spp, if c.is_finite() { c } else { V3::zero() });
            }
            x += n;
        }
    }

    /// Traces the samples `samples` of `n` pixels of row `y` from column `x`; the paths' sums
    /// are left in `self.paths`, pixel-major.
    fn batch(&mut self, inp: &ShadeInputs, y: u32, x: u32, n: usize, samples: std::ops::Range<u32>) {
        let f = inp.frame;
        let mut times = self.times;
        let t = self.clock();
        self.paths.clear();
        self.rngs.clear();
        for px in x..x + n as u32 {
            for s in samples.clone() {
                self.rngs.push(Sampler::new(y * f.width + px, s, f.seed));
                self.paths.push(PathState::new(path::camera_ray(inp, px, y, s)));
            }
        }
        self.live.clear();
        self.live.extend(0..self.paths.len() as u32);
        let mut t = self.lap(t, &mut times.generate);
        let width = self.isa.width();
        let mut rays = [Ray::new(V3::zero(), V3::zero()); MAX_WIDTH];
        let mut tmax = [0.0f32; MAX_WIDTH];
        while !self.live.is_empty() {
            // Rays: nearest hits, a bundle at a time; shading right after each bundle.
            let mut keep = 0;
            self.shadow.clear();
            let live_n = self.live.len();
            let mut start = 0;
            while start < live_n {
                let end = (start + width).min(live_n);
                for (r, &i) in rays.iter_mut().zip(&self.live[start..end]) {
                    *r = self.paths[i as usize].ray;
                }
                bundle::nearest(self.isa, inp.wide, inp.prims, &rays[..end - start], &mut self.hits);
                t = self.lap(t, &mut times.trace);
                for k in start..end {
                    let i = self.live[k] as usize;
                    let mut nee = None;
                    let more = path::shade_vertex(
                        inp,
                        &mut self.paths[i],
                        self.hits[k - start].as_ref(),
                        &mut self.rngs[i],
                        &mut nee,
                    );
                    if let Some(n) = nee {
                        self.shadow.push((i as u32, n));
                    }
                    if more {
                        self.live[keep] = i as u32;
                        keep += 1;
                    }
                }
                t = self.lap(t, &mut times.shade);
                start = end;
            }
            self.live.truncate(keep);
            // Shadow rays: each unblocked one adds its light to its path.
            for chunk in self.shadow.chunks(width) {
                for (k, (_, n)) in chunk.iter().enumerate() {
                    rays[k] = n.ray;
                    tmax[k] = n.dist;
                }
                let blocked = bundle::occluded(self.isa, inp.wide, inp.prims, &rays[..chunk.len()], &tmax);
                for (k, (i, n)) in chunk.iter().enumerate() {
                    if blocked >> k & 1 == 0 {
                        self.paths[*i as usize].sum += n.value;
                    }
                }
            }
            t = self.lap(t, &mut times.shadow);
        }
        self.times = times;
    }
}
