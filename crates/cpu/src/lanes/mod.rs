//! The lane path tracer: the CPU backend's path tracing, many paths at a time.
//!
//! A batch holds the samples of a few neighbouring pixels, one path each, field by field
//! ([`paths`]). Every round walks the rays of the batch's live paths (as bundles,
//! [`crate::accel::bundle`]: 16 lanes with AVX-512, 8 with AVX2, 4 elsewhere, or one at a
//! time, as [`Choice`] measures faster), puts the paths whose rays hit first, shades their
//! vertices a bundle at a time ([`path`], by the steps of [`vertex`]), traces the shadow rays
//! of next-event estimation,
//! and moves the live paths together, so that bundles stay full while paths end.
//!
//! Every path performs the operations of [`super::path::radiance`] in the same order (the
//! bundle walk's hits are the one-ray walk's, bit for bit, and the shading lanes compute what
//! [`super::path::shade_vertex`] computes), and each pixel adds its samples in sample order,
//! so the image equals the one-path-at-a-time tracer's ([`super::path`]) bit for bit;
//! `tests/path_tracing.rs` checks it.
//!
//! Each file is the lane form of the stage it is named for, the twin of the WGSL module of that
//! name as the one-path code is (`path.rs` of `path.wgsl`'s vertex shading, `emitters.rs`,
//! `environment.rs`, `pbr.rs`, `surface.rs`, `camera.rs`); the small formulas both forms use
//! are written once in `strahl_core::render` over lanes, the one-path form their one-lane
//! case. Whitted mode takes the bundles for its camera rays only ([`whitted`]).

mod camera;
mod emitters;
mod environment;
mod facts;
mod guide;
mod path;
mod paths;
mod pbr;
mod surface;
mod texels;
mod vertex;
pub mod whitted;

use super::path::NeeRay;
use super::shade::ShadeInputs;
use crate::accel::bundle::{self, BundleRays, Isa, MAX_WIDTH};
use crate::accel::wide_traverse;
pub use facts::Facts;
use paths::Paths;
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{Hit, Nearest};
pub use vertex::Fallbacks;
use vertex::{Bundle, Out};

use std::time::Duration;
use web_time::Instant;

/// Paths per batch: enough that bundles stay full for most rounds (the later rounds' live
/// paths fill fewer bundles, the last of each round part full), few enough that the batch
/// stays in the first two cache levels (measured in the book's performance chapter).
const BATCH: usize = 2048;

/// Where the lane tracer's time went.
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// Camera rays made, paths ended and pixels summed.
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

/// How a batch's rays walk the tree: as bundles of lanes ([`bundle`]), or each alone, several
/// in flight ([`wide_traverse::nearest_many`]; shadow rays one after the other).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Walk {
    Bundles,
    OneRay,
}

/// The kinds of rays [`Choice`] decides apart: the first bounce's (leaving a pixel's
/// camera hits, so a bundle's rays start close together and share the nodes near them), the
/// later bounces' (from points scattered over the scene), and the shadow rays.
pub(super) const FIRST_BOUNCE: usize = 0;
pub(super) const LATER_BOUNCES: usize = 1;
pub(super) const SHADOWS: usize = 2;
const KINDS: usize = 3;

