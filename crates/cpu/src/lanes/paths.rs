//! The paths of a batch, one array per field (a structure of arrays), so that a bundle's
//! lanes load and store each field of consecutive paths with one vector instruction. The
//! arrays have a fixed length: a bundle may read up to a bundle's width past the last path.

use crate::path::PathState;
use strahl_core::math::{Ray, V3};
use strahl_core::render::sampler::Sampler;

pub struct Paths {
    pub o: [Vec<f32>; 3],
    pub d: [Vec<f32>; 3],
    pub beta: [Vec<f32>; 3],
    pub sum: [Vec<f32>; 3],
    pub pdf: Vec<f32>,
    pub seg: Vec<u32>,
    /// 1 where the last scattering was specular (or the path is at the camera).
    pub specular: Vec<u32>,
    pub rng: Vec<u32>,
    /// Where the path's radiance goes when it ends.
    pub slot: Vec<u32>,
    /// Paths held: the first `len` entries.
    pub len: usize,
}

impl Paths {
    /// Room for `cap` paths.
    pub fn new(cap: usize) -> Self {
        let f = || vec![0.0f32; cap];
        let u = || vec![0u32; cap];
        Self {
            o: [f(), f(), f()],
            d: [f(), f(), f()],
            beta: [f(), f(), f()],
            sum: [f(), f(), f()],
            pdf: f(),
            seg: u(),
            specular: u(),
            rng: u(),
            slot: u(),
            len: 0,
        }
    }

    pub fn capacity(&self) -> usize {
        self.pdf.len()
    }

    #[inline]
    pub fn ray(&self, i: usize) -> Ray<f32> {
        Ray::new(V3::new(self.o[0][i], self.o[1][i], self.o[2][i]), V3::new(self.d[0][i], self.d[1][i], self.d[2][i]))
    }

    #[inline]
    pub fn sum(&self, i: usize) -> V3<f32> {
        V3::new(self.sum[0][i], self.sum[1][i], self.sum[2][i])
    }

    #[inline]
    pub fn add_to_sum(&mut self, i: usize, v: V3<f32>) {
        let s = self.sum(i) + v;
        (self.sum[0][i], self.sum[1][i], self.sum[2][i]) = (s.x, s.y, s.z);
    }

    /// Path `i` as the one-path tracer holds it.
    #[inline]
    pub fn get(&self, i: usize) -> (PathState, Sampler) {
        let p = PathState {
            ray: self.ray(i),
            seg: self.seg[i],
            beta: V3::new(self.beta[0][i], self.beta[1][i], self.beta[2][i]),
            pdf_bsdf: self.pdf[i],
            sum: self.sum(i),
            specular: self.specular[i] != 0,
        };
        (p, Sampler::from_state(self.rng[i]))
    }

    #[inline]
    pub fn set(&mut self, i: usize, p: &PathState, rng: &Sampler) {
        let (o, d, b, s) = (p.ray.origin, p.ray.dir, p.beta, p.sum);
        (self.o[0][i], self.o[1][i], self.o[2][i]) = (o.x, o.y, o.z);
        (self.d[0][i], self.d[1][i], self.d[2][i]) = (d.x, d.y, d.z);
        (self.beta[0][i], self.beta[1][i], self.beta[2][i]) = (b.x, b.y, b.z);
        (self.sum[0][i], self.sum[1][i], self.sum[2][i]) = (s.x, s.y, s.z);
        self.pdf[i] = p.pdf_bsdf;
        self.seg[i] = p.seg;
        self.specular[i] = p.specular as u32;
        self.rng[i] = rng.state();
    }

    /// Exchanges paths `i` and `j`.
    #[inline]
    pub fn swap(&mut self, i: usize, j: usize) {
        for a in 0..3 {
            self.o[a].swap(i, j);
            self.d[a].swap(i, j);
            self.beta[a].swap(i, j);
            self.sum[a].swap(i, j);
        }
        self.pdf.swap(i, j);
        self.seg.swap(i, j);
        self.specular.swap(i, j);
        self.rng.swap(i, j);
        self.slot.swap(i, j);
    }

    /// Moves path `from` to entry `to`, for compaction.
    #[inline]
    pub fn move_path(&mut self, from: usize, to: usize) {
        for a in 0..3 {
            self.o[a][to] = self.o[a][from];
            self.d[a][to] = self.d[a][from];
            self.beta[a][to] = self.beta[a][from];
            self.sum[a][to] = self.sum[a][from];
        }
        self.pdf[to] = self.pdf[from];
        self.seg[to] = self.seg[from];
        self.specular[to] = self.specular[from];
        self.rng[to] = self.rng[from];
        self.slot[to] = self.slot[from];
    }
}
