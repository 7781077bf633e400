//! Whitted ray tracing with the lanes' camera rays: the primary rays of a row's samples walk
//! the tree as bundles ([`crate::accel::bundle`]: 16 lanes with AVX-512, 8 with AVX2, 4
//! elsewhere), then each ray tree goes on one ray at a time ([`shade::radiance_from`]) from
//! the hit its bundle found. Camera rays are where bundles pay: neighbouring pixels' rays meet
//! the same nodes. The rays a tree spawns (mirror, glass, shadow rays to each light) go their
//! own ways, and the one-ray walk serves them as it serves [`shade::shade_pixel`].
//!
//! The bundle walk's hits are the one-ray walk's, bit for bit, and so are their records
//! ([`Primitives::hit`] of them), and each pixel adds its samples in sample order, so the
//! image equals [`shade::shade_pixel`]'s bit for bit (`crates/cpu/tests/lane_tracer.rs`).
//!
//! [`Primitives::hit`]: strahl_core::primitives::Primitives::hit

use crate::accel::bundle::{self, Isa, MAX_WIDTH};
use crate::shade::{self, ShadeInputs};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::Nearest;
use strahl_core::render::camera::primary_ray;

/// Pixels `x0 .. x0 + row.len()` of row `y`, Whitted, each the mean of its `spp` samples
/// (those not finite left out), as [`shade::shade_pixel`] computes them.
pub fn row(isa: Isa, inp: &ShadeInputs, y: u32, x0: u32, row: &mut [[f32; 3]]) {
    let f = inp.frame;
    let (spp, width) = (f.spp as usize, isa.width());
    let total = row.len() * spp;
    let mut sums = vec![V3::<f32>::zero(); row.len()];
    let mut rays = [Ray::new(V3::zero(), V3::new(0.0, 0.0, 1.0)); MAX_WIDTH];
    let mut hits = [Nearest::new(0.0); MAX_WIDTH];
    // Pixel-major (pixel, sample) pairs, a bundle at a time.
    let mut k = 0;
    while k < total {
        let n = width.min(total - k);
        for (l, ray) in rays[..n].iter_mut().enumerate() {
            let (px, s) = ((k + l) / spp, (k + l) % spp);
            *ray = primary_ray(f, x0 + px as u32, y, f.sample_base + s as u32);
        }
        bundle::nearest(isa, inp.wide, inp.prims, &rays[..n], &mut hits);
        for (l, (ray, h)) in rays[..n].iter().zip(&hits).enumerate() {
            let hit = h.found.then(|| inp.prims.hit(h.prim_ref, ray, h.t, h.part));
            let c = shade::radiance_from(inp, *ray, Some(hit));
            if c.is_finite() {
                sums[(k + l) / spp] += c;
            }
        }
        k += n;
    }
    for (px, sum) in row.iter_mut().zip(&sums) {
        *px = (*sum / f.spp as f32).to_array();
    }
}