/// Which walk serves each kind of ray faster here, measured throughout the render (shared by
/// its threads through [`Facts`]): until each walk has walked [`Choice::ENOUGH`] rays of a
/// kind, the batches alternate the two walks and time them; after that, two batches in
/// [`Choice::EVERY`] go on doing so (in [`Choice::EVERY_CLEAR`] where one walk has taken
/// [`Choice::CLEAR`] times the other's time per ray so far), and the others take the walk
/// faster per ray so far. One of each two timed batches walks the slower way, so a clear
/// choice is checked less often (the gain is in the book's performance chapter).
/// Measuring throughout, not only at the start, matters: the first batches are the image's
/// top rows, whose rays need not be like the rest's (the textured glTF under a map: its first
/// 4096 shadow rays walked faster as bundles, the whole image's 1.6 times faster one at a
/// time). The rays after the camera's are timed with their shading, which makes the hit
/// records the one-ray walk hands over; the shadow rays with adding their light. Bundles pay
/// where rays of different directions still meet the same nodes and quadrics (the seed
/// scene); where they part in a large mesh, each ray alone, with several in flight hiding
/// the memory latency, is faster. On the textured glTF the first bounce's rays are faster as
/// bundles and the later bounces' alone, hence the kinds. Both walks find the same hits, so
/// the choice changes the time only, never the image.
#[derive(Clone, Copy, Debug, Default)]
pub struct Choice {
    /// Per kind and walk: time and rays measured.
    spent: [[Duration; 2]; KINDS],
    rays: [[usize; 2]; KINDS],
    /// The walk every ray after the camera's takes, unmeasured (for tests and comparisons).
    forced: Option<Walk>,
}

impl Choice {
    const ENOUGH: usize = 4096;
    const EVERY: u32 = 32;
    const EVERY_CLEAR: u32 = 64;
    const CLEAR: f64 = 1.5;

    /// `walk` for every ray where given, else measured.
    fn forced(walk: Option<Walk>) -> Self {
        Self { forced: walk, ..Self::default() }
    }

    /// The walk for rays of `kind` in batch `batch`, and whether it is to be timed.
    pub(super) fn walk(&self, kind: usize, batch: u32) -> (Walk, bool) {
        if let Some(w) = self.forced {
            return (w, false);
        }
        let alternate = (if batch.is_multiple_of(2) { Walk::Bundles } else { Walk::OneRay }, true);
        if self.rays[kind].iter().any(|&r| r < Self::ENOUGH) {
            return alternate;
        }
        let per_ray = |w: usize| self.spent[kind][w].as_secs_f64() / self.rays[kind][w] as f64;
        let (bundles, alone) = (per_ray(0), per_ray(1));
        let clear = bundles.max(alone) > Self::CLEAR * bundles.min(alone);
        if batch % if clear { Self::EVERY_CLEAR } else { Self::EVERY } < 2 {
            return alternate;
        }
        (if bundles <= alone { Walk::Bundles } else { Walk::OneRay }, false)
    }

    pub(super) fn record(&mut self, kind: usize, walk: Walk, spent: Duration, rays: usize) {
        let w = walk as usize;
        self.spent[kind][w] += spent;
        self.rays[kind][w] += rays;
    }
}

/// Samples `samples` of pixels `x0 .. x0 + width` of row `y`.
#[derive(Clone, Debug)]
pub struct Span {
    pub y: u32,
    pub x0: u32,
    pub width: u32,
    pub samples: std::ops::Range<u32>,
}

/// `$module::batch(tracer, …)`: one batch of [`Tracer::row`] in lanes of `$n`, compiled with
/// the target features `$features` where given (called only where the processor has them).
/// Each is a free function in a module of its own, as rustc places a function in the codegen
/// unit of its module (and a method in that of its type's): with `codegen-units` high enough
/// that the units are not merged (strahl-cpu's profile in the workspace's `Cargo.toml`), LLVM
/// optimises the three forms, each the whole lane tracer inlined into one function and about a
/// minute of LLVM's time, on as many threads as the build has instead of one after another.
macro_rules! isa_batch {
    ($module:ident, $n:literal $(, $features:literal)?) => {
        mod $module {
            use super::{ShadeInputs, Span, Tracer};
            $(#[target_feature(enable = $features)])?
            #[inline(never)]
            pub(super) fn batch(tracer: &mut Tracer, inp: &ShadeInputs, span: &Span, next: u64) -> u64 {
                tracer.batch_of_row::<$n>(inp, span, next)
            }
        }
    };
}

/// The lane tracer's working memory, kept from batch to batch (one per thread).
pub struct Tracer<'f> {
    isa: Isa,
    facts: &'f Facts,
    paths: Paths,
    /// Per path: it goes on after this round's vertex.
    more: Vec<bool>,
    /// Per slot (pixel-major, then sample): the pixel's offset in the row, and the radiance.
    slots: Vec<(u32, V3<f32>)>,
    hits: [Nearest<f32>; MAX_WIDTH],
    shadow: Vec<(u32, NeeRay)>,
    /// The one-ray walks' rays and answers (as many answers as a batch has paths).
    one_rays: Vec<Ray<f32>>,
    one_hits: Vec<Option<Hit<f32>>>,
    nearest: Vec<Nearest<f32>>,
    /// How rays after the camera's walk the tree: this tracer's copy of `facts.choice`, taken
    /// at each batch.
    choice: Choice,
    /// Batches traced (the choice alternates the walks while it measures).
    batches: u32,
    /// Where the time went, when timed.
    pub times: StageTimes,
    /// Vertices shaded in lanes and those left to the one-path code.
    pub fallbacks: Fallbacks,
    timed: bool,
}

impl<'f> Tracer<'f> {
    /// A tracer with `isa`'s lanes for scenes `facts` describes; `timed`: measure each stage
    /// (two clock reads per stage and round).
    pub fn new(isa: Isa, facts: &'f Facts, timed: bool) -> Self {
        let cap = BATCH + MAX_WIDTH;
        Self {
            isa,
            facts,
            paths: Paths::new(cap),
            more: vec![false; cap],
            slots: Vec::with_capacity(BATCH),
            hits: [Nearest::new(0.0); MAX_WIDTH],
            shadow: Vec::with_capacity(cap),
            one_rays: Vec::with_capacity(cap),
            one_hits: vec![None; cap],
            nearest: Vec::with_capacity(cap),
            choice: Choice::default(),
            batches: 0,
            times: StageTimes::default(),
            fallbacks: Fallbacks::default(),
            timed,
        }
    }

    /// The samples of the pixels of `span`: each sample's radiance (0 where not finite) goes to
    /// `add(pixel offset, radiance)`, every pixel's in sample order. The batches are traced by
    /// one function per lane width, whatever `add` is: only this loop is compiled per caller.
    pub fn row(&mut self, inp: &ShadeInputs, span: Span, add: &mut impl FnMut(usize, V3<f32>)) {
        let total = span.width as u64 * span.samples.len() as u64;
        let mut next = 0;
        while next < total {
            next = match self.isa {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: the processor has AVX-512 (a tracer is only made for lanes it runs).
                Isa::Avx512 => unsafe { isa_avx512::batch(self, inp, &span, next) },
                #[cfg(target_arch = "x86_64")]
                // SAFETY: as above, AVX2.
                Isa::Avx2 => unsafe { isa_avx2::batch(self, inp, &span, next) },
                _ => isa_4::batch(self, inp, &span, next),
            };
            let t = self.clock();
            for &(px, c) in &self.slots {
                add(px as usize, c);
            }
            Self::lap(t, &mut self.times.generate);
        }
    }
}

#[cfg(target_arch = "x86_64")]
isa_batch!(isa_avx512, 16, "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma,bmi1,bmi2,lzcnt,popcnt");
#[cfg(target_arch = "x86_64")]
isa_batch!(isa_avx2, 8, "avx2,fma,bmi1,bmi2,lzcnt,popcnt");
isa_batch!(isa_4, 4);

impl<'f> Tracer<'f> {
    /// The batch of `span`'s (pixel, sample) pairs, in pixel-major order, that starts at pair
    /// `next` (at most [`BATCH`] of them), traced into `self.slots`; returns where the next
    /// batch starts.
    #[inline(always)]
    fn batch_of_row<const N: usize>(&mut self, inp: &ShadeInputs, span: &Span, next: u64) -> u64 {
        let Span { y, x0, width, ref samples } = *span;
        let f = inp.frame;
        let spp = samples.len() as u32;
        let total = width as u64 * spp as u64;
        let t = self.clock();
        let end = (next + BATCH as u64).min(total);
        let count = (end - next) as usize;
        self.slots.clear();
        // The first pair's pixel and sample; each lane steps on from there.
        let (mut px, mut s) = ((next / spp as u64) as u32, (next % spp as u64) as u32);
        for k in (0..count).step_by(N) {
            let mut x = [0u32; N];
            let mut smp = [0u32; N];
            for l in 0..N {
                (x[l], smp[l]) = (x0 + px, samples.start + s);
                // Lanes past the batch repeat its last pair.
                if k + l + 1 < count {
                    s += 1;
                    if s == spp {
                        (px, s) = (px + 1, 0);
                    }
                }
            }
            camera::start::<N>(
                f,
                &mut self.paths,
                k,
                strahl_core::math::lanes::U(x),
                y,
                strahl_core::math::lanes::U(smp),
                k as u32,
            );
            self.slots.extend(x[..N.min(count - k)].iter().map(|&xx| (xx - x0, V3::zero())));
        }
        self.paths.len = count;
        let mut times = self.times;
        Self::lap(t, &mut times.generate);
        self.batch::<N>(inp, &mut times);
        self.times = times;
        end
    }

    #[inline(always)]
    fn clock(&self) -> Option<Instant> {
        self.timed.then(Instant::now)
    }

    #[inline(always)]
    fn lap(since: Option<Instant>, into: &mut Duration) -> Option<Instant> {
        since.map(|s| {
            let n = Instant::now();
            *into += n - s;
            n
        })
    }

    /// Path `i` has ended: its radiance (0 where not finite) goes to its slot.
    #[inline(always)]
    fn finish(&mut self, i: usize) {
        let c = self.paths.sum(i);
        self.slots[self.paths.slot[i] as usize].1 = if c.is_finite() { c } else { V3::zero() };
    }

    /// Orders the round's `live` paths so that those whose rays hit something come first,
    /// their hits (and the one-ray walk's records, where `records`) moving with them: bundles
    /// then hold hits only or misses only, and a bundle of misses is shaded by the little that
    /// a miss needs (in an open scene half the rays leave it; in mixed bundles their lanes
    /// waited on the surface shading). The order of paths in a batch does not matter: each
    /// knows its slot.
    fn hits_first(&mut self, live: usize, records: bool) {
        let (mut i, mut end) = (0, live);
        loop {
            while i < end && self.nearest[i].found {
                i += 1;
            }
            while end > i && !self.nearest[end - 1].found {
                end -= 1;
            }
            if end <= i {
                break;
            }
            end -= 1;
            self.paths.swap(i, end);
            self.nearest.swap(i, end);
            if records {
                self.one_hits.swap(i, end);
            }
            i += 1;
        }
    }

    /// Traces the batch's paths to their ends; each path's radiance goes to its slot.
    #[inline(always)]
    fn batch<const N: usize>(&mut self, inp: &ShadeInputs, times: &mut StageTimes) {
        let mut rays = BundleRays { o: [[0.0; MAX_WIDTH]; 3], d: [[0.0; MAX_WIDTH]; 3] };
        let mut tmax = [0.0f32; MAX_WIDTH];
        let batch = self.batches;
        self.batches += 1;
        // The round: 0 for the camera rays, 1 for the first bounce, ...
        let mut round = 0;
        self.choice = self.facts.walks();
        while self.paths.len > 0 {
            let mut t = self.clock();
            self.shadow.clear();
            let live = self.paths.len;
            // Camera rays walk as bundles; later rays as the choice says for their bounce.
            let kind = if round == 1 { FIRST_BOUNCE } else { LATER_BOUNCES };
            let (walk, timed) = if round == 0 { (Walk::Bundles, false) } else { self.choice.walk(kind, batch) };
            // Measured: the walk and the shading of the round, which takes the one-ray walk's
            // hit records and makes them itself after bundles.
            let measuring = timed.then(Instant::now);
            // The round's hits first, so that the shading of one bundle can ask for the next
            // one's primitives ahead (path::prefetch).
            self.nearest.clear();
            let records = match walk {
                Walk::OneRay => {
                    self.one_rays.clear();
                    self.one_rays.extend((0..live).map(|i| self.paths.ray(i)));
                    // (nearest_many writes every answer: the last round's need no clearing.)
                    let hits = &mut self.one_hits[..live];
                    wide_traverse::nearest_many(inp.wide, inp.prims, &self.one_rays, 0.0, f32::INFINITY, hits);
                    self.nearest.extend(hits.iter().map(|h| match h {
                        Some(h) => Nearest { t: h.t, prim_ref: h.prim_ref, part: h.part, found: true },
                        None => Nearest::new(f32::INFINITY),
                    }));
                    true
                }
                Walk::Bundles => {
                    for k in (0..live).step_by(N) {
                        let n = N.min(live - k);
                        // The lanes past n hold other paths' rays (the arrays are padded): not
                        // read.
                        for a in 0..3 {
                            rays.o[a][..N].copy_from_slice(&self.paths.o[a][k..k + N]);
                            rays.d[a][..N].copy_from_slice(&self.paths.d[a][k..k + N]);
                        }
                        bundle::nearest_lanes(self.isa, inp.wide, inp.prims, &rays, n, &mut self.hits);
                        self.nearest.extend_from_slice(&self.hits[..n]);
                    }
                    false
                }
            };
            t = Self::lap(t, &mut times.trace);
            self.hits_first(live, records);
            path::prefetch(inp, &self.nearest[..N.min(live)]);
            let mut k = 0;
            while k < live {
                let n = N.min(live - k);
                let ahead = (k + N).min(live)..(k + 2 * N).min(live);
                path::prefetch(inp, &self.nearest[ahead]);
                let b = Bundle { k, n, hits: &self.nearest[k..], records: records.then(|| &self.one_hits[k..]) };
                let mut out = Out { more: &mut self.more, nee: &mut self.shadow, fallbacks: &mut self.fallbacks };
                // (Called directly, not through a pointer: inlined here, in the ISA's code.)
                if self.facts.rich {
                    path::shade::<N, true>(inp, self.facts, &mut self.paths, &b, &mut out);
                } else {
                    path::shade::<N, false>(inp, self.facts, &mut self.paths, &b, &mut out);
                }
                t = Self::lap(t, &mut times.shade);
                k += n;
            }
            if let Some(start) = measuring {
                self.facts.record_walk(kind, walk, start.elapsed(), live);
            }
            round += 1;
            // Shadow rays: each unblocked one adds its light to its path.
            let (walk, timed) = self.choice.walk(SHADOWS, batch);
            let start = timed.then(Instant::now);
            for chunk in self.shadow.chunks(N) {
                let blocked = match walk {
                    Walk::Bundles => {
                        for (l, (_, s)) in chunk.iter().enumerate() {
                            for a in 0..3 {
                                rays.o[a][l] = s.ray.origin[a];
                                rays.d[a][l] = s.ray.dir[a];
                            }
                            tmax[l] = s.dist;
                        }
                        bundle::occluded_lanes(self.isa, inp.wide, inp.prims, &rays, &tmax, chunk.len())
                    }
                    Walk::OneRay => wide_traverse::occluded_mask(inp.wide, inp.prims, chunk.len(), |l| {
                        (&chunk[l].1.ray, chunk[l].1.dist)
                    }),
                };
                for (l, (i, s)) in chunk.iter().enumerate() {
                    if blocked >> l & 1 == 0 {
                        self.paths.add_to_sum(*i as usize, s.value);
                    }
                }
            }
            if let Some(start) = start {
                self.facts.record_walk(SHADOWS, walk, start.elapsed(), self.shadow.len());
            }
            t = Self::lap(t, &mut times.shadow);
            // The paths that ended leave their radiance; the last live paths move into their
            // places (the order of paths in a batch does not matter: each knows its slot).
            let (mut i, mut end) = (0, live);
            while i < end {
                if self.more[i] {
                    i += 1;
                    continue;
                }
                self.finish(i);
                end -= 1;
                while end > i && !self.more[end] {
                    self.finish(end);
                    end -= 1;
                }
                if end > i {
                    self.paths.move_path(end, i);
                    i += 1;
                }
            }
            let keep = i;
            self.paths.len = keep;
            Self::lap(t, &mut times.generate);
        }
    }
}

/// A direction uniform over the sphere, for the lanes' tests.
#[cfg(test)]
fn unit_direction(rng: &mut strahl_core::render::sampler::Sampler) -> V3<f32> {
    let z = 1.0 - 2.0 * rng.next_f32();
    let phi = 2.0 * std::f32::consts::PI * rng.next_f32();
    let r = (1.0 - z * z).max(0.0).sqrt();
    V3::new(r * phi.cos(), r * phi.sin(), z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The batches that time both walks (alternating them) and the walk the others take:
    /// every batch until both have walked enough rays, then two in 32, or two in 64 where
    /// one walk is clearly faster; the faster one otherwise, each kind of ray measured apart.
    #[test]
    fn the_choice_times_close_walks_often_and_clear_ones_rarely() {
        let timed = |c: &Choice, kind: usize| (0..128u32).filter(|&b| c.walk(kind, b).1).count();
        let mut c = Choice::default();
        assert_eq!(timed(&c, FIRST_BOUNCE), 128, "before enough rays, every batch is timed");
        assert_eq!((c.walk(FIRST_BOUNCE, 4).0, c.walk(FIRST_BOUNCE, 5).0), (Walk::Bundles, Walk::OneRay));
        let ms = Duration::from_millis;
        // The first bounce: bundles 1.2 times as fast (close); shadow rays alone
        // 2 times as fast (clear).
        c.record(FIRST_BOUNCE, Walk::Bundles, ms(100), Choice::ENOUGH);
        c.record(FIRST_BOUNCE, Walk::OneRay, ms(120), Choice::ENOUGH);
        c.record(SHADOWS, Walk::Bundles, ms(200), Choice::ENOUGH);
        c.record(SHADOWS, Walk::OneRay, ms(100), Choice::ENOUGH);
        assert_eq!(timed(&c, FIRST_BOUNCE), 2 * 128 / 32);
        assert_eq!(timed(&c, SHADOWS), 2 * 128 / 64);
        assert_eq!(c.walk(FIRST_BOUNCE, 3), (Walk::Bundles, false));
        assert_eq!(c.walk(SHADOWS, 3), (Walk::OneRay, false));
        assert_eq!(c.walk(SHADOWS, 64), (Walk::Bundles, true));
        assert_eq!(c.walk(SHADOWS, 65), (Walk::OneRay, true));
        // The later bounces' rays are measured apart: before enough of theirs, every batch
        // is timed.
        assert_eq!(timed(&c, LATER_BOUNCES), 128);
        c.record(LATER_BOUNCES, Walk::Bundles, ms(130), Choice::ENOUGH);
        c.record(LATER_BOUNCES, Walk::OneRay, ms(100), Choice::ENOUGH);
        assert_eq!(c.walk(LATER_BOUNCES, 3), (Walk::OneRay, false));
        assert_eq!(c.walk(FIRST_BOUNCE, 3), (Walk::Bundles, false));
        // A forced walk is never timed.
        let f = Choice::forced(Some(Walk::OneRay));
        assert_eq!((f.walk(FIRST_BOUNCE, 0), f.walk(SHADOWS, 1)), ((Walk::OneRay, false), (Walk::OneRay, false)));
    }
}
